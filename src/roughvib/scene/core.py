"""The whole scene: :class:`~roughvib.scene.Scene`, its cross-section checks and its plain-dict
form.

:class:`~roughvib.scene.Scene` holds one section each (:mod:`.bodies`, :mod:`.forces`,
:mod:`.solver_output`) and checks what spans sections (the block on the plate, what the solver
runs, derived counts); :func:`scene_to_dict` and :func:`scene_from_dict` convert it to and from
the nested dict a TOML file reads as.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from roughvib.scene.bodies import Block, Contact, Plate, Roughness
from roughvib.scene.checks import MAX_FIXED_STEPS, MAX_PROFILE_SAMPLES, SceneError, _file_name, _fmt
from roughvib.scene.forces import (
    FRICTION_LAWS,
    Excitation,
    Friction,
    fold_law_keys,
    law_key_path,
)
from roughvib.scene.solver_output import _TOLERANCE_KEYS, Output, Solver
from roughvib.solvers import registry as _registry

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
        law = items.get("friction.law", self.friction.law)
        if law != self.friction.law:  # another law: its keys, not the defaults of this one's
            own = FRICTION_LAWS[self.friction.law].keys
            data["friction"]["parameters"] = {
                k: v for k, v in data["friction"].get("parameters", {}).items()
                if k not in own or not own[k].holds_default(v)}
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
    parts = law_key_path(key).split(".")  # friction.a1 is friction.parameters.a1
    if len(parts) == 1 and parts[0] in _TOP_KEYS:
        data[parts[0]] = value
        return
    if len(parts) == 3 and parts[0] in _SECTIONS:
        # a key of a table inside a section (friction.parameters.sigma0)
        section, name, inner = parts
        table = data.setdefault(section, {}).setdefault(name, {})
        if not isinstance(table, dict):
            raise SceneError(f"{key}: {section}.{name} is not a table, got {_fmt(table)}")
        table[inner] = value
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
            if v is None or (isinstance(v, Mapping) and not v):
                continue
            d[f.name] = (list(v) if isinstance(v, tuple) else
                         {k: x for k, x in v.items() if x is not None}
                         if isinstance(v, Mapping) else v)
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
        if cls is Friction:  # the flat law keys of earlier scene files (friction.a1)
            value = fold_law_keys(value)
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
                                      "summit_density", "summit_radius", "summit_std")
                                or (cls is Solver and k in _TOLERANCE_KEYS)):
                sec[k] = None
        try:
            kwargs[key] = cls(**sec)
        except TypeError as exc:  # pragma: no cover - guarded by the key check above
            raise SceneError(f"{key}: {exc}") from None
    return Scene(**kwargs, base_dir=str(base_dir))


def replace_section(scene: Scene, section: str, **changes: Any) -> Scene:
    """Return a copy of ``scene`` with fields of one section replaced (validated)."""
    return dataclasses.replace(scene, **{section: replace(getattr(scene, section), **changes)})
