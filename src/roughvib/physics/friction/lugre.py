"""The LuGre dynamic friction law, normalised by the normal force (docs/friction.md).

Canudas de Wit, Olsson, Astrom and Lischinsky, "A new model for control of systems with
friction", IEEE Trans. Automatic Control 40 (1995) 419-425. Bristles of mean deflection z
[m] carry the friction force; here the force scales with the normal force, as the paper's law
does::

    T = mu F_N,   mu = sigma0 z + sigma1 dz/dt + sigma2 v,
    dz/dt = v - sigma0 |v| z / g(v),   g(v) = mu_c + (mu_s - mu_c) exp(-(v / v_s)^2),

with ``mu_c = friction.mu_slip`` and ``mu_s = friction.mu_stick`` (so the law's steady
sliding and break-away levels are the paper's), ``sigma0`` [1/m] the bristles' stiffness per
unit normal force, ``sigma1`` [s/m] their damping and ``sigma2`` [s/m] the viscous term.

Closed forms (the tests assert both):

* steady sliding at constant v (dz/dt = 0): ``z = g(v) sgn(v) / sigma0`` and
  :func:`steady_coefficient` ``mu_ss(v) = g(v) sgn(v) + sigma2 v``;
* small displacements from rest (pre-sliding, ``sigma0 |x| << g``): ``z = x`` and
  ``mu = sigma0 x + (sigma1 + sigma2) v``, a spring of stiffness ``sigma0 F_N``.

The state z is one differential state of the DAE (``friction.state``); ``|v|`` is written
``b v`` with the sign b of the velocity held as the regime (``REG_B``) and switched by the root
``b v`` at every reversal, so the right-hand side is smooth within a regime.
The law's regimes are that sign and the logged stick/slip phase (:data:`ROOTS`,
:func:`regime_at_start`, :func:`regime_transition`); it has no latch.

All kernels take floats and arrays only and run unchanged with ``NUMBA_DISABLE_JIT=1``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from roughvib.physics.friction.feldmann import regime_notation as feldmann_regime_notation
from roughvib.physics.friction.regime import RootValues, StartValues, Transition

#: the regime as the event log writes it: the Feldmann law's form ``b=+1 s=-1 slip``, b the
#: sign of the velocity (the latch s is held at its start)
regime_notation = feldmann_regime_notation

__all__ = ["LAW_ID", "N_PARAMETERS", "P_SIGMA0", "P_SIGMA1", "P_SIGMA2", "P_VS", "ROOTS",
           "bristle_law", "pack_parameters", "regime_at_start", "regime_notation",
           "regime_transition", "steady_coefficient", "stribeck_curve", "tangential_lugre"]

#: the law's id in the kernels (``off[OFF_LAW]``; ``roughvib.physics.friction.laws``)
LAW_ID = 3

#: positions of the law's own parameters in its packed block (``fp`` from ``kernels.N_FP``)
P_SIGMA0 = 0  # bristle stiffness per unit normal force [1/m]
P_SIGMA1 = 1  # bristle damping [s/m]
P_SIGMA2 = 2  # viscous coefficient [s/m]
P_VS = 3      # Stribeck velocity v_s [m/s]
N_PARAMETERS = 4


def pack_parameters(parameters) -> np.ndarray:
    """The law's packed parameter block from the scene's ``friction.parameters``.

    Parameters
    ----------
    parameters : mapping
        ``sigma0`` [1/m], ``sigma1`` [s/m], ``sigma2`` [s/m], ``stribeck_velocity`` [m/s]
        (validated and completed by the scene).

    Returns
    -------
    ndarray, shape (N_PARAMETERS,)
    """
    p = np.zeros(N_PARAMETERS)
    p[P_SIGMA0] = parameters["sigma0"]
    p[P_SIGMA1] = parameters["sigma1"]
    p[P_SIGMA2] = parameters["sigma2"]
    p[P_VS] = parameters["stribeck_velocity"]
    return p


@njit(cache=True)
def stribeck_curve(v, mu_c, mu_s, vs):
    """``g(v) = mu_c + (mu_s - mu_c) exp(-(v / v_s)^2)`` and ``dg/dv``.

    Returns
    -------
    g : float
        [-].
    dg_dv : float
        [s/m].
    """
    u = v / vs
    e = math.exp(-u * u)
    return mu_c + (mu_s - mu_c) * e, -2.0 * u / vs * (mu_s - mu_c) * e


@njit(cache=True)
def bristle_law(v, z, b, mu_c, mu_s, p):
    """The law's coefficient, the bristle rate and their exact partial derivatives.

    Parameters
    ----------
    v : float
        Sliding velocity [m/s].
    z : float
        Bristle deflection [m].
    b : float
        Sign of the velocity in the current regime (+1.0 or -1.0): ``|v| = b v``.
    mu_c, mu_s : float
        Coulomb and static levels [-] (``friction.mu_slip``, ``friction.mu_stick``).
    p : ndarray
        Packed parameters (:func:`pack_parameters`).

    Returns
    -------
    mu, zdot : float
        Coefficient [-] and dz/dt [m/s].
    dmu_dv, dmu_dz : float
        [s/m], [1/m].
    dzdot_dv, dzdot_dz : float
        [-], [1/s].
    """
    s0 = p[P_SIGMA0]
    s1 = p[P_SIGMA1]
    g, dg = stribeck_curve(v, mu_c, mu_s, p[P_VS])
    a = b * v
    zdot = v - s0 * a * z / g
    dzdot_dv = 1.0 - s0 * b * z / g + s0 * a * z * dg / (g * g)
    dzdot_dz = -s0 * a / g
    mu = s0 * z + s1 * zdot + p[P_SIGMA2] * v
    return (mu, zdot, s1 * dzdot_dv + p[P_SIGMA2], s0 + s1 * dzdot_dz, dzdot_dv, dzdot_dz)


def steady_coefficient(v: float, mu_c: float, mu_s: float, sigma2: float, vs: float) -> float:
    """The closed-form steady-sliding coefficient ``g(v) sgn(v) + sigma2 v`` (plain Python).

    Parameters
    ----------
    v : float
        Constant sliding velocity [m/s] (not 0).
    mu_c, mu_s : float
        Coulomb and static levels [-].
    sigma2, vs : float
        Viscous coefficient [s/m], Stribeck velocity [m/s].
    """
    g = mu_c + (mu_s - mu_c) * math.exp(-(v / vs) ** 2)
    return math.copysign(g, v) + sigma2 * v


@njit(cache=True)
def tangential_lugre(t0_amp, mass, r2, normal_force, omega, mu_c, mu_s, p, dt, n_steps, v_out,
                     x_out):
    """The law's tangential-only model: trapezoidal rule on (v, z), Newton per step.

    ``m v' = T0 cos(omega t) - mu(v, z) F_N - r2 v`` with the law's bristle state, from rest
    (v = z = 0). ``|v|`` takes the sign of the Newton iterate (the step is A-stable and second
    order; the kink at v = 0 costs the order only in the step that contains the reversal).
    Fills ``v_out``, ``x_out`` (length n_steps + 1); returns the largest Newton count.
    """
    v0 = 0.0
    z0 = 0.0
    x0 = 0.0
    v_out[0] = v0
    x_out[0] = x0
    half = 0.5 * dt
    b0 = 1.0 if t0_amp >= 0.0 else -1.0
    mu0, zd0, _, _, _, _ = bristle_law(v0, z0, b0, mu_c, mu_s, p)
    f0 = t0_amp - mu0 * normal_force - r2 * v0
    max_iter = 0
    for n in range(n_steps):
        drive1 = t0_amp * math.cos(omega * (n + 1) * dt)
        v1 = v0 + dt * f0 / mass
        z1 = z0 + dt * zd0
        it = 0
        f1 = 0.0
        zd1 = 0.0
        while True:
            it += 1
            b = 1.0 if v1 >= 0.0 else -1.0
            mu1, zd1, dmv, dmz, dzv, dzz = bristle_law(v1, z1, b, mu_c, mu_s, p)
            f1 = drive1 - mu1 * normal_force - r2 * v1
            r_v = mass * (v1 - v0) - half * (f0 + f1)
            r_z = z1 - z0 - half * (zd0 + zd1)
            j11 = mass + half * (dmv * normal_force + r2)
            j12 = half * dmz * normal_force
            j21 = -half * dzv
            j22 = 1.0 - half * dzz
            det = j11 * j22 - j12 * j21
            dv = (r_v * j22 - j12 * r_z) / det
            dz = (j11 * r_z - j21 * r_v) / det
            v1 -= dv
            z1 -= dz
            if (abs(dv) <= 1e-14 * (1.0 + abs(v1)) and abs(dz) <= 1e-14 * (1e-6 + abs(z1))) \
                    or it >= 50:
                break
        if it > max_iter:
            max_iter = it
        x1 = x0 + half * (v0 + v1)
        v_out[n + 1] = v1
        x_out[n + 1] = x1
        v0 = v1
        z0 = z1
        x0 = x1
        f0 = f1
        zd0 = zd1
    return max_iter


# --------------------------------------------------------------------------------------------
# the law's regimes: the velocity's sign and the logged phase (docs/architecture.md)
# --------------------------------------------------------------------------------------------

#: the law's friction roots ``K + j`` (``kernels.events``): the velocity's sign (margin b v),
#: none (a constant margin: the law has no latch), the logged stick/slip phase
ROOTS = ("velocity sign", "none", "phase")


def regime_at_start(regime, start: StartValues) -> None:
    """The law's regime at t = 0, block at rest, set in ``regime`` (in place).

    The sign b of the velocity is that of T0 (+1 for T0 = 0), the block's first motion; the
    logged phase is stick and the running extremum 0 m/s. The law has no latch: ``latch``
    keeps the value the event logs have always shown for it, -1 when T0 >= 0, else +1.

    Parameters
    ----------
    regime : roughvib.model.regimes.Regime
        Its ``branch``, ``latch``, ``v_ext`` and ``stick`` are set.
    start : StartValues
        T0 [N] is read.
    """
    forward = start.force_amplitude >= 0
    regime.latch = -1 if forward else 1
    regime.branch = 1 if forward else -1
    regime.v_ext = 0.0
    regime.stick = True


def regime_transition(regime, j: int, at: RootValues) -> list[Transition]:
    """The law's transition for its friction root ``j`` (0, 1, 2; see ``ROOTS``), in place.

    Root 0 (the velocity reverses, margin b v) flips the sign b; root 1 has a constant margin
    and never fires (nothing to switch); root 2 (``|v|`` crosses
    ``friction.stick_velocity``) flips the logged phase.

    Parameters
    ----------
    regime : roughvib.model.regimes.Regime
        Switched in place.
    j : int
        The friction root that fired.
    at : RootValues
        Not read: the law's transitions depend on the regime alone.

    Returns
    -------
    list of Transition
        The event to log: ``friction_branch``, ``stick`` or ``slip`` (none for root 1).
    """
    if j == 0:
        regime.branch = -regime.branch
        return [Transition("friction_branch", -1)]
    if j == 1:
        return []
    if j == 2:
        regime.stick = not regime.stick
        return [Transition("stick" if regime.stick else "slip", -1)]
    raise ValueError(f"lugre friction law: no friction root {j} (its roots: "
                     f"{', '.join(ROOTS)})")
