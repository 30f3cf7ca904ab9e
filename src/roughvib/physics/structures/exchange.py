"""The modes exchange format: read and write mass-normalised modes at nodes (docs/structures.md).

Two containers hold the same content:

* ``.npz`` (NumPy): ``frequency`` [Hz] (R,), ``nodes`` [m] (N, 2) with x, y in the plate's frame,
  ``shapes`` [1/sqrt(kg)] (R, N) the mass-normalised vertical displacement, optional
  ``damping_ratio`` [-] (R,).
* ``.unv`` / ``.uff`` (universal file format, through pyuff): dataset 2411 for the nodes (x, y
  in m; z ignored) and one dataset 55 per mode (analysis type 2, normal mode; the frequency,
  the modal viscous damping ratio, the modal mass, and the z component as the vertical
  displacement). Shapes with a modal mass m_r > 0 are divided by sqrt(m_r) (so unit-maximum
  shapes with their modal masses are read correctly); m_r = 0 means already mass-normalised.

Every check raises one line naming the file and the array.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from roughvib.physics.structures.base import check_frequencies
from roughvib.scene import SANE_BOUNDS, SceneError

__all__ = ["MAX_SHAPE", "ModeSet", "SUFFIXES", "read_modes", "universal_file_bad_value",
           "universal_file_datasets", "write_modes"]

#: the file suffixes the exchange format knows (lower case)
SUFFIXES = (".npz", ".unv", ".uff")

#: the largest mass-normalised displacement a mode may have [1/sqrt(kg)]: the peak 2 / sqrt(M)
#: of the lightest simply supported plate within the sane ranges of plate.density, thickness,
#: length and width (M = 1e-12 kg). Shapes 1e200 times too large passed every other check and
#: made the static equilibrium a singular matrix.
MAX_SHAPE = 2.0 / float(np.sqrt(np.prod([SANE_BOUNDS[f"plate.{k}"][0] for k in (
    "density", "thickness", "length", "width")])))


@dataclass(frozen=True)
class ModeSet:
    """Mass-normalised modes at scattered nodes, sorted by frequency.

    Attributes
    ----------
    frequency : ndarray, shape (R,)
        Natural frequencies [Hz], > 0, ascending.
    nodes : ndarray, shape (N, 2)
        Node coordinates (x, y) in the plate's frame [m].
    shapes : ndarray, shape (R, N)
        Mass-normalised vertical displacement of each mode at the nodes [1/sqrt(kg)].
    damping_ratio : ndarray, shape (R,), or None
        Modal viscous damping ratios [-] in [0, 1); None: not given.
    """

    frequency: np.ndarray
    nodes: np.ndarray
    shapes: np.ndarray
    damping_ratio: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.frequency.size)


def validated(frequency, nodes, shapes, damping_ratio=None, *, where: str) -> ModeSet:
    """Check the arrays of a mode set and sort it by frequency.

    Parameters
    ----------
    frequency, nodes, shapes, damping_ratio : array_like
        As in :class:`ModeSet`.
    where : str
        What the arrays come from, for the message (``"plate.modes_file 'x.npz'"``).

    Raises
    ------
    SceneError
        One line naming ``where``, the array, the rule and the value.
    """
    def arr(name, value, ndim, axes):
        if np.iscomplexobj(value):
            value = _real(np.asarray(value), f"{where}: {name}", axes)
        try:
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise SceneError(f"{where}: {name} must be an array of real numbers, got "
                             f"{np.asarray(value).dtype}") from None
        if a.ndim != ndim:
            raise SceneError(f"{where}: {name} must have {ndim} dimension(s), got shape "
                             f"{a.shape}")
        if not np.isfinite(a).all():
            raise SceneError(f"{where}: {name} must be finite, got {int((~np.isfinite(a)).sum())}"
                             f" non-finite value(s)")
        return a

    f = arr("frequency [Hz]", frequency, 1, ("mode",))
    xy = arr("nodes [m]", nodes, 2, ("node", "column"))
    S = arr("shapes [1/sqrt(kg)]", shapes, 2, ("mode", "node"))
    if xy.shape[1] != 2:
        raise SceneError(f"{where}: nodes [m] must have shape (N, 2) (x, y), got {xy.shape}")
    if xy.shape[0] < 3:
        raise SceneError(f"{where}: nodes [m] must hold at least 3 nodes, got {xy.shape[0]}")
    if np.linalg.matrix_rank(xy - xy.mean(axis=0), tol=1e-9 * float(np.ptp(xy))) < 2:
        raise SceneError(f"{where}: nodes [m] must span an area of the plate (not all on one "
                         f"line): interpolation needs nodes around every point")
    if f.size == 0:
        raise SceneError(f"{where}: frequency [Hz] must hold at least one mode, got none")
    if S.shape != (f.size, xy.shape[0]):
        raise SceneError(f"{where}: shapes [1/sqrt(kg)] must have shape (R, N) = "
                         f"({f.size}, {xy.shape[0]}) (modes, nodes), got {S.shape}")
    check_frequencies(f, f"{where}: frequency")
    z = None
    if damping_ratio is not None:
        z = arr("damping_ratio [-]", damping_ratio, 1, ("mode",))
        if z.shape != f.shape:
            raise SceneError(f"{where}: damping_ratio [-] must have shape ({f.size},) like "
                             f"frequency, got {z.shape}")
        bad = np.flatnonzero((z < 0) | (z >= 1))
        if bad.size:
            raise SceneError(f"{where}: damping_ratio [-] must be in [0, 1) (underdamped "
                             f"modes), got {z[bad[0]]} for mode {bad[0] + 1}")
    if not np.any(S):
        raise SceneError(f"{where}: shapes [1/sqrt(kg)] are all zero")
    peak = np.abs(S).max(axis=1)
    if peak.max() > MAX_SHAPE:
        r = int(np.argmax(peak > MAX_SHAPE))
        raise SceneError(f"{where}: shapes [1/sqrt(kg)] must be mass-normalised, at most "
                         f"{MAX_SHAPE:g} in magnitude (a modal mass of at least "
                         f"{4.0 / MAX_SHAPE**2:g} kg, the lightest plate within the sane "
                         f"ranges), got {peak[r]:.6g} for mode {r + 1}")
    order = np.argsort(f, kind="stable")
    return ModeSet(frequency=f[order], nodes=xy, shapes=S[order],
                   damping_ratio=None if z is None else z[order])


def _real(a: np.ndarray, where: str, axes: tuple[str, ...]) -> np.ndarray:
    """The real part of a complex array whose imaginary part is exactly zero; anything else is
    refused: the model takes real normal modes, and dropping an imaginary part (the complex
    modes of a non-proportionally damped structure) would change the structure silently.
    ``axes`` names the array's axes for the message (``("mode", "node")``)."""
    nonzero = np.argwhere(a.imag != 0)
    if nonzero.size:
        first = tuple(nonzero[0])
        at = ", ".join(f"{ax} {int(i) + 1}" for ax, i in zip(axes, first, strict=False))
        raise SceneError(f"{where} must be real numbers (real normal modes; realise complex "
                         f"modes before importing them), got {nonzero.shape[0]} value(s) with "
                         f"an imaginary part, the first {complex(a[first]):.6g} at {at}")
    return np.ascontiguousarray(a.real, dtype=float)


def _suffix(path: Path, what: str) -> str:
    suf = path.suffix.lower()
    if suf not in SUFFIXES:
        raise SceneError(f"{what} {str(path)!r} must end in one of {', '.join(SUFFIXES)}, got "
                         f"{suf or 'no suffix'!r}")
    return suf


def read_modes(path: str | Path, *, what: str = "plate.modes_file") -> ModeSet:
    """Read and check a modes file (``.npz``, ``.unv``, ``.uff``).

    Parameters
    ----------
    path : str or Path
    what : str
        The scene key or argument the path came from, for messages.

    Returns
    -------
    ModeSet
        Sorted by frequency.

    Raises
    ------
    SceneError
        Missing or unreadable file, unknown suffix, a missing or bad array (one line).
    """
    path = Path(path)
    suf = _suffix(path, what)
    where = f"{what} {str(path)!r}"
    if not path.is_file():
        raise SceneError(f"{where} does not exist (relative paths are relative to the scene "
                         f"file)")
    if suf == ".npz":
        arrays = _read_npz(path, where)
        missing = [k for k in ("frequency", "nodes", "shapes") if k not in arrays]
        if missing:
            raise SceneError(f"{where} must hold the arrays frequency [Hz], nodes [m], shapes "
                             f"[1/sqrt(kg)], missing {', '.join(missing)}")
        return validated(arrays["frequency"], arrays["nodes"], arrays["shapes"],
                         arrays.get("damping_ratio"), where=where)
    return _read_uff(path, where)


def _read_npz(path: Path, where: str) -> dict[str, np.ndarray]:
    """The arrays of a ``.npz`` file; an empty, truncated or damaged file in one line."""
    import zipfile
    import zlib

    size = path.stat().st_size
    rule = "a .npz file (a zip archive of arrays, as numpy.savez writes)"
    if size == 0:
        raise SceneError(f"{where} must be {rule}, got an empty file (0 bytes)")
    if not zipfile.is_zipfile(path):
        raise SceneError(f"{where} must be {rule}, got {size} bytes that are not a complete zip "
                         f"archive (truncated, or another format?)")
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError, AttributeError, zipfile.BadZipFile,
            zlib.error) as exc:
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise SceneError(f"{where} is not a readable .npz file (damaged or truncated?): "
                         f"{reason}") from None


#: the line that opens and closes a dataset of a universal file
_UFF_DELIMITER = b"    -1"
#: text records at the head of a dataset (after its type line), skipped when looking for a
#: value that is not a number: dataset 55's five ID lines, dataset 58's records 1 to 11
_UFF_TEXT_RECORDS = {"55": 5, "58": 11}


def universal_file_datasets(raw: bytes) -> tuple[list[tuple[int, int, str]],
                                                 tuple[int, str, int] | None]:
    """The datasets of a universal file, found by their delimiter lines as pyuff finds them.

    Parameters
    ----------
    raw : bytes
        The file's content.

    Returns
    -------
    datasets : list of (int, int, str)
        Each complete dataset as (first line, last line, type), its two delimiter lines
        included; lines count from 1.
    unterminated : (int, str, int) or None
        A last dataset without its closing delimiter (a truncated file; pyuff drops it
        without a word) as (its opening line, its type or "", the file's last line).
    """
    # pyuff's rule: the tag anywhere, then a line end, the file's end or blanks to column 80
    # (a binary dataset's closing tag follows its data on the same line)
    delims: list[tuple[int, int]] = []  # (line, byte offset)
    line, counted = 1, 0
    at = raw.find(_UFF_DELIMITER)
    while at >= 0:
        after = raw[at + 6:at + 80]
        if after[:1] in (b"", b"\n", b"\r") or after == b" " * 74:
            line += raw.count(b"\n", counted, at)
            counted = at
            delims.append((line, at))
        at = raw.find(_UFF_DELIMITER, at + 1)

    def kind(offset: int) -> str:
        """The type of the dataset opened by the tag at ``offset`` (first word of the next
        line)."""
        nl = raw.find(b"\n", offset)
        head = raw[nl + 1:nl + 81].split(b"\n", 1)[0] if nl >= 0 else b""
        words = head.decode("ascii", "replace").split()
        return words[0] if words else ""

    blocks = [(first, last, kind(opened)) for (first, opened), (last, _)
              in zip(delims[::2], delims[1::2], strict=False)]
    if len(delims) % 2 == 0:
        return blocks, None
    line, opened = delims[-1]
    end = raw.count(b"\n") + (0 if raw.endswith(b"\n") else 1)
    return blocks, (line, kind(opened), end)


def universal_file_bad_value(raw: bytes, dataset: tuple[int, int, str]) -> str:
    """Where an ASCII dataset of a universal file holds a value that is not a finite number.

    Parameters
    ----------
    raw : bytes
        The file's content.
    dataset : (int, int, str)
        One of :func:`universal_file_datasets`.

    Returns
    -------
    str
        ``"line L: every value must be a (finite) number, got 'x'"``, or ``""`` where every
        value after the dataset's text records is a finite number.
    """
    first, last, typ = dataset
    lines = raw.split(b"\n")[first:last - 1]  # between the delimiters, the type line first
    skip = 1 + _UFF_TEXT_RECORDS.get(typ, 0)
    for k, line in enumerate(lines[skip:], start=first + 1 + skip):
        for tok in line.decode("ascii", "replace").split():
            try:
                val = float(tok.replace("D", "E").replace("d", "e"))
            except ValueError:
                return f"line {k}: every value must be a number, got {tok!r}"
            if not np.isfinite(val):
                return f"line {k}: every value must be a finite number, got {tok!r}"
    return ""


def _uff_blocks(raw: bytes, where: str) -> list[tuple[int, int, str]]:
    """:func:`universal_file_datasets`, a truncated file refused in one line."""
    blocks, unterminated = universal_file_datasets(raw)
    if unterminated is not None:
        start, typ, end = unterminated
        raise SceneError(f"{where} is truncated: dataset {typ + ' ' if typ else ''}opened on "
                         f"line {start} never ends (every dataset must end with a line "
                         f"'    -1'), got the end of the file on line {end}")
    return blocks


def _uff_sets(path: Path, where: str) -> list[dict]:
    """The datasets 2411 and 55 of a universal file, read by pyuff; a truncated file, or a
    dataset pyuff cannot read, refused in one line naming the dataset's lines."""
    import pyuff

    raw = path.read_bytes()
    blocks = _uff_blocks(raw, where)
    try:
        uff = pyuff.UFF(str(path))
        types = [int(t) for t in uff.get_set_types()]
    except Exception as exc:  # pyuff raises many kinds on a malformed file
        raise SceneError(f"{where} is not a readable universal file: {exc}") from None
    sets = []
    for i, t in enumerate(types):
        if t not in (2411, 55):
            continue
        try:
            sets.append(uff.read_sets(i))
        except Exception as exc:  # pyuff says only "Error when reading data-set(s)."
            if len(blocks) != len(types):
                raise SceneError(f"{where}: dataset {t} (the file's dataset {i + 1}) cannot be "
                                 f"read: {exc}") from None
            a, b, _ = blocks[i]
            bad = universal_file_bad_value(raw, blocks[i])
            raise SceneError(f"{where}: dataset {t} (lines {a}-{b}), "
                             + (bad if bad else f"cannot be read (its records do not follow "
                                                f"the universal file format: {exc})")) from None
    return sets


def _read_uff(path: Path, where: str) -> ModeSet:
    sets = _uff_sets(path, where)
    nodes = [s for s in sets if s.get("type") == 2411]
    modes = [s for s in sets if s.get("type") == 55 and s.get("analysis_type") == 2]
    if not nodes:
        raise SceneError(f"{where} must hold a dataset 2411 (nodes), got none")
    if not modes:
        raise SceneError(f"{where} must hold datasets 55 of analysis type 2 (normal modes), "
                         f"got none")
    num = np.concatenate([np.asarray(s["node_nums"], dtype=np.int64) for s in nodes])
    xy = np.column_stack([np.concatenate([np.asarray(s["x"], dtype=float) for s in nodes]),
                          np.concatenate([np.asarray(s["y"], dtype=float) for s in nodes])])
    pos = {int(n): i for i, n in enumerate(num)}
    freq, damp, shapes = [], [], []
    for j, s in enumerate(modes):
        comp = "r3" if "r3" in s else "r1"
        mode = f"dataset 55 #{j + 1} (mode {s.get('mode_n')})"
        vals = np.asarray(s[comp])
        vals = _real(vals, f"{where}: {mode} shapes", ("value",)) if np.iscomplexobj(vals) else \
            vals.astype(float)
        nn = np.asarray(s["node_nums"], dtype=np.int64)
        if not np.isfinite(vals).all():
            k = int(np.flatnonzero(~np.isfinite(vals))[0])
            raise SceneError(f"{where}: {mode} must give a finite number at every node, got "
                             f"{vals[k]} at node {int(nn[k])}")
        unknown = [int(n) for n in nn if int(n) not in pos]
        if unknown:
            raise SceneError(f"{where}: {mode} names node {unknown[0]}, which no dataset 2411 "
                             f"defines")
        row = np.full(xy.shape[0], np.nan)
        row[[pos[int(n)] for n in nn]] = vals
        mm = float(s.get("modal_m", 0.0) or 0.0)
        if mm < 0:
            raise SceneError(f"{where}: dataset 55 #{j + 1} modal mass must be >= 0 kg (0: "
                             f"mass-normalised), got {mm}")
        shapes.append(row / np.sqrt(mm) if mm > 0 else row)
        freq.append(float(s["freq"]))
        damp.append(float(s.get("modal_damp_vis", 0.0) or 0.0))
    S = np.array(shapes)
    if np.isnan(S).any():
        raise SceneError(f"{where}: every dataset 55 must give a value at every node of "
                         f"dataset 2411, {int(np.isnan(S).any(axis=0).sum())} node(s) lack one")
    z = np.array(damp)
    return validated(np.array(freq), xy, S, z if np.any(z) else None, where=where)


def write_modes(path: str | Path, modes: ModeSet) -> Path:
    """Write a mode set to ``path``; the format follows the suffix (``.npz``, ``.unv``,
    ``.uff``).

    The universal file's dataset 55 stores numbers with 6 significant digits (format E13.5:
    a frequency to 5e-6 relative, a shape to 5e-6 of its value); ``.npz`` stores them exactly.

    Parameters
    ----------
    path : str or Path
    modes : ModeSet

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    suf = _suffix(path, "output file")
    if suf == ".npz":
        arrays = {"frequency": modes.frequency, "nodes": modes.nodes, "shapes": modes.shapes}
        if modes.damping_ratio is not None:
            arrays["damping_ratio"] = modes.damping_ratio
        with open(path, "wb") as fh:
            np.savez(fh, **arrays)
        return path
    import pyuff

    if path.exists():
        path.unlink()  # pyuff appends to an existing file
    uff = pyuff.UFF(str(path))
    num = np.arange(1, modes.nodes.shape[0] + 1)
    node_x, node_y = modes.nodes.T
    sets = [pyuff.prepare_2411(node_nums=num, def_cs=np.ones(num.size, dtype=int),
                               disp_cs=np.ones(num.size, dtype=int),
                               color=np.ones(num.size, dtype=int), x=node_x, y=node_y,
                               z=np.zeros(num.size), return_full_dict=True)]
    zeta = (modes.damping_ratio if modes.damping_ratio is not None
            else np.zeros(len(modes)))
    for r in range(len(modes)):
        zero = np.zeros(num.size)
        sets.append(pyuff.prepare_55(
            id1="roughvib modes", id2="NONE", id3="NONE", id4="NONE", id5="NONE",
            model_type=1, analysis_type=2, data_ch=2, spec_data_type=8, data_type=2,
            n_data_per_node=3, r1=zero, r2=zero, r3=modes.shapes[r], node_nums=num,
            load_case=1, mode_n=r + 1, freq=float(modes.frequency[r]), modal_m=0.0,
            modal_damp_vis=float(zeta[r]), modal_damp_his=0.0))
    uff.write_sets(sets, mode="add")
    return path
