"""The set-valued ``coulomb`` law's kinetic curve (docs/friction.md).

Stick is a regime with the velocity held at zero (the solvers own that part, shared with every
set-valued law); in slip the coefficient is :func:`coulomb_kinetic`, constant ``mu_slip`` or
decaying from ``mu_stick`` with the Stribeck velocity ``friction.parameters.stribeck_velocity``.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["LAW_ID", "coulomb_kinetic"]

#: the law's id in the kernels (``off[OFF_LAW]``; ``roughvib.physics.friction.laws``)
LAW_ID = 1


@njit(cache=True)
def coulomb_kinetic(v, mu_slip, mu_stick, vs):
    """Kinetic coefficient mu_k(v) = mu_slip + (mu_stick - mu_slip) exp(-v / vs), v >= 0.

    Parameters
    ----------
    v : float
        Sliding speed [m/s].
    mu_slip, mu_stick : float
        Coefficients [-].
    vs : float
        Stribeck velocity [m/s]; ``vs <= 0`` gives the constant mu_slip.

    Returns
    -------
    mu_k : float
        [-].
    dmu_k_dv : float
        [s/m].
    """
    if vs <= 0.0:
        return mu_slip, 0.0
    e = math.exp(-v / vs)
    return mu_slip + (mu_stick - mu_slip) * e, -(mu_stick - mu_slip) * e / vs

