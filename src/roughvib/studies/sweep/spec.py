"""Parameter studies ("sweeps") on dask.distributed: resumable, one result directory per case.

This module owns the sweep file format, the naming of cases, running them as Dask tasks, the
sweep tables and the sweep report.

A sweep file (TOML) names a base scene and the values to vary::

    name = "velocity"
    base = "paper"                        # built-in scene name or a scene file (relative to here)

    [set]                                 # fixed overrides for every case
    "output.duration" = 0.2

    [grid]                                # product of all lists (dimensions of sweep.nc)
    "excitation.target_rms_velocity" = [0.01, 0.02, 0.04, 0.1]
    "roughness.seed" = [1, 2, 3]

    [[case]]                              # and/or a list of cases (the "case" dimension)
    "block.mass" = 0.221

Keys are the dotted scene keys of ``roughvib run --set``; ``[grid.excitation]`` tables with plain
keys work as well. With both ``[grid]`` and ``[[case]]`` every case is run at every grid point.

``run_sweep(sweep, DIR)`` writes::

    DIR/sweep.json         what was swept (base, fixed values, grid, cases)
    DIR/cases/<case>/      one result directory per case (result.nc, events.csv, summary.json,
                           scene.toml as written by Result.save, plus case.json)
    DIR/sweep.csv          one row per case: varied values, status, message, wall time, metrics
    DIR/sweep.nc           the metrics on the sweep's dimensions (xarray, units attributes)

A case directory is written under a temporary name and renamed when complete, so a sweep killed
at any moment loses only the cases in flight. Re-running skips the cases whose summary.json says
``success`` and re-runs failed and missing ones. A case's name is readable values plus a hash of
the base scene and the case's values, so it stays the same when the grid is extended and changes
when the base scene or the fixed values change.

Each case is one Dask task. Without a scheduler address a ``LocalCluster`` of worker processes
with one thread each is started; numba, OpenMP and BLAS are limited to one thread per worker so
that the workers do not oversubscribe the cores.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import hashlib
import itertools
import json
import math
import os
import re
import secrets
import shutil
import signal
import socket
import sys
import time
import tomllib
import traceback
from collections.abc import Callable, Iterable
from datetime import UTC, datetime
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from roughvib.scene import Scene, SceneError, load_scene, scene_to_dict

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd
    import xarray as xr

__all__ = [
    "Case",
    "Sweep",
    "SweepRun",
    "THREAD_ENV",
    "add_parsers",
    "builtin_sweeps",
    "case_name",
    "cmd_sweep",
    "cmd_sweep_report",
    "collect_table",
    "load_sweep",
    "run_sweep",
    "scene_key_units",
    "sweep_report",
]

#: Environment of every local worker process: one thread for numba, OpenMP and BLAS, so that
#: N single-threaded workers use N cores and not N x cores.
THREAD_ENV: dict[str, str] = {
    "NUMBA_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
}

SUCCESS = "success"
CASES_DIR = "cases"
_TOKEN_FILE = ".sweep-token"
_TOP_KEYS = ("name", "description", "base", "set", "grid", "case")
_SAFE = re.compile(r"[^A-Za-z0-9._=,+-]+")
_STALE = re.compile(r"^\..*\.(tmp|old)-")

#: table column -> (where in summary.json, units, long name)
METRICS: dict[str, tuple[tuple[str, ...], str, str]] = {
    "block_vertical_acceleration_level_db_re_1e-6": (
        ("metrics", "block_vertical_acceleration_level_db_re_1e-6"), "dB re 1e-6 m s-2",
        "total block vertical acceleration level"),
    "plate_vertical_acceleration_level_db_re_1e-6": (
        ("metrics", "plate_vertical_acceleration_level_db_re_1e-6"), "dB re 1e-6 m s-2",
        "total plate acceleration level at the observation point"),
    "block_vertical_acceleration_rms": (
        ("metrics", "block_vertical_acceleration_rms"), "m s-2",
        "rms vertical block acceleration"),
    "plate_vertical_acceleration_rms": (
        ("metrics", "plate_vertical_acceleration_rms"), "m s-2",
        "rms plate acceleration at the observation point"),
    "block_tangential_velocity_rms": (
        ("metrics", "block_tangential_velocity_rms"), "m s-1",
        "rms tangential block velocity (friction velocity)"),
    "stick_fraction": (("metrics", "stick_fraction"), "1", "fraction of time stuck"),
    "normal_force_mean": (("metrics", "normal_force_mean"), "N", "mean total normal force"),
    "normal_force_min": (("metrics", "normal_force_min"), "N", "minimum total normal force"),
    "force_amplitude": (("force_amplitude",), "N", "excitation force amplitude T0"),
    "energy_relative_residual": (("energy_audit", "relative_residual"), "1",
                                 "energy audit residual / sum of |terms|"),
    "steps": (("solver", "steps"), "1", "solver steps"),
    "solver_wall_time": (("solver", "wall_time"), "s", "solver wall time"),
}

#: the varied keys a report plots against, with the x quantity of the plot
_STUDIES: tuple[tuple[str, tuple[str, ...], str | None, str], ...] = (
    ("velocity", ("excitation.target_rms_velocity", "excitation.velocity"),
     "block_tangential_velocity_rms", "friction velocity v_rms [m/s]"),
    ("load", ("block.mass",), None, "block mass [kg]"),
    ("roughness", ("roughness.rms",), None, "roughness rms [m]"),
)
_LEVELS = (("block", "block_vertical_acceleration_level_db_re_1e-6"),
           ("plate", "plate_vertical_acceleration_level_db_re_1e-6"))
_DB_PER_DOUBLING_POWER = 10.0 * math.log10(2.0)


# --------------------------------------------------------------------------------------------
# sweep description
# --------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Case:
    """One case of a sweep.

    Attributes
    ----------
    name : str
        Directory name under ``DIR/cases`` (filesystem-safe, stable).
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
        section, _, field = key.partition(".")
        return scene_to_dict(self.base).get(section, {}).get(field)

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
    section, dot, field = key.partition(".")
    if key in ("name", "description"):
        raise SceneError(f"{where}{key} cannot be swept (each case is named by the sweep)")
    if not dot or "." in field or section not in sections:
        raise SceneError(f"{where}{key} is not a scene key (use section.key, sections: "
                         f"{', '.join(sections)})")
    known = sorted(f.name for f in dataclasses.fields(getattr(base, section)))
    if field not in known:
        raise SceneError(f"{where}{key} is not a known key of [{section}] (known: "
                         f"{', '.join(known)})")


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


def case_name(base: Scene, values: dict[str, Any], keys: Iterable[str] | None = None) -> str:
    """Stable, filesystem-safe directory name of a case.

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
        ``"target_rms_velocity=0.01,seed=2-1a2b3c4d5e"``: readable values (at most 80
        characters of ``[A-Za-z0-9._=,+-]``) and 10 hex digits of a SHA-256 over the base scene
        and the values.
    """
    keys = list(keys) if keys is not None else list(values)
    lasts = [k.rsplit(".", 1)[-1] for k in keys]
    parts = []
    for k in [k for k in keys if k in values] + [k for k in values if k not in keys]:
        last = k.rsplit(".", 1)[-1]
        label = last if lasts.count(last) <= 1 else k
        parts.append(f"{label}={_fmt_value(values[k])}")
    readable = _SAFE.sub("_", ",".join(parts))[:80].lstrip(".")
    digest = hashlib.sha256(_canonical({"base": _fingerprint(base), "values": values})
                            .encode()).hexdigest()[:10]
    return f"{readable}-{digest}" if readable else digest


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
    if not path.is_file():
        raise SceneError(f"sweep {text!r} is neither a built-in sweep "
                         f"({', '.join(builtins) or 'none installed'}) nor an existing file")
    try:
        data = tomllib.loads(path.read_text())
    except OSError as exc:
        raise SceneError(f"sweep file {path} cannot be read: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"sweep file {path} is not valid TOML: {exc}") from None
    stem = _SAFE.sub("_", path.stem) or "sweep"
    return _parse(data, base_dir=path.resolve().parent, source=str(path.resolve()),
                  default_name=stem, overrides=overrides)


# --------------------------------------------------------------------------------------------
# running one case (on a worker)
# --------------------------------------------------------------------------------------------


def _write_json(path: Path, obj: Any) -> None:
    from roughvib.results import _jsonable

    path.write_text(json.dumps(_jsonable(obj), indent=2))


def _replace_file(path: Path, text: str) -> None:
    """Write a file under a temporary name and rename it into place."""
    tmp = path.with_name(f".{path.name}.tmp-{secrets.token_hex(4)}")
    tmp.write_text(text)
    os.replace(tmp, path)


def _new_tmp(root: Path, name: str) -> Path:
    """A fresh temporary case directory (created with the umask's permissions, unlike
    ``mkdtemp``'s 0700, so that a shared sweep directory stays readable)."""
    while True:
        tmp = root / f".{name}.tmp-{secrets.token_hex(6)}"
        try:
            tmp.mkdir()
            return tmp
        except FileExistsError:  # pragma: no cover - 48 random bits
            continue


def _publish(tmp: Path, final: Path) -> None:
    """Rename a complete case directory into place, replacing an older (failed) one."""
    try:
        os.rename(tmp, final)
        return
    except OSError:
        if not final.exists():
            raise
    old = final.with_name(f".{final.name}.old-{secrets.token_hex(4)}")
    os.rename(final, old)
    os.rename(tmp, final)
    shutil.rmtree(old, ignore_errors=True)


def _failure_summary(name: str, status: str, message: str) -> dict[str, Any]:
    from roughvib.results import FORMAT_VERSION

    return {"format_version": FORMAT_VERSION, "status": status, "message": message,
            "scene": name, "solver": {}, "metrics": {}}


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if not isinstance(exc, SceneError) else text


def _run_case(base: Scene, name: str, values: dict[str, Any], cases_dir: str,
              token: str) -> dict[str, Any]:
    """Run one case and publish its directory; the Dask task of a sweep.

    Parameters
    ----------
    base : Scene
        Base scene with the fixed overrides.
    name : str
        Case name (directory under ``cases_dir``).
    values : dict
        The case's varied values (dotted keys).
    cases_dir : str
        Absolute path of ``DIR/cases``; must be visible to the worker.
    token : str
        Content of ``DIR/.sweep-token``: proves the worker sees the client's directory.

    Returns
    -------
    dict
        ``{"name", "status", "message", "wall_time"}``. Errors of the case itself are
        recorded, not raised.
    """
    for k, v in THREAD_ENV.items():
        os.environ.setdefault(k, v)  # effective if numba/BLAS are not imported yet
    t0 = time.perf_counter()
    started = datetime.now(UTC).isoformat(timespec="seconds")
    root = Path(cases_dir)
    token_file = root.parent / _TOKEN_FILE
    try:
        seen = token_file.read_text().strip()
    except OSError:
        seen = ""
    if seen != token:
        raise RuntimeError(f"worker {socket.gethostname()} does not see the sweep directory "
                           f"{root.parent} of the client (the workers need it on a shared "
                           f"filesystem under the same path)")
    tmp = _new_tmp(root, name)
    try:
        try:
            from roughvib.api import simulate

            scene = base.with_overrides({**values, "name": name})
            result = simulate(scene, progress=False)
            with _local_dask():
                result.save(tmp)
            status, message = result.status, str(result.summary.get("message", ""))
        except SceneError as exc:
            status, message = "input_error", _one_line(exc)
            _write_json(tmp / "summary.json", _failure_summary(name, status, message))
        except Exception as exc:
            status, message = "error", _one_line(exc)
            _write_json(tmp / "summary.json", _failure_summary(name, status, message))
            (tmp / "error.txt").write_text(traceback.format_exc())
        wall = time.perf_counter() - t0
        _write_json(tmp / "case.json", {
            "name": name, "values": values, "status": status, "wall_time": wall,
            "host": socket.gethostname(), "pid": os.getpid(), "started": started,
            "finished": datetime.now(UTC).isoformat(timespec="seconds")})
        _publish(tmp, root / name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {"name": name, "status": status, "message": message, "wall_time": wall}


def _local_dask():
    """Inside a task, make xarray lock its netCDF writes locally: each case writes its own
    files, and a cluster-wide lock would tie every write to the scheduler connection."""
    try:
        import dask
    except ImportError:  # pragma: no cover - tasks always run under dask
        return contextlib.nullcontext()
    return dask.config.set(scheduler="synchronous")


def _ignore_sigint() -> bool:
    """Run on the workers of a sweep's own LocalCluster: Ctrl-C in the terminal reaches the
    whole process group; the client shuts the workers down, so they need not react."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread of the worker process
        return False
    return True


def _is_complete(case_dir: Path) -> bool:
    try:
        summary = json.loads((case_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return False
    return summary.get("status") == SUCCESS and (case_dir / "result.nc").is_file()


def _remove_stale(cases_dir: Path) -> None:
    """Temporary and replaced case directories left by a killed sweep."""
    for entry in cases_dir.iterdir():
        if _STALE.match(entry.name):
            if entry.is_dir():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)


# --------------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------------


def _dig(d: dict, path: tuple[str, ...]) -> Any:
    for p in path:
        if not isinstance(d, dict):
            return None
        d = d.get(p)
    return d


def _number(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float):
        return math.nan
    return float(v)


def collect_table(sweep: Sweep, directory: str | os.PathLike,
                  errors: dict[str, tuple[str, str]] | None = None) -> pd.DataFrame:
    """The sweep table from the case directories.

    Parameters
    ----------
    sweep : Sweep
    directory : path
        Sweep directory (holding ``cases/``).
    errors : dict, optional
        Case name -> (status, message) for cases whose failure could not be written.

    Returns
    -------
    pandas.DataFrame
        One row per case in sweep order: ``case``, the varied keys, ``status``, ``message``,
        ``wall_time`` [s] (the whole task: calibration, solve, saving), then the columns of
        :data:`METRICS` (NaN where a case did not succeed). A case without a directory has
        status ``missing``.
    """
    import pandas as pd

    cases_dir = Path(directory) / CASES_DIR
    keys = sweep.varied_keys
    rows = []
    for case in sweep.cases():
        row: dict[str, Any] = {"case": case.name}
        for k in keys:
            row[k] = case.values[k] if k in case.values else sweep.base_value(k)
        try:
            summary = json.loads((cases_dir / case.name / "summary.json").read_text())
        except (OSError, ValueError):
            summary = None
        try:
            info = json.loads((cases_dir / case.name / "case.json").read_text())
        except (OSError, ValueError):
            info = {}
        if summary is None:
            status, message = (errors or {}).get(case.name, ("missing", "not run (yet)"))
            summary = {}
        else:
            status, message = summary.get("status", "unknown"), summary.get("message", "")
        row["status"] = status
        row["message"] = " ".join(str(message or "").split())
        row["wall_time"] = _number(info.get("wall_time"))
        for col, (path, _, _) in METRICS.items():
            row[col] = _number(_dig(summary, path)) if status == SUCCESS else math.nan
        rows.append(row)
    return pd.DataFrame(rows, columns=["case", *keys, "status", "message", "wall_time",
                                       *METRICS])


def scene_key_units(key: str) -> str | None:
    """Unit of a dotted scene key, read from the section's numpydoc ``Attributes``.

    Parameters
    ----------
    key : str
        ``"section.field"``.

    Returns
    -------
    str or None
        The bracketed unit of the field's description (``"-"`` becomes ``"1"``), or None
        when the docstring gives none.
    """
    import inspect

    section, _, field = key.partition(".")
    cls = next((f.type for f in dataclasses.fields(Scene) if f.name == section), None)
    if cls is None:
        return None
    cls = getattr(sys.modules[Scene.__module__], cls, None) if isinstance(cls, str) else cls
    doc = inspect.getdoc(cls) or ""
    current: tuple[str, ...] = ()
    descr: dict[tuple[str, ...], str] = {}
    for line in doc.splitlines():
        m = re.match(r"^(\w[\w, ]*) : ", line)
        if m:
            current = tuple(n.strip() for n in m.group(1).split(","))
            descr[current] = ""
        elif current:
            descr[current] += " " + line.strip()
    for names, text in descr.items():
        if field in names:
            units = re.findall(r"\[([^\[\]]+)\]", text)
            if len(units) == len(names):
                unit = units[names.index(field)]
            elif len(units) == 1:
                unit = units[0]
            else:
                return None
            return "1" if unit == "-" else unit
    return None


def _coord(values: list[Any]):
    import numpy as np

    if all(isinstance(v, bool) for v in values):
        return np.array(values, dtype=bool)
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        return np.array(values)
    if all(isinstance(v, str) for v in values):
        return np.array(values, dtype=str)
    return np.array([_canonical(v) for v in values], dtype=str)


def _dataset(sweep: Sweep, table: pd.DataFrame) -> xr.Dataset:
    import numpy as np
    import xarray as xr

    from roughvib import __version__

    dims, shape = sweep.dims, sweep.shape
    index = [c.index for c in sweep.cases()]
    coords: dict[str, Any] = {}
    for k, values in sweep.grid.items():
        attrs = {"long_name": f"scene value {k}"}
        if (u := scene_key_units(k)) is not None:
            attrs["units"] = u
        coords[k] = (k, _coord(values), attrs)
    if sweep.cases_list:
        coords["case"] = ("case", np.arange(len(sweep.cases_list)),
                          {"long_name": "index into the [[case]] list"})
        for k in sweep.varied_keys:
            if k in sweep.grid:
                continue
            vals = [e.get(k, sweep.base_value(k)) for e in sweep.cases_list]
            attrs = {"long_name": f"scene value {k}"}
            if (u := scene_key_units(k)) is not None:
                attrs["units"] = u
            coords[k] = ("case", _coord(vals), attrs)

    def grid_of(column: str, fill: Any, dtype: Any):
        a = np.full(shape, fill, dtype=dtype)
        for idx, v in zip(index, table[column].to_numpy(), strict=True):
            a[idx] = v
        return a

    data = {
        "case_name": (dims, grid_of("case", "", object).astype(str),
                      {"long_name": "case directory under cases/"}),
        "status": (dims, grid_of("status", "", object).astype(str),
                   {"long_name": "run status (success or the failure cause)"}),
        "message": (dims, grid_of("message", "", object).astype(str),
                    {"long_name": "status message"}),
        "wall_time": (dims, grid_of("wall_time", np.nan, float),
                      {"units": "s", "long_name": "task wall time (calibration, solve, save)"}),
    }
    for col, (_, units, long_name) in METRICS.items():
        data[col] = (dims, grid_of(col, np.nan, float), {"units": units, "long_name": long_name})
    return xr.Dataset(data, coords=coords, attrs={
        "title": f"roughvib sweep {sweep.name}",
        "description": sweep.description,
        "base_scene": sweep.base_label,
        "fixed_values": _canonical(sweep.fixed),
        "source": sweep.source,
        "comment": "metrics are NaN where status is not success",
        "roughvib_version": __version__,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
    })


def _write_tables(sweep: Sweep, out: Path,
                  errors: dict[str, tuple[str, str]] | None = None) -> pd.DataFrame:
    table = collect_table(sweep, out, errors)
    _replace_file(out / "sweep.csv", table.to_csv(index=False, float_format="%.12g"))
    tmp = out / f".sweep.nc.tmp-{secrets.token_hex(4)}"
    try:
        _dataset(sweep, table).to_netcdf(tmp, engine="h5netcdf")
        os.replace(tmp, out / "sweep.nc")
    finally:
        tmp.unlink(missing_ok=True)
    return table


# --------------------------------------------------------------------------------------------
# running a sweep (client side)
# --------------------------------------------------------------------------------------------


@dataclasses.dataclass
class SweepRun:
    """Outcome of :func:`run_sweep`.

    Attributes
    ----------
    directory : Path
        The sweep directory.
    table : pandas.DataFrame
        The sweep table (as in sweep.csv).
    skipped : int
        Cases complete before this run (not re-run).
    ran : int
        Cases run now.
    failed : int
        Cases in the table whose status is not success.
    """

    directory: Path
    table: pd.DataFrame
    skipped: int
    ran: int
    failed: int


def _connect(scheduler: str | None, workers: int | None):
    """A Dask client: to ``scheduler`` if given, else to a new LocalCluster (returned too)."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - depends on the installation
        raise SceneError("sweeps need dask.distributed: "
                         "pip install 'dask[distributed]>=2024.1'") from None
    if scheduler:
        return Client(scheduler), None
    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                           env=dict(THREAD_ENV))
    try:
        client = Client(cluster)
        client.run(_ignore_sigint)
        return client, cluster
    except BaseException:
        cluster.close()
        raise


def run_sweep(sweep: str | os.PathLike | Sweep | dict, out: str | os.PathLike, *,
              scheduler: str | None = None, workers: int | None = None, client: Any = None,
              overrides: dict[str, Any] | None = None, progress: bool = True,
              log: Callable[[str], None] | None = None) -> SweepRun:
    """Run (or resume) a sweep: each case one Dask task writing ``out/cases/<case>/``.

    Parameters
    ----------
    sweep : str, path, Sweep or dict
        See :func:`load_sweep`.
    out : path
        Sweep directory; created if needed. With a remote scheduler it must be on a filesystem
        the workers share, under the same path.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://head:8786``). Default: a new
        ``LocalCluster`` for this call.
    workers : int, optional
        Worker processes of the local cluster (default: all cores), one thread each.
        Ignored with ``scheduler`` or ``client``.
    client : dask.distributed.Client, optional
        Use this client (and its cluster) instead; it is not closed.
    overrides : dict, optional
        Extra fixed values for every case (dotted keys).
    progress : bool
        A progress bar over the cases on stderr.
    log : callable, optional
        Receives one-line notes (dashboard address, skipped cases); default: ignored.

    Returns
    -------
    SweepRun
        The table (also in ``out/sweep.csv`` and ``out/sweep.nc``) and the counts.

    Raises
    ------
    SceneError
        Bad sweep file or ``workers < 1``. A failing case does not raise: its status and
        message are in its directory and in the table.
    """
    from tqdm.auto import tqdm

    spec = load_sweep(sweep, overrides)
    if workers is not None and workers < 1:
        raise SceneError(f"workers must be >= 1, got {workers}")
    note = log or (lambda _msg: None)
    out = Path(out).resolve()
    cases_dir = out / CASES_DIR
    cases_dir.mkdir(parents=True, exist_ok=True)
    token = secrets.token_hex(8)
    _replace_file(out / _TOKEN_FILE, token)
    _replace_file(out / "sweep.json", json.dumps(spec.to_json(), indent=2))
    _remove_stale(cases_dir)

    cases = spec.cases()
    todo = [c for c in cases if not _is_complete(cases_dir / c.name)]
    skipped = len(cases) - len(todo)
    if skipped:
        note(f"{skipped} of {len(cases)} cases complete in {out}; running the other "
             f"{len(todo)}")
    errors: dict[str, tuple[str, str]] = {}
    interrupted = False
    if todo:
        from dask.distributed import as_completed

        own = client is None
        cluster = None
        if own:
            client, cluster = _connect(scheduler, workers)
        futures: dict[Any, Case] = {}
        bar = None
        try:
            if getattr(client, "dashboard_link", None):
                note(f"dask dashboard: {client.dashboard_link}")
            bar = tqdm(total=len(cases), initial=skipped, desc=f"sweep {spec.name}",
                       unit="case", disable=not progress, file=sys.stderr)
            for c in todo:
                fut = client.submit(_run_case, spec.base, c.name, c.values, str(cases_dir),
                                    token, pure=False, key=f"case-{c.name}-{token}")
                futures[fut] = c
            failed_now = 0
            for fut in as_completed(list(futures)):
                case = futures[fut]
                try:
                    status = fut.result()["status"]
                except Exception as exc:  # the task itself died (worker lost, no directory)
                    status = "worker_lost" if type(exc).__name__ == "KilledWorker" else "error"
                    errors[case.name] = (status, _one_line(exc))
                    _record_failure(cases_dir, case.name, status, _one_line(exc))
                failed_now += status != SUCCESS
                bar.set_postfix(failed=failed_now, refresh=False)
                bar.update()
        except BaseException:
            # interrupted: queued cases are dropped; the tables are written below, once the
            # local workers have stopped (cases in flight may still finish and count)
            interrupted = True
            with contextlib.suppress(Exception):  # never hide the interrupt itself
                client.cancel([f for f in futures if not f.done()])
            raise
        finally:
            if bar is not None:
                bar.close()
            if own:
                client.close()
                if cluster is not None:
                    cluster.close()
            if interrupted:
                with contextlib.suppress(Exception):
                    _write_tables(spec, out, errors)
    table = _write_tables(spec, out, errors)
    return SweepRun(out, table, skipped, len(todo), int((table["status"] != SUCCESS).sum()))


def _record_failure(cases_dir: Path, name: str, status: str, message: str) -> None:
    """Write a failed case's directory from the client (when the task could not)."""
    try:
        tmp = _new_tmp(cases_dir, name)
        try:
            _write_json(tmp / "summary.json", _failure_summary(name, status, message))
            _write_json(tmp / "case.json", {"name": name, "status": status})
            _publish(tmp, cases_dir / name)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    except OSError:
        pass  # the table still carries the error (collect_table's ``errors``)


# --------------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------------


def _fit(x, y, seeds) -> dict[str, Any]:
    """dB per doubling of y over x: per seed, then mean and 95 % interval across seeds.

    ``x`` > 0 (shape (m,)), ``y`` [dB] (shape (m,)), ``seeds``: labels (shape (m,)) or None.
    With fewer than two seeds that each span two x values, the pooled least-squares slope and
    its t interval (m - 2 degrees of freedom) are given instead.
    """
    import numpy as np
    from scipy import stats

    from roughvib.analysis.levels import velocity_exponent

    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    slopes = []
    if seeds is not None:
        labels = np.asarray(seeds)
        for s in dict.fromkeys(labels.tolist()):
            sel = labels == s
            if np.unique(x[sel]).size >= 2:
                slopes.append(velocity_exponent(x[sel], y[sel]).db_per_doubling)
    if len(slopes) >= 2:
        s = float(np.mean(slopes))
        half = float(stats.t.ppf(0.975, len(slopes) - 1) * np.std(slopes, ddof=1)
                     / math.sqrt(len(slopes)))
        how = f"mean over {len(slopes)} seeds, 95 % t interval across seeds"
    else:
        s, _, se = velocity_exponent(x, y)
        half = float(stats.t.ppf(0.975, x.size - 2) * se) if x.size > 2 else math.nan
        how = "least squares over all points, 95 % t interval of the slope" \
            if x.size > 2 else "two points, no interval"
    lx = np.log2(x)
    return {"db_per_doubling": s, "ci_low": s - half, "ci_high": s + half,
            "exponent_power": s / _DB_PER_DOUBLING_POWER, "n_seeds": len(slopes),
            "n_points": int(x.size), "method": how,
            "intercept": float(np.mean(y) - s * np.mean(lx)), "per_seed": slopes}


def _study_figure(study: str, xlabel: str, groups: list[tuple[str, Any]], xcol: str,
                  seed_col: str | None, fits: dict, path: Path) -> None:
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2, sharex=True)
    markers = "osD^v<>pP*"
    for ax, (which, col) in zip(axes, _LEVELS, strict=True):
        for gi, (label, df) in enumerate(groups):
            color = f"C{gi % 10}"
            seeds = df[seed_col].tolist() if seed_col else [None] * len(df)
            seed_order = list(dict.fromkeys(seeds))
            for si, seed in enumerate(seed_order):
                sel = [s == seed for s in seeds]
                ax.plot(df[xcol][sel], df[col][sel], linestyle="none",
                        marker=markers[si % len(markers)], color=color, alpha=0.8,
                        label=(f"seed {seed}" if seed is not None and gi == 0 else None))
            f = fits.get((which, label))
            if f is not None:
                xs = np.geomspace(df[xcol].min(), df[xcol].max(), 50)
                ci = "" if not math.isfinite(f["ci_low"]) else \
                    f" [{f['ci_low']:.1f}, {f['ci_high']:.1f}]"
                ax.plot(xs, f["intercept"] + f["db_per_doubling"] * np.log2(xs), color=color,
                        label=f"{label}: {f['db_per_doubling']:.1f}{ci} dB/doubling")
        ax.set_xscale("log")
        ticks: list[float] = []
        for v in sorted({float(f"{v:.2g}") for _, df in groups for v in df[xcol]}):
            if not ticks or v > 1.08 * ticks[-1]:  # values of several seeds differ slightly
                ticks.append(v)
        if len(ticks) <= 10:
            ax.set_xticks(ticks, [f"{t:.2g}" for t in ticks])
            ax.minorticks_off()
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"{which} acceleration level [dB re 1e-6 m/s²]")
        ax.set_title(f"{which} (total level)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{study} study")
    fig.savefig(path, dpi=110)


def _md_table(header: list[str], rows: list[list[str]]) -> str:
    def esc(s: str) -> str:
        return str(s).replace("|", "\\|")

    lines = ["| " + " | ".join(esc(h) for h in header) + " |",
             "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(esc(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def _html_table(header: list[str], rows: list[list[str]]) -> str:
    import html

    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>"
                   for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _g(v: Any, fmt: str = ".4g") -> str:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return "" if math.isnan(f) else format(f, fmt)


def sweep_report(directory: str | os.PathLike) -> Path:
    """Plots and a short report of a finished (or partly finished) sweep.

    For a velocity sweep (``excitation.target_rms_velocity`` or ``excitation.velocity``
    varied) the total block and plate levels are drawn against the measured friction
    velocity (rms tangential block velocity) with the fitted slope in dB per doubling; when a
    ``*.seed`` key varies, the slope is fitted per seed and given as the mean with its 95 %
    confidence interval across seeds. ``block.mass`` (load) and ``roughness.rms`` (roughness)
    get the same treatment. Other varied keys split the points into groups, one fit each.
    Only successful cases are used.

    Parameters
    ----------
    directory : path
        Sweep directory written by :func:`run_sweep`.

    Returns
    -------
    Path
        ``DIR/report/report.md``; next to it ``report.html``, ``fits.csv`` and one PNG per
        study (``velocity.png``, ``load.png``, ``roughness.png``).

    Raises
    ------
    FileNotFoundError
        ``directory`` holds no sweep.csv / sweep.json.
    """
    import pandas as pd

    d = Path(directory)
    if not (d / "sweep.csv").is_file() or not (d / "sweep.json").is_file():
        raise FileNotFoundError(f"{d} is not a sweep directory (no sweep.csv / sweep.json)")
    meta = json.loads((d / "sweep.json").read_text())
    table = pd.read_csv(d / "sweep.csv", keep_default_na=False,
                        na_values=[""]).astype({"status": str, "message": str})
    varied = [k for k in meta.get("varied_keys", []) if k in table.columns]
    seed_keys = [k for k in meta.get("seed_keys", []) if k in table.columns]
    ok = table[table["status"] == SUCCESS]
    rep = d / "report"
    rep.mkdir(exist_ok=True)

    blocks: list[tuple[str, Any]] = []  # (kind, payload): h2, p, table, img
    fit_rows = []
    for study, keys, measured, xlabel in _STUDIES:
        key = next((k for k in keys if k in varied and ok[k].nunique() >= 2), None)
        if key is None:
            continue
        df = ok.copy()
        xcol = key
        if measured and measured in df and df[measured].notna().all() \
                and (df[measured] > 0).all():
            xcol = measured
        df = df[df[xcol] > 0]
        seed_col = seed_keys[0] if seed_keys and df[seed_keys[0]].nunique() >= 2 else None
        others = [k for k in varied if k not in keys and k not in seed_keys
                  and df[k].astype(str).nunique() >= 2]
        if others:
            groups = [(", ".join(f"{k}={v}" for k, v in
                                 zip(others, g if isinstance(g, tuple) else (g,), strict=True)),
                       sub) for g, sub in df.groupby(others, sort=False)]
        else:
            groups = [("all", df)]
        fits = {}
        for which, col in _LEVELS:
            for label, sub in groups:
                sub = sub[sub[col].notna()]
                if sub[xcol].nunique() < 2:
                    continue
                f = _fit(sub[xcol], sub[col], sub[seed_col] if seed_col else None)
                fits[(which, label)] = f
                fit_rows.append({"study": study, "x": xcol, "quantity": f"{which} level",
                                 "group": label, **{k: v for k, v in f.items()
                                                    if k != "per_seed"},
                                 "per_seed": " ".join(f"{s:.3f}" for s in f["per_seed"])})
        png = rep / f"{study}.png"
        _study_figure(study, xlabel if xcol == measured or not measured else
                      f"{key} (target)", groups, xcol, seed_col, fits, png)
        blocks.append(("h2", f"{study.capitalize()}: total levels vs {xlabel.split(' [')[0]}"))
        blocks.append(("p", f"x = `{xcol}`" + (f" (measured; the target `{key}` is in the "
                                                 f"table)" if xcol != key else "")
                       + (f"; seeds: `{seed_col}`" if seed_col else "")
                       + f"; {len(df)} successful cases."))
        blocks.append(("img", png.name))
        header = ["quantity", "group", "dB per doubling", "95 % interval",
                  "n (a² ∝ x^n)", "how"]
        rows = [[f"{w} level", lab, _g(f["db_per_doubling"], ".2f"),
                 f"[{_g(f['ci_low'], '.2f')}, {_g(f['ci_high'], '.2f')}]"
                 if math.isfinite(f["ci_low"]) else "n/a",
                 _g(f["exponent_power"], ".2f"), f["method"]]
                for (w, lab), f in fits.items()]
        blocks.append(("table", (header, rows)))
        if study == "velocity":
            blocks.append(("p", "The paper reads its velocity study on the power basis: a² ∝ "
                                "v^n with n = 3 to 3.5, i.e. 9 to 10.5 dB per doubling."))
    if not fit_rows:
        blocks.append(("p", "No velocity, load or roughness key varies over two or more "
                            "successful cases; nothing to fit."))
    pd.DataFrame(fit_rows).to_csv(rep / "fits.csv", index=False, float_format="%.6g")

    failed = table[table["status"] != SUCCESS]
    if len(failed):
        blocks.append(("h2", f"Failed or missing cases ({len(failed)})"))
        blocks.append(("table", (["case", "status", "message"],
                                 [[r["case"], r["status"], r["message"]]
                                  for _, r in failed.iterrows()])))
    blocks.append(("h2", "Cases"))
    cols = [("block dB", _LEVELS[0][1]), ("plate dB", _LEVELS[1][1]),
            ("v_rms m/s", "block_tangential_velocity_rms"), ("stick", "stick_fraction"),
            ("wall s", "wall_time")]
    blocks.append(("table", (["case", *varied, "status", *(c for c, _ in cols)],
                             [[r["case"], *(_g(r[k]) for k in varied), r["status"],
                               *(_g(r[c]) for _, c in cols)] for _, r in table.iterrows()])))

    title = f"Sweep report: {meta.get('name', d.name)}"
    descr = str(meta.get("description", "")).strip()
    if descr and not descr.endswith("."):
        descr += "."
    intro = (f"{descr} Base scene `{meta.get('base')}`; "
             f"{len(table)} cases, {len(ok)} succeeded, {len(table) - len(ok)} failed or "
             f"missing. Tables: `sweep.csv`, `sweep.nc`; fits: `report/fits.csv`.").strip()
    md = [f"# {title}", "", intro, ""]
    body = [f"<h1>{_esc(title)}</h1>", f"<p>{_esc(intro)}</p>"]
    for kind, payload in blocks:
        if kind == "h2":
            md += [f"## {payload}", ""]
            body.append(f"<h2>{_esc(payload)}</h2>")
        elif kind == "p":
            md += [payload, ""]
            body.append(f"<p>{_esc(payload)}</p>")
        elif kind == "img":
            md += [f"![{payload}]({payload})", ""]
            body.append(f'<p><img src="{_esc(payload)}" alt="{_esc(payload)}" '
                        f'style="max-width:100%"></p>')
        else:
            md += [_md_table(*payload), ""]
            body.append(_html_table(*payload))
    _replace_file(rep / "report.md", "\n".join(md))
    _replace_file(rep / "report.html", (
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
        f"<title>{_esc(title)}</title><style>body{{font-family:sans-serif;max-width:1100px;"
        "margin:2em auto}table{border-collapse:collapse;font-size:0.85em}"
        "td,th{border:1px solid #ccc;padding:2px 6px}</style></head><body>\n"
        + "\n".join(body) + "\n</body></html>\n"))
    return rep / "report.md"


def _esc(text: str) -> str:
    import html

    return html.escape(str(text))


# --------------------------------------------------------------------------------------------
# command line
# --------------------------------------------------------------------------------------------


def cmd_sweep(args: argparse.Namespace) -> int:
    """``roughvib sweep``: run or resume a sweep; 0 all cases succeeded, 1 some failed.

    Parameters
    ----------
    args : argparse.Namespace
        ``sweep`` (file or built-in name), ``out`` (directory or None: ``runs/<name>``),
        ``scheduler`` (address or None), ``workers`` (int or None); optional ``set`` (list of
        KEY=VALUE), ``no_progress``, ``report``, ``list``.
    """
    if getattr(args, "list", False):
        sweeps = builtin_sweeps()
        width = max((len(n) for n in sweeps), default=0)
        for name, descr in sweeps.items():
            print(f"{name:<{width}}  {descr}")
        return 0
    if not getattr(args, "sweep", None):
        raise SceneError(f"sweep: name a sweep file or a built-in sweep "
                         f"({', '.join(builtin_sweeps()) or 'none installed'})")
    from roughvib.cli import _parse_sets

    spec = load_sweep(args.sweep, _parse_sets(getattr(args, "set", None)))
    out = Path(args.out) if getattr(args, "out", None) else Path("runs") / spec.name
    scheduler = getattr(args, "scheduler", None)
    workers = getattr(args, "workers", None)
    if scheduler and workers is not None:
        print("roughvib: note: --workers is ignored with --scheduler (the cluster has its own "
              "workers)", file=sys.stderr)
        workers = None
    quiet_log = getattr(args, "no_progress", False)
    try:
        run = run_sweep(spec, out, scheduler=scheduler, workers=workers,
                        progress=not getattr(args, "no_progress", False),
                        log=None if quiet_log else (lambda m: print(m, file=sys.stderr)))
    except KeyboardInterrupt:
        print(f"roughvib: sweep interrupted; completed cases are kept in {out}/cases, run the "
              f"same command again to resume", file=sys.stderr)
        return 130
    n = len(run.table)
    print(f"{n} cases: {run.skipped} complete before, {run.ran} run now, {n - run.failed} "
          f"succeeded, {run.failed} failed -> {run.directory}/sweep.csv, sweep.nc")
    for _, row in run.table[run.table["status"] != SUCCESS].iterrows():
        print(f"  {row['case']}: {row['status']}: {row['message']}")
    if getattr(args, "report", False):
        print(sweep_report(run.directory))
    return 0 if run.failed == 0 else 1


def cmd_sweep_report(args: argparse.Namespace) -> int:
    """``roughvib sweep-report DIR``: plots and report of a sweep directory; 0 on success.

    Parameters
    ----------
    args : argparse.Namespace
        ``dir``: the sweep directory.
    """
    try:
        path = sweep_report(args.dir)
    except FileNotFoundError as exc:
        raise SceneError(str(exc)) from None
    print(path)
    return 0


def add_parsers(subparsers: Any) -> None:
    """Add the ``sweep`` and ``sweep-report`` subcommands to a ``roughvib`` subparser set.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        From ``parser.add_subparsers()``.
    """
    fmt = argparse.RawDescriptionHelpFormatter
    s = subparsers.add_parser(
        "sweep", formatter_class=fmt,
        help="run a parameter study on a local or Dask cluster (resumable)",
        description="Run every case of a sweep (a base scene and the values to vary, as a grid "
                    "and/or a list of cases) as one task on dask.distributed: a local cluster "
                    "of single-threaded worker processes by default, or the cluster of "
                    "--scheduler. Each case writes DIR/cases/<case>/ atomically; re-running "
                    "the same command skips completed cases and re-runs failed or missing "
                    "ones. At the end DIR/sweep.csv and DIR/sweep.nc hold one row per case. "
                    "See docs/sweeps.md for the file format.",
        epilog="examples:\n"
               "  roughvib sweep --list                                # built-in sweeps\n"
               "  roughvib sweep paper-velocity --out runs/velocity    # all local cores\n"
               "  roughvib sweep velocity.toml --out runs/v --workers 4\n"
               "  roughvib sweep velocity.toml --out runs/v --scheduler tcp://head:8786\n"
               "  roughvib sweep paper-velocity --set output.duration=0.2 --report\n\n"
               "exit status: 0 all cases succeeded, 1 some failed (see sweep.csv), "
               "2 bad sweep file")
    s.add_argument("sweep", nargs="?",
                   help="built-in sweep name (see --list) or a sweep .toml file")
    s.add_argument("--out", metavar="DIR", help="sweep directory (default: runs/<sweep name>)")
    s.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of a running Dask scheduler, e.g. tcp://head:8786 (default: "
                        "start a local cluster); DIR must be on a filesystem the workers share")
    s.add_argument("--workers", type=int, metavar="N",
                   help="worker processes of the local cluster (default: all cores; one "
                        "thread each)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="fixed value for every case, e.g. --set output.duration=0.2 "
                        "(repeatable; changes the case names)")
    s.add_argument("--report", action="store_true", help="write the sweep report at the end")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    s.add_argument("--list", action="store_true", help="list the built-in sweeps and exit")
    s.set_defaults(func=cmd_sweep)

    r = subparsers.add_parser(
        "sweep-report", formatter_class=fmt,
        help="plots and report of a sweep (levels vs velocity, load, roughness)",
        description="Draw total block and plate levels against friction velocity (and load, "
                    "roughness) with the fitted slope in dB per doubling and its 95 % "
                    "interval across seeds; write DIR/report/report.md, report.html, "
                    "fits.csv and the PNGs.",
        epilog="example:\n  roughvib sweep-report runs/velocity\n")
    r.add_argument("dir", help="sweep directory written by 'roughvib sweep'")
    r.set_defaults(func=cmd_sweep_report)
