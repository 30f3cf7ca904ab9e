"""What a friction law's regime functions read and return (docs/architecture.md, "A friction law").

Every law module provides, besides its curve, its discrete regimes: the regime at t = 0
(``regime_at_start(regime, start)``), the transition for each of its three friction roots
(``regime_transition(regime, j, at)``, j = 0, 1, 2, the roots ``K + j`` of
``roughvib.model.kernels.events``) and the names of those roots (``ROOTS``); they are
registered in ``laws.LAWS`` (``FrictionLaw.initial``, ``.transition``, ``.roots``). The
regime they switch is the model's (``roughvib.model.regimes.Regime``); the functions set its
fields ``branch``, ``latch``, ``v_ext`` [m/s], ``stick``, ``dwell_end`` [s] and
``switch_times`` [s] in place. They read plain values, the records below, which the model
builds from its packed parameters and the state, so that the physics does not depend on the
model's array layout.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["NO_DWELL", "N_ROOTS", "RootValues", "StartValues", "Transition"]

#: ``Regime.dwell_end`` when no dwell hold is active
NO_DWELL = -1.0

#: friction roots of every law (after the K contact roots)
N_ROOTS = 3


@dataclass
class Transition:
    """One logged consequence of a root: event kind, contact (-1: block level), guard.

    Attributes
    ----------
    kind : str
        The event kind of the log (``lift_off``, ``stick``, ``friction_branch``, ...).
    contact : int
        The contact of a contact event, -1 for a block-level (friction) event.
    guard : str
        The guard that acted (``dwell``, ``hysteresis``, ``chatter``), or ``""``.
    """

    kind: str
    contact: int
    guard: str = ""


@dataclass(frozen=True)
class RootValues:
    """What a law's transition reads at a friction root.

    Attributes
    ----------
    t : float
        Time of the root [s].
    vx : float
        Tangential velocity of the block [m/s].
    exciting_force : float
        The exciting force ``T0 cos(omega t)`` at ``t`` [N].
    normal_force : float
        Sum of the closed contacts' forces [N].
    mu_stick : float
        ``friction.mu_stick`` [-].
    hysteresis : float
        Relative switching hysteresis of the break-away ``friction.switching_hysteresis`` [-].
    r2 : float
        Tangential damping of the block [N s/m].
    dwell_time : float
        Every stick phase of a set-valued law is held this long [s] (0: off).
    chatter_switches : int
        The chatter guard acts past this many stick/slip switches within ``chatter_window``
        (0: off).
    chatter_window : float
        The chatter guard's window and hold [s].
    """

    t: float
    vx: float
    exciting_force: float
    normal_force: float
    mu_stick: float
    hysteresis: float
    r2: float
    dwell_time: float
    chatter_switches: int
    chatter_window: float


@dataclass(frozen=True)
class StartValues:
    """What a law's regime at t = 0 reads (block at rest on its static contact set).

    Attributes
    ----------
    force_amplitude : float
        The exciting force at t = 0, T0 [N].
    mass : float
        Block mass [kg].
    gravity : float
        Gravitational acceleration [m/s^2] (the static normal force is ``mass * gravity``).
    mu_stick : float
        ``friction.mu_stick`` [-].
    hysteresis : float
        Relative switching hysteresis of the break-away [-].
    hysteresis_velocity : float
        The latch's velocity shift v_h [m/s] as packed for the law (0 where it has none).
    """

    force_amplitude: float
    mass: float
    gravity: float
    mu_stick: float
    hysteresis: float
    hysteresis_velocity: float
