"""Measured profiles: plain-text files and instrument files, read into SI units and checked
(one-line refusals naming the file, the line, the rule and the value).
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from roughvib.scene import SANE_BOUNDS, Block, Roughness, SceneError

__all__ = ["PAPER_SPACING", "MeasuredProfile", "read_measured", "read_profile_file"]

_UNITS = {"m": 1.0, "um": 1e-6, "nm": 1e-9}
#: the paper's profile grid [m]: the grid of the kinds sampled on a plain grid when
#: ``roughness.spacing`` is "auto" (and of a one-column file, see read_profile_file)
PAPER_SPACING = 10e-6
# x steps of a two-column file may deviate this much from the mean spacing (printing x with
# six significant digits already costs a few per mille at 0.16 m / 10 um)
_X_STEP_RTOL = 0.01


@dataclass(frozen=True)
class MeasuredProfile:
    """A profile file as read, in SI units.

    Attributes
    ----------
    z : ndarray, shape (n,) or (n, m)
        Heights [m]; 2-D for a matrix of m parallel traces (one column per trace).
    dx : float
        Spacing [m] (from the x column, else ``roughness.spacing``).
    y : ndarray, shape (m,) or None
        Trace positions [m] from a ``# y:`` header line, None if not given (or one trace).
    layout : {"heights", "x-z", "traces"}
    path : Path
    last_line : int
        Line number of the last data line (1-based).
    sha256 : str
        SHA-256 of the file's bytes as read (a resumed run checks the file is unchanged).
    """

    z: np.ndarray
    dx: float
    y: np.ndarray | None
    layout: str
    path: Path
    last_line: int
    sha256: str = ""


_Y_HEADER = re.compile(r"^\s*#\s*y\s*:\s*(.*)$", re.IGNORECASE)


def _tokens(text: str) -> list[str]:
    return text.replace(",", " ").replace(";", " ").split()


def _float(tok: str) -> float | None:
    try:
        return float(tok)
    except ValueError:
        return None


#: the sampling step a measured roughness profile may have [m]: at least the lowest
#: roughness.spacing, at most 1 mm, 200 times the coarsest step of a standard roughness
#: measurement (ISO 3274: 5 um for the longest cut-off, 8 mm); coarser, the profile resolves
#: only wavelengths above 2 mm (waviness). A trace in um read as m has steps of metres.
FILE_SPACING = (SANE_BOUNDS["roughness.spacing"][0], 1e-3)
#: the largest rms height of a measured profile about its mean line [m], the sane range of
#: roughness.rms (form deviation of a curved sample included, which the filter removes)
_, FILE_RMS, _ = SANE_BOUNDS["roughness.rms"]


def _check_scale(z: np.ndarray, dx: float | None, where: str, units: str | None) -> None:
    """Refuse a measured profile whose sampling step (``dx``, where the file gives it) or rms
    height about its least-squares line is absurd for a rough surface, naming the units that
    would make it plausible (the likely mistake)."""
    zz = z.reshape(z.shape[0], -1)
    s = np.linspace(-1.0, 1.0, zz.shape[0]) if zz.shape[0] > 1 else np.zeros(1)
    # each trace about its least-squares line (s has zero mean: the line is mean + b s)
    resid = zz - zz.mean(axis=0) - np.outer(s, (s @ zz) / max(float(s @ s), 1.0))
    rms = float(np.sqrt(np.mean(resid**2, axis=0)).max())
    lo, hi = FILE_SPACING

    def fits(f: float) -> bool:
        return (dx is None or lo <= dx * f <= hi) and rms * f <= FILE_RMS

    if fits(1.0):
        return
    hint = "check the file's own units" if units is None else next(
        (f"are the file's x and heights in {u} (roughness.units = {u!r})?"
         for u, f in _UNITS.items()
         if u != units and fits(f / _UNITS[units])), "check roughness.units")
    if dx is not None and not lo <= dx <= hi:
        raise SceneError(f"{where}: the sampling step must be in [{lo:g}, {hi:g}] m for a "
                         f"roughness profile, got {dx:.6g} m; {hint}")
    raise SceneError(f"{where}: the rms height about the mean line must be at most "
                     f"{FILE_RMS:g} m for a roughness profile, got {rms:.6g} m; {hint}")


def read_profile_file(path: str | Path, units: str = "m", spacing: float = 10e-6, *,
                      base_dir: str | Path = ".", min_length: float | None = None,
                      min_length_reason: str = "") -> MeasuredProfile:
    """Read a measured profile from a text/CSV file.

    Format: one row per section along the sliding direction; values separated by commas,
    semicolons or whitespace; ``#`` starts a comment; a first non-comment line of names
    (``x, z``) is skipped. Columns:

    * one: heights at ``spacing``;
    * two: x and z (x increasing, uniform within 1 %; the spacing is the mean step);
    * three or more: a matrix of parallel traces at ``spacing``, one column per trace.
      A comment line ``# y: y1 y2 ...`` (file units) gives the trace positions across the
      width; with it, a file with one more column than positions has an x column first.
      Without it, the traces are taken as equally spaced across the block width.

    Parameters
    ----------
    path : str or Path
        The file; relative paths are relative to ``base_dir``.
    units : {"m", "um", "nm"}
        Unit of heights, x and y in the file.
    spacing : float
        Section spacing when there is no x column [m].
    base_dir : str or Path
        Directory relative paths are resolved against.
    min_length : float, optional
        Required covered length (n - 1) dx [m].
    min_length_reason : str
        What ``min_length`` is made of, for the error message.

    Returns
    -------
    MeasuredProfile

    Raises
    ------
    SceneError
        Unreadable file; non-numeric, NaN or infinite value; inconsistent column count;
        non-uniform or non-increasing x; too few points. The message names the file, the line
        and the problem.
    """
    p = Path(path)
    if not p.is_absolute():
        p = Path(base_dir) / p
    where = f"roughness.path {p}"
    raw, text = _read_text(p, path, where)
    scale = _UNITS[units]
    rows, lines, y_hdr = _data_rows(text, where, units)
    x, z, y, layout = _columns(np.array(rows, dtype=float) * scale, y_hdr, where, scale)
    dx = spacing if x is None else _x_spacing(x, lines, where, scale, units)
    _check_scale(z, dx if x is not None else None, f"{where} (units = {units!r})", units)
    n = z.shape[0]
    if min_length is not None and (n - 1) * dx < min_length:
        why = f" ({min_length_reason})" if min_length_reason else ""
        raise SceneError(f"{where} line {lines[-1]}: too few points for the stroke plus the "
                         f"block length: need a length >= {min_length:.6g} m{why}, got {n} "
                         f"points x {dx:.6g} m = {(n - 1) * dx:.6g} m")
    return MeasuredProfile(z=z, dx=float(dx), y=y, layout=layout, path=p,
                           last_line=lines[-1], sha256=hashlib.sha256(raw).hexdigest())


def _read_text(p: Path, path: str | Path, where: str) -> tuple[bytes, str]:
    """The file's bytes and its text (UTF-8, a leading byte-order mark dropped); ``path`` as
    given, for the message.

    Raises
    ------
    SceneError
        The file cannot be read, or is not UTF-8 (naming the line of the first bad byte).
    """
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise SceneError(f"{where} cannot be read: {exc.strerror}, got path "
                         f"{str(path)!r}") from None
    try:  # UTF-8 (ASCII included); a leading byte-order mark is dropped, not read as data
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise SceneError(f"{where} line {line}: the file must be UTF-8 text (a binary file, or "
                         f"another encoding?), got byte 0x{raw[exc.start]:02x}") from None
    return raw, text


def _data_rows(text: str, where: str, units: str
               ) -> tuple[list[list[float]], list[int], tuple[int, list[float]] | None]:
    """The numeric rows of a profile file (in file units), the line number of each (1-based)
    and the ``# y:`` header (its line and trace positions in file units) if there is one.

    Comments and blank lines are skipped, and a first line of column names.

    Raises
    ------
    SceneError
        A bad ``# y:`` line, a value that is not a number or not finite, a row with another
        number of columns than the first, or no data line at all.
    """
    rows: list[list[float]] = []
    lines: list[int] = []
    y_hdr: tuple[int, list[float]] | None = None
    header_seen = False
    for i, line in enumerate(text.splitlines(), start=1):
        m = _Y_HEADER.match(line)
        if m and y_hdr is None:
            vals = [_float(t) for t in _tokens(m.group(1))]
            if not vals or any(v is None or not math.isfinite(v) for v in vals):
                raise SceneError(f"{where} line {i}: '# y:' must list finite trace positions "
                                 f"[{units}], got {m.group(1).strip()!r}")
            y_hdr = (i, [float(v) for v in vals])
            continue
        body = line.split("#", 1)[0].strip()
        if not body:
            continue
        toks = _tokens(body)
        vals = [_float(t) for t in toks]
        if any(v is None for v in vals):
            if not rows and not header_seen and all(v is None for v in vals):
                header_seen = True  # a line of column names
                continue
            bad = toks[[v is None for v in vals].index(True)]
            raise SceneError(f"{where} line {i}: every value must be a number, got {bad!r}")
        if any(not math.isfinite(v) for v in vals):
            raise SceneError(f"{where} line {i}: NaN or infinite values are not allowed, got "
                             f"{body!r}")
        if rows and len(vals) != len(rows[0]):
            raise SceneError(f"{where} line {i}: every row must have {len(rows[0])} columns "
                             f"like line {lines[0]}, got {len(vals)}")
        rows.append(vals)  # type: ignore[arg-type]
        lines.append(i)
    if not rows:
        raise SceneError(f"{where} holds no data lines (only comments or blank lines), got "
                         f"{len(text.splitlines())} lines")
    return rows, lines, y_hdr


def _columns(data: np.ndarray, y_hdr: tuple[int, list[float]] | None, where: str,
             scale: float) -> tuple[np.ndarray | None, np.ndarray, np.ndarray | None, str]:
    """Split the data (rows x columns, [m]) into the x column, the heights and the trace
    positions, by the column count and the ``# y:`` header (positions in file units, times
    ``scale`` to m).

    Returns
    -------
    x : ndarray, shape (n,), or None
        The x column [m], None without one.
    z : ndarray, shape (n,) or (n, m)
        Heights [m].
    y : ndarray, shape (m,), or None
        Trace positions [m].
    layout : {"heights", "x-z", "traces"}

    Raises
    ------
    SceneError
        A column count that does not fit the header, or positions that do not increase.
    """
    ncol = data.shape[1]
    y = None
    x = None
    if y_hdr is not None:
        hline, yv = y_hdr
        if ncol == len(yv) + 1:
            x, traces = data[:, 0], data[:, 1:]
        elif ncol == len(yv):
            traces = data
        else:
            raise SceneError(f"{where} line {hline}: '# y:' lists {len(yv)} trace positions, so "
                             f"rows need {len(yv)} (or {len(yv) + 1} with x) columns, got "
                             f"{ncol}")
        y = np.asarray(yv) * scale
        if np.any(np.diff(y) <= 0):
            raise SceneError(f"{where} line {hline}: trace positions must increase strictly, "
                             f"got {yv}")
        layout = "traces"
        z = traces if traces.shape[1] > 1 else traces[:, 0]
        if z.ndim == 1:
            layout, y = "heights", None
    elif ncol == 1:
        z, layout = data[:, 0], "heights"
    elif ncol == 2:
        x, z, layout = data[:, 0], data[:, 1], "x-z"
    else:
        z, layout = data, "traces"
    return x, z, y, layout


def _x_spacing(x: np.ndarray, lines: list[int], where: str, scale: float, units: str
               ) -> float:
    """The spacing of an x column [m]: its mean step, checked increasing and uniform within
    :data:`_X_STEP_RTOL` (``lines``: the data rows' line numbers, for the message).

    Raises
    ------
    SceneError
        Fewer than two rows, x not increasing, or a step off the mean spacing.
    """
    if x.size < 2:
        raise SceneError(f"{where} line {lines[-1]}: an x column needs at least two rows "
                         f"to give the spacing, got {x.size}")
    steps = np.diff(x)
    dx = float((x[-1] - x[0]) / (x.size - 1))
    if dx <= 0:
        raise SceneError(f"{where} line {lines[1]}: x must increase, got x = "
                         f"{x[0] / scale:g} then {x[1] / scale:g} {units}")
    dev = np.abs(steps - dx)
    j = int(np.argmax(dev))
    if dev[j] > _X_STEP_RTOL * dx:
        raise SceneError(f"{where} line {lines[j + 1]}: x must be uniformly spaced (within "
                         f"{_X_STEP_RTOL:.0%} of the mean spacing {dx / scale:.6g} "
                         f"{units}; resample non-uniform data), got a step of "
                         f"{steps[j] / scale:.6g} {units}")
    return dx


def read_measured(roughness: Roughness, block: Block, base_dir: str | Path = ".", *,
                  min_length: float | None = None,
                  min_length_reason: str = "") -> MeasuredProfile:
    """Read the measured profile of a ``roughness.kind = "file"`` scene, text or instrument.

    Plain text goes to :func:`read_profile_file`; instrument formats (``roughness.format``,
    or by suffix for ``"auto"``) are read through SurfaceTopography
    (:func:`roughvib.physics.surface.topography.read_topography_map`): the file's x axis is
    the sliding direction, its units and pixel sizes are used, and of a map wider than the
    block only the traces within ``block.width`` about the map's centre line are kept (the
    block averages only over its own width). A map becomes a trace matrix with its y
    positions, exactly like a text file with a ``# y:`` line.

    Parameters
    ----------
    roughness : Roughness
        ``path``, ``format``, ``units`` and ``spacing`` (text only).
    block : Block
        Width (crop of a map).
    base_dir, min_length, min_length_reason
        As for :func:`read_profile_file`.

    Returns
    -------
    MeasuredProfile
        ``layout`` "map" for an instrument map (one trace: "heights"); ``last_line`` 0.

    Raises
    ------
    SceneError
        As the readers; a file too short for ``min_length``.
    """
    from roughvib.physics.surface.topography import read_topography_map, uses_topography

    r = roughness
    if not uses_topography(r.path, r.format, base_dir=base_dir):
        spacing = PAPER_SPACING if isinstance(r.spacing, str) else r.spacing
        return read_profile_file(r.path, r.units, spacing, base_dir=base_dir,
                                 min_length=min_length, min_length_reason=min_length_reason)
    p = Path(r.path) if Path(r.path).is_absolute() else Path(base_dir) / r.path
    tm = read_topography_map(r.path, base_dir=base_dir)
    z, y = tm.z, None
    if z.ndim == 2:
        y_all = (np.arange(z.shape[1]) - (z.shape[1] - 1) / 2.0) * tm.dy
        # a trace on the block's edge stays: files may store pixel sizes in float32 (netCDF
        # from SurfaceTopography does), 6e-8 relative, so the edge is matched to 1e-6
        keep = np.abs(y_all) <= block.width / 2.0 * (1.0 + 1e-6)
        z, y = z[:, keep], y_all[keep]
        if z.shape[1] == 1:
            z, y = z[:, 0], None
    _check_scale(z, float(tm.dx), f"roughness.path {p}", None)
    n = z.shape[0]
    if min_length is not None and (n - 1) * tm.dx < min_length:
        why = f" ({min_length_reason})" if min_length_reason else ""
        raise SceneError(f"roughness.path {p}: too few points along x (the sliding direction) "
                         f"for the stroke plus the block length: need a length >= "
                         f"{min_length:.6g} m{why}, got {n} points x {tm.dx:.6g} m = "
                         f"{(n - 1) * tm.dx:.6g} m")
    return MeasuredProfile(z=z, dx=float(tm.dx), y=y, layout="map" if z.ndim == 2 else "heights",
                           path=p, last_line=0)


