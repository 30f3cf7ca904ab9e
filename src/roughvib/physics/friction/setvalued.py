"""What the set-valued laws share: their curves' dispatch, their regimes and tangential model.

A set-valued law (``coulomb``, ``table``) holds the block in stick at v = 0 with the friction
force an algebraic unknown, breaks away at ``mu_stick F_N`` and slides on its kinetic curve;
the solvers hold the stick regime, each law module its curve. :func:`kinetic_coefficient` is
the one place that dispatches on the set-valued law's id; :func:`tangential_set_valued` is
their tangential-only model (the calibration of T0); :func:`regime_at_start` and
:func:`regime_transition` are their regimes (stick, slip+ and slip-) with the dwell,
hysteresis and chatter guards, switched at their three friction roots (:data:`ROOTS`).
"""

from __future__ import annotations

import math

from numba import njit

from roughvib.physics.friction import coulomb, table
from roughvib.physics.friction.regime import NO_DWELL, RootValues, StartValues, Transition

__all__ = ["ROOTS", "kinetic_coefficient", "regime_at_start", "regime_notation",
           "regime_transition", "tangential_set_valued"]

#: the set-valued laws' friction roots ``K + j`` (``kernels.events``): in stick the break-away
#: margin (in slip b v, the velocity's zero), in stick the bare threshold without the switching
#: hysteresis, in stick the dwell timer
ROOTS = ("break-away or v = 0", "threshold", "dwell timer")


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


# --------------------------------------------------------------------------------------------
# the regimes: stick (branch 0), slip+ and slip- (branch +1 / -1), and their guards
# --------------------------------------------------------------------------------------------


def regime_at_start(regime, start: StartValues) -> None:
    """The regime at t = 0, block at rest, set in ``regime`` (in place).

    Stick (branch 0) unless ``|T0|`` exceeds the break-away bound with the static normal force,
    ``mu_stick m g (1 + hysteresis)``; then slip in the direction of T0.

    Parameters
    ----------
    regime : roughvib.model.regimes.Regime
        Its ``branch`` and ``stick`` are set.
    start : StartValues
        T0 [N], the mass [kg], gravity [m/s^2], ``mu_stick`` [-] and the hysteresis [-].
    """
    t0 = start.force_amplitude
    bound = start.mu_stick * start.mass * start.gravity * (1 + start.hysteresis)
    regime.branch = 0 if abs(t0) <= bound else int(math.copysign(1, t0))
    regime.stick = regime.branch == 0


def regime_notation(regime) -> str:
    """The friction part of the regime as the event log writes it: ``stick``, ``slip+`` or
    ``slip-``."""
    return "stick" if regime.branch == 0 else ("slip+" if regime.branch > 0 else "slip-")


def regime_transition(regime, j: int, at: RootValues) -> list[Transition]:
    """The transition for friction root ``j`` (0, 1, 2; see ``ROOTS``), in place.

    In slip only root 0 fires (the velocity reaches zero): stick when the static bound holds,
    ``|T_exc| <= mu_stick F_N`` with the exciting force T_exc and the closed contacts' normal
    force F_N, else slip in the direction of T_exc. A stick phase is held for
    ``dwell_time`` [s] (0: off), and for ``chatter_window`` [s] when it begins with more than
    ``chatter_switches`` stick/slip switches within the last ``chatter_window`` (the chatter
    guard; 0: off). In stick, root 0 (the break-away margin with the hysteresis) breaks away
    in the direction of T_exc unless the dwell holds; root 1 (the bare threshold) is only
    logged as a hysteresis hold; root 2 (the dwell timer) ends the hold and breaks away at
    once when ``|T_exc - r2 v| > mu_stick F_N (1 + hysteresis)``.

    Parameters
    ----------
    regime : roughvib.model.regimes.Regime
        Switched in place (``branch``, ``stick``, ``dwell_end`` [s], ``switch_times`` [s]).
    j : int
        The friction root that fired.
    at : RootValues
        The values at the root.

    Returns
    -------
    list of Transition
        The events to log, possibly none (a guard held the regime).
    """
    if j not in (0, 1, 2):
        raise ValueError(f"set-valued friction law: no friction root {j} (its roots: "
                         f"{', '.join(ROOTS)})")
    t, texc, fsum, mu_st = at.t, at.exciting_force, at.normal_force, at.mu_stick
    if regime.branch != 0:
        if j != 0:
            return []
        # velocity zero in slip: stick if the static bound holds, else slip the other way
        chatter = _count_switch(regime, t, at.chatter_switches, at.chatter_window)
        if abs(texc) <= mu_st * fsum:
            regime.branch = 0
            regime.stick = True
            regime.dwell_end = t + at.dwell_time if at.dwell_time > 0 else NO_DWELL
            if chatter:
                regime.dwell_end = max(regime.dwell_end, t + at.chatter_window)
                return [Transition("stick", -1),
                        Transition("chatter_guard", -1, guard="chatter")]
            return [Transition("stick", -1)]
        regime.branch = int(math.copysign(1, texc))
        return [Transition("slip", -1, guard="")]
    if j == 0:  # break-away margin
        if regime.dwell_end != NO_DWELL and t < regime.dwell_end:
            return [Transition("dwell_hold", -1, guard="dwell")]
        return _break_away(regime, texc, t)
    if j == 1:  # bare threshold crossed while the hysteresis still holds
        return [Transition("hysteresis_hold", -1, guard="hysteresis")]
    # dwell timer expired: break away now if the bound is already exceeded
    regime.dwell_end = NO_DWELL
    lam = texc - at.r2 * at.vx
    if abs(lam) > mu_st * fsum * (1 + at.hysteresis):
        return _break_away(regime, lam, t)
    return []


def _count_switch(regime, t: float, n_max: int, window: float) -> bool:
    """Record a stick/slip switch at ``t``; True when more than ``n_max`` (> 0) lie within
    the last ``window`` [s] (chatter)."""
    times = [s for s in regime.switch_times if s > t - window] if n_max > 0 else []
    times.append(t)
    regime.switch_times = times
    return n_max > 0 and len(times) > n_max


def _break_away(regime, direction: float, t: float) -> list[Transition]:
    regime.switch_times.append(t)
    regime.branch = int(math.copysign(1, direction))
    regime.stick = False
    regime.dwell_end = NO_DWELL
    return [Transition("slip", -1)]
