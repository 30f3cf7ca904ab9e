"""Scene sections of the forces on the block: the friction law and the excitation.

Frozen dataclasses in SI units, each validated in ``__post_init__`` with the helpers of
:mod:`.checks`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from roughvib.scene.checks import (
    SceneError,
    _check_bounds,
    _choice,
    _fmt,
    _integer,
    _nonneg,
    _number,
    _opt_positive,
    _positive,
    _range,
    _set,
)


@dataclass(frozen=True)
class LawKey:
    """One key of a friction law's own parameters (``friction.parameters``).

    Attributes
    ----------
    default : float
        Its value when the scene does not give it.
    unit : str
        SI unit ("" for none).
    lowest, highest : float
        The physically sane range (inclusive).
    meaning : str
        What it is, in a few words (the refusal and docs/friction.md say it).
    """

    default: float
    unit: str
    lowest: float
    highest: float
    meaning: str


@dataclass(frozen=True)
class LawDeclaration:
    """What the scene knows of a friction law: its kind and its own keys.

    Attributes
    ----------
    kind : {"single-valued", "set-valued", "dynamic"}
        ``single-valued``: mu a function of the velocity and discrete regimes (feldmann);
        ``set-valued``: stick held at v = 0, the friction force an algebraic unknown
        (coulomb, table); ``dynamic``: internal states with their own rate equations (lugre).
        The solvers declare which kinds they run (``roughvib.solvers.registry``).
    keys : mapping
        ``{name: LawKey}``: the law's own keys, given in ``friction.parameters`` (the laws
        that predate that table read their keys from the section itself and declare none
        here).
    """

    kind: str
    keys: Mapping[str, LawKey] = field(default_factory=dict)


#: the friction laws a scene can name (``friction.law``), in the order of
#: ``roughvib.physics.friction.LAWS`` (the registration checks it), with their kinds and keys
FRICTION_LAWS: dict[str, LawDeclaration] = {
    "feldmann": LawDeclaration("single-valued"),
    "coulomb": LawDeclaration("set-valued"),
    "table": LawDeclaration("set-valued"),
    # LuGre (Canudas de Wit et al. 1995). mu_c, mu_s are friction.mu_slip, mu_stick; v_s the
    # decay of the paper's law's Stribeck term (1 / a1 = 2 mm/s); sigma1 damps the block's
    # pre-sliding oscillation on its own weight, sqrt(sigma0 g), to a damping ratio of about
    # 0.5 (as sigma1 = sqrt(sigma0) does for the unit mass and load of the original example);
    # sigma2 = 0 keeps the steady sliding level at mu_slip
    "lugre": LawDeclaration("dynamic", {
        "sigma0": LawKey(1e5, "1/m", 1.0, 1e10, "bristle stiffness per unit normal force"),
        "sigma1": LawKey(100.0, "s/m", 0.0, 1e6, "bristle damping per unit normal force"),
        "sigma2": LawKey(0.0, "s/m", 0.0, 1e4, "viscous coefficient"),
        "stribeck_velocity": LawKey(2e-3, "m/s", 1e-9, 10.0, "Stribeck velocity v_s"),
    }),
}
#: the set-valued laws (stick held at v = 0)
SET_VALUED_LAWS = tuple(n for n, d in FRICTION_LAWS.items() if d.kind == "set-valued")


@dataclass(frozen=True)
class Friction:
    """Friction law between block and plate.

    Attributes
    ----------
    law : {"feldmann", "coulomb", "table", "lugre"}
        ``feldmann``: the paper's Eq. 10 with the latched hysteresis of docs/theory.md
        (a smooth regularisation: stick is a steep slope). ``coulomb``: set-valued
        Coulomb friction with regimes slip+, slip-, stick; in stick the velocity is held at
        zero and the friction force is an algebraic unknown (docs/theory.md). ``table``: the
        same set-valued law with the kinetic coefficient read from ``table``
        (docs/friction.md). ``lugre``: the LuGre dynamic law with one bristle state, its
        constants in ``parameters`` (docs/friction.md).
    parameters : mapping
        The law's own keys (``roughvib.scene.FRICTION_LAWS``), completed with their
        defaults; empty for a law that declares none. A key of another law is refused.
    table : str or None
        ``table``: CSV file of the kinetic curve, columns ``velocity`` [m/s] (from 0,
        increasing) and ``mu`` [-], relative to the scene file's folder.
    mu_slip, mu_stick : float
        Quasi-static kinetic and static coefficients [-].
    a1, a2 : float
        Exponential constants of Eq. 10 [s/m].
    hysteresis_velocity : float
        v_h, the shift of the zero crossing [m/s].
    latch_velocity : float
        epsilon_v: the latch flips once the velocity has moved back from its running extremum
        by more than this [m/s]; the effective value is max(latch_velocity, hysteresis_velocity).
    stick_velocity : float
        ``|v|`` below this counts as stick for phase logging and the stick fraction [m/s].
    stribeck_velocity : float or None
        ``coulomb``: kinetic coefficient mu_slip + (mu_stick - mu_slip) exp(-``|v|`` / v_s) with
        this v_s [m/s]; ``None`` (default) gives a constant mu_slip.
    switching_hysteresis : float
        ``coulomb``: break-away needs ``|friction|`` > mu_stick F_N (1 + this) [-]. 0
        (default): the exact law, break-away when ``|friction|`` reaches mu_stick F_N. A value
        > 0 is an opt-in guard that changes the law everywhere: each time it holds the block in
        stick is logged (``hysteresis_hold``) and counted.
    dwell_time : float
        ``coulomb``: minimum time in stick before break-away is allowed [s]. 0 (default): off.
        Like the hysteresis an opt-in guard; each hold is logged (``dwell_hold``) and counted.
    chatter_switches : int
        ``coulomb``: chatter guard. A stick phase that begins when more than this many
        stick/slip switches lie within the last ``chatter_window`` is held for
        ``chatter_window`` (logged as ``chatter_guard``, counted as ``guard_chatter``;
        break-away attempts during the hold as ``dwell_hold``). It acts only on such
        chatter, never on ordinary stick-slip; 0 turns it off (then the event-storm guard
        ``solver.max_events`` is the only limit).
    chatter_window : float
        ``coulomb``: window of the chatter guard and the length of its hold [s].
    """

    law: str = "feldmann"
    parameters: Mapping[str, float] = field(default_factory=dict)
    table: str | None = None
    mu_slip: float = 0.30
    mu_stick: float = 0.40
    a1: float = 500.0
    a2: float = 2e4
    hysteresis_velocity: float = 5e-5
    latch_velocity: float = 1e-4
    stick_velocity: float = 5e-4
    stribeck_velocity: float | None = None
    switching_hysteresis: float = 0.0
    dwell_time: float = 0.0
    chatter_switches: int = 20
    chatter_window: float = 1e-3

    def __post_init__(self) -> None:
        p = "friction"
        _set(self, "law", _choice(f"{p}.law", self.law, tuple(FRICTION_LAWS)))
        _set(self, "parameters", _law_parameters(self.law, self.parameters))
        if self.law == "table":
            if not isinstance(self.table, str) or not self.table.strip():
                raise SceneError(f"{p}.table must name a CSV file (velocity [m/s], mu [-]) when "
                                 f"friction.law = 'table', got {_fmt(self.table)}")
        elif self.table is not None:
            raise SceneError(f"{p}.table is read by friction.law = 'table' only, got law "
                             f"{self.law!r} with table {self.table!r}")
        _set(self, "stribeck_velocity",
             _opt_positive(f"{p}.stribeck_velocity", self.stribeck_velocity, "m/s"))
        _set(self, "switching_hysteresis",
             _range(f"{p}.switching_hysteresis", self.switching_hysteresis, 0.0, 1.0, ""))
        _set(self, "dwell_time", _nonneg(f"{p}.dwell_time", self.dwell_time, "s"))
        _set(self, "chatter_switches",
             _integer(f"{p}.chatter_switches", self.chatter_switches, 0))
        _set(self, "chatter_window",
             _positive(f"{p}.chatter_window", self.chatter_window, "s"))
        _set(self, "mu_slip", _nonneg(f"{p}.mu_slip", self.mu_slip, ""))
        _set(self, "mu_stick", _nonneg(f"{p}.mu_stick", self.mu_stick, ""))
        _set(self, "a1", _nonneg(f"{p}.a1", self.a1, "s/m"))
        _set(self, "a2", _positive(f"{p}.a2", self.a2, "s/m"))
        _set(self, "hysteresis_velocity",
             _nonneg(f"{p}.hysteresis_velocity", self.hysteresis_velocity, "m/s"))
        _set(self, "latch_velocity", _positive(f"{p}.latch_velocity", self.latch_velocity, "m/s"))
        _set(self, "stick_velocity", _positive(f"{p}.stick_velocity", self.stick_velocity, "m/s"))
        _check_bounds(self, "friction")
        if self.mu_stick < self.mu_slip:
            raise SceneError(f"{p}.mu_stick must be >= friction.mu_slip ({self.mu_slip}), "
                             f"got {self.mu_stick}")
        if self.a2 <= self.a1:
            raise SceneError(f"{p}.a2 must be > friction.a1 ({self.a1} s/m), got {self.a2} s/m")

    @property
    def effective_latch_velocity(self) -> float:
        """epsilon_v = max(latch_velocity, hysteresis_velocity) [m/s]."""
        return max(self.latch_velocity, self.hysteresis_velocity)

    @property
    def kind(self) -> str:
        """The law's kind: ``"single-valued"``, ``"set-valued"`` or ``"dynamic"``."""
        return FRICTION_LAWS[self.law].kind

    @property
    def set_valued(self) -> bool:
        """Whether the law is set-valued (stick held at v = 0, ``SET_VALUED_LAWS``)."""
        return self.kind == "set-valued"


def _law_parameters(law: str, given) -> dict[str, float]:
    """``friction.parameters`` checked against the law's own keys and completed with their
    defaults (one line naming the key, rule, unit and value otherwise)."""
    keys = FRICTION_LAWS[law].keys
    if given is None:
        given = {}
    if not isinstance(given, Mapping):
        raise SceneError(f"friction.parameters must be a table of the law's own keys, got "
                         f"{_fmt(given)}")
    out = {}
    for name, value in given.items():
        if name not in keys:
            owners = [n for n, d in FRICTION_LAWS.items() if name in d.keys]
            whose = (f"a key of friction.law = {owners[0]!r}" if owners else "no law's key")
            known = ", ".join(keys) if keys else "none"
            raise SceneError(f"friction.parameters.{name} is {whose}, not of friction.law = "
                             f"{law!r} (its keys: {known}), got {_fmt(value)}")
        key = keys[name]
        path = f"friction.parameters.{name}"
        v = _number(path, value, key.unit)
        if not (key.lowest <= v <= key.highest):
            unit = f" {key.unit}" if key.unit else ""
            raise SceneError(f"{path} ({key.meaning}) must be in [{key.lowest:g}, "
                             f"{key.highest:g}]{unit} (the physically sane range), got "
                             f"{_fmt(value)}")
        out[name] = float(v)
    for name, key in keys.items():
        out.setdefault(name, float(key.default))
    return out


@dataclass(frozen=True)
class Excitation:
    """Tangential drive of the block.

    Attributes
    ----------
    kind : {"force", "prescribed"}
        ``force``: T_exc = T0 cos(2 pi f t). ``prescribed``: x(t) = velocity t +
        amplitude sin(2 pi f t) is imposed and the tangential dynamics leave the state.
    frequency : float
        f [Hz] (7 in the paper).
    force_amplitude : float or None
        T0 [N]; exactly one of force_amplitude / target_rms_velocity must be set.
    target_rms_velocity : float or None
        Target rms of the block's tangential velocity [m/s]; T0 is calibrated to it.
    velocity : float
        ``prescribed``: constant sliding velocity [m/s].
    amplitude : float
        ``prescribed``: displacement amplitude [m].
    """

    kind: str = "force"
    frequency: float = 7.0
    force_amplitude: float | None = None
    target_rms_velocity: float | None = 0.01
    velocity: float = 0.0
    amplitude: float = 0.227e-3

    def __post_init__(self) -> None:
        p = "excitation"
        _set(self, "kind", _choice(f"{p}.kind", self.kind, ("force", "prescribed")))
        _set(self, "frequency", _nonneg(f"{p}.frequency", self.frequency, "Hz"))
        if self.force_amplitude is not None:
            _set(self, "force_amplitude",
                 _nonneg(f"{p}.force_amplitude", self.force_amplitude, "N"))
        if self.target_rms_velocity is not None:
            _set(self, "target_rms_velocity",
                 _positive(f"{p}.target_rms_velocity", self.target_rms_velocity, "m/s"))
        _set(self, "velocity", _number(f"{p}.velocity", self.velocity, "m/s"))
        _set(self, "amplitude", _nonneg(f"{p}.amplitude", self.amplitude, "m"))
        _check_bounds(self, "excitation")
        if self.kind == "force":
            if (self.force_amplitude is None) == (self.target_rms_velocity is None):
                raise SceneError(
                    f"{p}: set exactly one of force_amplitude [N] or target_rms_velocity "
                    f"[m/s], got force_amplitude={self.force_amplitude}, "
                    f"target_rms_velocity={self.target_rms_velocity}")
            if self.target_rms_velocity is not None and self.frequency < 0.1:
                # the calibration simulates three periods of the tangential model at 1 us
                raise SceneError(f"{p}.frequency must be >= 0.1 Hz to calibrate "
                                 f"target_rms_velocity (or give force_amplitude), got "
                                 f"{self.frequency} Hz")

    @property
    def omega(self) -> float:
        """Angular excitation frequency [rad/s]."""
        return 2.0 * math.pi * self.frequency
