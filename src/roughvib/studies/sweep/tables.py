"""The sweep table (``sweep.csv``) and dataset (``sweep.nc``) from the case directories, and the
slope fits (dB per doubling) of the sweep report."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from roughvib.results import read_summary
from roughvib.rundir import write_file
from roughvib.scene import Scene
from roughvib.studies.sweep.spec import CASES_DIR, SUCCESS, Sweep, _canonical, _replace_file

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

__all__ = ["METRICS", "collect_table", "scene_key_units"]

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
    "sound_power_level_db_re_1pW": (
        ("radiation", "sound_power_level_db_re_1pW"), "dB re 1 pW",
        "radiated sound power level of the plate (output.radiation; NaN without it)"),
    "force_amplitude": (("force_amplitude",), "N", "excitation force amplitude T0"),
    "energy_relative_residual": (("energy_audit", "relative_residual"), "1",
                                 "energy audit residual / sum of |terms|"),
    "steps": (("solver", "steps"), "1", "solver steps"),
    "solver_wall_time": (("solver", "wall_time"), "s", "solver wall time"),
}

_DB_PER_DOUBLING_POWER = 10.0 * math.log10(2.0)


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
        damaged = None
        try:  # checked as load_result checks it: an edited case is not taken at its word
            summary = read_summary(cases_dir / case.name)
        except OSError:
            summary = None
        except ValueError as exc:  # RunDirectoryError: one line naming the file
            summary, damaged = {}, str(exc)
        try:
            info = json.loads((cases_dir / case.name / "case.json").read_text())
        except (OSError, ValueError):
            info = {}
        if summary is None:
            status, message = (errors or {}).get(case.name, ("missing", "not run (yet)"))
            summary = {}
        elif damaged is not None:
            status, message = "damaged", damaged
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


def _dataset_parts(sweep: Sweep, table: pd.DataFrame) -> tuple[dict, dict, dict]:
    """The contents of ``sweep.nc`` as numpy arrays: ``(coords, data, attrs)``, each variable
    ``name: (dims, values, attributes)``, as ``xarray.Dataset(data, coords=coords,
    attrs=attrs)`` takes them; :func:`_write_sweep_nc` writes the file (without xarray)."""
    import numpy as np

    from roughvib._version import __version__

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
    return coords, data, {
        "title": f"roughvib sweep {sweep.name}",
        "description": sweep.description,
        "base_scene": sweep.base_label,
        "fixed_values": _canonical(sweep.fixed),
        "source": sweep.source,
        "comment": "metrics are NaN where status is not success",
        "roughvib_version": __version__,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
    }


def _write_sweep_nc(path: Path, coords: dict, data: dict, attrs: dict) -> None:
    """Write :func:`_dataset_parts` as netCDF-4 with h5netcdf's public API, the file
    ``xarray.Dataset(data, coords=coords, attrs=attrs).to_netcdf(path, engine="h5netcdf")``
    writes (tested: the two decode identically), without xarray: building a Dataset and
    ``to_netcdf`` import ``dask.array`` and ``dask.distributed`` when dask is installed; written
    this way, ``sweep.csv`` and ``sweep.nc`` cost 0.5-0.6 s of CPU (docs/performance.md,
    "Sweeps and ensembles").

    CF's layout as xarray writes it: dimensions, then the coordinates and the data variables
    in order; floats with a NaN ``_FillValue``, integers and texts (variable-length UTF-8)
    without; a data variable lists the non-dimension coordinates on its dimensions in its
    ``coordinates`` attribute.

    The file is built in memory and written complete or not at all
    (:func:`roughvib.rundir.write_file`): HDF5 never meets a full disk itself, and a failed
    write is one :class:`~roughvib.rundir.WriteError` naming ``path``.
    """
    import io

    import h5netcdf
    import h5py
    import numpy as np

    def dims_of(dims) -> tuple[str, ...]:
        return (dims,) if isinstance(dims, str) else tuple(dims)

    sizes: dict[str, int] = {}
    for dims, values, _ in (*coords.values(), *data.values()):
        sizes.update(zip(dims_of(dims), np.shape(values), strict=True))
    extra = [k for k, (dims, _, _) in coords.items() if dims_of(dims) != (k,)]
    buf = io.BytesIO()
    with h5netcdf.File(buf, "w") as f:
        for k, v in attrs.items():
            f.attrs[k] = v
        for dim, size in sizes.items():
            f.dimensions[dim] = size
        for name, (dims, values, vattrs) in (*coords.items(), *data.items()):
            values = np.asarray(values)
            dims = dims_of(dims)
            if values.dtype.kind in "UO":
                var = f.create_variable(name, dimensions=dims, dtype=h5py.string_dtype(),
                                        chunks=None)
                var[...] = values.astype(object)
            else:
                fill = np.nan if values.dtype.kind == "f" else None
                var = f.create_variable(name, dimensions=dims, dtype=values.dtype,
                                        fillvalue=fill, chunks=None)
                var[...] = values
            for k, v in vattrs.items():
                var.attrs[k] = v
            mine = sorted(c for c in extra
                          if name in data and set(dims_of(coords[c][0])) <= set(dims))
            if mine:
                var.attrs["coordinates"] = " ".join(mine)
    with buf.getbuffer() as view:
        write_file(path, lambda tmp: tmp.write_bytes(view), need=view.nbytes)



def _write_tables(sweep: Sweep, out: Path,
                  errors: dict[str, tuple[str, str]] | None = None) -> pd.DataFrame:
    table = collect_table(sweep, out, errors)
    _replace_file(out / "sweep.csv", table.to_csv(index=False, float_format="%.12g"))
    _write_sweep_nc(out / "sweep.nc", *_dataset_parts(sweep, table))
    return table


# --------------------------------------------------------------------------------------------
# fits
# --------------------------------------------------------------------------------------------


def _joint_fit(ra, v, y) -> dict[str, Any]:
    """Least-squares fit of y = 20 log10(ra^a v^b) + c [dB] with 95 % t intervals.

    Parameters
    ----------
    ra, v : array_like, shape (m,)
        Roughness rms [m] and friction velocity [m/s], > 0 (at least two values of each).
    y : array_like, shape (m,)
        Levels [dB].

    Returns
    -------
    dict
        ``a``, ``b``, ``c`` and their 95 % intervals (``a_low``, ``a_high``, ...; from the
        residual variance with m - 3 degrees of freedom, NaN when m = 3), the same exponents as
        dB per doubling (``a_db_per_doubling`` = 20 log10(2) a, ...), ``rms_residual`` [dB]
        and ``n_points``.
    """
    import numpy as np
    from scipy import stats

    ra = np.asarray(ra, dtype=float)
    v = np.asarray(v, dtype=float)
    y = np.asarray(y, dtype=float)
    X = np.column_stack([20.0 * np.log10(ra), 20.0 * np.log10(v), np.ones(ra.size)])
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    res = y - X @ coef
    dof = ra.size - 3
    if dof > 0:
        s2 = float(res @ res) / dof
        cov = s2 * np.linalg.inv(X.T @ X)
        half = stats.t.ppf(0.975, dof) * np.sqrt(np.diag(cov))
    else:
        half = np.full(3, math.nan)
    per = 20.0 * math.log10(2.0)
    out: dict[str, Any] = {"n_points": int(ra.size),
                           "rms_residual": float(np.sqrt(np.mean(res**2)))}
    for name, c, h in zip("abc", coef, half, strict=True):
        out[name] = float(c)
        out[f"{name}_low"] = float(c - h)
        out[f"{name}_high"] = float(c + h)
    for name in "ab":
        out[f"{name}_db_per_doubling"] = per * out[name]
        out[f"{name}_db_per_doubling_low"] = per * out[f"{name}_low"]
        out[f"{name}_db_per_doubling_high"] = per * out[f"{name}_high"]
    return out


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

