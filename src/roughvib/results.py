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

import contextlib
import hashlib
import io
import json
import math
import os
import secrets
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from roughvib._eventlog import EVENT_KINDS, REGIME_NOTATION
from roughvib.model.variables import VARIABLE_TABLE
from roughvib.rundir import (
    MICROPHONES_FILE,
    RADIATION_FILE,
    RUN_FILES,
    RunDirectory,
    check_room,
    write_failed,
)
from roughvib.solvers.checkpoint import CHECKPOINT_NAME

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr

# xarray and pandas are imported where a Dataset or an event table is built, written or read:
# a run builds its Result from plain arrays and event records and writes its files without
# them (RunData, _write_events_csv)

__all__ = ["EVENT_COLUMNS", "EVENT_KINDS", "MICROPHONES_FILE", "MixedRunError", "NotARunError",
           "RADIATION_FILE", "REGIME_NOTATION", "Result", "RunData", "RunDirectoryError",
           "SUMMARY_DIGEST", "VARIABLES", "check_run_files", "expected_result_bytes",
           "load_result", "read_summary", "seal_summary"]

#: name -> (units, long name) of every variable of a result: the one table of
#: :mod:`roughvib.model.variables` (the outputs the solvers write and those rebuilt from the
#: event log)
VARIABLES: dict[str, tuple[str, str]] = {v.name: (v.unit, v.description)
                                         for v in VARIABLE_TABLE}

EVENT_COLUMNS = ["time", "kind", "contact", "regime_before", "regime_after", "margin_before",
                 "margin_after", "tangential_velocity", "normal_force", "contact_force",
                 "friction_before", "friction_after"]
_TEXT_COLUMNS = ("kind", "regime_before", "regime_after")

FORMAT_VERSION = 1

# RADIATION_FILE (rundir): the radiated-sound table of a run with ``output.radiation``
# (columns band_hz [Hz, nominal third-octave centre], sound_power_db [dB re 1 pW],
# mean_square_velocity_db [dB re (1e-9 m/s)^2, space average over the plate],
# radiation_efficiency_db [dB re 1]); MICROPHONES_FILE (rundir): sound pressure levels at
# ``output.microphones`` (columns band_hz [Hz], mic1_spl_db, ... [dB re 20 uPa], one per
# microphone in the scene's order)


class RunData:
    """The time series of a run as numpy arrays, laid out as in ``result.nc``.

    ``simulate`` builds a run's :class:`Result` from this instead of an xarray.Dataset:
    building a Dataset and writing it with xarray import dask (``dask.array`` with
    scipy.sparse, scipy.special and scipy.fft, for xarray's duck-array checks), which a run
    does without (docs/performance.md, "Fixed cost of a run").
    :meth:`to_dataset` gives the xarray.Dataset (``Result.dataset`` calls it on first use) and
    :meth:`write_netcdf` writes it with h5netcdf's public API as a netCDF-4 file of the CF
    conventions that ``xarray.open_dataset`` and :func:`load_result` read back to the same
    Dataset (tested, also against the file ``to_netcdf`` writes, group for group and attribute
    for attribute).

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

    @classmethod
    def from_dataset(cls, ds: xr.Dataset) -> RunData | None:
        """The arrays of a Dataset: its variables in its order, its coordinates and attributes.

        Parameters
        ----------
        ds : xarray.Dataset
            Any Dataset; its values are read into memory.

        Returns
        -------
        RunData or None
            None if a variable is not numeric (integer or float: text, booleans and times
            are not what :meth:`write_netcdf` writes).
        """
        data = cls()
        coords = set(ds.coords)
        for name, var in ds.variables.items():
            if var.dtype.kind not in "iuf":
                return None
            data.add(str(name), tuple(str(d) for d in var.dims), np.asarray(var.values),
                     dict(var.attrs), coord=name in coords)
        data.attrs = dict(ds.attrs)
        return data

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
        """Write the arrays as netCDF-4 with global attributes ``attrs`` (h5netcdf's public
        API).

        The layout is CF's, as xarray decodes it: global attributes, dimensions, variables in
        order; float variables carry a NaN ``_FillValue``, integer ones none, and the data
        variables list their non-dimension coordinates in the ``coordinates`` attribute
        (coordinates on no variable's dimensions in the global one). ``to_dataset()
        .assign_attrs(attrs).to_netcdf(path, engine="h5netcdf")`` writes the same file
        (tested).

        The file is built in memory (:meth:`netcdf_image`) and written with plain file I/O, so
        that a failed write (a full disk) is an :class:`OSError` of that write and nothing
        else: HDF5 itself never meets it. An HDF5 file whose close fails on a full disk stays
        half-open, and freeing it later crashed the interpreter (SIGSEGV).

        Raises
        ------
        OSError
            The file cannot be written; a partial file may be left at ``path``.
        """
        with self.netcdf_image(attrs).getbuffer() as view, open(path, "wb") as fh:
            fh.write(view)

    def netcdf_image(self, attrs: dict) -> io.BytesIO:
        """The netCDF-4 file of :meth:`write_netcdf`, in memory.

        Parameters
        ----------
        attrs : dict
            Global attributes.

        Returns
        -------
        io.BytesIO
            The file's bytes (``getbuffer()``), about the size of the arrays plus 30 kB.
        """
        import h5netcdf

        per_var, global_coords = self._coordinates_attrs()
        buf = io.BytesIO()
        with h5netcdf.File(buf, "w") as f:
            for k, v in attrs.items():
                f.attrs[k] = v
            if global_coords is not None:
                f.attrs["coordinates"] = global_coords
            for dim, size in self.sizes.items():
                f.dimensions[dim] = size
            for name, (dims, values, vattrs) in self.variables.items():
                fill = np.nan if values.dtype.kind == "f" else None
                # the values with the variable: a separate ``var[...] = values`` costs
                # h5netcdf's dimension checks once more per variable (~1 ms each)
                var = f.create_variable(name, dimensions=dims, dtype=values.dtype,
                                        data=values, fillvalue=fill, chunks=None)
                va = var.attrs  # each ``var.attrs`` looks the variable up in the file again
                for k, v in vattrs.items():
                    va[k] = v
                if name in per_var:
                    va["coordinates"] = per_var[name]
        return buf


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
    """Write a Dataset as ``result.nc`` / ``partial.nc``, through public APIs only.

    A Dataset of numeric variables (every Dataset a run makes or :func:`load_result` reads)
    goes through :meth:`RunData.from_dataset` and :meth:`RunData.write_netcdf` (h5netcdf's
    public API): the same file as for a run that never built its Dataset, and no look-up of
    the dask scheduler that ``to_netcdf`` makes (about 0.4 s of a short run, importing
    ``dask.distributed``). Anything else (a Dataset with text, booleans or times, made by
    hand) is written by ``Dataset.to_netcdf(engine="h5netcdf")``.
    """
    data = RunData.from_dataset(ds)
    if data is None:
        ds.to_netcdf(path, engine="h5netcdf")
    else:
        data.write_netcdf(path, dict(ds.attrs))


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
            self._write_files(rd.stage, rd.given)
            rd.publish(keep=() if self.ok else (CHECKPOINT_NAME,))
        except OSError as exc:  # a full disk, a read-only file system: one line
            raise write_failed(rd.given, exc, what="the run") from None
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

        Raises
        ------
        roughvib.rundir.WriteError
            The files do not fit on the file system (checked before anything is written), or a
            write failed: one line naming ``directory`` (and for a full disk the space needed
            and free).
        """
        return self._write_files(Path(directory), str(directory))

    def _bytes_estimate(self) -> tuple[int, int]:
        """The bytes of the run's files: at least (its arrays) and about (with the event log,
        the scene and the metadata of the netCDF file and of the summary)."""
        data = Result.__dict__["dataset"].raw(self)
        arrays = (sum(v.nbytes for _, v, _ in data.variables.values())
                  if isinstance(data, RunData) else int(data.nbytes))
        events = Result.__dict__["events"].raw(self)
        return arrays, (arrays + _EVENT_ROW_BYTES * len(events) + len(self.scene_toml)
                        + _METADATA_BYTES)

    def _write_files(self, tmp: Path, shown: str) -> list[str]:
        """:meth:`write_files` into ``tmp``, with ``shown`` naming the run's directory in a
        message."""
        at_least, about = self._bytes_estimate()
        check_room(tmp, at_least, "the run's time series", shown=shown)
        try:
            return self._write_into(tmp)
        except OSError as exc:
            for name in RUN_FILES:  # first: the message names the space free without them
                with contextlib.suppress(OSError):
                    (tmp / name).unlink(missing_ok=True)
            raise write_failed(shown, exc, about, what="the run's files", approx=True
                               ) from None

    def _write_into(self, tmp: Path) -> list[str]:
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
            else:  # the Dataset was asked for (and may have been changed)
                ds = data.copy(deep=False)
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
        self.summary.pop(SUMMARY_DIGEST, None)
        sealed = seal_summary(_jsonable(self.summary))
        self.summary[SUMMARY_DIGEST] = sealed[SUMMARY_DIGEST]
        (tmp / "summary.json").write_text(json.dumps(sealed, indent=2), encoding="utf-8")
        return [*names, "summary.json"]


#: bytes of a row of events.csv (12 columns, numbers of up to 12 significant digits, the
#: regimes of the contacts) and of the metadata of a run (the netCDF file's header and
#: attributes, summary.json), about, for the message of a full disk: with them the files of
#: the 5 ms run of the tests (77 kB) and of paper-100mms (4.25 MB) are estimated within 5 kB
_EVENT_ROW_BYTES = 96
_METADATA_BYTES = 40_000


def expected_result_bytes(scene) -> int:
    """The bytes a complete run of ``scene`` writes at least: the time series of ``result.nc``.

    Every variable of :data:`VARIABLES` on the output grid (``output.duration /
    output.step + 1`` samples; float64, the contact and stick flags int8), per contact where it
    is per contact, and the time; the event log and the metadata come on top. A scene with
    ``contact.points = "auto"`` counts one contact (the count is known only once the profile
    is built), so that the figure stays a lower bound.

    Parameters
    ----------
    scene : roughvib.scene.Scene

    Returns
    -------
    int
        Bytes.
    """
    out = scene.output
    n = int(round(out.duration / out.step)) + 1
    points = scene.contact.points
    contacts = points if isinstance(points, int) else 1
    row = _TIME_BYTES
    for name in VARIABLES:
        row += _VARIABLE_BYTES.get(name, 8) * (contacts if name in _PER_CONTACT else 1)
    return n * row


_TIME_BYTES = 8  # the time coordinate, float64
#: bytes per sample of the variables that are not float64
_VARIABLE_BYTES = {"contact_closed": 1, "stick": 1}
#: the variables with one column per contact
_PER_CONTACT = frozenset({"contact_force", "roughness_input", "contact_closed"})


class RunDirectoryError(ValueError):
    """A file of a run directory that is not what roughvib wrote (wrong type or shape, not
    readable, edited after saving); the message is one line naming the file (exit status 2)."""


class MixedRunError(RunDirectoryError):
    """A run directory whose files do not all belong to the run of its summary.json."""


class NotARunError(RunDirectoryError, FileNotFoundError):
    """A path that is not a run directory: missing, a file, or a directory without
    ``summary.json``; the message is one line naming it (exit status 2).

    Also a :class:`FileNotFoundError`, the error :func:`load_result` raised for it before, so
    that code catching that still does.
    """


#: the key of ``summary.json`` that holds the SHA-256 of the rest of the summary
SUMMARY_DIGEST = "summary_sha256"


def _canonical(obj: Any) -> bytes:
    """The JSON text a summary's digest is taken of: sorted keys, no spaces, ASCII."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True
                      ).encode("ascii")


def seal_summary(summary: dict) -> dict:
    """A copy of a JSON-able summary with its digest ``summary[SUMMARY_DIGEST]``.

    The digest is the SHA-256 of the summary without that key, as canonical JSON (sorted keys,
    no spaces, ASCII): :func:`read_summary` refuses a ``summary.json`` whose values were
    changed after the run wrote it. It guards against edits and damage, not against someone
    who recomputes it.

    Parameters
    ----------
    summary : dict
        The summary, JSON-able (finite floats, str keys).

    Returns
    -------
    dict
        ``summary`` and its digest (the digest key last).
    """
    body = {k: v for k, v in summary.items() if k != SUMMARY_DIGEST}
    return {**body, SUMMARY_DIGEST: hashlib.sha256(_canonical(body)).hexdigest()}


def _json_type(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    name = {dict: "an object", list: "an array", str: "a string", int: "an integer",
            float: "a number"}.get(type(value), type(value).__name__)
    text = json.dumps(value) if not isinstance(value, dict | list) else ""
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{name} {text}".rstrip()


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


#: what each kind of value in the shape of summary.json accepts, and its name in a message
_KINDS: dict[str, tuple[Any, str]] = {
    "int": (lambda v: isinstance(v, int) and not isinstance(v, bool), "an integer"),
    "num?": (lambda v: v is None or _is_number(v), "a number or null"),
    "str": (lambda v: isinstance(v, str), "a string"),
    "str?": (lambda v: v is None or isinstance(v, str), "a string or null"),
    "dict": (lambda v: isinstance(v, dict), "an object"),
    "dict?": (lambda v: v is None or isinstance(v, dict), "an object or null"),
    "list": (lambda v: isinstance(v, list), "an array"),
}
#: the shape of summary.json: dotted key -> kind (every key optional except format_version
#: and status; ``*`` stands for every key of an object, ``[]`` for every item of an array)
_SUMMARY_SHAPE: dict[str, str] = {
    "format_version": "int", "status": "str", "message": "str?", "scene": "str?",
    "run_id": "str", SUMMARY_DIGEST: "str", "force_amplitude": "num?",
    "solver": "dict", "calibration": "dict", "model": "dict", "events_by_kind": "dict",
    "metrics": "dict", "energy_audit": "dict", "warnings": "list", "files": "dict",
    "last_events": "list", "partial_result": "dict?", "accuracy": "dict?",
    "solver.method": "str?", "solver.wall_time": "num?",
    "calibration.target_rms_velocity": "num?", "calibration.achieved_rms_velocity": "num?",
    "model.modes": "int", "model.contacts": "int", "model.states": "int",
    "model.contact_stiffness_total": "num?", "model.contact": "dict?", "model.profile": "dict",
    "model.residual_compliance": "dict?", "model.residual_compliance.source": "str?",
    "model.residual_compliance.largest": "num?",
    "events_by_kind.*": "int", "metrics.*": "num?", "energy_audit.*": "num?",
    "warnings.[]": "str", "last_events.[]": "dict", "partial_result.t_end": "num?",
    "accuracy.verdict": "str?", "accuracy.failures": "list",
    "files.*": "dict", "files.*.bytes": "int", "files.*.sha256": "str",
}


def _check_shape(summary: dict, path: Path) -> None:
    """Refuse a summary whose values have another type than roughvib writes (one line)."""
    for key, kind in _SUMMARY_SHAPE.items():
        parts = key.split(".")
        found: list[tuple[str, Any]] = [("", summary)]
        for part in parts:
            nxt = []
            for where, obj in found:
                if part == "*" and isinstance(obj, dict):
                    nxt += [(f"{where}.{k}", v) for k, v in obj.items()]
                elif part == "[]" and isinstance(obj, list):
                    nxt += [(f"{where}[{i}]", v) for i, v in enumerate(obj)]
                elif isinstance(obj, dict) and part in obj:
                    nxt.append((f"{where}.{part}", obj[part]))
            found = nxt
        ok, what = _KINDS[kind]
        for where, value in found:
            if not ok(value):
                raise RunDirectoryError(f"{path}: {where[1:]} must be {what}, got "
                                        f"{_json_type(value)} (not a summary roughvib wrote)")
    bad = [n for n in summary.get("files", {}) if n not in RUN_FILES or n == "summary.json"]
    if bad:
        raise RunDirectoryError(f"{path}: files lists {bad[0]!r}, which is not a file of a run "
                                f"({', '.join(n for n in RUN_FILES if n != 'summary.json')})")


def _read_run_text(path: Path, what: str) -> str:
    """The text of a run directory's file, or one line naming it (unreadable, not UTF-8).

    ``what`` names the file's kind in the message ("summary", "scene")."""
    try:
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise RunDirectoryError(f"{path} cannot be read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise RunDirectoryError(f"{path} is not UTF-8 text (not a {what} roughvib wrote)"
                                ) from None


def read_summary(directory: str | os.PathLike) -> dict:
    """Read and check ``summary.json`` of a run directory.

    The file must hold a JSON object of the shape roughvib writes (type of every value it
    reads) and of a supported format version; a summary with a digest (every summary this
    version writes, :func:`seal_summary`) must match it. A summary without a digest (written by
    an older roughvib) is read unchecked in its values.

    Parameters
    ----------
    directory : path
        The run directory.

    Returns
    -------
    dict
        The summary.

    Raises
    ------
    NotARunError
        ``directory`` does not exist, is a file, or holds no summary.json (also a
        FileNotFoundError).
    RunDirectoryError
        Not readable, not JSON, not an object, another format version, a value of the wrong
        type, or edited after saving (one line naming the file).
    """
    d = Path(directory)
    path = d / "summary.json"
    if not path.is_file():
        why = ("no such directory" if not os.path.lexists(d) else
               "a file; roughvib run writes a directory" if not d.is_dir() else
               "no summary.json")
        raise NotARunError(f"{d} is not a roughvib result directory ({why})")
    text = _read_run_text(path, "summary")
    try:
        summary = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RunDirectoryError(f"{path} is not valid JSON ({exc.msg} at line {exc.lineno} "
                                f"column {exc.colno})") from None
    except RecursionError:
        raise RunDirectoryError(f"{path}: JSON nested too deeply (not a summary roughvib "
                                f"wrote)") from None
    if not isinstance(summary, dict):
        raise RunDirectoryError(f"{path} must hold a JSON object, got {_json_type(summary)} "
                                f"(not a summary roughvib wrote)")
    fv = summary.get("format_version")
    if fv != FORMAT_VERSION:
        raise RunDirectoryError(f"{d}: result format version {fv} is not supported (this "
                                f"roughvib reads version {FORMAT_VERSION})")
    if "status" not in summary:
        raise RunDirectoryError(f"{path} has no status (not a summary roughvib wrote)")
    _check_shape(summary, path)
    digest = summary.get(SUMMARY_DIGEST)
    if digest is not None and seal_summary(summary)[SUMMARY_DIGEST] != digest:
        raise RunDirectoryError(f"{path} was changed after the run wrote it (it no longer "
                                f"matches its {SUMMARY_DIGEST}): its values are not the run's; "
                                f"run the scene again (its scene.toml)")
    return summary


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
    RunDirectoryError
        ``summary`` or its list of files is not of the shape roughvib writes.
    """
    d = Path(directory)
    if not isinstance(summary, dict):
        raise RunDirectoryError(f"{d / 'summary.json'} must hold a JSON object, got "
                                f"{_json_type(summary)} (not a summary roughvib wrote)")
    files = summary.get("files")
    if not isinstance(files, dict):
        return
    run = summary.get("run_id", "?")
    for name, info in files.items():
        if not isinstance(info, dict) or name not in RUN_FILES:
            raise RunDirectoryError(f"{d / 'summary.json'}: files.{name} is not an entry "
                                    f"roughvib wrote")
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


def _short(exc: BaseException) -> str:
    """An exception as a short single line (first line, at most 160 characters)."""
    lines = str(exc).strip().splitlines()
    text = lines[0] if lines else ""
    text = text if len(text) <= 160 else text[:157] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _read_scene_toml(d: Path) -> str:
    import tomllib

    path = d / "scene.toml"
    if not path.exists():
        return ""
    text = _read_run_text(path, "scene")
    try:
        tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RunDirectoryError(f"{path} is not valid TOML ({_short(exc)})") from None
    return text


def _read_dataset(path: Path) -> xr.Dataset:
    """A run's time series, checked to be one: a time coordinate, our variables along it."""
    import xarray as xr

    try:
        ds = xr.load_dataset(path, engine="h5netcdf")
    except Exception as exc:  # any reader error of a damaged or foreign file: one line
        raise RunDirectoryError(f"{path} cannot be read as netCDF-4 ({_short(exc)}): a "
                                f"damaged file, or not one roughvib wrote") from None
    t = ds.variables.get("time")
    if t is None or t.dims != ("time",) or t.dtype.kind != "f" or not (
            np.all(np.isfinite(t.values)) and np.all(np.diff(t.values) > 0)):
        raise RunDirectoryError(f"{path} has no time coordinate of increasing finite seconds "
                                f"(not a time series roughvib wrote)")
    ours = [n for n in VARIABLES if n in ds.variables]
    if not ours:
        raise RunDirectoryError(f"{path} holds none of the variables of a run (e.g. "
                                f"block_tangential_velocity): not a file roughvib wrote")
    for name in ours:
        v = ds.variables[name]
        if v.dims[:1] != ("time",) or v.dtype.kind not in "fiub":
            raise RunDirectoryError(f"{path}: {name} must be numbers along time, got "
                                    f"{v.dtype} over {v.dims} (not a file roughvib wrote)")
    return ds


def _read_events(path: Path) -> pd.DataFrame:
    """A run's event log, checked to be one: our columns, numbers where we write numbers."""
    import pandas as pd

    if not path.exists() or path.stat().st_size == 0:
        return pd.DataFrame(columns=EVENT_COLUMNS)
    try:
        ev = pd.read_csv(path, dtype={"contact": "Int64"})
    except Exception as exc:  # any parser error of a damaged or foreign file: one line
        raise RunDirectoryError(f"{path} cannot be read as an event log ({_short(exc)})"
                                ) from None
    missing = [c for c in EVENT_COLUMNS if c not in ev.columns]
    if missing:
        shown = ", ".join(missing[:3]) + (f", ... ({len(missing) - 3} more)"
                                          if len(missing) > 3 else "")
        raise RunDirectoryError(f"{path} lacks the column{'s' if len(missing) > 1 else ''} "
                                f"{shown} (not an event log roughvib wrote)")
    if len(ev):
        for c in EVENT_COLUMNS:
            if c not in _TEXT_COLUMNS and c != "contact" and \
                    not pd.api.types.is_numeric_dtype(ev[c]):
                raise RunDirectoryError(f"{path}: column {c} must hold numbers (not an event "
                                        f"log roughvib wrote)")
        if not np.all(np.isfinite(ev["time"].to_numpy(dtype=float))):
            raise RunDirectoryError(f"{path}: column time must hold finite seconds (not an "
                                    f"event log roughvib wrote)")
    return ev


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

    Every file is checked as untrusted input before it is used (docs/robustness.md, "Reading
    a run directory"): ``summary.json`` by :func:`read_summary` (a JSON object of the shape
    roughvib writes, unchanged since the run wrote it), the other files against its list
    (:func:`check_run_files`), ``scene.toml`` as TOML, ``result.nc`` / ``partial.nc`` as a
    time series and ``events.csv`` as an event log.

    Parameters
    ----------
    directory : path
    partial : bool
        For a failed run, also read the time series up to the failure (``partial.nc``) and
        the event log; by default a failed run comes back with an empty dataset.

    Raises
    ------
    NotARunError
        ``directory`` is missing, a file, or holds no summary.json (a
        :class:`RunDirectoryError`, and a FileNotFoundError as before).
    RunDirectoryError
        A file that is not what roughvib wrote: not readable, of another type or shape,
        edited after saving, or a status that contradicts the files, among them both
        ``result.nc`` and ``partial.nc`` in the directory (one line naming the files); also a
        directory from an incompatible format version.
    MixedRunError
        A file listed in ``summary.json`` is missing or is not the one the run wrote (a
        directory left half-replaced, or edited after saving).
    """
    d = Path(directory)
    summary = read_summary(d)
    check_run_files(d, summary)
    scene_toml = _read_scene_toml(d)
    import pandas as pd
    import xarray as xr

    status = summary["status"]
    ok = status == "success"
    files = summary.get("files")
    listed = set(files) if isinstance(files, dict) else None
    if ok and not (d / "result.nc").is_file():
        raise RunDirectoryError(f"{d}: summary.json says the run succeeded, but result.nc is "
                                f"missing")
    wrong = "partial.nc" if ok else "result.nc"
    if (wrong in listed) if listed is not None else (not ok and (d / wrong).is_file()):
        raise RunDirectoryError(
            f"{d / 'summary.json'}: status {status!r} contradicts {wrong} in the directory "
            f"({'a failed' if ok else 'only a complete'} run writes it): the summary was "
            f"edited or belongs to another run")
    if os.path.lexists(d / "result.nc") and os.path.lexists(d / "partial.nc"):
        raise RunDirectoryError(
            f"{d} holds both result.nc and partial.nc: a run writes one of them (result.nc "
            f"when it succeeds, partial.nc when it fails), so one belongs to another run; "
            f"summary.json says {status!r}, remove {wrong} if it is not this run's")
    if not ok and not (partial and (d / "partial.nc").exists()):
        return Result(xr.Dataset(), pd.DataFrame(columns=EVENT_COLUMNS), summary, scene_toml)
    ds = _read_dataset(d / ("result.nc" if ok else "partial.nc"))
    ev = _read_events(d / "events.csv")
    return Result(ds, ev, summary, scene_toml, extra=_extra_tables(d, summary))


def _extra_tables(d: Path, summary: dict) -> dict:
    """The optional tables of a run directory that ``summary.json`` lists."""
    import pandas as pd

    files = summary.get("files", {})
    return {key: pd.read_csv(d / name) for key, name in
            (("radiation", RADIATION_FILE), ("microphones", MICROPHONES_FILE)) if name in files}
