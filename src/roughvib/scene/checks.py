"""Scene validation helpers: the one-line errors, the field checks and the sane bounds.

:class:`~roughvib.scene.SceneError` and :class:`~roughvib.scene.ModelValidityWarning`, the
checks each section applies to its values (``_number``, ``_positive``, ``_range``, ``_choice``,
...), the upper limits of what a scene may ask for (``MAX_*``), the scene name's rule and
:data:`SANE_BOUNDS` with :func:`bounds_rule`. Nothing in here knows a section; the sections
(:mod:`.bodies`, :mod:`.forces`, :mod:`.solver_output`) call these.
"""

from __future__ import annotations

import math
import os
from dataclasses import fields
from typing import Any


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
    import sys

    # the roughvib package folder (this module is in its scene/ subfolder)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep
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
    "friction.stick_velocity": (0.0, 100.0, "m/s"),
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
