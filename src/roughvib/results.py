"""The result contract shared by every solver: time series, event log, summary; netCDF I/O.

A :class:`Result` holds an :class:`xarray.Dataset` on the uniform output grid (every variable
with a ``units`` attribute; vertical quantities positive downward, docs/theory.md), the event
log as a :class:`pandas.DataFrame`, and a JSON-able summary (solver statistics, calibrated
T0, rms values, stick fraction, energy audit). ``Result.save(dir)`` writes

``result.nc``  the Dataset (h5netcdf engine)
``events.csv`` the event log
``summary.json`` statistics and metrics, the run id and the size and SHA-256 of every other file
``scene.toml`` the fully resolved scene (repeatable run)
``radiation.csv`` with ``output.radiation``: band levels of the radiated sound
(docs/radiation.md); in ``Result.extra["radiation"]`` as a table
``microphones.csv`` with ``output.microphones``: sound pressure levels there
(``Result.extra["microphones"]``)

atomically for the run as a whole: everything is written into a staging directory next to the
output directory and renamed into place when complete (:mod:`roughvib.rundir` has the rules of
what a run may touch). ``load_result`` checks each file against the list in ``summary.json``
and refuses a directory that mixes files of different runs.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import secrets
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from roughvib._eventlog import EVENT_KINDS, REGIME_NOTATION
from roughvib.rundir import RunDirectory
from roughvib.solvers.checkpoint import CHECKPOINT_NAME

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr

# xarray and pandas are imported where a Dataset or an event table is built, written or read:
# a run builds its Result from plain arrays and event records and writes its files without
# them (RunData, _write_events_csv)

__all__ = ["EVENT_COLUMNS", "EVENT_KINDS", "MICROPHONES_FILE", "MixedRunError",
           "RADIATION_FILE", "REGIME_NOTATION", "Result", "RunData", "VARIABLES",
           "check_run_files", "load_result"]

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
    "contact_closed": ("1", "contact closed (1) or open, lifted off (0), from the event log"),
    "stick": ("1", "block in a stick phase (1) or sliding (0), from the event log"),
}

EVENT_COLUMNS = ["time", "kind", "contact", "regime_before", "regime_after", "margin_before",
                 "margin_after", "tangential_velocity", "normal_force", "contact_force",
                 "friction_before", "friction_after"]
_TEXT_COLUMNS = ("kind", "regime_before", "regime_after")

FORMAT_VERSION = 1

#: the radiated-sound table of a run with ``output.radiation`` (columns band_hz [Hz, nominal
#: third-octave centre], sound_power_db [dB re 1 pW], mean_square_velocity_db [dB re
#: (1e-9 m/s)^2, space average over the plate], radiation_efficiency_db [dB re 1])
RADIATION_FILE = "radiation.csv"
#: sound pressure levels at ``output.microphones`` (columns band_hz [Hz], mic1_spl_db, ...
#: [dB re 20 uPa], one per microphone in the scene's order)
MICROPHONES_FILE = "microphones.csv"


class RunData:
    """The time series of a run as numpy arrays, laid out as in ``result.nc``.

    ``simulate`` builds a run's :class:`Result` from this instead of an xarray.Dataset:
    building a Dataset and writing it with xarray import dask (``dask.array`` with
    scipy.sparse, scipy.special and scipy.fft, for xarray's duck-array checks), about half a
    second of a short run on the 2-core machine (docs/performance.md, "Fixed cost of a run").
    :meth:`to_dataset` gives the xarray.Dataset (``Result.dataset`` calls it on first use) and
    :meth:`write_netcdf` writes the very file xarray's ``to_netcdf`` writes (tested group for
    group, attribute for attribute and byte for byte).

    Attributes
    ----------
    variables : dict
        name -> (dims, values, attrs), in the order of the Dataset's variables.
    coords : list of str
        The names in ``variables`` that are coordinates.
    attrs : dict
        Global attributes.
    """

    def __init__(self) -> None:
        self.variables: dict[str, tuple[tuple[str, ...], np.ndarray, dict]] = {}
        self.coords: list[str] = []
        self.attrs: dict = {}

    def add(self, name: str, dims: str | tuple[str, ...], values: np.ndarray,
            attrs: dict | None = None, *, coord: bool = False) -> None:
        """Add (or replace) a variable; ``coord=True`` makes it a coordinate."""
        dims = (dims,) if isinstance(dims, str) else tuple(dims)
        values = np.asarray(values)
        if values.ndim != len(dims):
            raise ValueError(f"{name}: {values.ndim}-d values for dims {dims}")
        self.variables[name] = (dims, values, dict(attrs or {}))
        if coord and name not in self.coords:
            self.coords.append(name)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.variables[name][1]

    def __contains__(self, name: str) -> bool:
        return name in self.variables

    @property
    def sizes(self) -> dict[str, int]:
        """Length of each dimension."""
        out: dict[str, int] = {}
        for dims, values, _ in self.variables.values():
            out.update(zip(dims, values.shape, strict=True))
        return out

    def to_dataset(self) -> xr.Dataset:
        """The xarray.Dataset of these arrays (variables, coordinates and attributes)."""
        import xarray as xr

        names = list(self.variables)
        coords = {n: self.variables[n] for n in names if n in self.coords}
        # the data variables before the first coordinate make the Dataset, the later ones are
        # added in order: the variable order of the Datasets built before RunData existed
        first = min((names.index(c) for c in coords), default=len(names))
        ds = xr.Dataset({n: self.variables[n] for n in names[:first] if n not in coords},
                        coords=coords)
        for n in names[first:]:
            if n not in coords:
                ds[n] = self.variables[n]
        ds.attrs.update(self.attrs)
        return ds

    def _coordinates_attrs(self) -> tuple[dict[str, str], str | None]:
        """The ``coordinates`` attributes of xarray's CF encoding: on every variable, the
        non-dimension coordinates whose dimensions it has; globally, those on none."""
        extra = [c for c in self.coords if (c,) != self.variables[c][0]]
        per_var: dict[str, str] = {}
        for name, (dims, _, _) in self.variables.items():
            if name in extra or name in dims:
                continue
            mine = sorted(c for c in extra if set(self.variables[c][0]) <= set(dims))
            if mine:
                per_var[name] = " ".join(mine)
        used = {c for text in per_var.values() for c in text.split()}
        rest = sorted(set(extra) - used)
        return per_var, (" ".join(rest) if rest else None)

    def write_netcdf(self, path: str | os.PathLike, attrs: dict) -> None:
        """Write the arrays as netCDF-4 (h5netcdf) with global attributes ``attrs``.

        The file is the one ``to_dataset().assign_attrs(attrs).to_netcdf(path,
        engine="h5netcdf")`` writes, in the same order (global attributes, dimensions,
        variables): float variables carry a NaN ``_FillValue``, integer ones none, and the
        data variables list their non-dimension coordinates in ``coordinates``.
        """
        import h5netcdf

        per_var, global_coords = self._coordinates_attrs()
        with h5netcdf.File(str(path), "w") as f:
            for k, v in attrs.items():
                f.attrs[k] = v
            if global_coords is not None:
                f.attrs["coordinates"] = global_coords
            for dim, size in self.sizes.items():
                f.dimensions[dim] = size
            for name, (dims, values, vattrs) in self.variables.items():
                fill = np.nan if values.dtype.kind == "f" else None
                var = f.create_variable(name, dimensions=dims, dtype=values.dtype,
                                        fillvalue=fill, chunks=None)
                for k, v in vattrs.items():
                    var.attrs[k] = v
                if name in per_var:
                    var.attrs["coordinates"] = per_var[name]
                var[...] = values


class _LazyField:
    """A field of :class:`Result` that may hold a plain stand-in until it is first read.

    ``Result.dataset`` may hold a :class:`RunData` and ``Result.events`` the list of event
    records of a run: a run that is only saved never imports xarray or pandas. On first
    access the stand-in is converted (``RunData.to_dataset``, :func:`events_frame`) and
    replaced by the result. A dataclass field whose default is a descriptor (Python >= 3.10):
    the constructor's argument goes through ``__set__``, and raising AttributeError on the
    class keeps the field without a default.
    """

    def __init__(self, plain: type, convert) -> None:
        self.plain, self.convert = plain, convert

    def __set_name__(self, owner, name: str) -> None:
        self.slot = f"_{name}"

    def raw(self, obj):
        """The stored value, unconverted."""
        return obj.__dict__[self.slot]

    def __get__(self, obj, objtype=None):
        if obj is None:
            raise AttributeError(self.slot[1:])
        value = obj.__dict__[self.slot]
        if isinstance(value, self.plain):
            value = self.convert(value)
            obj.__dict__[self.slot] = value
        return value

    def __set__(self, obj, value) -> None:
        obj.__dict__[self.slot] = value


def _write_events_csv(records: list, path: Path) -> None:
    """The event log as ``events_frame(records).to_csv(path, index=False,
    float_format="%.12g")`` writes it, with the csv module instead of pandas.

    pandas writes through the csv module (minimal quoting, ``os.linesep``); each numeric
    column is float64 (``%.12g``, NaN and None empty), ``contact`` an integer (empty for the
    block-level events, index -1) and the texts as they are. Tested against pandas.
    """
    import csv

    def cell(column: str, v) -> str:
        if column == "contact":
            return "" if v is None or not v >= 0 else str(int(v))  # as where(contact >= 0)
        if column in _TEXT_COLUMNS:
            return "" if v is None else str(v)
        if v is None or math.isnan(float(v)):
            return ""
        return "%.12g" % float(v)  # noqa: UP031 - pandas' float_format

    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator=os.linesep)
        writer.writerow(EVENT_COLUMNS)
        for r in records:
            writer.writerow([cell(c, getattr(r, c)) for c in EVENT_COLUMNS])


def _write_netcdf(ds: xr.Dataset, path: Path) -> None:
    """``ds.to_netcdf(path, engine="h5netcdf")`` without asking dask for its scheduler.

    ``to_netcdf`` looks up the active dask scheduler (importing ``dask.distributed`` and its
    dependencies: about 0.4 s of a short run on the 2-core machine) to decide whether to close
    the file between chunk writes, which only matters for dask arrays; ours are numpy arrays.
    Writing through the same h5netcdf store with xarray's HDF5 lock gives the same file
    (tested against ``to_netcdf``). With an xarray that no longer has these names, the public
    ``to_netcdf`` is used.
    """
    try:
        from xarray.backends import H5NetCDFStore
        from xarray.backends.locks import HDF5_LOCK
    except ImportError:  # pragma: no cover - another xarray layout
        ds.to_netcdf(path, engine="h5netcdf")
        return
    store = H5NetCDFStore.open(str(path), mode="w", lock=HDF5_LOCK)
    try:
        ds.dump_to_store(store, unlimited_dims=ds.encoding.get("unlimited_dims"))
    finally:
        store.close()


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
        contact positions. The constructor also takes a :class:`RunData`, which becomes the
        Dataset on first access (a run that is only saved never builds one).
    events : pandas.DataFrame
        Event log, columns ``EVENT_COLUMNS`` (contact is empty for block-level events). The
        constructor also takes the list of event records, which becomes the table on first
        access (:func:`events_frame`).
    summary : dict
        Status, solver statistics, calibrated T0, rms values, stick fraction, energy audit.
    scene_toml : str
        The fully resolved scene.
    """

    dataset: xr.Dataset = _LazyField(RunData, RunData.to_dataset)
    events: pd.DataFrame = _LazyField(list, lambda records: events_frame(records))
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

    def save(self, directory: str | os.PathLike | RunDirectory, *,
             overwrite: bool = False) -> Path:
        """Write result.nc, events.csv, summary.json and scene.toml into ``directory``.

        The run appears as a whole or not at all: the files are written into a staging
        directory next to ``directory`` and renamed into place when complete, replacing an
        earlier roughvib run there as a whole (see :mod:`roughvib.rundir`). A failed run
        (status != success) writes summary.json, scene.toml, the event log and, if any output
        rows were filled, ``partial.nc`` (the time series up to the failure; never
        ``result.nc``, so nothing takes it for a complete run; read it with
        ``load_result(directory, partial=True)``), and keeps a checkpoint in ``directory``.
        A checkpoint there refuses the save unless this result's own run wrote it
        (``simulate(..., checkpoint_dir=directory)`` or ``resume(directory)``).

        Parameters
        ----------
        directory : path or RunDirectory
            The output directory, or one already opened (and locked) by the caller.
        overwrite : bool
            Accept a directory holding files roughvib did not write (they are kept).

        Returns
        -------
        Path
            ``directory``.

        Raises
        ------
        roughvib.rundir.OutputError
            The directory cannot be used (a file, not writable, locked by another run, holding
            an unfinished run's checkpoint or, without ``overwrite``, other files).
        """
        own = not isinstance(directory, RunDirectory)
        if own:  # the run's own checkpoints in that directory do not refuse it
            cp_dir = self.extra.get("checkpoint_dir")
            mine = cp_dir is not None and os.path.realpath(cp_dir) == os.path.realpath(directory)
            rd = RunDirectory(directory, overwrite=overwrite, resume=mine)
        else:
            rd = directory
        if own:
            rd.open()
        try:
            self.write_files(rd.stage)
            rd.publish(keep=() if self.ok else (CHECKPOINT_NAME,))
        finally:
            if own:
                rd.close()
        return Path(rd.given)

    def write_files(self, directory: str | os.PathLike) -> list[str]:
        """Write the run's files into the existing directory ``directory``, ``summary.json``
        last, and record a new run id and the list of files in ``summary``.

        This is the writing half of :meth:`save`, without its staging and renaming: use it
        only on a fresh directory that is renamed into place afterwards.

        Returns
        -------
        list of str
            The names written.
        """
        tmp = Path(directory)
        run_id = secrets.token_hex(8)
        names = ["scene.toml"]
        (tmp / "scene.toml").write_text(self.scene_toml, encoding="utf-8")
        nc = "result.nc" if self.ok else "partial.nc"
        data = Result.__dict__["dataset"].raw(self)  # RunData until the Dataset was asked for
        if self.ok or data.sizes.get("time", 0) > 0:
            attrs = {k: (json.dumps(_jsonable(v)) if isinstance(v, dict | list) else v)
                     for k, v in data.attrs.items()}
            if not self.ok:
                attrs.update(status=self.status, message=str(self.summary.get("message", "")))
            attrs["run_id"] = run_id
            if isinstance(data, RunData):
                data.write_netcdf(tmp / nc, attrs)
            else:
                ds = data.copy()
                ds.attrs = attrs
                _write_netcdf(ds, tmp / nc)
            names.append(nc)
        events = Result.__dict__["events"].raw(self)  # records until the table was asked for
        if self.ok or len(events):
            if isinstance(events, list):
                _write_events_csv(events, tmp / "events.csv")
            else:
                ev = events.copy()
                ev["contact"] = ev["contact"].astype("Int64")
                ev.to_csv(tmp / "events.csv", index=False, float_format="%.12g")
            names.append("events.csv")
        radiation = self.extra.get("radiation")
        if self.ok and radiation is not None:  # output.radiation: the band table
            radiation.to_csv(tmp / RADIATION_FILE, index=False, float_format="%.6g")
            names.append(RADIATION_FILE)
        mics = self.extra.get("microphones")
        if self.ok and mics is not None:  # output.microphones: levels at the microphones
            mics.to_csv(tmp / MICROPHONES_FILE, index=False, float_format="%.6g")
            names.append(MICROPHONES_FILE)
        self.summary["run_id"] = run_id
        self.summary["files"] = {n: _file_info(tmp / n) for n in names}
        (tmp / "summary.json").write_text(json.dumps(_jsonable(self.summary), indent=2),
                                          encoding="utf-8")
        return [*names, "summary.json"]


class MixedRunError(ValueError):
    """A run directory whose files do not all belong to the run of its summary.json."""


def _file_info(path: Path) -> dict[str, Any]:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        while chunk := fh.read(1 << 20):
            h.update(chunk)
    return {"bytes": path.stat().st_size, "sha256": h.hexdigest()}


def check_run_files(directory: str | os.PathLike, summary: dict, *, hashes: bool = True
                    ) -> None:
    """Check that every file ``summary["files"]`` lists is there and is the one the run wrote.

    Parameters
    ----------
    directory : path
        The run directory.
    summary : dict
        Its summary (a summary written before the list existed passes unchecked).
    hashes : bool
        Compare SHA-256 digests too (else sizes only, which is cheap).

    Raises
    ------
    MixedRunError
        One line naming the directory, the file and the run.
    """
    files = summary.get("files")
    if not isinstance(files, dict):
        return
    d = Path(directory)
    run = summary.get("run_id", "?")
    for name, info in files.items():
        path = d / name
        if not path.is_file():
            raise MixedRunError(f"{d}: {name} of run {run} is missing: the directory is "
                                f"incomplete (a killed save, or a file removed by hand)")
        size = path.stat().st_size
        if size != info.get("bytes") or (hashes and _file_info(path)["sha256"]
                                         != info.get("sha256")):
            raise MixedRunError(f"{d}: {name} is not the file run {run} wrote (summary.json "
                                f"lists another size or SHA-256): the directory mixes files of "
                                f"different runs, or {name} was changed after saving")


def events_frame(records: list) -> pd.DataFrame:
    """Event records (dataclasses) to the event-log table."""
    import pandas as pd

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
    MixedRunError
        A file listed in ``summary.json`` is missing or is not the one the run wrote (a
        directory left half-replaced, or edited after saving).
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
    check_run_files(d, summary)
    scene_toml = (d / "scene.toml").read_text() if (d / "scene.toml").exists() else ""
    import pandas as pd
    import xarray as xr

    ok = summary.get("status") == "success"
    if not ok and not (partial and (d / "partial.nc").exists()):
        return Result(xr.Dataset(), pd.DataFrame(columns=EVENT_COLUMNS), summary, scene_toml)
    ds = xr.load_dataset(d / ("result.nc" if ok else "partial.nc"), engine="h5netcdf")
    if not (d / "events.csv").exists() or (d / "events.csv").stat().st_size == 0:
        return Result(ds, pd.DataFrame(columns=EVENT_COLUMNS), summary, scene_toml,
                      extra=_extra_tables(d, summary))
    ev = pd.read_csv(d / "events.csv", dtype={"contact": "Int64"})
    return Result(ds, ev, summary, scene_toml, extra=_extra_tables(d, summary))


def _extra_tables(d: Path, summary: dict) -> dict:
    """The optional tables of a run directory that ``summary.json`` lists."""
    import pandas as pd

    files = summary.get("files", {})
    return {key: pd.read_csv(d / name) for key, name in
            (("radiation", RADIATION_FILE), ("microphones", MICROPHONES_FILE)) if name in files}
