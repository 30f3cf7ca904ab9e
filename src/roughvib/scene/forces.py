"""Scene sections of the forces on the block: the friction law and the excitation.

Frozen dataclasses in SI units, each validated in ``__post_init__`` with the helpers of
:mod:`.checks`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from roughvib.scene.checks import (
    SceneError,
    _check_bounds,
    _choice,
    _fmt,
    _integer,
    _nonneg,
    _number,
    _positive,
    _set,
)


@dataclass(frozen=True)
class LawKey:
    """One key of a friction law's own parameters (``friction.parameters``).

    Attributes
    ----------
    default : float, int, str or None
        Its value when the scene does not give it (``None``: off, or required for a file).
    unit : str
        SI unit ("" for none).
    lowest, highest : float
        The physically sane range (inclusive; a ``file`` key has none).
    meaning : str
        What it is, in a few words (the refusal and docs/friction.md say it).
    kind : {"real", "integer", "optional", "file"}
        ``real``: a number; ``integer``: a whole number; ``optional``: a number or ``None``
        (``"none"`` in TOML: off); ``file``: the name of a file relative to the scene file's
        folder (required: no default).
    positive : bool
        The lowest value is excluded (the key must be > ``lowest``).
    """

    default: float | int | str | None
    unit: str
    lowest: float
    highest: float
    meaning: str
    kind: str = "real"
    positive: bool = False

    def holds_default(self, value: Any) -> bool:
        """Whether ``value`` is this key's default (``"none"`` counts as None)."""
        if self.default is None:
            return value is None or value == "none"
        return value == self.default


@dataclass(frozen=True)
class LawDeclaration:
    """What the scene knows of a friction law: its kind, its own keys and their joint rule.

    Attributes
    ----------
    kind : {"single-valued", "set-valued", "dynamic"}
        ``single-valued``: mu a function of the velocity and discrete regimes (feldmann);
        ``set-valued``: stick held at v = 0, the friction force an algebraic unknown
        (coulomb, table); ``dynamic``: internal states with their own rate equations (lugre).
        The solvers declare which kinds they run (``roughvib.solvers.registry``).
    keys : mapping
        ``{name: LawKey}``: the law's own keys, given in ``friction.parameters``.
    rule : callable or None
        ``rule(parameters) -> str | None``: a rule between the law's keys (the checked and
        completed ``parameters``), returning the one-line refusal or None.
    """

    kind: str
    keys: Mapping[str, LawKey] = field(default_factory=dict)
    rule: Callable[[Mapping[str, Any]], str | None] | None = None


def _feldmann_rule(par: Mapping[str, Any]) -> str | None:
    if par["a2"] <= par["a1"]:
        return (f"friction.parameters.a2 must be > friction.parameters.a1 ({par['a1']} s/m), "
                f"got {par['a2']} s/m")
    return None


#: the guards of the set-valued laws (coulomb and table share them)
_SET_VALUED_GUARDS = {
    "switching_hysteresis": LawKey(
        0.0, "", 0.0, 1.0, "relative break-away hysteresis (opt-in guard, 0: off)"),
    "dwell_time": LawKey(0.0, "s", 0.0, 1e3, "least time in stick (opt-in guard, 0: off)"),
    "chatter_switches": LawKey(
        20, "", 0, 1e9, "stick/slip switches within chatter_window that engage the "
        "chatter guard (0: off)", kind="integer"),
    "chatter_window": LawKey(1e-3, "s", 0.0, 1e3, "window and hold of the chatter guard",
                             positive=True),
}

#: the friction laws a scene can name (``friction.law``), in the order of
#: ``roughvib.physics.friction.LAWS`` (the registration checks it), with their kinds and keys
FRICTION_LAWS: dict[str, LawDeclaration] = {
    # Eq. 10 of the paper: a1, a2 its exponential constants; v_h the hysteresis shift of the
    # zero crossing and epsilon_v the latch's margin (docs/theory.md)
    "feldmann": LawDeclaration("single-valued", {
        "a1": LawKey(500.0, "s/m", 0.0, 1e8, "Eq. 10's first exponential constant"),
        "a2": LawKey(2e4, "s/m", 0.0, 1e8, "Eq. 10's second exponential constant (> a1)",
                     positive=True),
        "hysteresis_velocity": LawKey(5e-5, "m/s", 0.0, 100.0,
                                      "v_h, the shift of the zero crossing"),
        "latch_velocity": LawKey(1e-4, "m/s", 0.0, 100.0, "epsilon_v, the latch's margin",
                                 positive=True),
    }, _feldmann_rule),
    "coulomb": LawDeclaration("set-valued", {
        "stribeck_velocity": LawKey(None, "m/s", 0.0, 100.0, "Stribeck velocity v_s of the "
                                    "kinetic coefficient (none: constant mu_slip)",
                                    kind="optional", positive=True),
        **_SET_VALUED_GUARDS,
    }),
    "table": LawDeclaration("set-valued", {
        "table": LawKey(None, "", 0.0, 0.0, "a CSV file of the kinetic curve, velocity [m/s] "
                        "and mu [-]", kind="file"),
        **_SET_VALUED_GUARDS,
    }),
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
#: every key some law declares (a flat ``friction.<key>`` is read as ``friction.parameters``)
LAW_KEYS = frozenset(k for d in FRICTION_LAWS.values() for k in d.keys)


@dataclass(frozen=True)
class Friction:
    """Friction law between block and plate.

    The keys every law reads are attributes; each law's own keys are in ``parameters``
    (``[friction.parameters]`` in a scene file; the flat form ``friction.a1`` of earlier
    scene files is read into it).

    Attributes
    ----------
    law : {"feldmann", "coulomb", "table", "lugre"}
        ``feldmann``: the paper's Eq. 10 with the latched hysteresis of docs/theory.md
        (a smooth regularisation: stick is a steep slope). ``coulomb``: set-valued
        Coulomb friction with regimes slip+, slip-, stick; in stick the velocity is held at
        zero and the friction force is an algebraic unknown (docs/theory.md). ``table``: the
        same set-valued law with the kinetic coefficient read from a CSV file
        (docs/friction.md). ``lugre``: the LuGre dynamic law with one bristle state
        (docs/friction.md).
    parameters : mapping
        The law's own keys (``roughvib.scene.FRICTION_LAWS``, listed in docs/friction.md),
        completed with their defaults. A key of another law is refused unless it holds that
        law's default (as scene files written before the keys moved here do).

        * feldmann: ``a1``, ``a2`` (Eq. 10's exponential constants [s/m]),
          ``hysteresis_velocity`` (v_h, the shift of the zero crossing [m/s]),
          ``latch_velocity`` (epsilon_v: the latch flips once the velocity has moved back
          from its running extremum by more than this [m/s]; the effective value is
          max(latch_velocity, hysteresis_velocity)).
        * coulomb: ``stribeck_velocity`` (kinetic coefficient mu_slip + (mu_stick - mu_slip)
          exp(-``|v|`` / v_s) with this v_s [m/s]; ``None``, the default, gives a constant
          mu_slip), and the guards below.
        * table: ``table`` (CSV file of the kinetic curve, columns ``velocity`` [m/s], from 0,
          increasing, and ``mu`` [-], relative to the scene file's folder), and the guards.
        * the guards of coulomb and table, all off or inactive by default:
          ``switching_hysteresis`` (break-away needs ``|friction|`` > mu_stick F_N (1 + this)
          [-]; each hold is logged as ``hysteresis_hold``), ``dwell_time`` (least time in
          stick before break-away [s]; holds logged as ``dwell_hold``), ``chatter_switches``
          and ``chatter_window`` (a stick phase that begins when more than this many
          stick/slip switches lie within the last window [s] is held for the window, logged
          as ``chatter_guard``; it acts only on such chatter; 0 switches turns it off).
        * lugre: ``sigma0`` [1/m], ``sigma1``, ``sigma2`` [s/m], ``stribeck_velocity`` [m/s].
    mu_slip, mu_stick : float
        Quasi-static kinetic and static coefficients [-].
    stick_velocity : float
        ``|v|`` below this counts as stick for phase logging and the stick fraction [m/s].
    """

    law: str = "feldmann"
    parameters: Mapping[str, Any] = field(default_factory=dict)
    mu_slip: float = 0.30
    mu_stick: float = 0.40
    stick_velocity: float = 5e-4

    def __post_init__(self) -> None:
        p = "friction"
        _set(self, "law", _choice(f"{p}.law", self.law, tuple(FRICTION_LAWS)))
        _set(self, "parameters", _law_parameters(self.law, self.parameters))
        _set(self, "mu_slip", _nonneg(f"{p}.mu_slip", self.mu_slip, ""))
        _set(self, "mu_stick", _nonneg(f"{p}.mu_stick", self.mu_stick, ""))
        _set(self, "stick_velocity", _positive(f"{p}.stick_velocity", self.stick_velocity, "m/s"))
        _check_bounds(self, "friction")
        if self.mu_stick < self.mu_slip:
            raise SceneError(f"{p}.mu_stick must be >= friction.mu_slip ({self.mu_slip}), "
                             f"got {self.mu_stick}")
        rule = FRICTION_LAWS[self.law].rule
        refusal = rule(self.parameters) if rule is not None else None
        if refusal is not None:
            raise SceneError(refusal)

    @property
    def kind(self) -> str:
        """The law's kind: ``"single-valued"``, ``"set-valued"`` or ``"dynamic"``."""
        return FRICTION_LAWS[self.law].kind

    @property
    def set_valued(self) -> bool:
        """Whether the law is set-valued (stick held at v = 0, ``SET_VALUED_LAWS``)."""
        return self.kind == "set-valued"


def law_key_path(key: str) -> str:
    """The dotted scene key as it is stored: ``friction.a1`` (the flat form of earlier scene
    files) is ``friction.parameters.a1``; any other key is returned unchanged.

    Parameters
    ----------
    key : str
        A dotted scene key.

    Returns
    -------
    str
    """
    section, _, name = key.partition(".")
    if section == "friction" and name in LAW_KEYS:
        return f"friction.parameters.{name}"
    return key


def fold_law_keys(section: Mapping[str, Any]) -> dict[str, Any]:
    """A friction section with its flat law keys (``a1 = 600``, the form of earlier scene
    files) moved into ``parameters``; one line if both forms give a key different values.

    Parameters
    ----------
    section : mapping
        The ``[friction]`` table as read from TOML.

    Returns
    -------
    dict
    """
    out = dict(section)
    flat = {k: out.pop(k) for k in list(out) if k in LAW_KEYS}
    if not flat:
        return out
    table = out.get("parameters", {})
    if not isinstance(table, Mapping):
        return out  # refused by the section's own check, naming the key
    table = dict(table)
    for k, v in flat.items():
        if k in table and table[k] != v:
            raise SceneError(f"friction.{k} and friction.parameters.{k} give different "
                             f"values; give it once, in [friction.parameters], got {_fmt(v)} "
                             f"and {_fmt(table[k])}")
        table[k] = v
    out["parameters"] = table
    return out


def _law_value(path: str, key: LawKey, value: Any) -> Any:
    """One law key checked against its kind and sane range (one line otherwise)."""
    if key.kind == "file":
        if not isinstance(value, str) or not value.strip():
            raise SceneError(f"{path} must name {key.meaning}, got {_fmt(value)}")
        return value
    if key.kind == "optional" and (value is None or value == "none"):
        return None
    if key.kind == "integer":
        v = _integer(path, value, int(key.lowest))
    else:
        v = _number(path, value, key.unit)
    below = v <= key.lowest if key.positive else v < key.lowest
    if below or v > key.highest:
        unit = f" {key.unit}" if key.unit else ""
        low = "(" if key.positive else "["
        raise SceneError(f"{path} ({key.meaning}) must be in {low}{key.lowest:g}, "
                         f"{key.highest:g}]{unit} (the physically sane range), got "
                         f"{_fmt(value)}")
    return int(v) if key.kind == "integer" else float(v)


def _law_parameters(law: str, given) -> dict[str, Any]:
    """``friction.parameters`` checked against the law's own keys and completed with their
    defaults (one line naming the key, rule, unit and value otherwise). A key of another law
    that holds that law's default is dropped (scene files written before the keys moved here
    list every law's keys)."""
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
            if owners and all(FRICTION_LAWS[o].keys[name].holds_default(value)
                              for o in owners):
                continue
            whose = (f"a key of friction.law = {owners[0]!r}" if owners else "no law's key")
            known = ", ".join(keys) if keys else "none"
            raise SceneError(f"friction.parameters.{name} is {whose}, not of friction.law = "
                             f"{law!r} (its keys: {known}), got {_fmt(value)}")
        out[name] = _law_value(f"friction.parameters.{name}", keys[name], value)
    for name, key in keys.items():
        if name not in out:
            if key.kind == "file":
                raise SceneError(f"friction.parameters.{name} must name {key.meaning} when "
                                 f"friction.law = {law!r}, got none")
            out[name] = key.default
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
