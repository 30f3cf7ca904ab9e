"""Discrete regimes of the hybrid system and the transition table (regime, event) -> regime.

The solver owns *when* a root fires; this module owns *what it means*: which regime follows,
what the event is called in the log, and which guard acted. Root indices follow
:func:`roughvib.model.kernels.events`: ``0..K-1`` contacts, switched here, then three friction
roots whose meaning and transitions are the friction law's (``LAWS[law].roots`` and
``.transition``, in the law's module of ``roughvib.physics.friction``: feldmann's branch,
latch and phase; the set-valued laws' break-away or velocity zero, bare threshold and dwell
timer; a dynamic law's velocity sign, none and phase). This module builds what a law reads
(``RootValues``, ``StartValues``) from the packed parameters and the state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from roughvib.model import kernels as kn
from roughvib.physics.friction.laws import LAWS, FrictionLaw
from roughvib.physics.friction.regime import NO_DWELL, RootValues, StartValues, Transition

__all__ = ["NO_DWELL", "Regime", "Transition", "initial_regime", "switch"]

#: the law of a regime pickled before the regime carried its law (a checkpoint stored
#: ``set_valued``), and the notation of a regime without friction (False): each has its
#: kind's start, transitions and notation (``table`` has ``coulomb``'s; a dynamic
#: law's roots 0 and 2 switch as ``feldmann``'s do, its root 1 never fires)
_LAW_OF_KIND = {False: "feldmann", True: "coulomb"}


def _law(name: str) -> FrictionLaw:
    """The registered law ``name``; ValueError for a name no law is registered under."""
    try:
        return LAWS[name]
    except (KeyError, TypeError):
        raise ValueError(f"friction law {name!r}: no law is registered under this name "
                         f"(registered: {', '.join(LAWS)})") from None


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
    law : str or None
        The friction law (``friction.law``), whose ``LAWS`` entry starts and switches the
        friction part of the regime; None without tangential dynamics (no friction regime:
        the friction roots never fire).
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
    law: str | None = None
    switch_times: list = field(default_factory=list)

    @property
    def set_valued(self) -> bool:
        """Whether the law is set-valued (``coulomb`` or ``table``: stick is a regime with an
        algebraic friction force); False for the single-valued and dynamic laws, whose
        regimes are the branch (the sign of the velocity for a dynamic law), the latch and the
        logged stick phase, and without a friction regime (``law`` None)."""
        return self.law is not None and _law(self.law).set_valued

    def __setstate__(self, state: dict) -> None:
        """Unpickle; a regime pickled before it carried its law (a checkpoint that stored
        ``set_valued``) gets the law of that kind (``_LAW_OF_KIND``)."""
        state = dict(state)
        legacy = state.pop("set_valued", None)
        if "law" not in state:
            state["law"] = _LAW_OF_KIND[bool(legacy)]
        self.__dict__.update(state)

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
        # the law's notation; without a friction regime the single-valued one (as always)
        law = _law(self.law if self.law is not None else _LAW_OF_KIND[False])
        return f"closed={c} {law.notation(self)}"


def initial_regime(closed: np.ndarray, fp: np.ndarray, tangential: bool,
                   law: str) -> Regime:
    """Regime at t = 0: the static contact set, block at rest, the law's friction regime.

    The friction part is the law's (``LAWS[law].initial``): feldmann, latch s = -1
    (accelerating branch), branch from sign(s v_h) (or of T0 when v_h = 0), stick phase; the
    set-valued laws, stick unless ``|T0|`` exceeds the break-away bound with the static normal
    force m g, then slip in the direction of T0. Without tangential dynamics only the contacts
    (``Regime.law`` None).

    Parameters
    ----------
    closed : ndarray of int, shape (K,)
        The static contact set (1: closed).
    fp : ndarray
        The kernels' packed parameters (``kernels.FP_*``).
    tangential : bool
        Whether the block moves tangentially.
    law : str
        The friction law's name (``friction.law``).

    Returns
    -------
    Regime
    """
    entry = _law(law)
    if not tangential:
        return Regime(closed=closed.astype(np.int64))
    reg = Regime(closed=closed.astype(np.int64), law=law)
    entry.initial(reg, StartValues(
        force_amplitude=fp[kn.FP_T0], mass=fp[kn.FP_MASS], gravity=fp[kn.FP_GRAV],
        mu_stick=fp[kn.FP_MU_STICK], hysteresis=fp[kn.FP_HYST],
        hysteresis_velocity=fp[kn.FP_VH]))
    return reg


def switch(regime: Regime, idx: int, t: float, y: np.ndarray, fp: np.ndarray,
           n_contacts: int, i_vx: int, i_force: slice, dwell_time: float,
           chatter_switches: int = 0, chatter_window: float = 0.0) -> list[Transition]:
    """Apply the transition for root ``idx`` fired at time ``t`` with state ``y`` (in place).

    A contact root opens or closes its contact; a friction root ``K + j`` is the law's
    (``LAWS[regime.law].transition``), given the values at the root. ``dwell_time`` [s] holds
    every stick phase of a set-valued law (0: off). The chatter guard holds a stick phase for
    ``chatter_window`` [s] only when it begins with more than ``chatter_switches`` stick/slip
    switches within the last ``chatter_window`` (0: off).

    Returns the transitions to log (possibly none: a guard held the regime).
    """
    K = n_contacts
    if idx < K:
        if regime.closed[idx] == 1:
            regime.closed[idx] = 0
            return [Transition("lift_off", idx)]
        regime.closed[idx] = 1
        return [Transition("touch_down", idx)]
    entry = _law(regime.law)
    at = RootValues(
        t=t, vx=float(y[i_vx]),
        exciting_force=fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t),
        normal_force=float(np.sum(y[i_force] * regime.closed)),
        mu_stick=fp[kn.FP_MU_STICK], hysteresis=fp[kn.FP_HYST], r2=fp[kn.FP_R2],
        dwell_time=dwell_time, chatter_switches=chatter_switches,
        chatter_window=chatter_window)
    return entry.transition(regime, idx - K, at)
