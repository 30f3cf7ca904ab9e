"""What a sweep is: the sweep file (parsing and validation), its cases and their stable names,
and the layout of a sweep directory (``DIR/cases/<case>/``, files replaced atomically).

The file format is described in :mod:`roughvib.studies.sweep` and docs/sweeps.md.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import os
import re
import tomllib
from collections.abc import Iterable, Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from roughvib.rundir import write_file
from roughvib.scene import (
    Scene,
    SceneError,
    law_key_path,
    load_scene,
    read_toml_file,
    scene_to_dict,
)

__all__ = ["CASES_DIR", "SUCCESS", "Case", "Sweep", "adopt_old_case_names", "builtin_sweeps",
           "case_name", "load_sweep", "old_case_name"]

SUCCESS = "success"
CASES_DIR = "cases"
_TOP_KEYS = ("name", "description", "base", "set", "grid", "case")
_SAFE = re.compile(r"[^A-Za-z0-9._=,+-]+")  # sweep names (and the case names before 0.2)
_SHELL_SAFE = re.compile(r"[^A-Za-z0-9._+-]+")  # case names: nothing a shell needs quoted

# --------------------------------------------------------------------------------------------
# sweep description
# --------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Case:
    """One case of a sweep.

    Attributes
    ----------
    name : str
        Directory name under ``DIR/cases`` (stable; no character a shell needs quoted).
    values : dict
        The varied values of this case, dotted scene key -> value.
    index : tuple of int
        Position on the sweep's dimensions (grid keys in file order, then ``case``).
    """

    name: str
    values: dict[str, Any]
    index: tuple[int, ...]


@dataclasses.dataclass(frozen=True)
class Sweep:
    """A validated sweep: base scene, fixed overrides, grid and case list.

    Build one with :func:`load_sweep`.

    Attributes
    ----------
    name, description : str
    base : Scene
        The base scene with the fixed overrides applied.
    base_label : str
        The base as written in the file (built-in name or path).
    fixed : dict
        Fixed overrides (``[set]`` and command-line ``--set``), dotted key -> value.
    grid : dict
        Dotted key -> list of values (in file order); the sweep is their product.
    cases_list : list of dict
        ``[[case]]`` entries, each dotted key -> value.
    source : str
        Where the sweep came from (file path or ``builtin:NAME``).
    """

    name: str
    description: str
    base: Scene
    base_label: str
    fixed: dict[str, Any]
    grid: dict[str, list[Any]]
    cases_list: list[dict[str, Any]]
    source: str = ""

    @property
    def dims(self) -> tuple[str, ...]:
        """Dimension names of sweep.nc: the grid keys, then ``"case"`` if there is a case list."""
        return tuple(self.grid) + (("case",) if self.cases_list else ())

    @property
    def shape(self) -> tuple[int, ...]:
        """Sizes of :attr:`dims`."""
        return tuple(len(v) for v in self.grid.values()) + \
            ((len(self.cases_list),) if self.cases_list else ())

    @property
    def varied_keys(self) -> list[str]:
        """Grid keys, then case keys in order of first appearance."""
        keys = list(self.grid)
        for entry in self.cases_list:
            keys += [k for k in entry if k not in keys]
        return keys

    def base_value(self, key: str) -> Any:
        """Value of a dotted key in the base scene (None if unset)."""
        value: Any = scene_to_dict(self.base)
        for part in law_key_path(key).split("."):  # section.key, or section.table.key
            value = value.get(part) if isinstance(value, dict) else None
        return value

    def cases(self) -> list[Case]:
        """All cases in C order (grid keys in file order, the case list last)."""
        keys = self.varied_keys
        entries = self.cases_list or [None]
        out = []
        for gidx in itertools.product(*(range(len(v)) for v in self.grid.values())):
            for ci, entry in enumerate(entries):
                values = {k: self.grid[k][i] for k, i in zip(self.grid, gidx, strict=True)}
                values.update(entry or {})
                index = gidx + ((ci,) if self.cases_list else ())
                out.append(Case(case_name(self.base, values, keys), values, index))
        return out

    def to_json(self) -> dict[str, Any]:
        """JSON-able description (written to ``DIR/sweep.json``)."""
        return {
            "name": self.name,
            "description": self.description,
            "base": self.base_label,
            "source": self.source,
            "set": self.fixed,
            "grid": self.grid,
            "case": self.cases_list,
            "dims": list(self.dims),
            "varied_keys": self.varied_keys,
            "seed_keys": [k for k in self.varied_keys if k.rsplit(".", 1)[-1] == "seed"],
        }


def _flatten(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested TOML tables to dotted keys (scene values themselves are never tables)."""
    out: dict[str, Any] = {}
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


def _check_key(base: Scene, key: str, where: str) -> None:
    sections = [f.name for f in dataclasses.fields(Scene)
                if dataclasses.is_dataclass(getattr(base, f.name))]
    section, dot, field = law_key_path(key).partition(".")  # friction.a1: in parameters
    if key in ("name", "description"):
        raise SceneError(f"{where}{key} cannot be swept (each case is named by the sweep)")
    name, inner_dot, inner = field.partition(".")
    table = getattr(getattr(base, section, None), name, None) if inner_dot else None
    if isinstance(table, Mapping):  # a key of a table in a section (friction.parameters.sigma0)
        if inner not in table:  # the base's table holds every key its law has (defaults)
            raise SceneError(f"{where}{key} is not a known key of {section}.{name} for this "
                             f"base scene (known: {', '.join(table) or 'none'})")
        return
    if not dot or "." in field or section not in sections:
        raise SceneError(f"{where}{key} is not a scene key (use section.key, sections: "
                         f"{', '.join(sections)})")
    known = sorted(f.name for f in dataclasses.fields(getattr(base, section)))
    if field not in known:
        raise SceneError(f"{where}{key} is not a known key of [{section}] (known: "
                         f"{', '.join(known)})")


def _check_range(value: Any, where: str) -> None:
    """Numbers of a grid or case must fit a float64 or int64 (the tables store them)."""
    if isinstance(value, list):
        for v in value:
            _check_range(v, where)
    elif isinstance(value, int) and not isinstance(value, bool) and abs(value) > 2**63 - 1:
        raise SceneError(f"{where} must be a number within the range of a 64-bit integer or "
                         f"float, got an integer of {len(str(abs(value)))} digits")


def _canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=True)


def _fingerprint(base: Scene) -> dict[str, Any]:
    d = scene_to_dict(base)
    d.pop("name", None)
    d.pop("description", None)
    d.get("output", {}).pop("progress", None)
    return d


def _fmt_value(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, str | bool | int):
        return str(v).lower() if isinstance(v, bool) else str(v)
    return _canonical(v)


def _case_name(base: Scene, values: dict[str, Any], keys: Iterable[str] | None, *,
               pair: str, sep: str, tail: str, safe: re.Pattern) -> str:
    keys = list(keys) if keys is not None else list(values)
    lasts = [k.rsplit(".", 1)[-1] for k in keys]
    parts = []
    for k in [k for k in keys if k in values] + [k for k in values if k not in keys]:
        last = k.rsplit(".", 1)[-1]
        label = last if lasts.count(last) <= 1 else k
        parts.append(f"{label}{pair}{_fmt_value(values[k])}")
    readable = safe.sub("_", sep.join(parts))[:80].lstrip(".-")
    digest = hashlib.sha256(_canonical({"base": _fingerprint(base), "values": values})
                            .encode()).hexdigest()[:10]
    return f"{readable}{tail}{digest}" if readable else digest


def case_name(base: Scene, values: dict[str, Any], keys: Iterable[str] | None = None) -> str:
    """Stable directory name of a case that a shell takes without quotes.

    Parameters
    ----------
    base : Scene
        Base scene (with the fixed overrides applied); part of the hash.
    values : dict
        The case's varied values, dotted key -> value.
    keys : iterable of str, optional
        All varied keys of the sweep: the readable part uses the last component of a key
        unless two varied keys share it.

    Returns
    -------
    str
        ``"target_rms_velocity-0.01__seed-2__1a2b3c4d5e"``: ``key-value`` pairs joined by
        ``__`` (at most 80 characters of ``[A-Za-z0-9._+-]``, anything else replaced by
        ``_``), then ``__`` and 10 hex digits of a SHA-256 over the base scene and the values.
        The exact values are in the case's ``case.json``.
    """
    return _case_name(base, values, keys, pair="-", sep="__", tail="__", safe=_SHELL_SAFE)


def old_case_name(base: Scene, values: dict[str, Any], keys: Iterable[str] | None = None
                  ) -> str:
    """The name roughvib 0.1 gave a case (``"target_rms_velocity=0.01,seed=2-1a2b3c4d5e"``),
    same hash as :func:`case_name`; kept to adopt the case directories of older sweeps."""
    return _case_name(base, values, keys, pair="=", sep=",", tail="-", safe=_SAFE)


def adopt_old_case_names(sweep: Sweep, cases_dir: Path) -> list[tuple[str, str]]:
    """Rename the case directories of an older roughvib (``key=value,...``) to today's names.

    A directory is renamed only if no directory of the new name exists; its ``case.json``
    then records the old name under ``renamed_from``. Nothing is recomputed: a complete case
    stays complete under its new name.

    Parameters
    ----------
    sweep : Sweep
    cases_dir : Path
        ``DIR/cases`` of the sweep.

    Returns
    -------
    list of (str, str)
        The (old, new) names renamed.
    """
    renamed = []
    keys = sweep.varied_keys
    for case in sweep.cases():
        old = cases_dir / old_case_name(sweep.base, case.values, keys)
        new = cases_dir / case.name
        if old == new or not old.is_dir() or new.exists():
            continue
        os.rename(old, new)
        info_path = new / "case.json"
        try:
            info = json.loads(info_path.read_text())
        except (OSError, ValueError):
            info = {"values": case.values}
        info.update(name=case.name, renamed_from=old.name)
        _replace_file(info_path, json.dumps(info, indent=2))
        renamed.append((old.name, case.name))
    return renamed


def _sweeps_dir():
    return resources.files("roughvib.scenes").joinpath("sweeps")


def builtin_sweeps() -> dict[str, str]:
    """Names of the built-in sweeps and their one-line descriptions.

    Returns
    -------
    dict
        Name -> description (empty if the sweep files are not installed).
    """
    out: dict[str, str] = {}
    try:
        entries = sorted(_sweeps_dir().iterdir(), key=lambda e: e.name)
    except (FileNotFoundError, NotADirectoryError):  # pragma: no cover - packaging problem
        return out
    for entry in entries:
        if entry.name.endswith(".toml"):
            out[entry.name[:-5]] = tomllib.loads(entry.read_text()).get("description", "")
    return out


def _parse(data: dict[str, Any], *, base_dir: Path, source: str, default_name: str,
           overrides: dict[str, Any] | None) -> Sweep:
    for k in data:
        if k not in _TOP_KEYS:
            raise SceneError(f"{k} is not a sweep file key (known: {', '.join(_TOP_KEYS)})")
    name = data.get("name", default_name)
    description = data.get("description", "")
    if not isinstance(name, str) or not name or _SAFE.search(name):
        raise SceneError(f"name must be a non-empty string of letters, digits and ._=,+-, got "
                         f"{name!r}")
    if not isinstance(description, str):
        raise SceneError(f"description must be a string, got {description!r}")
    base_label = data.get("base", "paper")
    if not isinstance(base_label, str) or not base_label:
        raise SceneError(f"base must be a built-in scene name or a scene file, got "
                         f"{base_label!r}")
    looks_like_path = base_label.endswith(".toml") or "/" in base_label or os.sep in base_label
    base_src: str | Path = (base_dir / base_label) if looks_like_path else base_label
    try:
        base = load_scene(base_src)
    except SceneError as exc:
        raise SceneError(f"base: {exc}") from None

    raw_set = data.get("set", {})
    if not isinstance(raw_set, dict):
        raise SceneError(f"set must be a table [set] of scene keys, got {raw_set!r}")
    fixed = _flatten(raw_set)
    fixed.update(overrides or {})
    for k in fixed:
        _check_key(base, k, "set.")
    try:
        base = base.with_overrides(fixed)
    except SceneError as exc:
        raise SceneError(f"set: {exc}") from None

    raw_grid = data.get("grid", {})
    if not isinstance(raw_grid, dict):
        raise SceneError(f"grid must be a table [grid] of scene keys -> lists, got {raw_grid!r}")
    grid = _flatten(raw_grid)
    for k, values in grid.items():
        _check_key(base, k, "grid.")
        if not isinstance(values, list) or not values:
            raise SceneError(f"grid.{k} must be a non-empty list of values, got {values!r}")
        seen = []
        for v in values:
            _check_range(v, f"grid.{k}")
            c = _canonical(v)
            if c in seen:
                raise SceneError(f"grid.{k} has the value {v!r} more than once")
            seen.append(c)
        if k in fixed:
            raise SceneError(f"grid.{k} is also a fixed value ([set] or --set); give it once")

    raw_cases = data.get("case", [])
    if not isinstance(raw_cases, list):
        raise SceneError(f"case must be an array of tables [[case]], got {raw_cases!r}")
    cases_list: list[dict[str, Any]] = []
    seen_cases: list[str] = []
    for i, entry in enumerate(raw_cases):
        if not isinstance(entry, dict) or not entry:
            raise SceneError(f"case[{i}] must be a non-empty table of scene keys, got {entry!r}")
        flat = _flatten(entry)
        for k in flat:
            _check_key(base, k, f"case[{i}].")
            _check_range(flat[k], f"case[{i}].{k}")
            if k in grid:
                raise SceneError(f"case[{i}].{k} is also a grid key; give it in one place")
            if k in fixed:
                raise SceneError(f"case[{i}].{k} is also a fixed value ([set] or --set); give "
                                 f"it once")
        c = _canonical(flat)
        if c in seen_cases:
            raise SceneError(f"case[{i}] repeats case[{seen_cases.index(c)}]")
        seen_cases.append(c)
        cases_list.append(flat)

    if not grid and not cases_list:
        raise SceneError("grid: a sweep file needs a [grid] table or [[case]] entries, got "
                         "neither")
    return Sweep(name, description, base, base_label, fixed, grid, cases_list, source)


def load_sweep(source: str | os.PathLike | Sweep | dict,
               overrides: dict[str, Any] | None = None) -> Sweep:
    """Read and validate a sweep: a built-in name, a TOML file or a dict of the same layout.

    Parameters
    ----------
    source : str, path, Sweep or dict
        Built-in sweep name (see :func:`builtin_sweeps`), path of a sweep file, an already
        loaded :class:`Sweep` (returned as is when there are no overrides) or the parsed TOML.
    overrides : dict, optional
        Extra fixed values for every case (dotted keys), applied after ``[set]``.

    Returns
    -------
    Sweep

    Raises
    ------
    SceneError
        Unknown sweep, unreadable file, bad structure or an unknown scene key; the one-line
        message names the key. Values are checked per case when the case runs, so a bad
        value fails only its case.
    """
    if isinstance(source, Sweep):
        if not overrides:
            return source
        source = {"name": source.name, "description": source.description,
                  "base": source.base_label, "set": source.fixed, "grid": source.grid,
                  "case": source.cases_list}
    if isinstance(source, dict):
        return _parse(source, base_dir=Path.cwd(), source="dict", default_name="sweep",
                      overrides=overrides)
    text = str(source)
    builtins = builtin_sweeps()
    path = Path(text)
    if text in builtins and not path.is_file():
        data = tomllib.loads(_sweeps_dir().joinpath(f"{text}.toml").read_text())
        return _parse(data, base_dir=Path.cwd(), source=f"builtin:{text}", default_name=text,
                      overrides=overrides)
    if not path.exists():  # a FIFO or a directory: read_toml_file says what it is instead
        raise SceneError(f"sweep {text!r} is neither a built-in sweep "
                         f"({', '.join(builtins) or 'none installed'}) nor an existing file")
    data = read_toml_file(path, "sweep file")
    stem = _SAFE.sub("_", path.stem) or "sweep"
    return _parse(data, base_dir=path.resolve().parent, source=str(path.resolve()),
                  default_name=stem, overrides=overrides)


# --------------------------------------------------------------------------------------------
# files of a sweep directory
# --------------------------------------------------------------------------------------------


def _replace_file(path: Path, text: str) -> None:
    """Write a UTF-8 text file complete or not at all (under a temporary name, renamed into
    place); a failed write (a full disk) is one :class:`~roughvib.rundir.WriteError` naming
    ``path``, and leaves no temporary file."""
    data = text.encode("utf-8")
    write_file(path, lambda tmp: tmp.write_bytes(data), need=len(data))

