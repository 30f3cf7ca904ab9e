"""The result contract shared by every solver: time series, event log, summary; netCDF I/O.

A :class:`Result` holds an :class:`xarray.Dataset` on the uniform output grid (every variable
with a ``units`` attribute; vertical quantities positive downward, docs/theory.md), the event
log as a :class:`pandas.DataFrame`, and a JSON-able summary (solver statistics, calibrated
T0, rms values, stick fraction, energy audit). ``Result.save(dir)`` writes

``result.nc``  the Dataset (h5netcdf engine)
``events.csv`` the event log
``summary.json`` statistics and metrics
``scene.toml`` the fully resolved scene (repeatable run)

atomically: everything is written into a temporary sibling directory and moved into place
only when complete, so an interrupted save never leaves a half-written ``result.nc``.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

__all__ = ["EVENT_COLUMNS", "Result", "VARIABLES", "load_result"]

#: name -> (units, long name)
VARIABLES: dict[str, tuple[str, str]] = {
    "block_vertical_displacement": ("m", "vertical block displacement (positive down)"),
    "block_vertical_velocity": ("m s-1", "vertical block velocity (positive down)"),
    "block_vertical_acceleration": ("m s-2", "vertical block acceleration (positive down)"),
    "plate_vertical_acceleration": ("m s-2",
                                    "plate acceleration at the observation point (positive down)"),
    "block_tangential_displacement": ("m", "tangential block displacement"),
    "block_tangential_velocity": ("m s-1", "tangential block velocity (friction velocity)"),
    "friction_force": ("N", "friction force on the block (opposing +velocity)"),
    "normal_force": ("N", "total normal contact force"),
    "friction_coefficient": ("1", "friction force / normal force"),
    "contact_force": ("N", "normal force per contact spring"),
    "roughness_input": ("m", "roughness displacement input per contact (positive down)"),
}

EVENT_COLUMNS = ["time", "kind", "contact", "regime_before", "regime_after", "margin_before",
                 "margin_after", "tangential_velocity", "normal_force", "contact_force",
                 "friction_before", "friction_after"]

FORMAT_VERSION = 1


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


@dataclass
class Result:
    """Outcome of :func:`roughvib.simulate <roughvib.simulation.simulate>`.

    Attributes
    ----------
    dataset : xarray.Dataset
        Time series on the output grid (see ``VARIABLES``); coordinate ``contact`` carries the
        contact positions.
    events : pandas.DataFrame
        Event log, columns ``EVENT_COLUMNS`` (contact is empty for block-level events).
    summary : dict
        Status, solver statistics, calibrated T0, rms values, stick fraction, energy audit.
    scene_toml : str
        The fully resolved scene.
    """

    dataset: xr.Dataset
    events: pd.DataFrame
    summary: dict
    scene_toml: str
    extra: dict = field(default_factory=dict)

    @property
    def status(self) -> str:
        """``"success"`` or the failure cause."""
        return self.summary.get("status", "unknown")

    @property
    def ok(self) -> bool:
        return self.status == "success"

    def to_dataset(self) -> xr.Dataset:
        """The time series as an :class:`xarray.Dataset` (units in each variable's attrs)."""
        return self.dataset

    def __getitem__(self, name: str) -> xr.DataArray:
        return self.dataset[name]

    def save(self, directory: str | os.PathLike) -> Path:
        """Write result.nc, events.csv, summary.json and scene.toml into ``directory``.

        The files are written to a temporary directory next to it and moved into place when
        complete. A failed run (status != success) writes summary.json, scene.toml, the event
        log and, if any output rows were filled, ``partial.nc`` (the time series up to the
        failure; never ``result.nc``, so nothing takes it for a complete run; read it with
        ``load_result(directory, partial=True)``).
        """
        out = Path(directory)
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
        try:
            names = ["summary.json", "scene.toml"]
            (tmp / "summary.json").write_text(json.dumps(_jsonable(self.summary), indent=2))
            (tmp / "scene.toml").write_text(self.scene_toml)
            nc = "result.nc" if self.ok else "partial.nc"
            if self.ok or self.dataset.sizes.get("time", 0) > 0:
                ds = self.dataset.copy()
                ds.attrs = {k: (json.dumps(_jsonable(v)) if isinstance(v, dict | list) else v)
                            for k, v in ds.attrs.items()}
                if not self.ok:
                    ds.attrs.update(status=self.status,
                                    message=str(self.summary.get("message", "")))
                ds.to_netcdf(tmp / nc, engine="h5netcdf")
                names.append(nc)
            if self.ok or len(self.events):
                ev = self.events.copy()
                ev["contact"] = ev["contact"].astype("Int64")
                ev.to_csv(tmp / "events.csv", index=False, float_format="%.12g")
                names.append("events.csv")
            out.mkdir(parents=True, exist_ok=True)
            for stale in ("result.nc", "partial.nc", "events.csv"):
                if stale not in names and (out / stale).exists():
                    (out / stale).unlink()
            for name in names:
                os.replace(tmp / name, out / name)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        return out


def events_frame(records: list) -> pd.DataFrame:
    """Event records (dataclasses) to the event-log table."""
    rows = [{c: getattr(r, c) for c in EVENT_COLUMNS} for r in records]
    df = pd.DataFrame(rows, columns=EVENT_COLUMNS)
    df["contact"] = df["contact"].where(df["contact"] >= 0).astype("Int64") if len(df) else \
        df["contact"].astype("Int64")
    return df


def load_result(directory: str | os.PathLike, *, partial: bool = False) -> Result:
    """Read a result directory written by :meth:`Result.save <roughvib.results.Result.save>`.

    Parameters
    ----------
    directory : path
    partial : bool
        For a failed run, also read the time series up to the failure (``partial.nc``) and
        the event log; by default a failed run comes back with an empty dataset.

    Raises
    ------
    FileNotFoundError, ValueError
        Missing files, or a directory from an incompatible format version.
    """
    d = Path(directory)
    summary_path = d / "summary.json"
    if not summary_path.exists():
        raise FileNotFoundError(f"{d} is not a roughvib result directory (no summary.json)")
    summary = json.loads(summary_path.read_text())
    fv = summary.get("format_version")
    if fv != FORMAT_VERSION:
        raise ValueError(f"{d}: result format version {fv} is not supported (this roughvib "
                         f"reads version {FORMAT_VERSION})")
    scene_toml = (d / "scene.toml").read_text() if (d / "scene.toml").exists() else ""
    ok = summary.get("status") == "success"
    if not ok and not (partial and (d / "partial.nc").exists()):
        return Result(xr.Dataset(), pd.DataFrame(columns=EVENT_COLUMNS), summary, scene_toml)
    ds = xr.load_dataset(d / ("result.nc" if ok else "partial.nc"), engine="h5netcdf")
    if not (d / "events.csv").exists() or (d / "events.csv").stat().st_size == 0:
        return Result(ds, pd.DataFrame(columns=EVENT_COLUMNS), summary, scene_toml)
    ev = pd.read_csv(d / "events.csv")
    ev["contact"] = ev["contact"].astype("Int64")
    return Result(ds, ev, summary, scene_toml)
