"""Scene description: frozen, validated dataclasses in SI units, TOML load/save.

This module owns the *contract* of a scene file. Every value has a default taken from the
paper scene (docs/theory.md), so an empty TOML file is the paper scene. A bad value raises
:class:`SceneError` (a ``ValueError``) whose message names the field path, the rule, the unit
and the value, e.g. ``plate.thickness must be > 0 m, got -0.003``.

Nothing in here knows how a solver works; what each one runs is asked of the solver registry
(:mod:`roughvib.solvers.registry`, which imports nothing from roughvib), so that a scene a
solver cannot run is refused when it is loaded. Later pipeline stages read these objects and
turn them into flat arrays once.
"""

from __future__ import annotations

import dataclasses
import math
import os
import stat
import tomllib
from dataclasses import dataclass, field, fields, replace
from importlib import resources
from pathlib import Path
from typing import Any

from roughvib.solvers import registry as _registry

__all__ = [
    "Block",
    "Contact",
    "Excitation",
    "Friction",
    "ModelValidityWarning",
    "Output",
    "Plate",
    "Roughness",
    "Scene",
    "SceneError",
    "ACCURACY_LEVELS",
    "ACCURACY_PRESETS",
    "FIXED_STEP_METHODS",
    "SOLVER_METHODS",
    "Solver",
    "builtin_scenes",
    "load_scene",
    "read_toml_file",
    "scene_to_toml",
    "validity_warnings",
]


class SceneError(ValueError):
    """A scene value is invalid; the message is one line naming field, rule, unit and value."""


class ModelValidityWarning(UserWarning):
    """A scene value is legal but outside the range where the model is valid (one line); a run
    issues it before its expensive work and lists it in ``summary["warnings"]``."""


def user_stacklevel() -> int:
    """The ``stacklevel`` for ``warnings.warn`` that names the first caller outside roughvib.

    A warning issued deep inside a run then points at the user's own line (``result =
    roughvib.simulate(scene)``) instead of an internal one, and Python's default filter shows
    it once per such line.

    Returns
    -------
    int
        For a ``warnings.warn`` call in the function that calls this one (1 if that function
        is not part of roughvib).
    """
    import os
    import sys

    root = os.path.dirname(os.path.abspath(__file__)) + os.sep
    frame = sys._getframe(1)  # the function that calls warnings.warn: level 1
    level = 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(root):
        frame = frame.f_back
        level += 1
    return level


#: upper limit of the plate's mode count (estimated from the scene before any work)
MAX_MODES = 20000
#: upper limit of the samples of a synthetic profile (``trace_length / spacing``)
MAX_PROFILE_SAMPLES = 10_000_000
#: upper limit of the fixed steps of a run (``output.duration / solver.step``)
MAX_FIXED_STEPS = 10_000_000_000

#: upper limit of ``contact.points`` (also for the derived count of ``points = "auto"``)
MAX_CONTACTS = 200


# --------------------------------------------------------------------------------------------
# validation helpers
# --------------------------------------------------------------------------------------------


def _fmt(value: Any) -> str:
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**16:
        digits = str(abs(value))  # a huge integer (1 followed by 400 zeros): keep the line short
        return f"{'-' if value < 0 else ''}{digits[0]}.{digits[1:4]}e+{len(digits) - 1}"
    return str(value)


def _u(unit: str) -> str:
    return f" {unit}" if unit else ""


def _number(path: str, value: Any, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SceneError(f"{path} must be a number{_u(unit)}, got {_fmt(value)}")
    try:
        value = float(value)
    except OverflowError:  # an integer beyond the float range
        raise SceneError(f"{path} must be a finite number{_u(unit)}, got {_fmt(value)}") from None
    if not math.isfinite(value):
        raise SceneError(f"{path} must be a finite number{_u(unit)}, got {_fmt(value)}")
    return value


def _positive(path: str, value: Any, unit: str) -> float:
    v = _number(path, value, unit)
    if v <= 0.0:
        raise SceneError(f"{path} must be > 0{_u(unit)}, got {_fmt(value)}")
    return v


def _nonneg(path: str, value: Any, unit: str) -> float:
    v = _number(path, value, unit)
    if v < 0.0:
        raise SceneError(f"{path} must be >= 0{_u(unit)}, got {_fmt(value)}")
    return v


def _range(path: str, value: Any, lo: float, hi: float, unit: str, *, lo_open=False,
           hi_open=False) -> float:
    v = _number(path, value, unit)
    bad = (v <= lo if lo_open else v < lo) or (v >= hi if hi_open else v > hi)
    if bad:
        lb = "(" if lo_open else "["
        hb = ")" if hi_open else "]"
        raise SceneError(f"{path} must be in {lb}{lo}, {hi}{hb}{_u(unit)}, got {_fmt(value)}")
    return v


#: the largest integer a scene key takes (int64: kernels and seeds store integers as int64)
_INT_MAX = 2**63 - 1


def _integer(path: str, value: Any, lo: int, hi: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise SceneError(f"{path} must be an integer, got {_fmt(value)}")
    if value < lo or value > (_INT_MAX if hi is None else hi):
        rule = f">= {lo} (at most 2**63 - 1)" if hi is None else f"in [{lo}, {hi}]"
        raise SceneError(f"{path} must be an integer {rule}, got {_fmt(value)}")
    return value


def _choice(path: str, value: Any, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        opts = ", ".join(repr(c) for c in choices)
        raise SceneError(f"{path} must be one of {opts}, got {_fmt(value)}")
    return value


def _boolean(path: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise SceneError(f"{path} must be true or false, got {_fmt(value)}")
    return value


def _pair(path: str, value: Any, unit: str) -> tuple[float, float]:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise SceneError(f"{path} must be a pair [x, y]{_u(unit)}, got {_fmt(value)}")
    return (_number(f"{path}[0]", value[0], unit), _number(f"{path}[1]", value[1], unit))


def _set(obj: Any, name: str, value: Any) -> None:
    object.__setattr__(obj, name, value)


def _opt_positive(path: str, value: Any, unit: str) -> float | None:
    return None if value is None else _positive(path, value, unit)


def _auto_or_positive(path: str, value: Any, unit: str) -> float | str:
    """``"auto"``, or a number > 0 in ``unit``."""
    if isinstance(value, str):
        return _choice(path, value, ("auto",))
    return _positive(path, value, unit)


#: longest scene name [characters]; it names the output directory runs/<name>, next to which a
#: run keeps a temporary directory and a lock file with a few more characters
NAME_MAX = 100
_NAME_FORBIDDEN = set('/\\:*?"<>|')


def _file_name(path: str, value: Any) -> str:
    """A plain file name: what ``runs/<name>`` may be without leaving ``runs/``."""
    if not isinstance(value, str):
        raise SceneError(f"{path} must be a string, got {_fmt(value)}")
    rule = (f"{path} must be a plain file name (1 to {NAME_MAX} characters, no leading '.', "
            f"no path separator, none of : * ? \" < > |, no control character)")
    if len(value) > NAME_MAX:
        raise SceneError(f"{rule}, got {len(value)} characters ({value[:20]!r}...)")
    if not value or value.startswith(".") or value != value.strip() or \
            any(c in _NAME_FORBIDDEN or ord(c) < 32 or ord(c) == 127 for c in value):
        raise SceneError(f"{rule}, got {value!r}")
    return value


#: physically sane bounds of the numeric scene keys: (lowest, highest, unit). They lie far
#: beyond any block, plate or surface this model describes, and keep every quantity a run
#: derives from them (bending stiffness, wave speed, mode count, static load, profile, step
#: counts, tolerances per state) a finite float64; docs/scenes.md lists them. A lowest value of
#: 0 leaves the key's own rule (> 0 or >= 0) as the only lower limit.
SANE_BOUNDS: dict[str, tuple[float, float, str]] = {
    "block.mass": (1e-6, 1e18, "kg"),
    "block.length": (1e-4, 10.0, "m"),
    "block.width": (1e-4, 10.0, "m"),
    "block.vertical_damping": (0.0, 1e12, "N s/m"),
    "block.tangential_damping": (0.0, 1e6, "N s/m"),
    "plate.length": (1e-3, 100.0, "m"),
    "plate.width": (1e-3, 100.0, "m"),
    "plate.thickness": (1e-6, 10.0, "m"),
    "plate.youngs_modulus": (1e3, 1e13, "Pa"),
    "plate.density": (1.0, 1e5, "kg/m^3"),
    "plate.max_frequency": (0.0, 1e7, "Hz"),
    "contact.stiffness": (1e-6, 1e16, "N/m"),
    "contact.min_separation": (0.0, 1.0, "m"),
    "contact.summit_density": (1.0, 1e18, "1/m^2"),
    "contact.summit_radius": (1e-9, 10.0, "m"),
    "contact.summit_std": (1e-12, 1e-3, "m"),
    "contact.hardness": (1e5, 1e12, "Pa"),
    "contact.spot_radius": (1e-9, 1e-2, "m"),
    "roughness.amplitude": (0.0, 1e-2, "m"),
    "roughness.wavelength": (1e-9, 10.0, "m"),
    "roughness.rms": (0.0, 1e-2, "m"),
    "roughness.raw_rms": (0.0, 1e-2, "m"),
    "roughness.rolloff_wavelength": (1e-9, 10.0, "m"),
    "roughness.shortest_wavelength": (1e-9, 10.0, "m"),
    "roughness.longest_wavelength": (1e-9, 10.0, "m"),
    "roughness.spacing": (1e-9, 1e-3, "m"),
    "roughness.trace_length": (0.0, 100.0, "m"),
    "friction.mu_slip": (0.0, 10.0, ""),
    "friction.mu_stick": (0.0, 10.0, ""),
    "friction.a1": (0.0, 1e8, "s/m"),
    "friction.a2": (0.0, 1e8, "s/m"),
    "friction.hysteresis_velocity": (0.0, 100.0, "m/s"),
    "friction.latch_velocity": (0.0, 100.0, "m/s"),
    "friction.stick_velocity": (0.0, 100.0, "m/s"),
    "friction.stribeck_velocity": (0.0, 100.0, "m/s"),
    "friction.dwell_time": (0.0, 1e3, "s"),
    "friction.chatter_window": (0.0, 1e3, "s"),
    "excitation.frequency": (0.0, 1e4, "Hz"),
    "excitation.force_amplitude": (0.0, 1e25, "N"),
    "excitation.target_rms_velocity": (0.0, 100.0, "m/s"),
    "excitation.velocity": (-100.0, 100.0, "m/s"),
    "excitation.amplitude": (0.0, 1.0, "m"),
    "solver.step": (1e-12, 1.0, "s"),
    "solver.atol": (0.0, 1e-3, "m"),
    "solver.atol_acceleration": (0.0, 1e6, "m/s^2"),
    "solver.max_step": (1e-9, 1e4, "s"),
    "solver.event_window": (0.0, 1e4, "s"),
    "output.duration": (0.0, 1e6, "s"),
    "output.step": (1e-9, 1e3, "s"),
    "output.transient": (0.0, 1e6, "s"),
    "output.checkpoint_interval": (0.0, 1e6, "s"),
    # the fluid the plate radiates into: from air at about 1 hPa (continuum acoustics still
    # holds at audio frequencies) to beyond mercury (13.5e3 kg/m^3, the densest liquid at room
    # temperature); sound speeds from bubbly liquids (some 20 m/s) to beyond molten metals
    "output.air_density": (1e-3, 2e4, "kg/m^3"),
    "output.sound_speed": (10.0, 1e4, "m/s"),
}


def _check_bounds(obj: Any, section: str) -> None:
    """Refuse a numeric key of ``obj`` outside :data:`SANE_BOUNDS` (one line: key, rule, unit,
    value); ``solver.max_step = 0`` (unbounded) is exempt from its lowest value."""
    for f in fields(obj):
        path = f"{section}.{f.name}"
        v = getattr(obj, f.name)
        if path not in SANE_BOUNDS or isinstance(v, bool) or not isinstance(v, int | float):
            continue
        lo, hi, unit = SANE_BOUNDS[path]
        if not (lo <= v <= hi) and not (path == "solver.max_step" and v == 0):
            raise SceneError(f"{path} must be {bounds_rule(path)} (the physically sane range, "
                             f"docs/scenes.md), got {_fmt(v)}")


def bounds_rule(path: str) -> str:
    """The rule of a key's physically sane range as its refusal states it.

    Parameters
    ----------
    path : str
        A key of :data:`SANE_BOUNDS`, e.g. ``"plate.thickness"``.

    Returns
    -------
    str
        ``"in [lo, hi] unit"``, or ``"at most hi unit"`` where the key's own rule (> 0 or
        >= 0) is the lower limit (lowest value 0).
    """
    lo, hi, unit = SANE_BOUNDS[path]
    zero = " or 0 (unbounded)" if path == "solver.max_step" else ""
    if lo == 0:
        return f"at most {hi:g}{_u(unit)}"
    return f"in [{lo:g}, {hi:g}]{_u(unit)}{zero}"


# --------------------------------------------------------------------------------------------
# sections
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Block:
    """The sliding mass-block (rigid, one vertical and one tangential degree of freedom).

    Attributes
    ----------
    mass : float
        Block mass m [kg]. Paper: 0.221 or 0.543.
    length, width : float
        Block footprint along the sliding direction and across it [m] (0.04 x 0.04).
    vertical_damping : float or "auto"
        Viscous damper r1 on the absolute vertical block velocity [N s/m] (docs/theory.md).
        ``"auto"`` (default): r1 = 2 zeta sqrt(s_total m), the damping ratio
        ``vertical_damping_ratio`` at the rigid-plate contact resonance of the stiffness
        actually used. The paper's hand-set value is 83 N s/m (scene ``paper-handset``).
    tangential_damping : float
        Viscous damper r2 on the absolute tangential block velocity [N s/m].
    vertical_damping_ratio : float
        zeta of ``vertical_damping = "auto"`` [-].
    """

    mass: float = 0.221
    length: float = 0.04
    width: float = 0.04
    vertical_damping: float | str = "auto"
    tangential_damping: float = 0.5
    vertical_damping_ratio: float = 0.05

    def __post_init__(self) -> None:
        _set(self, "mass", _positive("block.mass", self.mass, "kg"))
        _set(self, "length", _positive("block.length", self.length, "m"))
        _set(self, "width", _positive("block.width", self.width, "m"))
        if isinstance(self.vertical_damping, str):
            _choice("block.vertical_damping", self.vertical_damping, ("auto",))
        else:
            _set(self, "vertical_damping",
                 _nonneg("block.vertical_damping", self.vertical_damping, "N s/m"))
        _set(self, "tangential_damping",
             _nonneg("block.tangential_damping", self.tangential_damping, "N s/m"))
        _set(self, "vertical_damping_ratio",
             _range("block.vertical_damping_ratio", self.vertical_damping_ratio, 0.0, 1.0, "",
                    hi_open=True))
        _check_bounds(self, "block")


@dataclass(frozen=True)
class Plate:
    """The structure under the block: a simply supported Kirchhoff plate (``kind="modal"``),
    an immovable base (``"rigid"``) or modes read from a file (``"imported"``).

    Attributes
    ----------
    kind : {"modal", "rigid", "imported"}
        Which structure component (``roughvib.physics.structures``): ``modal`` the simply
        supported plate of the fields below; ``rigid`` drops all plate states; ``imported``
        reads mass-normalised modes from ``modes_file`` (docs/structures.md), for which the
        material fields are not used and ``loss_factor`` gives the damping of modes the file
        gives none for.
    length, width, thickness : float
        a, b, h [m]. Sliding is along the plate length (x).
    youngs_modulus : float
        E [Pa].
    poisson_ratio : float
        nu [-], in [0, 0.5).
    density : float
        rho [kg/m^3].
    loss_factor : float
        delta_p [-]; modal damping ratio zeta = loss_factor / 2.
    max_frequency : float
        All modes with f <= max_frequency are kept [Hz].
    block_position : tuple of float
        Plate coordinates (x0, y0) of the block centre [m].
    observation_position : tuple of float
        Plate coordinates of the plate accelerometer [m]; keep it away from the contacts.
    residual_compliance : bool
        Add the static compliance of the truncated modes at the contacts (docs/theory.md).
        ``imported``: the static compliance of the file's modes above ``max_frequency``
        (none if the file holds none).
    modes_file : str
        ``imported``: the modes file (``.npz``, or ``.unv``/``.uff`` universal file with
        datasets 2411 and 55), relative to the scene file's folder (docs/structures.md).
    """

    kind: str = "modal"
    length: float = 0.30
    width: float = 0.26
    thickness: float = 0.003
    youngs_modulus: float = 2.1e11
    poisson_ratio: float = 0.3
    density: float = 7850.0
    loss_factor: float = 0.003
    max_frequency: float = 50e3
    block_position: tuple[float, float] = (0.12, 0.11)
    observation_position: tuple[float, float] = (0.20, 0.08)
    residual_compliance: bool = True
    modes_file: str = ""

    def __post_init__(self) -> None:
        _set(self, "kind", _choice("plate.kind", self.kind, ("modal", "rigid", "imported")))
        if not isinstance(self.modes_file, str):
            raise SceneError(f"plate.modes_file must be a string (file path), got "
                             f"{_fmt(self.modes_file)}")
        if self.kind == "imported" and not self.modes_file:
            raise SceneError("plate.modes_file must name a modes file (.npz, .unv, .uff) when "
                             "plate.kind = 'imported', got ''")
        _set(self, "length", _positive("plate.length", self.length, "m"))
        _set(self, "width", _positive("plate.width", self.width, "m"))
        _set(self, "thickness", _positive("plate.thickness", self.thickness, "m"))
        _set(self, "youngs_modulus", _positive("plate.youngs_modulus", self.youngs_modulus, "Pa"))
        _set(self, "poisson_ratio",
             _range("plate.poisson_ratio", self.poisson_ratio, 0.0, 0.5, "", hi_open=True))
        _set(self, "density", _positive("plate.density", self.density, "kg/m^3"))
        _set(self, "loss_factor", _range("plate.loss_factor", self.loss_factor, 0.0, 2.0, ""))
        _set(self, "max_frequency", _positive("plate.max_frequency", self.max_frequency, "Hz"))
        _set(self, "residual_compliance",
             _boolean("plate.residual_compliance", self.residual_compliance))
        _check_bounds(self, "plate")
        for name in ("block_position", "observation_position"):
            x, y = _pair(f"plate.{name}", getattr(self, name), "m")
            if not (0.0 < x < self.length):
                raise SceneError(f"plate.{name}[0] must be inside (0, plate.length="
                                 f"{self.length}) m, got {x}")
            if not (0.0 < y < self.width):
                raise SceneError(f"plate.{name}[1] must be inside (0, plate.width="
                                 f"{self.width}) m, got {y}")
            _set(self, name, (x, y))
        if self.kind == "modal":
            # the number of modes is bounded to keep a typo (1e9 Hz) from exhausting memory;
            # the estimate derives from six keys, so check it is a finite number and name them
            # all (the bounds keep it finite; this guards whatever they miss)
            n_est = math.nan
            try:
                b = self.youngs_modulus * self.thickness**3 / (12 * (1 - self.poisson_ratio**2))
                c = math.sqrt(b / (self.density * self.thickness))  # sqrt(B'/m'') [m^2/s]
                n_est = self.length * self.width * (2 * math.pi * self.max_frequency / c) / (
                    4 * math.pi)
            except (OverflowError, ZeroDivisionError):
                pass
            if not (math.isfinite(n_est) and n_est <= MAX_MODES):
                raise SceneError(f"plate.max_frequency gives about {n_est:.3g} modes with "
                                 f"plate.length, width, thickness, youngs_modulus, density and "
                                 f"poisson_ratio as given (limit {MAX_MODES}), lower it, got "
                                 f"{self.max_frequency} Hz")

    @property
    def bending_stiffness(self) -> float:
        """B' = E h^3 / (12 (1 - nu^2)) [N m]."""
        return self.youngs_modulus * self.thickness**3 / (12.0 * (1.0 - self.poisson_ratio**2))

    @property
    def mass_per_area(self) -> float:
        """m'' = rho h [kg/m^2]."""
        return self.density * self.thickness


@dataclass(frozen=True)
class Contact:
    """Unilateral linear contact springs between block and plate.

    Attributes
    ----------
    points : int or "auto"
        Number of contact springs N_c (the N highest profile maxima under the block);
        ``"auto"`` (default; the paper hand-set 10): the expected number of micro-contacts of
        the statistical contact model at the static load m g, rounded, at least 1
        (docs/theory.md, "Contact module").
    stiffness : float or "auto"
        Total incremental contact stiffness s_total [N/m], split equally; ``"auto"``
        (default; the paper hand-set 3.1e6 N/m) takes it from the surface statistics
        (Greenwood-Williamson / Greenwood-Tripp, roughvib.physics.surface).
    selection : {"separated", "highest"}
        Which profile maxima become contact points: ``separated`` (default), the highest
        maxima at least ``min_separation`` apart; ``highest``, the paper's literal rule, the
        N highest maxima with no separation constraint.
    min_separation : float
        Minimum distance between two chosen maxima [m] (so two maxima of one asperity are not
        both taken); our choice, used by ``selection = "separated"``.
    model : {"gw", "gt"}
        Statistical contact model used when ``stiffness = "auto"``.
    summit_density, summit_radius, summit_std : float or None
        Summit parameters eta_s [1/m^2], R [m], sigma_s [m]; ``None`` derives them from the
        spectral moments of the raw surface (Nayak / McCool).
    hardness : float
        Hardness of the softer surface [Pa], for the plasticity index.
    velocity_factor : bool
        Scale the stiffness by (v_rms / 0.01 m/s)^-0.481 (the paper's elevation effect);
        default true.
    patch : {"point", "area"}
        Where a contact meets the structure: ``point`` (default), at its own point under the
        block; ``area``, every contact force is spread evenly over the block's nominal contact
        area (``block.length`` x ``block.width``, centred at ``plate.block_position``) and
        feels the area mean of the structure's displacement (docs/structures.md).
    filter : {"hertz", "none"}
        The contact filter of the kinematic input: ``hertz`` (default), each contact sees the
        surface averaged over its real contact spot, weighted by the Hertz pressure of a spot
        of radius ``spot_radius`` (docs/theory.md, "The contact filter"); ``none``, the
        surface's own heights (the paper's model).
    spot_radius : float or "auto"
        Radius a of the contact spots [m]: the contact filter's radius and the scale at which
        the summits of the statistical contact are counted. ``"auto"`` (default): the mean
        micro-contact radius of the statistical contact, found self-consistently
        (docs/theory.md, "Contact module").
    friction_moment : bool
        Let the friction force act where it does, on the plate's top surface half a thickness
        (``plate.thickness`` / 2) above its mid-plane: besides the contact forces, the modes
        are then driven by the moment of the friction force through the x-slopes of their
        shapes (the paper's extension (v), docs/structures.md). Default false (the paper's
        model: friction acts on the block only). Needs a force-driven block and
        ``solver.method`` "ida" or "adaptive-modal".
    """

    points: int | str = "auto"
    stiffness: float | str = "auto"
    min_separation: float = 0.2e-3
    model: str = "gw"
    summit_density: float | None = None
    summit_radius: float | None = None
    summit_std: float | None = None
    hardness: float = 3e9
    velocity_factor: bool = True
    selection: str = "separated"
    patch: str = "point"
    filter: str = "hertz"
    spot_radius: float | str = "auto"
    friction_moment: bool = False

    def __post_init__(self) -> None:
        _set(self, "patch", _choice("contact.patch", self.patch, ("point", "area")))
        _set(self, "filter", _choice("contact.filter", self.filter, ("hertz", "none")))
        _set(self, "spot_radius",
             _auto_or_positive("contact.spot_radius", self.spot_radius, "m"))
        _set(self, "friction_moment", _boolean("contact.friction_moment", self.friction_moment))
        if isinstance(self.points, str):
            _choice("contact.points", self.points, ("auto",))
        else:
            _set(self, "points", _integer("contact.points", self.points, 1, MAX_CONTACTS))
        if isinstance(self.stiffness, str):
            _choice("contact.stiffness", self.stiffness, ("auto",))
        else:
            _set(self, "stiffness", _positive("contact.stiffness", self.stiffness, "N/m"))
        _set(self, "min_separation",
             _nonneg("contact.min_separation", self.min_separation, "m"))
        _set(self, "model", _choice("contact.model", self.model, ("gw", "gt")))
        _set(self, "summit_density",
             _opt_positive("contact.summit_density", self.summit_density, "1/m^2"))
        _set(self, "summit_radius",
             _opt_positive("contact.summit_radius", self.summit_radius, "m"))
        _set(self, "summit_std", _opt_positive("contact.summit_std", self.summit_std, "m"))
        _set(self, "hardness", _positive("contact.hardness", self.hardness, "Pa"))
        _set(self, "velocity_factor", _boolean("contact.velocity_factor", self.velocity_factor))
        _set(self, "selection", _choice("contact.selection", self.selection,
                                        ("separated", "highest")))
        _check_bounds(self, "contact")


@dataclass(frozen=True)
class Roughness:
    """Roughness profile z(s) (height, positive up) along the sliding direction.

    Attributes
    ----------
    kind : {"none", "sinusoid", "synthetic", "file"}
    interpolation : {"cubic", "linear", "quintic"}
        Interpolant between the samples of the input grid: ``quintic`` (default), a C4
        spline, whose knots an error-controlled step does not feel; ``cubic``, C2 (its
        third derivative jumps at every knot, which tight tolerances pay for in steps);
        ``linear``, C0, the paper's.
    amplitude, wavelength : float
        ``sinusoid``: z = amplitude cos(2 pi s / wavelength) [m], [m].
    rms : float
        ``synthetic``: rms of the kinematic input profile [m] (the 2-D reduced profile).
    seed : int
        ``synthetic``: random seed.
    hurst : float
        Hurst exponent H of the self-affine PSD tail, slope -(1 + 2H).
    rolloff_wavelength : float
        lambda_0 [m]: flat PSD above it, power law below it.
    shortest_wavelength : float or "auto"
        Where the surface's self-affine tail stops [m]. ``"auto"`` (default): the wavelength
        that the rms sliding speed maps to the top of the output band (v_rms / (2
        output.step): 0.2 um at 10 mm/s), at most 50 um, so that no band shown depends on it
        (docs/surfaces.md); 50e-6 is the paper's measured band.
    longest_wavelength : float
        Long end of the band [m] (40 mm, the block length, in the paper).
    spacing : float or "auto"
        Grid spacing of the input [m]: the field is sampled on it and interpolated between
        the samples (``synthetic``); the sample spacing of a one-column ``file``. ``"auto"``
        (default): a quarter of the shortest wavelength with the contact filter, an eighth without
        (``synthetic``), the paper's 10 um for a one-column file and the other kinds.
    trace_length : float
        Length of the synthetic trace [m].
    raw_rms : float
        Combined rms of the raw (3-D) surface [m]; feeds contact stiffness "auto" and the
        3-D surface generated when ``reduce_3d`` is true.
    reduce_3d : bool
        Generate an isotropic 2-D surface of rms ``raw_rms`` and reduce it to the input profile
        by span-averaging across the block width (then ``rms`` is not used).
    trace_layout : {"uniform", "cbrt2"}
        ``reduce_3d``: where the averaged traces lie across the width. ``uniform`` (default):
        a pitch of ``spacing``, the continuous width average of docs/theory.md (about
        -23 dB for the default surface). ``cbrt2``: the paper's separations growing by
        2^(1/3) from one edge, averaged with trapezoidal weights (about -10 dB; the paper
        used that layout for a coherence integral, see docs/theory.md).
    filter : {"highpass", "block-lowpass", "none"}
        Functional filter over the block length (docs/theory.md).
    tail : {"fit", "none"}
        ``file``: below the shortest wavelength the samples resolve (twice their spacing),
        ``fit`` (default) continues the profile's spectrum with the self-affine slope fitted
        to its own shortest resolved decade, down to ``shortest_wavelength`` (random phases
        from ``seed``); ``none`` keeps the file's band alone (the bands above v / (2 dx) then
        hold only the interpolant's residue).
    path : str
        ``file``: path of a profile file (relative paths are relative to the scene file).
    units : {"m", "um", "nm"}
        ``file``, text format: height unit of the file (and of the x column, if given).
    format : {"auto", "text", "topography"}
        ``file``: ``text`` is the plain-text/CSV reader; ``topography`` reads instrument
        formats (ISO 25178-71 SDF, X3P, Digital Surf .sur, Zygo .datx, ...) through the
        optional SurfaceTopography package (``pip install roughvib[topography]``); the x axis
        of the map is the sliding direction and units come from the file. ``auto``: by the
        file suffix (instrument suffixes -> topography) and content (netCDF or HDF5, e.g.
        SurfaceTopography's own ``.nc`` from contact.engineering -> topography), anything
        else -> text.
    """

    kind: str = "synthetic"
    interpolation: str = "quintic"
    amplitude: float = 0.35e-6
    wavelength: float = 1e-3
    rms: float = 0.35e-6
    seed: int = 1
    hurst: float = 0.8
    rolloff_wavelength: float = 0.5e-3
    shortest_wavelength: float | str = "auto"
    longest_wavelength: float = 0.04
    spacing: float | str = "auto"
    trace_length: float = 0.16
    raw_rms: float = 3.5e-6
    reduce_3d: bool = False
    trace_layout: str = "uniform"
    filter: str = "highpass"
    tail: str = "fit"
    path: str = ""
    units: str = "m"
    format: str = "auto"

    def __post_init__(self) -> None:
        p = "roughness"
        _set(self, "kind", _choice(f"{p}.kind", self.kind,
                                   ("none", "sinusoid", "synthetic", "file")))
        _set(self, "interpolation", _choice(f"{p}.interpolation", self.interpolation,
                                            ("cubic", "linear", "quintic")))
        _set(self, "amplitude", _nonneg(f"{p}.amplitude", self.amplitude, "m"))
        _set(self, "wavelength", _positive(f"{p}.wavelength", self.wavelength, "m"))
        _set(self, "rms", _nonneg(f"{p}.rms", self.rms, "m"))
        _set(self, "seed", _integer(f"{p}.seed", self.seed, 0))
        _set(self, "hurst", _range(f"{p}.hurst", self.hurst, 0.0, 1.0, "", lo_open=True))
        _set(self, "rolloff_wavelength",
             _positive(f"{p}.rolloff_wavelength", self.rolloff_wavelength, "m"))
        _set(self, "shortest_wavelength",
             _auto_or_positive(f"{p}.shortest_wavelength", self.shortest_wavelength, "m"))
        _set(self, "longest_wavelength",
             _positive(f"{p}.longest_wavelength", self.longest_wavelength, "m"))
        _set(self, "spacing", _auto_or_positive(f"{p}.spacing", self.spacing, "m"))
        _set(self, "trace_length", _positive(f"{p}.trace_length", self.trace_length, "m"))
        _set(self, "raw_rms", _nonneg(f"{p}.raw_rms", self.raw_rms, "m"))
        _set(self, "reduce_3d", _boolean(f"{p}.reduce_3d", self.reduce_3d))
        _set(self, "trace_layout", _choice(f"{p}.trace_layout", self.trace_layout,
                                           ("uniform", "cbrt2")))
        _set(self, "filter", _choice(f"{p}.filter", self.filter,
                                     ("highpass", "block-lowpass", "none")))
        _set(self, "tail", _choice(f"{p}.tail", self.tail, ("fit", "none")))
        if not isinstance(self.path, str):
            raise SceneError(f"{p}.path must be a string (file path), got {_fmt(self.path)}")
        _set(self, "units", _choice(f"{p}.units", self.units, ("m", "um", "nm")))
        _set(self, "format", _choice(f"{p}.format", self.format,
                                     ("auto", "text", "topography")))
        _check_bounds(self, "roughness")
        numeric = not isinstance(self.shortest_wavelength, str)
        if numeric and self.shortest_wavelength >= self.longest_wavelength:
            raise SceneError(f"{p}.shortest_wavelength must be < roughness.longest_wavelength "
                             f"({self.longest_wavelength} m), got {self.shortest_wavelength} m")
        if (self.kind == "synthetic" and numeric and not isinstance(self.spacing, str)
                and self.shortest_wavelength < 2 * self.spacing):
            raise SceneError(f"{p}.shortest_wavelength must be >= 2 * roughness.spacing "
                             f"({2 * self.spacing} m), got {self.shortest_wavelength} m")
        if self.kind == "file" and not self.path:
            raise SceneError(f"{p}.path must name a profile file when roughness.kind = "
                             f"'file', got ''")


#: the names ``friction.law`` accepts (the laws are registered in roughvib.physics.friction.LAWS;
#: a test keeps both lists equal) and those of them with a set-valued stick
FRICTION_LAWS = ("feldmann", "coulomb", "table")
SET_VALUED_LAWS = ("coulomb", "table")


@dataclass(frozen=True)
class Friction:
    """Friction law between block and plate.

    Attributes
    ----------
    law : {"feldmann", "coulomb", "table"}
        ``feldmann``: the paper's Eq. 10 with the latched hysteresis of docs/theory.md
        (a smooth regularisation: stick is a steep slope). ``coulomb``: set-valued
        Coulomb friction with regimes slip+, slip-, stick; in stick the velocity is held at
        zero and the friction force is an algebraic unknown (docs/theory.md). ``table``: the
        same set-valued law with the kinetic coefficient read from ``table``
        (docs/friction.md).
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
        _set(self, "law", _choice(f"{p}.law", self.law, FRICTION_LAWS))
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
    def set_valued(self) -> bool:
        """Whether the law is set-valued (stick held at v = 0, :data:`SET_VALUED_LAWS`)."""
        return self.law in SET_VALUED_LAWS


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


#: every solver (``solver.method`` may also be ``"auto"``), as registered in
#: :mod:`roughvib.solvers.registry`, which says what each one runs
SOLVER_METHODS = _registry.names()
#: the methods driven by a fixed step (``solver.step``); the others by tolerances
FIXED_STEP_METHODS = _registry.names(_registry.STEP)

#: the accuracy presets, from the most accurate to the cheapest (docs/accuracy.md)
ACCURACY_LEVELS = ("reference", "standard", "draft")

#: tolerances of each accuracy preset per method (``{method: {level: {key: value}}}``): what
#: ``solver.accuracy`` stands for when ``solver.rtol``, ``solver.atol``,
#: ``solver.atol_acceleration`` and ``solver.step`` are not given. Each solver's entry in
#: :mod:`roughvib.solvers.registry` holds its presets (and says how they were measured);
#: docs/accuracy.md lists them with their measured cost and error.
ACCURACY_PRESETS: dict[str, dict[str, dict[str, float]]] = {
    m.name: {level: dict(values) for level, values in m.presets.items()}
    for m in _registry.methods()}
_TOLERANCE_KEYS = ("rtol", "atol", "atol_acceleration", "atol_acceleration_relative", "step")


@dataclass(frozen=True)
class Solver:
    """Time integration.

    Attributes
    ----------
    method : {"auto", "ida", "adaptive-modal", "exact-modal", "newmark", "paper", "moreau"}
        ``auto`` (default): ``adaptive-modal`` where it can run (underdamped plate modes),
        otherwise ``ida`` (``plate.loss_factor >= 2``); :meth:`Scene.resolved_solver` makes
        the choice.
        ``ida``: event-driven adaptive DAE solver (SUNDIALS IDA). ``adaptive-modal``: exact
        per-mode propagation with error-controlled dyadic steps (step doubling, IDA's
        tolerances) and located events (every friction law, or prescribed motion). Fixed-step
        baselines (step ``solver.step``): ``exact-modal`` exact per-mode propagation with
        piecewise-linear force and an implicit contact/block step; ``newmark``
        average-acceleration Newmark on the modal model; ``paper`` the paper's scheme:
        backward Euler, Newton-Raphson with the Heaviside inside, plate by discrete
        convolution of its impulse response (explicit in the plate, O(N^2) cost); ``moreau``
        Moreau-Jean time-stepping of the set-valued laws (``friction.law = "coulomb"`` or
        ``"table"``) with the exact-modal plate. What each method runs is the solver
        registry's (:mod:`roughvib.solvers.registry`): a method that cannot run the scene is
        refused when the scene is built.
    accuracy : {"reference", "standard", "draft"}
        Accuracy preset: the tolerances (``rtol``, ``atol``, ``atol_acceleration``) or the step
        each method uses unless they are given explicitly (:data:`ACCURACY_PRESETS`).
        ``reference`` (default) meets the accuracy contract of docs/accuracy.md with the
        event-driven methods (the fixed-step ones locate events only to about a step).
    step : float or None
        Time step of the fixed-step methods [s]; ``None``: from the preset.
    rtol : float or None
        Relative tolerance; ``None``: from the preset.
    atol : float or None
        Absolute tolerance of the block's displacements [m]; block velocities and contact
        forces get tolerances scaled from it (docs/theory.md); ``None``: from the preset.
    atol_acceleration : float or None
        Absolute tolerance of the plate modes expressed as an acceleration [m/s^2]: mode r
        gets atol_q = a / w_r^2 and atol_dq = a / w_r, so high modes stay error-controlled
        down to this acceleration (what spectra to 50 kHz need); ``None``: from the preset,
        scaled with the run's acceleration level (``atol_acceleration_relative``).
    atol_acceleration_relative : float or None
        Plate-mode tolerance relative to the run's vertical acceleration level [-]: unless
        ``atol_acceleration`` is given, a pilot solve (the first 0.02 s, or a quarter of a
        shorter run, at draft tolerances) measures the larger rms vertical acceleration of
        block and plate, L, and the run uses ``atol_acceleration`` = this x max(L, 1e-6
        m/s^2). Quiet scenes get a tight tolerance, loud ones a loose one, so that the bands
        the accuracy contract checks (within 80 dB of the strongest) are resolved alike.
        ``None``: from the preset. The event-driven solvers refuse ``atol`` and
        ``atol_acceleration`` below the round-off floors of the scene (docs/robustness.md;
        they grow with the static load m g).
    max_order : int
        Highest BDF order (1..5). Default 2: orders >= 3 are not A-stable and were measured
        to excite the lightly damped top plate modes spuriously (docs/theory.md).
    max_step : float
        Largest internal step [s]; 0 means unbounded.
    linear_solver : {"sparse", "gmres"}
        IDA's linear solver for the Newton systems. ``sparse``: SuperLU_MT on the analytic
        arrow-shaped CSC Jacobian. ``gmres``: matrix-free GMRES (Krylov dimension 1) with the
        exact block-elimination preconditioner and analytic Jacobian-vector products of
        :mod:`roughvib.model.krylov` (docs/performance.md compares both).
    max_events : int
        Event-storm guard: at most this many events within ``event_window``.
    event_window : float
        Window of the event-storm guard [s].

    Notes
    -----
    An explicit value is one that is not ``None``: a scene file or ``--set`` that names
    ``solver.rtol`` (or ``atol``, ``atol_acceleration``, ``step``) overrides the preset for
    that key only; the other keys still come from the preset. :meth:`resolved` fills them in.
    """

    method: str = "auto"
    accuracy: str = "reference"
    step: float | None = None
    rtol: float | None = None
    atol: float | None = None
    atol_acceleration: float | None = None
    atol_acceleration_relative: float | None = None
    max_order: int = 2
    max_step: float = 0.0
    linear_solver: str = "sparse"
    max_events: int = 500
    event_window: float = 1e-3

    def __post_init__(self) -> None:
        p = "solver"
        _set(self, "method", _choice(f"{p}.method", self.method,
                                     ("auto",) + _registry.names()))
        _set(self, "accuracy", _choice(f"{p}.accuracy", self.accuracy, ACCURACY_LEVELS))
        if self.step is not None:
            _set(self, "step", _positive(f"{p}.step", self.step, "s"))
        if self.rtol is not None:
            _set(self, "rtol", _range(f"{p}.rtol", self.rtol, 1e-14, 1e-2, ""))
        if self.atol is not None:
            _set(self, "atol", _positive(f"{p}.atol", self.atol, "m"))
        if self.atol_acceleration is not None:
            _set(self, "atol_acceleration",
                 _positive(f"{p}.atol_acceleration", self.atol_acceleration, "m/s^2"))
        if self.atol_acceleration_relative is not None:
            _set(self, "atol_acceleration_relative",
                 _range(f"{p}.atol_acceleration_relative", self.atol_acceleration_relative,
                        0.0, 1.0, "", lo_open=True))
        _set(self, "max_order", _integer(f"{p}.max_order", self.max_order, 1, 5))
        _set(self, "max_step", _nonneg(f"{p}.max_step", self.max_step, "s"))
        _set(self, "linear_solver", _choice(f"{p}.linear_solver", self.linear_solver,
                                            ("sparse", "gmres")))
        _set(self, "max_events", _integer(f"{p}.max_events", self.max_events, 1))
        _set(self, "event_window", _positive(f"{p}.event_window", self.event_window, "s"))
        _check_bounds(self, "solver")

    def resolved(self, method: str | None = None) -> Solver:
        """This section with a concrete method and every tolerance and step filled in.

        Parameters
        ----------
        method : str, optional
            The method to resolve ``"auto"`` to (:meth:`Scene.resolved_solver` knows the
            scene); required when ``self.method == "auto"``.

        Returns
        -------
        Solver
            ``method`` concrete; ``rtol``, ``atol``, ``atol_acceleration`` and ``step`` the
            explicit values where given, else those of ``ACCURACY_PRESETS[method][accuracy]``,
            else those of the IDA preset of the same accuracy (tolerances) or 1e-5 s (step), so
            that every key holds a number whatever the method uses.
            ``atol_acceleration_relative`` is None for the fixed-step methods. Where
            ``atol_acceleration`` was not given, the run replaces it by
            ``atol_acceleration_relative`` times the level a pilot solve measures
            (:func:`roughvib.simulation.simulate`).
        """
        m = self.method if self.method != "auto" else method
        if m not in _registry.names():
            raise ValueError(f"Solver.resolved needs a concrete method, got {m!r}")
        solver = _registry.get(m)
        preset = {"step": 1e-5, **_registry.get("ida").presets[self.accuracy],
                  **solver.presets[self.accuracy]}
        values = {k: getattr(self, k) if getattr(self, k) is not None else preset[k]
                  for k in _TOLERANCE_KEYS}
        if solver.kind == _registry.STEP:
            values["atol_acceleration_relative"] = None
        return replace(self, method=m, **values)

    def from_preset(self) -> tuple[str, ...]:
        """Names of the tolerance keys (rtol, atol, atol_acceleration,
        atol_acceleration_relative, step) not given explicitly, i.e. taken from the accuracy
        preset."""
        return tuple(k for k in _TOLERANCE_KEYS if getattr(self, k) is None)


@dataclass(frozen=True)
class Output:
    """What is simulated and stored.

    Attributes
    ----------
    duration : float
        Simulated time [s].
    step : float
        Uniform output grid spacing [s] (1e-5 s: spectra to 50 kHz).
    transient : float
        Run-in excluded from the summary metrics [s]; metrics use whole excitation periods
        after it where possible.
    progress : bool
        Show a progress bar on stderr.
    checkpoint_interval : float
        Simulated time between checkpoints [s]; 0 (default) writes none. With ``roughvib run``
        each checkpoint is ``OUT/checkpoint.pkl`` (replaced atomically); ``roughvib run
        --resume OUT`` continues from it with results identical to an uninterrupted run of
        the same scene. IDA is restarted at every checkpoint (about 20 extra steps), so a run
        with checkpoints differs from one without them within the solver tolerance;
        adaptive-modal runs with and without checkpoints are identical. The interval is
        rounded to whole output steps, and with adaptive-modal's Hermite step (the Feldmann
        law with a force-driven block) up to a multiple of eight of them (its error estimate
        spans blocks of eight output intervals). ``solver.method = "ida"`` or ``"adaptive-modal"``.
    radiation : bool
        Compute the plate's radiated sound (docs/radiation.md): third-octave levels of the
        sound power, of the plate's mean-square velocity and of the radiation efficiency, in
        ``radiation.csv`` of the run directory and a figure in the run report. Needs the
        simply supported plate (``plate.kind = "modal"``).
    radiating_sides : int
        1 (a plate in an infinite baffle radiating into one half space) or 2 (both sides
        radiate, each as into a baffled half space: twice the power).
    air_density : float
        rho0 of the air [kg/m^3] (20 °C: 1.204).
    sound_speed : float
        c0 of the air [m/s] (20 °C: 343).
    microphones : tuple of (float, float, float)
        With ``radiation``: points [x, y, z] [m] in the plate's frame (z > 0 above the plate,
        on the radiating side) where the sound pressure is computed (third-octave levels to
        5 kHz in ``microphones.csv``, dB re 20 uPa); empty by default.
    """

    duration: float = 3.0 / 7.0
    step: float = 1e-5
    transient: float = 1.0 / 7.0
    progress: bool = True
    checkpoint_interval: float = 0.0
    radiation: bool = False
    radiating_sides: int = 1
    air_density: float = 1.204
    sound_speed: float = 343.0
    microphones: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self) -> None:
        p = "output"
        _set(self, "duration", _positive(f"{p}.duration", self.duration, "s"))
        _set(self, "step", _positive(f"{p}.step", self.step, "s"))
        _set(self, "transient", _nonneg(f"{p}.transient", self.transient, "s"))
        _set(self, "progress", _boolean(f"{p}.progress", self.progress))
        _set(self, "checkpoint_interval",
             _nonneg(f"{p}.checkpoint_interval", self.checkpoint_interval, "s"))
        _check_bounds(self, "output")
        if 0 < self.checkpoint_interval < self.step:
            raise SceneError(f"{p}.checkpoint_interval must be 0 (off) or >= output.step "
                             f"({self.step} s), got {self.checkpoint_interval} s")
        if self.step > self.duration:
            raise SceneError(f"{p}.step must be <= output.duration ({self.duration} s), "
                             f"got {self.step} s")
        if self.duration / self.step > 2e7:
            raise SceneError(f"{p}.step gives more than 2e7 output samples, got {self.step} s")
        _set(self, "radiation", _boolean(f"{p}.radiation", self.radiation))
        _set(self, "radiating_sides", _integer(f"{p}.radiating_sides", self.radiating_sides,
                                               1, 2))
        _set(self, "air_density", _positive(f"{p}.air_density", self.air_density, "kg/m^3"))
        _set(self, "sound_speed", _positive(f"{p}.sound_speed", self.sound_speed, "m/s"))
        mics = self.microphones
        if not isinstance(mics, list | tuple) or len(mics) > 64:
            raise SceneError(f"{p}.microphones must be a list of at most 64 points [x, y, z] m, "
                             f"got {_fmt(mics)}")
        points = []
        for i, m in enumerate(mics):
            if not isinstance(m, list | tuple) or len(m) != 3:
                raise SceneError(f"{p}.microphones[{i}] must be a point [x, y, z] m, "
                                 f"got {_fmt(m)}")
            x, y, z = (_number(f"{p}.microphones[{i}][{j}]", v, "m") for j, v in enumerate(m))
            if not z > 0:
                raise SceneError(f"{p}.microphones[{i}][2] must be > 0 m (above the plate), "
                                 f"got {_fmt(m[2])}")
            points.append((x, y, z))
        _set(self, "microphones", tuple(points))


#: longest scene description [characters]
DESCRIPTION_MAX = 10_000


@dataclass(frozen=True)
class Scene:
    """A complete, validated simulation scene (SI units throughout).

    Build one with :func:`load_scene`; change a copy with :meth:`with_overrides`.

    Attributes
    ----------
    name : str
        Names the run; ``roughvib run`` writes to ``runs/<name>`` unless ``--out`` is given, so
        it must be a plain file name: 1 to 100 characters, no leading ``.``, no leading or
        trailing blank, no ``/`` or ``\\``, none of ``: * ? " < > |`` and no control character.
    description : str
        About the scene, at most ``DESCRIPTION_MAX`` (10 000) characters (it is copied into
        scene.toml and result.nc of every run).
    """

    name: str = "paper"
    description: str = ""
    block: Block = field(default_factory=Block)
    plate: Plate = field(default_factory=Plate)
    contact: Contact = field(default_factory=Contact)
    roughness: Roughness = field(default_factory=Roughness)
    friction: Friction = field(default_factory=Friction)
    excitation: Excitation = field(default_factory=Excitation)
    solver: Solver = field(default_factory=Solver)
    output: Output = field(default_factory=Output)
    base_dir: str = field(default=".", compare=False)

    def __post_init__(self) -> None:
        _file_name("name", self.name)
        if not isinstance(self.description, str):
            raise SceneError(f"description must be a string, got {_fmt(self.description)}")
        if len(self.description) > DESCRIPTION_MAX:
            raise SceneError(f"description must have at most {DESCRIPTION_MAX} characters, got "
                             f"{len(self.description)}")
        bx, by = self.plate.block_position
        hl, hw = self.block.length / 2, self.block.width / 2
        if bx - hl <= 0 or bx + hl >= self.plate.length or by - hw <= 0 or \
                by + hw >= self.plate.width:
            raise SceneError(f"plate.block_position must keep the block ({self.block.length} x "
                             f"{self.block.width} m) on the plate, got {[bx, by]} m")
        if self.contact.friction_moment and self.excitation.kind != "force":
            raise SceneError(f"contact.friction_moment = true needs excitation.kind = "
                             f"'force' (a prescribed motion has no friction force), got "
                             f"{self.excitation.kind!r}")
        # what the solver runs (friction law, friction moment, checkpoints, structure): the
        # solver registry's rules, in one line naming solver.method and what would run it
        refused = _registry.refusal_line(self)
        if refused is not None:
            raise SceneError(refused)
        if self.output.radiation and self.plate.kind != "modal":
            raise SceneError(f"output.radiation needs the simply supported plate (plate.kind = "
                             f"'modal'), got plate.kind = {self.plate.kind!r}")
        if self.output.microphones and not self.output.radiation:
            raise SceneError(f"output.microphones needs output.radiation = true, got "
                             f"{len(self.output.microphones)} microphones with radiation off")
        # derived quantities a run needs, checked here with the keys they derive from
        r = self.roughness
        if (r.kind != "file" and not isinstance(r.spacing, str)
                and r.trace_length / r.spacing > MAX_PROFILE_SAMPLES):
            raise SceneError(f"roughness.trace_length / roughness.spacing must be at most "
                             f"{MAX_PROFILE_SAMPLES:.0e} profile samples, got "
                             f"{r.trace_length} m / {r.spacing} m = "
                             f"{r.trace_length / r.spacing:.3g}")
        method = self.resolved_solver()
        if _registry.get(method.method).kind == _registry.STEP and \
                self.output.duration / method.step > MAX_FIXED_STEPS:
            raise SceneError(f"output.duration / solver.step must be at most "
                             f"{MAX_FIXED_STEPS:.0e} steps of solver.method = "
                             f"{method.method!r}, got {self.output.duration} s / "
                             f"{method.step} s = {self.output.duration / method.step:.3g}")

    # ---- convenience -------------------------------------------------------------------
    def with_overrides(self, overrides: dict[str, Any] | None = None, **kw: Any) -> Scene:
        """Return a copy with dotted-path overrides applied (``{"block.mass": 0.543}``).

        Keyword form uses a double underscore: ``with_overrides(block__mass=0.543)``.
        """
        data = scene_to_dict(self)
        items = dict(overrides or {})
        items.update({k.replace("__", "."): v for k, v in kw.items()})
        for key, value in items.items():
            _assign(data, key, value)
        return scene_from_dict(data, base_dir=self.base_dir)

    def resolved_solver(self) -> Solver:
        """The solver section as it runs: ``method = "auto"`` replaced by the method chosen
        for this scene, every tolerance and step filled in from the accuracy preset unless
        given explicitly (:meth:`Solver.resolved`).

        ``auto`` is ``adaptive-modal`` (the fastest method that meets the accuracy contract,
        docs/accuracy.md; every friction law, with or without the friction moment) unless the
        scene needs what only ``ida`` offers: overdamped plate modes
        (``plate.loss_factor >= 2``). The solver registry decides
        (:func:`roughvib.solvers.registry.resolve_auto`: the first of ``AUTO`` that supports
        the scene).
        """
        s = self.solver
        if s.method != "auto":
            return s.resolved()
        method = _registry.resolve_auto(self)
        if method is None:  # validation refuses such a scene: this guards a half-built one
            raise SceneError(_registry.refusal_line(self))
        return s.resolved(method)

    @property
    def period(self) -> float:
        """Excitation period [s] (inf for zero frequency)."""
        f = self.excitation.frequency
        return math.inf if f == 0 else 1.0 / f


_SECTIONS: dict[str, type] = {
    "block": Block,
    "plate": Plate,
    "contact": Contact,
    "roughness": Roughness,
    "friction": Friction,
    "excitation": Excitation,
    "solver": Solver,
    "output": Output,
}
_TOP_KEYS = ("name", "description")


def _assign(data: dict, key: str, value: Any) -> None:
    parts = key.split(".")
    if len(parts) == 1 and parts[0] in _TOP_KEYS:
        data[parts[0]] = value
        return
    if len(parts) != 2 or parts[0] not in _SECTIONS:
        raise SceneError(f"{key} is not a scene key (use section.key, sections: "
                         f"{', '.join(_SECTIONS)}), got {_fmt(value)}")
    data.setdefault(parts[0], {})[parts[1]] = value


def scene_to_dict(scene: Scene) -> dict[str, Any]:
    """Plain nested dict of a scene (tuples become lists, ``None`` values are dropped)."""
    out: dict[str, Any] = {"name": scene.name, "description": scene.description}
    for sec in _SECTIONS:
        obj = getattr(scene, sec)
        d = {}
        for f in fields(obj):
            v = getattr(obj, f.name)
            if v is None:
                continue
            d[f.name] = list(v) if isinstance(v, tuple) else v
        out[sec] = d
    return out


def scene_from_dict(data: dict[str, Any], *, base_dir: str | Path = ".") -> Scene:
    """Build and validate a scene from a nested dict (as read from TOML).

    Raises
    ------
    SceneError
        Unknown section or key, wrong type or out-of-range value.
    """
    if not isinstance(data, dict):
        raise SceneError(f"scene must be a table of sections, got {_fmt(data)}")
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        if key in _TOP_KEYS:
            kwargs[key] = value
            continue
        if key not in _SECTIONS:
            raise SceneError(f"{key} is not a scene section (known: "
                             f"{', '.join(_SECTIONS)}), got {_fmt(value)}")
        cls = _SECTIONS[key]
        if not isinstance(value, dict):
            raise SceneError(f"{key} must be a table [{key}], got {_fmt(value)}")
        known = {f.name for f in fields(cls)}
        for k in value:
            if k not in known:
                raise SceneError(f"{key}.{k} is not a known key of [{key}] (known: "
                                 f"{', '.join(sorted(known))}), got {_fmt(value[k])}")
        sec = dict(value)
        if cls is Excitation and "force_amplitude" in sec and "target_rms_velocity" not in sec:
            sec["target_rms_velocity"] = None
        if cls is Excitation and "target_rms_velocity" in sec and "force_amplitude" not in sec:
            sec["force_amplitude"] = None
        # "none" clears an optional value (TOML has no null)
        for k, v in list(sec.items()):
            if v == "none" and (k in ("force_amplitude", "target_rms_velocity",
                                      "summit_density", "summit_radius", "summit_std",
                                      "stribeck_velocity")
                                or (cls is Solver and k in _TOLERANCE_KEYS)):
                sec[k] = None
        try:
            kwargs[key] = cls(**sec)
        except TypeError as exc:  # pragma: no cover - guarded by the key check above
            raise SceneError(f"{key}: {exc}") from None
    return Scene(**kwargs, base_dir=str(base_dir))


# --------------------------------------------------------------------------------------------
# TOML
# --------------------------------------------------------------------------------------------


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def scene_to_toml(scene: Scene, *, comments: dict[str, str] | None = None) -> str:
    """Serialise a scene to TOML text that :func:`load_scene` reads back to an equal scene.

    Parameters
    ----------
    scene : Scene
    comments : dict, optional
        ``{"excitation.force_amplitude": "calibrated ..."}``: a comment after that key.
    """
    comments = comments or {}
    d = scene_to_dict(scene)
    lines = [f"name = {_toml_value(d['name'])}",
             f"description = {_toml_value(d['description'])}"]
    for sec in _SECTIONS:
        lines.append("")
        lines.append(f"[{sec}]")
        for k, v in d[sec].items():
            c = comments.get(f"{sec}.{k}")
            lines.append(f"{k} = {_toml_value(v)}" + (f"  # {c}" if c else ""))
    return "\n".join(lines) + "\n"


def builtin_scenes() -> dict[str, str]:
    """Names of the built-in scenes and their one-line descriptions."""
    out = {}
    for entry in sorted(resources.files("roughvib.scenes").iterdir(), key=lambda e: e.name):
        if entry.name.endswith(".toml"):
            data = tomllib.loads(entry.read_text())
            out[entry.name[:-5]] = data.get("description", "")
    return out


_FILE_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
               (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
               (stat.S_ISSOCK, "a socket"))


def read_regular_file(path: Path, what: str) -> bytes:
    """The bytes of a regular file, refusing anything else in one line before reading.

    The file is opened without blocking and checked on the open descriptor, so a named pipe
    is refused at once instead of waiting for a writer, and nothing can swap the file between
    the check and the read.

    Parameters
    ----------
    path : Path
    what : str
        What the file is, for the message (``"scene file"``, ``"sweep file"``).

    Raises
    ------
    SceneError
        Unreadable, or not a regular file: ``<what> <path> must be a regular file, got a named
        pipe (FIFO)``.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise SceneError(f"{what} {path} cannot be read: {exc.strerror}") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = next((k for test, k in _FILE_KINDS if test(mode)), "not a file")
            raise SceneError(f"{what} {path} must be a regular file, got {kind}")
        chunks = []
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise SceneError(f"{what} {path} cannot be read: {exc.strerror}") from None
    finally:
        os.close(fd)


def read_toml_file(path: Path, what: str = "scene file") -> dict[str, Any]:
    """Read a TOML file as UTF-8 (a leading byte-order mark is accepted and dropped).

    Parameters
    ----------
    path : Path
    what : str
        What the file is, for the message (``"scene file"``, ``"sweep file"``).

    Raises
    ------
    SceneError
        Unreadable file, not a regular file (a directory, a named pipe, a device: reading a
        pipe would wait for a writer forever), bytes that are not UTF-8 (the line and the byte
        are named), or invalid TOML; one line.
    """
    raw = read_regular_file(path, what)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise SceneError(f"{what} {path} must be UTF-8 text (save it as UTF-8), got byte "
                         f"0x{raw[exc.start]:02x} on line {line}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{what} {path} is not valid TOML: {exc}") from None


def load_scene(source: str | Path | None = "paper", overrides: dict[str, Any] | None = None,
               **kw: Any) -> Scene:
    """Load a built-in scene by name or a TOML scene file, then apply overrides.

    Parameters
    ----------
    source : str or Path, optional
        A built-in name (``"paper"``, ``"paper-100mms"``, ...; see :func:`builtin_scenes`) or a
        path to a ``.toml`` file. An empty file is the paper scene.
    overrides : dict, optional
        Dotted keys, e.g. ``{"block.mass": 0.543, "output.duration": 0.2}``.
    **kw
        More overrides: ``load_scene("paper", **{"block.mass": 0.543})`` or
        ``load_scene("paper", block__mass=0.543)``.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        Unknown scene, unreadable file, unknown key or invalid value.

    Examples
    --------
    >>> scene = load_scene("paper", **{"output.duration": 0.05})
    >>> scene.block.mass
    0.221
    """
    if source is None:
        source = "paper"
    builtins = builtin_scenes()
    if isinstance(source, str) and source in builtins:
        text = resources.files("roughvib.scenes").joinpath(f"{source}.toml").read_text()
        data = tomllib.loads(text)
        base = Path.cwd()
    else:
        path = Path(source)
        if not path.exists():
            raise SceneError(f"scene {str(source)!r} is neither a built-in scene "
                             f"({', '.join(builtins)}) nor an existing file")
        data = read_toml_file(path)
        base = path.resolve().parent
    scene = scene_from_dict(data, base_dir=base)
    if overrides or kw:
        scene = scene.with_overrides(overrides, **kw)
    return scene


#: a plate thicker than this fraction of its smaller side is no thin (Kirchhoff) plate
THIN_PLATE_RATIO = 0.1
#: thin-plate theory holds for bending wavelengths longer than this many plate thicknesses
BENDING_WAVELENGTH_THICKNESSES = 6.0
#: relative shortfall of the analysis window against one excitation period that counts as
#: rounding, not as a short window: a period typed to 7 or more digits (the docs write two
#: periods at 7 Hz as 0.2857142857 s) passes. The metrics' whole-period window counts each
#: output sample as one step long, so a window short by less than one output step still
#: holds the period; 1e-6 of a period is below one step for any grid of fewer than 1e6
#: samples per period, so the tolerance never hides a window that misses a sample.
PERIOD_ROUNDING = 1e-6


def validity_warnings(scene: Scene) -> list[str]:
    """Legal scene values outside the model's validity, as one-line messages.

    * a plate thicker than 1/10 of its smaller side: Kirchhoff (thin-plate) theory does not
      hold;
    * plate modes whose bending wavelength is shorter than 6 plate thicknesses: thin-plate
      theory, which neglects shear and rotary inertia, overestimates their frequencies;
    * ``output.transient`` not shorter than ``output.duration``: the metrics include the
      run-in;
    * an analysis window (after the run-in) shorter than one excitation period: the rms
      values are no cycle averages, and a calibrated target velocity is missed.

    Parameters
    ----------
    scene : Scene

    Returns
    -------
    list of str
        Empty when nothing applies.
    """
    out = []
    plt = scene.plate
    side = min(plt.length, plt.width)
    if plt.kind == "modal":
        if plt.thickness > THIN_PLATE_RATIO * side:
            out.append(f"plate.thickness {plt.thickness} m is more than {THIN_PLATE_RATIO:g} x "
                       f"the plate's smaller side ({side} m): Kirchhoff (thin-plate) theory "
                       f"does not hold, so the plate modes are not those of this plate")
        else:
            # bending wavenumber k = 2 pi / (6 h) at omega = k^2 sqrt(B / m'')
            k = 2 * math.pi / (BENDING_WAVELENGTH_THICKNESSES * plt.thickness)
            f6 = k**2 * math.sqrt(plt.bending_stiffness / plt.mass_per_area) / (2 * math.pi)
            if f6 < plt.max_frequency:
                out.append(f"plate modes above {f6:.4g} Hz have bending wavelengths shorter than "
                           f"{BENDING_WAVELENGTH_THICKNESSES:g} x plate.thickness "
                           f"({plt.thickness} m): thin-plate theory overestimates their "
                           f"frequencies (no shear, no rotary inertia); lower "
                           f"plate.max_frequency to {f6:.4g} Hz or read those bands with care, "
                           f"got {plt.max_frequency} Hz")
    out_ = scene.output
    exc = scene.excitation
    window = out_.duration - out_.transient
    if window <= 0:
        out.append(f"output.transient ({out_.transient:.6g} s) is not shorter than "
                   f"output.duration ({out_.duration:.6g} s): the metrics are taken over the "
                   f"whole record, run-in included")
        window = out_.duration
    periodic = exc.frequency > 0 and (exc.kind == "force" or exc.amplitude > 0)
    if periodic and window < scene.period * (1.0 - PERIOD_ROUNDING):
        target = (" and miss excitation.target_rms_velocity, which is calibrated for whole "
                  "cycles") if exc.kind == "force" and exc.target_rms_velocity else ""
        out.append(f"the analysis window ({window:.6g} s) is shorter than one excitation period "
                   f"({scene.period:.6g} s): the rms values and levels average over part of a "
                   f"cycle{target}; make output.duration - output.transient at least one period")
    return out


def replace_section(scene: Scene, section: str, **changes: Any) -> Scene:
    """Return a copy of ``scene`` with fields of one section replaced (validated)."""
    return dataclasses.replace(scene, **{section: replace(getattr(scene, section), **changes)})
