"""Measured acceleration records in, exchange files of a run out.

This module owns the files that cross the border between roughvib and a laboratory:

* :func:`read_record` reads one measured channel into a :class:`Record` (samples in m/s^2, the
  sample rate, where its units came from): CSV (a time column and value columns, units in the
  headers), WAV (16/24/32-bit integer or 32/64-bit float, scaled by a given m/s^2 per
  full-scale unit), the universal file format dataset 58 (time response, through pyuff) and
  NI TDMS (through the optional npTDMS package, ``pip install roughvib[tdms]``).
* :func:`export_run` writes the block and plate accelerations and the total normal contact
  force of a run as UFF 58 records, float32 WAV files (with the scale in the name and a JSON
  sidecar) or one CSV file.

Readers refuse, in one line naming the file, what cannot be a record: NaN samples, unknown
units, a non-uniform time column, a missing channel. Whether a record is long enough and fast
enough for a comparison with a run is decided where it is compared
(:mod:`roughvib.analysis.validation`).

Units: samples in m/s^2 (accelerations) or N (force), times in s, rates in Hz. Vertical
quantities are positive down, as in the run (docs/theory.md).
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["EXPORT_FORMATS", "EXPORT_SIGNALS", "G_N", "MAX_SAMPLE", "Record", "RecordError",
           "UNITS", "export_run", "read_record", "units_factor"]

#: standard acceleration of gravity [m/s^2] (the "g" of accelerometer data sheets)
G_N = 9.80665

#: accepted spellings of acceleration units (normalised, see :func:`units_factor`) -> m/s^2
UNITS: dict[str, float] = {
    "m/s2": 1.0, "ms-2": 1.0, "m/s/s": 1.0,
    "mm/s2": 1e-3, "mms-2": 1e-3,
    "cm/s2": 1e-2, "cms-2": 1e-2,
    "um/s2": 1e-6, "ums-2": 1e-6,
    "g": G_N, "gn": G_N, "g0": G_N,
    "mg": 1e-3 * G_N,
}

#: what ``export_run`` writes: short name -> (dataset variable, units, UFF node, label)
EXPORT_SIGNALS: dict[str, tuple[str, str, int, str]] = {
    "block_acceleration": ("block_vertical_acceleration", "m/s^2", 1, "block"),
    "plate_acceleration": ("plate_vertical_acceleration", "m/s^2", 2, "plate"),
    "normal_force": ("normal_force", "N", 3, "contact"),
}

EXPORT_FORMATS = ("uff", "wav", "csv")

_READERS = {".csv": "csv", ".txt": "csv", ".dat": "csv", ".tsv": "csv",
            ".wav": "wav", ".uff": "uff", ".unv": "uff", ".tdms": "tdms"}

# UFF dataset 58: function type 1 = time response; specific data types (record 8-11, field 1)
_UFF_TIME_RESPONSE = 1
_UFF_TYPE_UNKNOWN, _UFF_TYPE_GENERAL = 0, 1
_UFF_TYPE_ACCELERATION, _UFF_TYPE_EXCITATION_FORCE, _UFF_TYPE_TIME = 12, 13, 17
_UFF_DIR_MINUS_Z = -3  # "positive down" in a frame whose Z points up, out of the plate

# relative precision of the abscissa increment in an ASCII UFF 58 header (format %13.5e)
_UFF_INC_RTOL = 5e-6

#: the largest sample magnitude a record may hold [m/s^2]: 1e8 g, a thousand times the range of
#: shock accelerometers; samples of 1e300 (units or scale mistaken) overflowed the band levels
#: to NaN, which validate printed with exit status 0
MAX_SAMPLE = 1e9


class RecordError(ValueError):
    """A file that cannot be read as a record (one line naming the file)."""


@dataclass(frozen=True)
class Record:
    """One measured channel on a uniform time grid.

    Attributes
    ----------
    path : str
        The file it was read from.
    signal : ndarray, shape (n,)
        Samples [m/s^2], float64, finite.
    fs : float
        Sample rate [Hz], > 0.
    units : str
        The units the file (or the caller) gave the samples in, e.g. ``"g"``.
    units_from : str
        ``"file"`` (a header, a UFF label, a TDMS property, a WAV sidecar) or ``"option"``
        (the ``units``/``scale`` the caller gave).
    channel : str
        The column, channel or data set that was read.
    start_time : float
        Time of the first sample in the file's own time axis [s] (0 where it has none).
    """

    path: str
    signal: np.ndarray
    fs: float
    units: str
    units_from: str
    channel: str
    start_time: float = 0.0

    def __post_init__(self):
        if not (math.isfinite(self.fs) and self.fs > 0):
            raise RecordError(f"{self.path}: sample rate must be > 0 Hz, got {self.fs}")
        x = np.asarray(self.signal, dtype=float)
        if x.ndim != 1 or x.size < 2:
            raise RecordError(f"{self.path}: a record needs at least 2 samples in one "
                              f"channel, got shape {x.shape}")
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise RecordError(f"{self.path}: {bad.size} NaN or infinite samples in "
                              f"{self.channel} (first at sample {bad[0]}); a record must be "
                              f"finite")
        big = np.flatnonzero(np.abs(x) > MAX_SAMPLE)
        if big.size:
            raise RecordError(f"{self.path}: samples of {self.channel} must be at most "
                              f"{MAX_SAMPLE:g} m/s^2 in magnitude (1e8 g, far beyond any "
                              f"accelerometer; wrong units or scale?), got {x[big[0]]:.6g} "
                              f"m/s^2 at sample {big[0]} (units {self.units!r})")
        object.__setattr__(self, "signal", x)

    @property
    def duration(self) -> float:
        """Length ``n / fs`` [s]."""
        return self.signal.size / self.fs


# --------------------------------------------------------------------------------------------
# units
# --------------------------------------------------------------------------------------------

def _normalise_units(text: str) -> str:
    s = text.strip().lower().replace("²", "2").replace("µ", "u").replace("μ", "u")
    return re.sub(r"[\s^*·.]", "", s)


def units_factor(units: str, *, path: str | os.PathLike = "") -> float:
    """Factor from the given acceleration units to m/s^2.

    Parameters
    ----------
    units : str
        ``g``, ``m/s^2`` (also ``m/s2``, ``m s^-2``, ``m/s²``), ``mm/s^2``, ``cm/s^2``,
        ``um/s^2``, ``mg`` (milli-g); case, blanks, ``^``, ``*`` and ``·`` are ignored.
    path : path, optional
        The file the units belong to (named in the error).

    Returns
    -------
    float
        Multiply samples in ``units`` by this to get m/s^2 (``g``: 9.80665).

    Raises
    ------
    RecordError
        Unknown units (one line naming the file and the accepted units).
    """
    key = _normalise_units(units)
    if key not in UNITS:
        where = f"{path}: " if str(path) else ""
        raise RecordError(f"{where}unknown acceleration units {units!r}; accepted: g, mg, "
                          f"m/s^2, cm/s^2, mm/s^2, um/s^2")
    return UNITS[key]


def _units(found: str | None, given: str | None, path) -> tuple[float, str, str]:
    """Factor, units and their source: the file's units win; ``given`` where it has none."""
    if found:
        f = units_factor(found, path=path)
        if given and units_factor(given, path=path) != f:
            raise RecordError(f"{path}: the file gives the units {found!r}, --units says "
                              f"{given!r}; leave --units out or correct the file")
        return f, found, "file"
    if not given:
        raise RecordError(f"{path}: the file does not state its units; give them (--units "
                          f"g, m/s^2 or mm/s^2)")
    return units_factor(given, path=path), given, "option"


def _pick(names: list[str], column: str | int | None, path, what: str) -> int:
    """Index of the chosen channel among ``names`` (a name or a 1-based number)."""
    if column is None or str(column).strip() == "":
        if len(names) == 1:
            return 0
        raise RecordError(f"{path}: {len(names)} {what}s ({', '.join(names)}); choose one "
                          f"with --column NAME or NUMBER (counting from 1)")
    text = str(column).strip()
    if text.isdigit():
        i = int(text) - 1
        if not 0 <= i < len(names):
            raise RecordError(f"{path}: --column {text} is out of range: {len(names)} "
                              f"{what}s ({', '.join(names)})")
        return i
    hits = [i for i, n in enumerate(names) if n == text]
    if not hits:
        hits = [i for i, n in enumerate(names) if n.lower() == text.lower()]
    if len(hits) != 1:
        raise RecordError(f"{path}: no single {what} named {text!r} (there are: "
                          f"{', '.join(names)})")
    return hits[0]


def _rate_from_times(t: np.ndarray, path, resolution: float = 0.0) -> float:
    """Sample rate of a uniform time column [Hz] (refuses a non-uniform one)."""
    if t.size < 2 or not np.all(np.isfinite(t)):
        raise RecordError(f"{path}: the time column needs at least 2 finite values")
    dt = (t[-1] - t[0]) / (t.size - 1)
    if not dt > 0:
        raise RecordError(f"{path}: the time column does not increase")
    dev = float(np.max(np.abs(t - (t[0] + dt * np.arange(t.size)))))
    if dev > 0.25 * dt + resolution:
        raise RecordError(f"{path}: the time column is not uniformly sampled (a sample lies "
                          f"{dev:.3g} s off the grid of step {dt:.6g} s)")
    return 1.0 / dt


# --------------------------------------------------------------------------------------------
# readers
# --------------------------------------------------------------------------------------------

_HEADER_UNITS = re.compile(r"^\s*(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")
_TIME_UNITS = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6}


def _split_header(cell: str) -> tuple[str, str | None]:
    m = _HEADER_UNITS.match(cell)
    if m:
        return m.group(1), m.group(2)
    return cell.strip(), None


def _text(path: Path) -> str:
    """A text file's content: UTF-8, a leading byte-order mark dropped; one line otherwise."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise RecordError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise RecordError(f"{path}: a CSV record must be UTF-8 text (save it as UTF-8), got "
                          f"byte 0x{raw[exc.start]:02x} at byte {exc.start} on line {line}"
                          ) from None


def _numbers(df, i: int, name: str, path: Path, decimal: str) -> np.ndarray:
    """Column ``i`` as floats; the first cell that is not a number named with its data row."""
    import pandas as pd

    col = df.iloc[:, i]
    if decimal != "." and not pd.api.types.is_numeric_dtype(col):
        col = col.where(col.isna(), col.astype(str).str.replace(decimal, ".", regex=False))
    num = pd.to_numeric(col, errors="coerce")
    bad = np.flatnonzero(num.isna().to_numpy() & col.notna().to_numpy())
    if bad.size:
        raise RecordError(f"{path}: column {name!r} must hold numbers, got "
                          f"{str(col.iloc[bad[0]])[:40]!r} in data row {bad[0] + 1}")
    return num.to_numpy(dtype=float)


def _read_csv(path: Path, column, units) -> Record:
    import io

    import pandas as pd

    text = _text(path)
    lines: list[tuple[int, str]] = []  # (line number, text) of the first two data lines
    for i, line in enumerate(text.splitlines()):
        if line.strip() and not line.lstrip().startswith("#"):
            lines.append((i, line.strip()))
        if len(lines) >= 2:
            break
    if not lines:
        raise RecordError(f"{path}: no data in the file")
    sep = next((s for s in (";", "\t", ",") if s in lines[-1][1]), None)
    # semicolons with commas in the numbers: the decimal comma of European spreadsheets
    decimal = "," if sep in (";", "\t") and "," in lines[-1][1] else "."

    def cells(line: str) -> list[str]:
        if sep is not None:
            return [c.strip() for c in line.split(sep)]
        # blank-separated: a unit in brackets stays with its name ("t (ms)  a [g]")
        return re.findall(r"[^\s\[(]+(?:\s*[\[(][^\])]*[\])])?|[\[(][^\])]*[\])]", line)

    def numeric(line: str) -> bool:
        try:
            [float(c.replace(decimal, ".")) for c in cells(line)]
            return True
        except ValueError:
            return False

    header = None if numeric(lines[0][1]) else cells(lines[0][1])
    skip = lines[0][0] + 1 if header is not None else 0
    try:
        df = pd.read_csv(io.StringIO(text), sep=sep if sep is not None else r"\s+",
                         comment="#", header=None, skiprows=skip, skipinitialspace=True,
                         decimal=decimal)
    except (ValueError, pd.errors.ParserError) as exc:
        reason = " ".join(str(exc).split())  # pandas ends some messages with a newline
        raise RecordError(f"{path}: not a readable CSV table ({reason})") from None
    if header is not None and len(header) != df.shape[1]:
        raise RecordError(f"{path}: the header names {len(header)} columns, the data has "
                          f"{df.shape[1]}")
    if df.shape[1] < 2:
        raise RecordError(f"{path}: a CSV record needs a time column and a value column, "
                          f"found {df.shape[1]} column")
    cols = header if header is not None else [f"column {i + 1}" for i in range(df.shape[1])]
    names, col_units = zip(*(_split_header(c) for c in cols), strict=True)
    names, col_units = list(names), list(col_units)
    it = next((i for i, n in enumerate(names) if n.lower() in ("t", "time")), 0)
    values = [i for i in range(len(names)) if i != it]
    iv = values[_pick([names[i] for i in values], column, path, "value column")]
    t = _numbers(df, it, names[it], path, decimal)
    x = _numbers(df, iv, names[iv], path, decimal)
    tu = (col_units[it] or "s").strip().lower()
    if tu not in _TIME_UNITS:
        raise RecordError(f"{path}: unknown time units {col_units[it]!r} (s, ms or us)")
    t = t * _TIME_UNITS[tu]
    if np.any(np.isnan(x)):
        raise RecordError(f"{path}: {int(np.isnan(x).sum())} NaN samples (or empty cells) in "
                          f"column {names[iv]!r}; a record must be finite")
    fs = _rate_from_times(t, path)
    f, u, src = _units(col_units[iv], units, path)
    return Record(str(path), x * f, fs, u, src, names[iv], float(t[0]))


def _full_scale(data: np.ndarray) -> np.ndarray:
    """WAV samples as fractions of full scale (float data as it is)."""
    if data.dtype == np.uint8:
        return (data.astype(float) - 128.0) / 128.0
    if data.dtype == np.int16:
        return data.astype(float) / 32768.0
    if data.dtype == np.int32:  # 32-bit, and 24-bit (scipy left-justifies it in int32)
        return data.astype(float) / 2147483648.0
    if np.issubdtype(data.dtype, np.floating):
        return data.astype(float)
    raise RecordError(f"unsupported WAV sample type {data.dtype}")


def _sidecar(path: Path, *, needed: bool) -> dict:
    """The JSON sidecar ``<stem>.json`` of a WAV file (as :func:`export_run` writes it), its
    keys checked: ``scale`` (a number > 0, only where ``needed``), ``units`` (known units) and
    ``start_time_s`` (a finite number [s]).

    A JSON file without ``scale`` is not a sidecar and is ignored (empty dict); a sidecar
    that cannot be read is refused where it is ``needed`` (no ``--scale``) and ignored
    otherwise. Every refusal is one line naming the sidecar, the key, the rule and the value.
    """
    side = path.with_suffix(".json")
    if not side.is_file():
        return {}
    try:
        meta = json.loads(side.read_bytes().decode("utf-8-sig"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        if not needed:
            return {}
        reason = " ".join(str(getattr(exc, "strerror", None) or exc).split())
        raise RecordError(f"{side}: the sidecar of {path.name} must be a readable JSON file "
                          f"(UTF-8) with 'scale' and 'units', got {reason}") from None
    if not isinstance(meta, dict) or "scale" not in meta:
        return {}

    def number(key: str, rule: str, ok) -> float:
        v = meta[key]
        if isinstance(v, bool) or not isinstance(v, int | float) or not ok(float(v)):
            raise RecordError(f"{side}: sidecar key {key!r} must be {rule}, got {v!r}")
        return float(v)

    out = {"start_time_s": 0.0}
    if "start_time_s" in meta:
        out["start_time_s"] = number("start_time_s", "a finite number [s] (the time of the "
                                     "first sample)", math.isfinite)
    if not needed:
        return out
    units = meta.get("units", "")
    if not isinstance(units, str):
        raise RecordError(f"{side}: sidecar key 'units' must be a string (g, m/s^2, ...), got "
                          f"{units!r}")
    if units.strip():
        units_factor(units, path=f"{side}: sidecar key 'units'")
    out["units"] = units
    per = units.strip() or "the sidecar's 'units'"
    out["scale"] = number("scale", f"a number > 0 ({per} per full-scale unit)",
                          lambda v: math.isfinite(v) and v > 0)
    return out


def _wav_header(path: Path) -> None:
    """Refuse a WAV file shorter than its RIFF header says (a truncated file): scipy reads
    the samples that are there, or fails on a cut header with struct.error."""
    size = path.stat().st_size
    if size == 0:
        raise RecordError(f"{path}: not a readable WAV file (it is empty, 0 bytes)")
    with path.open("rb") as fh:
        head = fh.read(12)
    if head[:4] not in (b"RIFF", b"RIFX"):
        return  # RF64, or not a WAV file: scipy says which
    if len(head) < 12:
        raise RecordError(f"{path}: not a readable WAV file (it ends after {size} bytes, "
                          f"inside its 12-byte RIFF header: truncated?)")
    declared = int.from_bytes(head[4:8], "little" if head[:4] == b"RIFF" else "big") + 8
    if declared - 8 not in (0, 0xFFFFFFFF) and size < declared:
        raise RecordError(f"{path}: the WAV file is truncated: its header declares {declared} "
                          f"bytes, the file has {size}")


def _read_wav(path: Path, column, units, scale) -> Record:
    import struct
    import warnings

    from scipy.io import wavfile

    _wav_header(path)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", wavfile.WavFileWarning)  # unknown chunks
            fs, data = wavfile.read(path)
    except (ValueError, OSError, EOFError, struct.error) as exc:
        reason = (f"it ends inside a header chunk after {path.stat().st_size} bytes, "
                  f"truncated?" if isinstance(exc, struct.error | EOFError) else str(exc))
        raise RecordError(f"{path}: not a readable WAV file ({reason})") from None
    short = [str(w.message) for w in caught if "EOF" in str(w.message)]
    if short:  # a data chunk longer than the file
        raise RecordError(f"{path}: the WAV file is truncated ({short[0]})")
    try:
        frac = _full_scale(data)
    except RecordError as exc:
        raise RecordError(f"{path}: {exc}") from None
    if frac.ndim == 2:
        names = [f"channel {i + 1}" for i in range(frac.shape[1])]
        i = _pick(names, column, path, "channel")
        frac, name = frac[:, i], names[i]
    else:
        _pick(["channel 1"], column, path, "channel")
        name = "channel 1"
    meta = _sidecar(path, needed=scale is None)
    if scale is None:
        if not meta:
            raise RecordError(f"{path}: a WAV file needs --scale (m/s^2 per full-scale unit; "
                              f"or a JSON sidecar {path.with_suffix('.json').name} with "
                              f"'scale' and 'units')")
        scale = meta["scale"]
        f, u, src = _units(meta["units"], units, path)
    else:
        if not (math.isfinite(scale) and scale > 0):
            raise RecordError(f"{path}: --scale must be > 0 (per full-scale unit), got {scale}")
        f, u, src = units_factor(units or "m/s^2", path=path), units or "m/s^2", "option"
    return Record(str(path), frac * (float(scale) * f), float(fs), u, src, name,
                  meta.get("start_time_s", 0.0))


def _uff_name(d: dict, i: int) -> str:
    for key in ("id1", "rsp_ent_name"):
        v = str(d.get(key, "")).strip()
        if v and v.upper() != "NONE":
            return v
    return f"set {i + 1}"


def _uff58_sets(path: Path) -> list[dict]:
    """The datasets 58 of a universal file, read by pyuff one by one: a truncated file, a
    dataset pyuff cannot read, or one with fewer samples than it declares is refused in one
    line naming the dataset's lines (and the value that is not a number, where there is one).
    """
    import pyuff

    from roughvib.physics.structures.exchange import (
        universal_file_bad_value,
        universal_file_datasets,
    )

    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise RecordError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    blocks, unterminated = universal_file_datasets(raw)
    if unterminated is not None:
        start, typ, end = unterminated
        raise RecordError(f"{path}: the universal file is truncated: dataset "
                          f"{typ + ' ' if typ else ''}opened on line {start} never ends (every "
                          f"dataset must end with a line '    -1'), got the end of the file on "
                          f"line {end}")
    try:
        uff = pyuff.UFF(str(path))
        types = [int(t) for t in uff.get_set_types()]
    except Exception as exc:  # pyuff raises plain Exceptions on damaged files
        raise RecordError(f"{path}: not a readable universal file ({exc})") from None
    spans = blocks if len(blocks) == len(types) else [None] * len(types)
    sets = []
    for i, (t, span) in enumerate(zip(types, spans, strict=True)):
        if t != 58:
            continue
        if span is None:
            where = f"dataset 58 (the file's dataset {i + 1})"
        else:
            first, last, _ = span
            where = f"dataset 58 (lines {first}-{last})"
        try:
            d = uff.read_sets(i)
        except Exception as exc:  # pyuff says only "Error when reading data-set(s)."
            bad = universal_file_bad_value(raw, span) if span else ""
            raise RecordError(f"{path}: {where}, " + (bad or f"cannot be read ({exc})")
                              ) from None
        n = int(d.get("num_pts", 0) or 0)
        if n and np.asarray(d.get("data", [])).size != n:
            bad = universal_file_bad_value(raw, span) if span else ""
            raise RecordError(f"{path}: {where} declares {n} samples, pyuff read "
                              f"{np.asarray(d['data']).size}" + (f"; {bad}" if bad else ""))
        sets.append(d)
    return sets


def _read_uff(path: Path, column, units) -> Record:
    sets = _uff58_sets(path)
    cand = [d for d in sets if d.get("type") == 58 and d.get("func_type") == _UFF_TIME_RESPONSE]
    if not cand:
        raise RecordError(f"{path}: no dataset 58 with a time response (function type 1)")
    d = cand[_pick([_uff_name(d, i) for i, d in enumerate(cand)], column, path,
                   "dataset 58 time record")]
    x = np.asarray(d["data"])
    if np.iscomplexobj(x):
        raise RecordError(f"{path}: the dataset 58 {_uff_name(d, 0)!r} holds complex data, "
                          f"not a time record")
    x = x.astype(float)
    kind = int(d.get("ordinate_spec_data_type", 0) or 0)
    if kind not in (_UFF_TYPE_UNKNOWN, _UFF_TYPE_GENERAL, _UFF_TYPE_ACCELERATION):
        raise RecordError(f"{path}: the dataset 58 {_uff_name(d, 0)!r} is not an acceleration "
                          f"(specific data type {kind}, acceleration is 12)")
    if np.any(np.isnan(x)):
        raise RecordError(f"{path}: {int(np.isnan(x).sum())} NaN samples in "
                          f"{_uff_name(d, 0)!r}; a record must be finite")
    if d.get("abscissa_spacing") == 1 and float(d.get("abscissa_inc", 0)) > 0:
        fs = 1.0 / float(d["abscissa_inc"])
        # an ASCII header holds the increment to 6 digits: 1/96 kHz reads 95999.7 Hz
        if abs(fs - round(fs)) <= _UFF_INC_RTOL * fs:
            fs = float(round(fs))
        t0 = float(d.get("abscissa_min", 0.0))
    else:
        t = np.asarray(d["x"], dtype=float)
        fs, t0 = _rate_from_times(t, path), float(t[0])
    label = str(d.get("ordinate_axis_units_lab", "")).strip()
    found = None if label.upper() in ("", "NONE") else label
    f, u, src = _units(found, units, path)
    return Record(str(path), x * f, fs, u, src, _uff_name(d, 0), t0)


#: the lead-in of a TDMS segment: tag, table-of-contents mask, version, offsets [bytes]
_TDMS_LEAD_IN = 28
_TDMS_BIG_ENDIAN = 1 << 6  # the table-of-contents flag of a big-endian segment
_TDMS_UNCLOSED = 0xFFFFFFFFFFFFFFFF  # the next-segment offset of a segment never finished


def _tdms_segments(path: Path) -> None:
    """Walk the segments' lead-ins: a file that ends inside a segment, or whose last segment
    was never finished (the writer stopped), is refused; npTDMS reads what is there and only
    logs a warning."""
    size = path.stat().st_size
    pos = 0
    with path.open("rb") as fh:
        while pos < size:
            fh.seek(pos)
            lead = fh.read(_TDMS_LEAD_IN)
            if len(lead) < _TDMS_LEAD_IN or lead[:4] != b"TDSm":
                what = ("ends inside a segment's lead-in" if len(lead) < _TDMS_LEAD_IN
                        else "has no segment tag 'TDSm'")
                raise RecordError(f"{path}: not a complete TDMS file: at byte {pos} it {what} "
                                  f"(truncated or damaged; the file has {size} bytes)")
            toc = int.from_bytes(lead[4:8], "little")
            order = "big" if toc & _TDMS_BIG_ENDIAN else "little"
            nxt = int.from_bytes(lead[12:20], order)
            if nxt == _TDMS_UNCLOSED:
                raise RecordError(f"{path}: the TDMS file is truncated: the segment at byte "
                                  f"{pos} was never finished (the writer stopped)")
            end = pos + _TDMS_LEAD_IN + nxt
            if end > size:
                raise RecordError(f"{path}: the TDMS file is truncated or damaged: the segment "
                                  f"at byte {pos} declares {end - pos} bytes, the file ends "
                                  f"{size - pos} bytes after its start")
            pos = end


def _tdms_number(props, key: str, rule: str, ok, where: str, default=None) -> float:
    """A numeric channel property, checked (one line naming the channel, the property, the
    rule and the value)."""
    v = props.get(key, default)
    try:
        val = float(v)
    except (TypeError, ValueError):
        val = math.nan
    if isinstance(v, bool) or not ok(val):
        raise RecordError(f"{where}: property {key} must be {rule}, got {v!r}")
    return val


def _read_tdms(path: Path, column, units) -> Record:
    try:
        from nptdms import TdmsFile
    except ImportError:
        raise RecordError(f"{path}: reading TDMS needs the npTDMS package (pip install "
                          f"'roughvib[tdms]')") from None
    _tdms_segments(path)
    try:
        f = TdmsFile.read(path)
    except Exception as exc:  # npTDMS raises plain Exceptions on damaged files
        raise RecordError(f"{path}: not a readable TDMS file ({exc})") from None
    chans = [(g.name, c) for g in f.groups() for c in g.channels() if len(c) > 0]
    if not chans:
        raise RecordError(f"{path}: no channel with data")
    full = [f"{g}/{c.name}" for g, c in chans]
    short = [c.name for _, c in chans]
    text = None if column is None else str(column).strip()
    if text and not text.isdigit() and "/" not in text and short.count(text) == 1:
        i = short.index(text)
    else:
        i = _pick(full, column, path, "channel")
    ch = chans[i][1]
    props = ch.properties
    where = f"{path}: channel {full[i]!r}"
    if not props.get("wf_increment"):
        raise RecordError(f"{where} has no sample interval (property wf_increment)")
    inc = _tdms_number(props, "wf_increment", "a number > 0 [s] (the sample interval)",
                       lambda v: math.isfinite(v) and v > 0, where)
    t0 = _tdms_number(props, "wf_start_offset", "a finite number [s]", math.isfinite, where,
                      default=0.0)
    data = np.asarray(ch[:])
    if data.dtype.kind not in "iuf":
        raise RecordError(f"{where} must hold real numbers (a time record), got samples of "
                          f"type {data.dtype}")
    x = data.astype(float)
    if np.any(np.isnan(x)):
        raise RecordError(f"{path}: {int(np.isnan(x).sum())} NaN samples in {full[i]!r}; a "
                          f"record must be finite")
    found = str(props.get("unit_string", "") or "").strip() or None
    fac, u, src = _units(found, units, path)
    return Record(str(path), x * fac, 1.0 / inc, u, src, full[i], t0)


def read_record(path: str | os.PathLike, *, column: str | int | None = None,
                units: str | None = None, scale: float | None = None,
                kind: str | None = None) -> Record:
    """Read one measured acceleration channel.

    Parameters
    ----------
    path : path
        ``.csv``/``.txt``/``.tsv``/``.dat`` (a time column, named ``t`` or ``time`` or else
        the first, in s, ms or us, and value columns; comma, semicolon, tab or blank
        separated, a decimal comma with semicolons or tabs; ``#`` comments; headers like
        ``acceleration [g]`` or ``plate (m/s^2)`` give the units), ``.wav`` (integer samples
        as fractions of full scale, float samples as they are, times ``scale``),
        ``.uff``/``.unv`` (dataset 58, function type 1; units from the ordinate units label)
        or ``.tdms`` (a channel with ``wf_increment``; units from ``unit_string``).
    column : str or int, optional
        The value column (CSV), channel (WAV, TDMS: ``group/channel`` or the channel name) or
        dataset (UFF: its ID line 1 or response entity name): a name, or a number counting
        from 1 among the candidates. Needed only where there are several.
    units : str, optional
        Units of the samples where the file does not state them (see :func:`units_factor`);
        for a WAV file the units of ``scale`` (default m/s^2). A file's own units win; a
        different ``units`` is refused.
    scale : float, optional
        WAV only: acceleration per full-scale unit [``units``, default m/s^2], > 0. Without
        it, a JSON sidecar ``<stem>.json`` with ``scale`` and ``units`` (as
        :func:`export_run` writes) is used.
    kind : {'csv', 'wav', 'uff', 'tdms'}, optional
        The format, if the file name's extension does not say it.

    Returns
    -------
    Record
        Samples in m/s^2 on the file's grid.

    Raises
    ------
    RecordError
        One line naming the file: unreadable, unknown units, NaN samples, a non-uniform
        time column, an ambiguous or missing channel.
    """
    p = Path(path)
    if not p.is_file():
        raise RecordError(f"{p}: " + ("is a directory, not a record file" if p.is_dir() else
                                      "is not a regular file" if p.exists() else
                                      "no such file"))
    kind = kind or _READERS.get(p.suffix.lower())
    if kind not in ("csv", "wav", "uff", "tdms"):
        raise RecordError(f"{p}: unknown record format {p.suffix!r} (.csv, .txt, .wav, .uff, "
                          f".unv, .tdms)")
    if kind == "wav":
        return _read_wav(p, column, units, scale)
    if scale is not None:
        raise RecordError(f"{p}: --scale applies to WAV files only")
    return {"csv": _read_csv, "uff": _read_uff, "tdms": _read_tdms}[kind](p, column, units)


# --------------------------------------------------------------------------------------------
# export
# --------------------------------------------------------------------------------------------

def _power_of_ten_at_least(peak: float) -> float:
    """The smallest power of ten >= peak (1 for a silent signal)."""
    if not peak > 0:
        return 1.0
    k = math.ceil(math.log10(peak))
    scale = 10.0**k
    return scale if scale >= peak else 10.0 ** (k + 1)


def _scale_tag(scale: float, units: str) -> str:
    return f"{scale:g}{'ms2' if units == 'm/s^2' else units}_per_unit"


def export_run(run_dir: str | os.PathLike, fmt: str, *, out: str | os.PathLike | None = None,
               binary: bool = False, overwrite: bool = False) -> list[Path]:
    """Write a run's block and plate accelerations and normal force as exchange files.

    * ``uff``: one file ``<scene>.uff`` with three datasets 58 (function type 1, time
      response; even abscissa in s; nodes 1 block, 2 plate observation point, 3 contact;
      direction -3, i.e. positive along -Z with Z pointing up out of the plate: positive
      down; ordinate specific data type 12 acceleration in m/s^2, 13 force in N, with unit
      labels). ASCII by default (12 significant digits); ``binary=True`` writes pyuff's binary
      form (double precision), which some commercial readers do not take.
    * ``wav``: one float32 WAV per signal, ``<signal>_<scale><units>_per_unit.wav``: the
      samples divided by ``scale``, the smallest power of ten at or above the signal's peak,
      so they lie within ±1 full scale (``plate_acceleration_10ms2_per_unit.wav``: one
      full-scale unit is 10 m/s^2), and a JSON sidecar of the same stem with the units, the
      scale, the sample rate, the start time and the run id; :func:`read_record` takes the
      scale from it.
    * ``csv``: one file ``<scene>.csv`` with the columns ``time [s]``,
      ``block_acceleration [m/s^2]``, ``plate_acceleration [m/s^2]``, ``normal_force [N]``
      (12 significant digits).

    Each file appears complete or not at all (written under a temporary name and renamed).

    Parameters
    ----------
    run_dir : path
        A complete run (``roughvib run``).
    fmt : {'uff', 'wav', 'csv'}
        The format.
    out : path, optional
        Directory for the files (created; default ``run_dir/export``, roughvib's own folder
        in the run directory, whose files an export replaces).
    binary : bool
        UFF only: binary instead of ASCII dataset 58.
    overwrite : bool
        Replace files of the same names in ``out`` (without it they are refused).

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    RecordError
        An unknown format, ``binary`` with another format, or a run without a complete
        time series (a failed run).
    roughvib.rundir.OutputError
        ``out`` cannot be created or written, or holds a file of a name to write and
        ``overwrite`` is false (one line naming it).
    roughvib.rundir.WriteError
        A write failed (a full disk: the space needed and free).
    """
    from roughvib.results import load_result
    from roughvib.rundir import check_room, claim_files, output_folder

    if fmt not in EXPORT_FORMATS:
        raise RecordError(f"export format must be one of {', '.join(EXPORT_FORMATS)}, got "
                          f"{fmt!r}")
    if binary and fmt != "uff":
        raise RecordError("--binary applies to the UFF format only")
    result = load_result(run_dir)
    if not result.ok:
        raise RecordError(f"{run_dir}: the run did not complete (status {result.status}); "
                          f"there is no complete record to export")
    ds = result.dataset
    t = ds["time"].values
    if t.size < 2:
        raise RecordError(f"{run_dir}: the run has fewer than 2 output samples")
    dt = float(t[1] - t[0])
    meta = {"run_id": result.summary.get("run_id"), "scene": result.summary.get("scene"),
            "sample_rate_hz": 1.0 / dt, "start_time_s": float(t[0]), "samples": int(t.size),
            "vertical": "positive down"}
    signals = {name: np.asarray(ds[var].values, dtype=float)
               for name, (var, _, _, _) in EXPORT_SIGNALS.items()}
    folder = (output_folder(out, "--out") if out is not None
              else output_folder(Path(run_dir) / "export"))
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(meta["scene"] or "run"))
    single = folder / f"{stem}.{fmt}"  # the UFF or CSV file
    if fmt == "wav":
        scales = _wav_scales(signals, meta)
        targets = [folder / f"{_wav_stem(name, scales[name])}{ext}"
                   for name in signals for ext in (".wav", ".json")]
    else:
        targets = [single]
    claim_files(targets, overwrite=overwrite or out is None)
    if fmt == "csv":
        return [_export_csv(single, t, signals)]
    # bytes per sample and signal, at least: 4 (float32 WAV), 20 (ASCII UFF: E20.11, four to
    # a line) or 8 (binary UFF, float64)
    need = t.size * len(signals) * {"wav": 4, "uff": 8 if binary else 20}[fmt]
    check_room(folder, need, f"the {fmt.upper()} export")
    if fmt == "wav":
        return _export_wav(folder, signals, meta, scales)
    return [_export_uff(single, t, dt, signals, meta, binary, need)]


def _export_csv(path: Path, t: np.ndarray, signals: dict) -> Path:
    """The CSV file, made in memory first: its size is known before the disk is touched."""
    import io

    from roughvib.rundir import check_room, write_file

    cols = ["time [s]"] + [f"{n} [{EXPORT_SIGNALS[n][1]}]" for n in signals]
    buf = io.BytesIO()
    np.savetxt(buf, np.column_stack([t, *signals.values()]), fmt="%.12g", delimiter=",",
               header=",".join(cols), comments="")
    with buf.getbuffer() as view:
        check_room(path.parent, view.nbytes, "the CSV export")
        return write_file(path, lambda tmp: tmp.write_bytes(view), need=view.nbytes)


def _wav_scales(signals: dict, meta: dict) -> dict[str, float]:
    """The full scale of each signal's WAV file (the smallest power of ten at or above its
    peak); RecordError for a sample rate a WAV file cannot hold."""
    fs = meta["sample_rate_hz"]
    if abs(round(fs) - fs) > 1e-6 * fs:
        raise RecordError(f"a WAV file needs an integer sample rate; the run's is {fs} Hz")
    return {name: _power_of_ten_at_least(float(np.max(np.abs(x))))
            for name, x in signals.items()}


def _wav_stem(name: str, scale: float) -> str:
    """The stem of a signal's WAV file and sidecar: the signal and its full scale."""
    _, units, _, _ = EXPORT_SIGNALS[name]
    return f"{name}_{_scale_tag(scale, units)}"


def _export_wav(folder: Path, signals: dict, meta: dict, scales: dict) -> list[Path]:
    from scipy.io import wavfile

    from roughvib.rundir import write_file

    paths = []
    rate = int(round(meta["sample_rate_hz"]))
    for name, x in signals.items():
        variable, units, _, _ = EXPORT_SIGNALS[name]
        scale = scales[name]
        base = _wav_stem(name, scale)
        wav = folder / f"{base}.wav"
        write_file(wav, lambda tmp, x=x, scale=scale: wavfile.write(
            tmp, rate, (x / scale).astype(np.float32)), need=4 * x.size)
        side = {"signal": name, "variable": variable, "units": units,
                "scale": scale, "scale_meaning": f"{units} per full-scale unit (sample 1.0)",
                "sample_format": "float32", **meta}
        write_file(folder / f"{base}.json",
                   lambda tmp, side=side: tmp.write_text(json.dumps(side, indent=2)))
        paths += [wav, folder / f"{base}.json"]
    return paths


def _export_uff(path: Path, t: np.ndarray, dt: float, signals: dict, meta: dict,
                binary: bool, need: int) -> Path:
    import pyuff

    from roughvib._version import __version__
    from roughvib.rundir import write_file

    sets = []
    for name, x in signals.items():
        var, units, node, entity = EXPORT_SIGNALS[name]
        accel = units == "m/s^2"
        sets.append(pyuff.prepare_58(
            binary=1 if binary else 0,
            id1=name, id2=f"roughvib run {meta['run_id']} scene {meta['scene']}"[:80],
            id3=var, id4="vertical: positive down (response direction -Z, Z up)",
            id5=f"roughvib {__version__}",
            func_type=_UFF_TIME_RESPONSE, rsp_ent_name=entity, rsp_node=node,
            rsp_dir=_UFF_DIR_MINUS_Z, ref_ent_name="NONE", ref_node=0, ref_dir=0,
            abscissa_spacing=1, abscissa_spec_data_type=_UFF_TYPE_TIME,
            abscissa_axis_units_lab="s",
            ordinate_spec_data_type=(_UFF_TYPE_ACCELERATION if accel
                                     else _UFF_TYPE_EXCITATION_FORCE),
            ordinate_len_unit_exp=1 if accel else 0, ordinate_force_unit_exp=0 if accel else 1,
            ordinate_axis_units_lab=units, orddenom_spec_data_type=0, z_axis_spec_data_type=0,
            data=np.asarray(x, dtype=float), x=np.asarray(t, dtype=float)))
        sets[-1].update(abscissa_axis_lab="time", ordinate_axis_lab=entity + (
            " acceleration" if accel else " force"))

    def write(tmp):
        # every set appended to an empty file: pyuff's binary writer truncates the file after
        # a set's header when asked to overwrite
        tmp.write_bytes(b"")
        pyuff.UFF(str(tmp)).write_sets(sets, mode="add")
    return write_file(path, write, need=need)
