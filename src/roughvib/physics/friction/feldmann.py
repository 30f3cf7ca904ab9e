"""The paper's friction law (Eq. 10) with the latched hysteresis, and its tangential-only model.

This module is the ``feldmann`` law of the friction-law component (docs/architecture.md, "A
friction law"); it owns

* the numba kernels of the regularised law (docs/theory.md): the branch expression
  :func:`feldmann_mu` (the event-driven solvers keep the branch ``b`` as a discrete state and
  switch it at ``x = 0``), the law itself :func:`feldmann_mu_law` (``b = sign(x)``), and the
  latched hysteresis sign :func:`latch_update` / :func:`latch_margin`;
* a plain-Python reference :func:`mu_reference` written from the two-branch form of Eq. 10;
* the law's tangential-only model (block under a constant normal force, no roughness), the
  trapezoidal rule with a scalar Newton iteration per step, in which T0 is calibrated
  (``roughvib.physics.friction.calibration``).
* the law's regimes (``roughvib.physics.friction.regime``): its start
  :func:`regime_at_start` and the transitions of its three friction roots (:data:`ROOTS`:
  branch, latch, phase) :func:`regime_transition`, which the model's
  ``roughvib.model.regimes.switch`` calls.

Conventions (docs/theory.md): the friction force on the block is ``-mu(v + s v_h) F_N``, with
``s = +1`` after a velocity maximum (decelerating branch) and ``s = -1`` after a velocity minimum
(accelerating branch). All kernels take floats, ints and arrays only and run unchanged with
``NUMBA_DISABLE_JIT=1``.
"""

from __future__ import annotations

import math

from numba import njit

from roughvib.physics.friction.regime import RootValues, StartValues, Transition

__all__ = ["EXP_ZERO_BELOW", "LAW_ID", "ROOTS", "effective_latch_velocity", "exp_or_zero",
           "feldmann_mu", "feldmann_mu_d2", "feldmann_mu_law", "latch_margin", "latch_update",
           "mu_reference", "regime_at_start", "regime_notation", "regime_transition",
           "tangential_feldmann"]

#: the law's id in the kernels (``off[OFF_LAW]``; ``roughvib.physics.friction.laws``)
LAW_ID = 0

#: below this argument ``math.exp`` returns exactly 0.0 (half the smallest subnormal is
#: exp(-745.133)); the C library reaches that 0 through its underflow handler, several times the
#: cost of an exp, and the Feldmann law's steep term exp(-a2 X) underflows whenever the block
#: slides (perf: about 1 % of a default solve)
EXP_ZERO_BELOW = -745.2


@njit(cache=True, inline="always")
def exp_or_zero(arg):
    """``math.exp(arg)``, with the exact 0.0 it underflows to below :data:`EXP_ZERO_BELOW`
    returned without calling it (so the same value to the bit; NaN stays NaN)."""
    if arg < EXP_ZERO_BELOW:
        return 0.0
    return math.exp(arg)


@njit(cache=True)
def feldmann_mu(x, b, mu_slip, mu_stick, a1, a2):
    """Branch ``b`` of Eq. 10 and its exact derivative.

    ``mu_b(x) = b (mu_slip + (mu_stick - mu_slip) exp(-a1 b x) - mu_stick exp(-a2 b x))``.
    With ``b = sign(x)`` this is the law; the other branch is its smooth continuation through
    ``x = 0`` (both branches give ``mu = 0`` and the same slope there).

    Parameters
    ----------
    x : float
        Shifted relative velocity X = v + s v_h [m/s].
    b : float
        Branch, +1.0 or -1.0.
    mu_slip, mu_stick : float
        Quasi-static kinetic and static coefficients [-].
    a1, a2 : float
        Exponential constants [s/m].

    Returns
    -------
    mu : float
        Friction coefficient [-].
    dmu_dx : float
        d mu / d x [s/m].
    """
    e1 = exp_or_zero(-a1 * b * x)
    e2 = exp_or_zero(-a2 * b * x)
    dmu = mu_stick - mu_slip
    mu = b * (mu_slip + dmu * e1 - mu_stick * e2)
    # b * b = 1: the derivative has the same expression on both branches
    dmu_dx = -a1 * dmu * e1 + a2 * mu_stick * e2
    return mu, dmu_dx


@njit(cache=True)
def feldmann_mu_d2(x, b, mu_slip, mu_stick, a1, a2):
    """:func:`feldmann_mu` and the branch's second derivative (for Newton matrices of
    fourth-order steps, whose tangential rate equation holds ``dmu/dx``).

    Returns
    -------
    mu, dmu_dx, d2mu_dx2 : float
        Friction coefficient [-], its first [s/m] and second [s^2/m^2] derivative in x;
        mu and dmu_dx are those of :func:`feldmann_mu`.
    """
    e1 = exp_or_zero(-a1 * b * x)
    e2 = exp_or_zero(-a2 * b * x)
    dmu = mu_stick - mu_slip
    mu = b * (mu_slip + dmu * e1 - mu_stick * e2)
    dmu_dx = -a1 * dmu * e1 + a2 * mu_stick * e2
    d2mu_dx2 = b * (a1 * a1 * dmu * e1 - a2 * a2 * mu_stick * e2)
    return mu, dmu_dx, d2mu_dx2


@njit(cache=True)
def feldmann_mu_law(x, mu_slip, mu_stick, a1, a2):
    """The law of Eq. 10: :func:`feldmann_mu` on the branch ``b = sign(x)`` (+1 at x = 0).

    The law is C1 at ``x = 0`` (its second derivative jumps there).

    Returns
    -------
    mu : float
        Friction coefficient [-].
    dmu_dx : float
        d mu / d x [s/m].
    """
    b = 1.0 if x >= 0.0 else -1.0
    return feldmann_mu(x, b, mu_slip, mu_stick, a1, a2)


@njit(cache=True)
def latch_update(s, v_ext, v, eps):
    """Advance the latched hysteresis sign by one velocity sample (docs/theory.md).

    ``s = +1`` (after a velocity maximum) tracks the running minimum of the velocity in
    ``v_ext``; ``s = -1`` (after a velocity minimum) tracks the running maximum. The sign flips
    once ``v`` has moved back from the running extremum by more than ``eps``; the extremum then
    restarts at ``v``.

    Parameters
    ----------
    s : float
        Current latch sign, +1.0 or -1.0.
    v_ext : float
        Running extremum of the velocity since the last flip [m/s].
    v : float
        New velocity sample [m/s].
    eps : float
        Flip threshold epsilon_v > 0 [m/s].

    Returns
    -------
    s_new : float
    v_ext_new : float [m/s]
    flipped : bool
    """
    if s > 0.0:
        if v < v_ext:
            v_ext = v
        if v - v_ext > eps:
            return -1.0, v, True
        return 1.0, v_ext, False
    if v > v_ext:
        v_ext = v
    if v_ext - v > eps:
        return 1.0, v, True
    return -1.0, v_ext, False


def effective_latch_velocity(parameters) -> float:
    """epsilon_v = max(latch_velocity, hysteresis_velocity) [m/s] of a law's own keys
    (``friction.parameters``; 0 for a law without them): the latch's margin.

    Parameters
    ----------
    parameters : mapping
        The law's own keys.

    Returns
    -------
    float
    """
    return max(float(parameters.get("latch_velocity", 0.0)),
               float(parameters.get("hysteresis_velocity", 0.0)))


@njit(cache=True)
def latch_margin(s, v_ext, v, eps):
    """Distance of the latch from its flip: ``eps - s (v - v_ext)`` [m/s].

    Positive while no flip is due; it crosses zero (downward) where :func:`latch_update` flips,
    so an event-driven solver can use it as a root function (``v_ext`` is then the running
    extremum held as a discrete state and updated at the step ends).
    """
    return eps - s * (v - v_ext)


@njit(cache=True)
def tangential_feldmann(t0_amp, mass, r2, normal_force, omega, mu_slip, mu_stick, a1, a2,
                        v_h, eps, dt, n_steps, v_out, x_out):
    """Trapezoidal rule with a scalar Newton iteration on v per step; latch after each step.

    Fills ``v_out`` and ``x_out`` (length n_steps + 1) and returns the number of latch flips and
    the largest Newton iteration count.
    """
    s = -1.0
    v_ext = 0.0
    v0 = 0.0
    x0 = 0.0
    v_out[0] = v0
    x_out[0] = x0
    half = 0.5 * dt
    mu0, _ = feldmann_mu_law(v0 + s * v_h, mu_slip, mu_stick, a1, a2)
    f0 = t0_amp - mu0 * normal_force - r2 * v0
    flips = 0
    max_iter = 0
    tol = 1e-14
    for n in range(n_steps):
        t1 = (n + 1) * dt
        drive1 = t0_amp * math.cos(omega * t1)
        # explicit Euler predictor; the residual is strictly increasing in v1 as long as
        # m + dt/2 (mu' F_N + r2) > 0, which holds for any dt << m / (a1 (mu_stick-mu_slip) F_N)
        v1 = v0 + dt * f0 / mass
        it = 0
        f1 = 0.0
        while True:
            it += 1
            mu1, dmu1 = feldmann_mu_law(v1 + s * v_h, mu_slip, mu_stick, a1, a2)
            f1 = drive1 - mu1 * normal_force - r2 * v1
            res = mass * (v1 - v0) - half * (f0 + f1)
            jac = mass + half * (dmu1 * normal_force + r2)
            dv = res / jac
            v1 -= dv
            if abs(dv) <= tol * (1.0 + abs(v1)) or it >= 50:
                break
        if it > max_iter:
            max_iter = it
        x1 = x0 + half * (v0 + v1)
        s, v_ext, flipped = latch_update(s, v_ext, v1, eps)
        if flipped:
            flips += 1
            mu1, _ = feldmann_mu_law(v1 + s * v_h, mu_slip, mu_stick, a1, a2)
            f1 = drive1 - mu1 * normal_force - r2 * v1
        v_out[n + 1] = v1
        x_out[n + 1] = x1
        v0 = v1
        x0 = x1
        f0 = f1
    return flips, max_iter

# --------------------------------------------------------------------------------------------
# the law's regimes: its start and its three friction roots (docs/architecture.md)
# --------------------------------------------------------------------------------------------

#: the law's friction roots ``K + j`` (``kernels.events``): the branch b = sign(X) with
#: X = v + s v_h, the latch's velocity extremum, the logged stick/slip phase
ROOTS = ("branch", "latch", "phase")


def regime_at_start(regime, start: StartValues) -> None:
    """The law's regime at t = 0, block at rest, set in ``regime`` (in place).

    Latch s = -1 (accelerating branch) when T0 >= 0, else +1; branch b = sign(s v_h), or the
    sign of T0 when v_h = 0; the running extremum 0 m/s; the logged phase stick.

    Parameters
    ----------
    regime : roughvib.model.regimes.Regime
        Its ``latch``, ``branch``, ``v_ext`` and ``stick`` are set.
    start : StartValues
        T0 [N] and v_h [m/s] are read.
    """
    t0 = start.force_amplitude
    regime.latch = -1 if t0 >= 0 else 1
    x0 = regime.latch * start.hysteresis_velocity
    regime.branch = int(math.copysign(1, x0)) if x0 != 0 else (1 if t0 >= 0 else -1)
    regime.v_ext = 0.0
    regime.stick = True


def regime_notation(regime) -> str:
    """The friction part of the regime as the event log writes it, e.g. ``b=+1 s=-1 slip``
    (branch, latch, logged phase)."""
    return f"b={regime.branch:+d} s={regime.latch:+d} {'stick' if regime.stick else 'slip'}"


def regime_transition(regime, j: int, at: RootValues) -> list[Transition]:
    """The law's transition for its friction root ``j`` (0, 1, 2; see ``ROOTS``), in place.

    Root 0 (X = v + s v_h crosses zero) flips the branch b; root 1 (the latch margin) flips
    the latch s and records the velocity at the flip as the new running extremum v_ext; root
    2 (``|v|`` crosses ``friction.stick_velocity``) flips the logged phase.

    Parameters
    ----------
    regime : roughvib.model.regimes.Regime
        Switched in place.
    j : int
        The friction root that fired.
    at : RootValues
        The velocity ``vx`` [m/s] is read (root 1).

    Returns
    -------
    list of Transition
        The one event to log: ``friction_branch``, ``latch_flip``, ``stick`` or ``slip``.
    """
    if j == 0:
        regime.branch = -regime.branch
        return [Transition("friction_branch", -1)]
    if j == 1:
        regime.latch = -regime.latch
        regime.v_ext = at.vx
        return [Transition("latch_flip", -1)]
    if j == 2:
        regime.stick = not regime.stick
        return [Transition("stick" if regime.stick else "slip", -1)]
    raise ValueError(f"feldmann friction law: no friction root {j} (its roots: "
                     f"{', '.join(ROOTS)})")


# --------------------------------------------------------------------------------------------
# plain-Python reference
# --------------------------------------------------------------------------------------------


def mu_reference(x: float, mu_slip: float, mu_stick: float, a1: float, a2: float) -> float:
    """Eq. 10 as printed in the paper, two explicit branches (no numba, for tests).

    Parameters
    ----------
    x : float
        X = relative velocity + hysteresis shift [m/s].

    Returns
    -------
    float
        mu(X) [-]; 0 at X = 0.
    """
    if x > 0.0:
        return mu_slip + (mu_stick - mu_slip) * math.exp(-a1 * x) - mu_stick * math.exp(-a2 * x)
    if x < 0.0:
        return -mu_slip - (mu_stick - mu_slip) * math.exp(a1 * x) + mu_stick * math.exp(a2 * x)
    return 0.0
