"""What the set-valued laws share: their kinetic curves' dispatch and the tangential model.

A set-valued law (``coulomb``, ``table``) holds the block in stick at v = 0 with the friction
force an algebraic unknown, breaks away at ``mu_stick F_N`` and slides on its kinetic curve;
the solvers own the stick regime, each law module its curve. :func:`kinetic_coefficient` is
the one place that dispatches on the set-valued law's id; :func:`tangential_set_valued` is
their tangential-only model (the calibration of T0).
"""

from __future__ import annotations

import math

from numba import njit

from roughvib.physics.friction import coulomb, table

__all__ = ["kinetic_coefficient", "tangential_set_valued"]


@njit(cache=True)
def kinetic_coefficient(law, v, mu_slip, mu_stick, vs, tab):
    """Kinetic coefficient of a set-valued law at sliding speed ``v`` >= 0, and its slope.

    Parameters
    ----------
    law : int
        A set-valued law's id (``coulomb.LAW_ID``, ``table.LAW_ID``; any other raises).
    v : float
        Sliding speed [m/s] (the kernels pass ``b v`` with the slip direction b).
    mu_slip, mu_stick, vs : float
        Coulomb law: ``coulomb_kinetic``.
    tab : ndarray
        Table law: its packed curve (``law_table``; ignored otherwise).

    Returns
    -------
    mu_k : float
        [-].
    dmu_k_dv : float
        [s/m].
    """
    if law == table.LAW_ID:
        return table.table_kinetic(v, tab)
    if law == coulomb.LAW_ID:
        return coulomb.coulomb_kinetic(v, mu_slip, mu_stick, vs)
    raise ValueError("friction law: kinetic_coefficient of a law that is not set-valued")


@njit(cache=True)
def tangential_set_valued(t0_amp, mass, r2, normal_force, omega, law, mu_slip, mu_stick, vs,
                          tab, dt, n_steps, v_out, x_out):
    """Backward-Euler (Moreau-Jean) steps of the set-valued law; exact stick (v = 0).

    Per step: the free velocity without friction; stick if the friction impulse that holds
    it at zero stays within ``dt mu_stick F_N``, else slip, ``|v1| = |v_free| - c mu_k(|v1|)``
    with ``c = dt F_N / (m + dt r2)`` solved by Newton (safeguarded by bisection). Fills
    ``v_out``, ``x_out`` (length n_steps + 1); returns the number of stick-to-slip switches.
    """
    v0 = 0.0
    x0 = 0.0
    v_out[0] = v0
    x_out[0] = x0
    c = dt * normal_force / (mass + dt * r2)
    breaks = 0
    stuck = True
    for n in range(n_steps):
        t1 = (n + 1) * dt
        vfree = (v0 + dt * t0_amp * math.cos(omega * t1) / mass) / (1.0 + dt * r2 / mass)
        a = abs(vfree)
        if a <= c * mu_stick:
            v1 = 0.0
            stuck = True
        else:
            if stuck:
                breaks += 1
            stuck = False
            lo = 0.0
            hi = a
            w = a
            for _it in range(100):
                mu, dmu = kinetic_coefficient(law, w, mu_slip, mu_stick, vs, tab)
                g = w - a + c * mu
                if g > 0.0:
                    hi = w
                else:
                    lo = w
                dw = g / (1.0 + c * dmu) if 1.0 + c * dmu > 0.0 else 0.5 * (hi - lo)
                w_new = w - dw
                if not (lo < w_new < hi):
                    w_new = 0.5 * (lo + hi)
                if abs(w_new - w) <= 1e-15 + 1e-13 * w_new:
                    w = w_new
                    break
                w = w_new
            v1 = math.copysign(w, vfree)
        x1 = x0 + dt * v1
        v_out[n + 1] = v1
        x_out[n + 1] = x1
        v0 = v1
        x0 = x1
    return breaks
