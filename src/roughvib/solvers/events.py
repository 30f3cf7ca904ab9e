"""What happens at a root, for every event-driven solver: switch, log, guard, consistent restart.

The solvers own *when* a root fires (IDA's root finding, or the adaptive exact-modal scheme's
own search); :class:`EventBook` owns what follows, so that both produce the same event log:
the regime is switched by :func:`roughvib.model.regimes.switch`, the state made consistent by
:meth:`.System.consistent`, both limits of the margins and of the friction force are logged,
and the event-storm guard (``solver.max_events`` within ``solver.event_window``) stops the run.
The stall guard (:func:`step_budget`, :func:`stall_failure`) bounds the solver work between two
output times, so that every run ends.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass, field

import numpy as np

from roughvib.model import kernels as kn
from roughvib.model.regimes import Regime, switch
from roughvib.model.system import System

__all__ = ["EventBook", "EventRecord", "SolverFailure", "initial_phase_events", "stall_failure",
           "step_budget"]

#: Stall guard: a run whose mean internal step within one output interval falls below
#: STALL_MEAN_STEP (and that takes more than STALL_MIN_STEPS steps there) stops as "stalled".
#: Legitimate runs stay far below it: IDA at rtol 1e-14 took ~6,500 steps per 1e-5 s output
#: interval on a lift-off scene, adaptive-modal ~1,000; the stalled runs took 20,000
#: steps (and as many Jacobians) without leaving the interval.
STALL_MEAN_STEP = 5e-10  # s
STALL_MIN_STEPS = 20_000


class SolverFailure(RuntimeError):
    """The integration could not continue; ``status`` names the cause."""

    def __init__(self, status: str, message: str, t: float):
        super().__init__(message)
        self.status = status
        self.t = t


def step_budget(output_step: float) -> int:
    """Internal steps allowed within one output interval of ``output_step`` [s]."""
    return max(STALL_MIN_STEPS, math.ceil(output_step / STALL_MEAN_STEP))


def stall_failure(method: str, t: float, what: str, regime: str) -> SolverFailure:
    """The ``stalled`` failure of the stall guard, with its hint.

    ``what`` says which budget ran out, e.g. "more than 20000 steps".
    """
    return SolverFailure(
        "stalled",
        f"{method} stalled at t = {t:.6g} s (regime {regime}): {what} within one output "
        f"interval without reaching its end. Hint: the tolerances may be below what double "
        f"precision resolves for this scene (loosen solver.atol, solver.atol_acceleration or "
        f"solver.rtol), or the scene has a discontinuity no event sees; the event log's last "
        f"entries show where", t)


@dataclass
class EventRecord:
    """One entry of the event log (the regime before and after, and the trigger values).

    Attributes
    ----------
    time : float [s]
    kind : str
        ``lift_off``, ``touch_down``, ``stick``, ``slip``, ``friction_branch``,
        ``latch_flip``, the guards' ``hysteresis_hold``, ``dwell_hold``, ``chatter_guard``,
        or ``event_storm``. The phase a run starts in is logged at its start time.
    contact : int
        Contact index for contact events, -1 for block-level events.
    regime_before, regime_after : str
        :meth:`.Regime.describe` texts.
    margin_before, margin_after : float
        The root function that fired, at the event, evaluated with the regime before (≈ 0,
        it just crossed) and with the regime after the switch (the new regime's margin for
        the same root: for contacts the compression in m with the sign of that regime, for
        friction the velocity [m/s], force margin [N] or phase margin [m^2/s^2]).
    tangential_velocity : float [m/s]
        After the switch.
    normal_force : float [N]
        Sum of contact forces after the switch.
    contact_force : float [N]
        Force of the event's contact after the switch (NaN for block-level events).
    friction_before, friction_after : float [N]
        Friction force on the block just before and just after the switch (left and right
        limits: it jumps at Coulomb stick/slip transitions).
    """

    time: float
    kind: str
    contact: int
    regime_before: str
    regime_after: str
    margin_before: float
    margin_after: float
    tangential_velocity: float
    normal_force: float
    contact_force: float
    friction_before: float
    friction_after: float


def initial_phase_events(system: System, t: float, y: np.ndarray, reg: np.ndarray,
                         rf: np.ndarray, stick: bool, regime_text: str = ""
                         ) -> list[EventRecord]:
    """The friction phase a run starts in, as a ``stick`` or ``slip`` event at ``t``.

    With it the log reads as a complete phase sequence: every phase, the first included,
    starts with an event. Empty without tangential dynamics (prescribed motion).

    Parameters
    ----------
    system : System
    t : float
        Start time [s].
    y : ndarray, shape (n_states,)
        Consistent initial state.
    reg, rf : ndarray
        The kernels' view of the initial regime.
    stick : bool
        The run starts in stick (else in slip).
    regime_text : str
        :meth:`~roughvib.model.regimes.Regime.describe` of the initial regime (``regime_after``).
    """
    if not system.tangential:
        return []
    K = system.n_contacts
    out = np.empty(kn.n_output_columns(K))
    kn.outputs(t, y, out, *system.kernel_args(reg, rf))
    fric = float(out[kn.OUT_FRICTION])
    return [EventRecord(t, "stick" if stick else "slip", -1, "", regime_text, float("nan"),
                        float("nan"), float(out[kn.OUT_VX]),
                        float(out[kn.OUT_NORMAL]), float("nan"), fric,
                        fric)]


@dataclass
class EventBook:
    """The regime of a run and the log of its switches.

    Parameters
    ----------
    system : System
    regime : Regime
        Switched in place; ``reg``/``rf`` (the kernels' view of it) are repacked after every
        switch.
    reg, rf : ndarray
        From :meth:`.System.new_regime_arrays`.
    """

    system: System
    regime: Regime
    reg: np.ndarray
    rf: np.ndarray
    events: list[EventRecord] = field(default_factory=list)
    recent: collections.deque = field(default_factory=collections.deque)
    stats: collections.Counter = field(default_factory=collections.Counter)
    #: root indices the latest :meth:`apply` switched: the fired ones and the contacts switched
    #: at a zero margin
    switched: set[int] = field(default_factory=set)

    def log_initial_phase(self, t: float, y: np.ndarray) -> None:
        """Log the friction phase the run starts in (see :func:`initial_phase_events`)."""
        for rec in initial_phase_events(self.system, t, y, self.reg, self.rf,
                                        self.regime.stick, self.regime.describe()):
            self.events.append(rec)
            self.stats[f"events_{rec.kind}"] += 1

    def apply(self, te: float, ye: np.ndarray, fired: set[int]
              ) -> tuple[np.ndarray, np.ndarray]:
        """Switch the regime for the roots ``fired`` at time ``te`` and state ``ye``.

        Returns the consistent (y, yp) of the new regime to restart from. Raises
        :class:`SolverFailure` (status ``event_storm``) when the storm guard trips; the
        storm is the last entry of the log then.
        """
        system, regime, reg, rf = self.system, self.regime, self.reg, self.rf
        scfg = system.scene.solver
        lay = system.layout
        K = system.n_contacts
        args = system.kernel_args(reg, rf)
        ev_args = system.event_args(reg, rf)
        ye = np.array(ye, dtype=float)
        n_ev = K + kn.N_LAW_ROOTS
        outbuf = np.empty(kn.n_output_columns(K))
        before = regime.describe()
        evbuf = np.empty(n_ev)
        kn.events(te, ye, evbuf, *ev_args)
        kn.outputs(te, ye, outbuf, *args)
        fric_before = float(outbuf[kn.OUT_FRICTION])
        par = system.scene.friction.parameters  # the set-valued laws' guards (0: off)
        guards = (par.get("dwell_time", 0.0), par.get("chatter_switches", 0),
                  par.get("chatter_window", 0.0))
        kinds = []

        self.switched = set()

        def switch_root(idx: int) -> None:
            self.switched.add(idx)
            for tr in switch(regime, idx, te, ye, system.fp, K, lay.index("block.vx"),
                             lay.slice("contact.force"), *guards):
                kinds.append((tr.kind, tr.contact, idx))
                if tr.guard:
                    self.stats[f"guard_{tr.guard}"] += 1

        for idx in sorted(fired):
            switch_root(idx)
        regime.pack(reg, rf)
        y, yp = system.consistent(te, ye, reg, rf)
        for _ in range(2 * K):
            # a contact whose margin is at or below zero and falling in the new regime would
            # never see the downward crossing its root watches for (contacts in phase reach
            # their margins together, and the solver may report only some of them): switch it
            # at the same instant
            c = self._unseen_crossing(te, y, yp, ev_args)
            if c is None:
                break
            switch_root(c)
            self.stats["switches_at_zero_margin"] += 1
            regime.pack(reg, rf)
            y, yp = system.consistent(te, ye, reg, rf)
        after = regime.describe()
        evafter = np.empty(n_ev)
        kn.events(te, y, evafter, *ev_args)
        kn.outputs(te, y, outbuf, *args)
        fric_after = float(outbuf[kn.OUT_FRICTION])
        fsum = float(outbuf[kn.OUT_NORMAL])
        vx = float(outbuf[kn.OUT_VX])
        for kind, c, idx in kinds:
            cf = float(outbuf[kn.out_force_column(c, K)]) if c >= 0 else float("nan")
            self.events.append(EventRecord(te, kind, c, before, after, float(evbuf[idx]),
                                           float(evafter[idx]), vx, fsum, cf, fric_before,
                                           fric_after))
            self.stats[f"events_{kind}"] += 1
            self.recent.append(te)
        while self.recent and self.recent[0] < te - scfg.event_window:
            self.recent.popleft()
        if len(self.recent) > scfg.max_events:
            kinds_txt = ", ".join(f"{kd}" + (f" (contact {c})" if c >= 0 else "")
                                  for kd, c, _ in kinds)
            self.events.append(EventRecord(te, "event_storm", -1, before, after, 0.0, 0.0, vx,
                                           fsum, float("nan"), fric_before, fric_after))
            raise SolverFailure(
                "event_storm",
                f"event storm: more than {scfg.max_events} events within "
                f"{scfg.event_window:g} s at t = {te:.6g} s (last: {kinds_txt}; "
                f"regime {after}). Hint: raise solver.max_events or "
                f"solver.event_window if the events are physical, or check for "
                f"grazing contact (roughness much smaller than the static "
                f"compression changes)"
                + ("; for stick/slip chatter of the Coulomb law, lower "
                   "friction.parameters.chatter_switches" if any(kd in ("stick", "slip")
                                                      for kd, _, _ in kinds) else "")
                + ".", te)
        self.stats["restarts"] += 1
        return y, yp

    def _unseen_crossing(self, te: float, y: np.ndarray, yp: np.ndarray, ev_args
                         ) -> int | None:
        """A contact whose margin a restart at ``(te, y, yp)`` leaves at or below zero and falling.

        A contact margin (``kernels.events``: closed, the compression; open, minus it) is
        continuous in the state and changes sign with the contact's regime; its root is watched
        for downward crossings only. A margin that is <= 0 right after a restart and falls
        (its value a step of ``1e-9 max(1, t)`` s ahead, along ``yp``, is below zero) would
        never fire. Returns the contact with the lowest margin ahead, or None. A contact the
        restart has just switched starts with its margin rising, so it is not returned again.
        """
        K = self.system.n_contacts
        dt = 1e-9 * max(1.0, te)
        now, ahead = np.empty(K + kn.N_LAW_ROOTS), np.empty(K + kn.N_LAW_ROOTS)
        kn.events(te, y, now, *ev_args)
        kn.events(te + dt, y + dt * yp, ahead, *ev_args)
        bad = [c for c in range(K) if now[c] <= 0.0 and ahead[c] < 0.0]
        return min(bad, key=lambda c: ahead[c]) if bad else None
