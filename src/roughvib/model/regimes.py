"""Discrete regimes of the hybrid system and the transition table (regime, event) -> regime.

The solver owns *when* a root fires; this module owns *what it means*: which regime follows,
what the event is called in the log, and which guard acted. Root indices follow
:func:`roughvib.model.kernels.events`: ``0..K-1`` contacts, then three friction roots whose
meaning depends on the law (feldmann: branch, latch, phase; set-valued laws: break-away or
velocity zero, bare threshold, dwell timer; dynamic laws: the velocity's sign, none, phase).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from roughvib.model import kernels as kn

__all__ = ["Regime", "Transition", "initial_regime", "switch"]

NO_DWELL = -1.0


@dataclass
class Regime:
    """Discrete state (mutable; switched at events).

    Attributes
    ----------
    closed : ndarray of int, shape (K,)
        1 where contact k is closed (spring active), 0 where it is open (lift-off).
    branch : int
        feldmann: friction-law branch b = sign(v + s v_h). coulomb: slip direction +1/-1, or 0
        in stick.
    latch : int
        feldmann: hysteresis latch s (+1 after a velocity maximum, -1 after a minimum).
    v_ext : float
        feldmann: running velocity extremum tracked by the latch [m/s].
    stick : bool
        Stick phase (feldmann: ``|v|`` < friction.stick_velocity, for logging; coulomb: the regime).
    dwell_end : float
        coulomb: break-away is held until this time [s] (``NO_DWELL`` when inactive).
    set_valued : bool
        Whether the law is set-valued (``coulomb`` or ``table``: stick is a regime with an
        algebraic friction force); False for the single-valued and dynamic laws, whose
        regimes are the branch (the sign of the velocity for a dynamic law), the latch and the
        logged stick phase.
    switch_times : list of float
        coulomb: times of the recent stick/slip switches [s], for the chatter guard (only
        those within its window are kept).
    """

    closed: np.ndarray
    branch: int = -1
    latch: int = -1
    v_ext: float = 0.0
    stick: bool = True
    dwell_end: float = NO_DWELL
    set_valued: bool = False
    switch_times: list = field(default_factory=list)

    def pack(self, reg: np.ndarray, rf: np.ndarray) -> None:
        """Write into the kernels' ``reg``/``rf`` arrays."""
        reg[kn.REG_B] = self.branch
        reg[kn.REG_S] = self.latch
        reg[kn.REG_PHASE] = 1 if self.stick else 0
        reg[kn.REG_CLOSED:] = self.closed
        rf[kn.RF_VEXT] = self.v_ext
        rf[kn.RF_DWELL] = self.dwell_end

    def describe(self) -> str:
        """Short text, e.g. ``closed=1111111011 slip+`` or ``... b=+1 s=-1 slip``."""
        c = "".join(str(int(v)) for v in self.closed)
        if self.set_valued:
            phase = "stick" if self.branch == 0 else ("slip+" if self.branch > 0 else "slip-")
            return f"closed={c} {phase}"
        return (f"closed={c} b={self.branch:+d} s={self.latch:+d} "
                f"{'stick' if self.stick else 'slip'}")


@dataclass
class Transition:
    """One logged consequence of a root: event kind, contact (-1: block level), guard."""

    kind: str
    contact: int
    guard: str = ""


def initial_regime(closed: np.ndarray, fp: np.ndarray, tangential: bool,
                   set_valued: bool) -> Regime:
    """Regime at t = 0: the static contact set, block at rest.

    feldmann: latch s = -1 (accelerating branch), branch from sign(s v_h) (or of T0 when
    v_h = 0), stick phase. coulomb: stick unless ``|T0|`` exceeds the break-away bound with the
    static normal force m g, then slip in the direction of T0.
    """
    reg = Regime(closed=closed.astype(np.int64), set_valued=set_valued)
    if not tangential:
        return reg
    t0 = fp[kn.FP_T0]
    if set_valued:
        bound = fp[kn.FP_MU_STICK] * fp[kn.FP_MASS] * fp[kn.FP_GRAV] * (1 + fp[kn.FP_HYST])
        reg.branch = 0 if abs(t0) <= bound else int(math.copysign(1, t0))
        reg.stick = reg.branch == 0
        return reg
    reg.latch = -1 if t0 >= 0 else 1
    x0 = reg.latch * fp[kn.FP_VH]
    reg.branch = int(np.sign(x0)) if x0 != 0 else (1 if t0 >= 0 else -1)
    reg.v_ext = 0.0
    reg.stick = True
    return reg


def switch(regime: Regime, idx: int, t: float, y: np.ndarray, fp: np.ndarray,
           n_contacts: int, i_vx: int, i_force: slice, dwell_time: float,
           chatter_switches: int = 0, chatter_window: float = 0.0) -> list[Transition]:
    """Apply the transition for root ``idx`` fired at time ``t`` with state ``y`` (in place).

    ``dwell_time`` [s] holds every stick phase of the Coulomb law (0: off). The chatter guard
    holds a stick phase for ``chatter_window`` [s] only when it begins with more than
    ``chatter_switches`` stick/slip switches within the last ``chatter_window`` (0: off).

    Returns the transitions to log (possibly none: a guard held the regime).
    """
    K = n_contacts
    if idx < K:
        if regime.closed[idx] == 1:
            regime.closed[idx] = 0
            return [Transition("lift_off", idx)]
        regime.closed[idx] = 1
        return [Transition("touch_down", idx)]
    j = idx - K
    vx = float(y[i_vx])
    if not regime.set_valued:
        if j == 0:
            regime.branch = -regime.branch
            return [Transition("friction_branch", -1)]
        if j == 1:
            regime.latch = -regime.latch
            regime.v_ext = vx
            return [Transition("latch_flip", -1)]
        regime.stick = not regime.stick
        return [Transition("stick" if regime.stick else "slip", -1)]
    # set-valued Coulomb law
    fsum = float(np.sum(y[i_force] * regime.closed))
    texc = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t)
    mu_st = fp[kn.FP_MU_STICK]
    if regime.branch != 0:
        if j != 0:
            return []
        # velocity zero in slip: stick if the static bound holds, else slip the other way
        chatter = _count_switch(regime, t, chatter_switches, chatter_window)
        if abs(texc) <= mu_st * fsum:
            regime.branch = 0
            regime.stick = True
            regime.dwell_end = t + dwell_time if dwell_time > 0 else NO_DWELL
            if chatter:
                regime.dwell_end = max(regime.dwell_end, t + chatter_window)
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
    lam = texc - fp[kn.FP_R2] * vx
    if abs(lam) > mu_st * fsum * (1 + fp[kn.FP_HYST]):
        return _break_away(regime, lam, t)
    return []


def _count_switch(regime: Regime, t: float, n_max: int, window: float) -> bool:
    """Record a stick/slip switch at ``t``; True when more than ``n_max`` (> 0) lie within
    the last ``window`` [s] (chatter)."""
    times = [s for s in regime.switch_times if s > t - window] if n_max > 0 else []
    times.append(t)
    regime.switch_times = times
    return n_max > 0 and len(times) > n_max


def _break_away(regime: Regime, direction: float, t: float) -> list[Transition]:
    regime.switch_times.append(t)
    regime.branch = int(math.copysign(1, direction))
    regime.stick = False
    regime.dwell_end = NO_DWELL
    return [Transition("slip", -1)]
