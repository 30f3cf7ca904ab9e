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
from roughvib.scene import SceneError

__all__ = ["ModeSet", "SUFFIXES", "read_modes", "write_modes"]

#: the file suffixes the exchange format knows (lower case)
SUFFIXES = (".npz", ".unv", ".uff")


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
    def arr(name, value, ndim):
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

    f = arr("frequency [Hz]", frequency, 1)
    xy = arr("nodes [m]", nodes, 2)
    S = arr("shapes [1/sqrt(kg)]", shapes, 2)
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
        z = arr("damping_ratio [-]", damping_ratio, 1)
        if z.shape != f.shape:
            raise SceneError(f"{where}: damping_ratio [-] must have shape ({f.size},) like "
                             f"frequency, got {z.shape}")
        bad = np.flatnonzero((z < 0) | (z >= 1))
        if bad.size:
            raise SceneError(f"{where}: damping_ratio [-] must be in [0, 1) (underdamped "
                             f"modes), got {z[bad[0]]} for mode {bad[0] + 1}")
    if not np.any(S):
        raise SceneError(f"{where}: shapes [1/sqrt(kg)] are all zero")
    order = np.argsort(f, kind="stable")
    return ModeSet(frequency=f[order], nodes=xy, shapes=S[order],
                   damping_ratio=None if z is None else z[order])


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
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
        except (OSError, ValueError) as exc:
            raise SceneError(f"{where} is not a readable .npz file: {exc}") from None
        missing = [k for k in ("frequency", "nodes", "shapes") if k not in arrays]
        if missing:
            raise SceneError(f"{where} must hold the arrays frequency [Hz], nodes [m], shapes "
                             f"[1/sqrt(kg)], missing {', '.join(missing)}")
        return validated(arrays["frequency"], arrays["nodes"], arrays["shapes"],
                         arrays.get("damping_ratio"), where=where)
    return _read_uff(path, where)


def _read_uff(path: Path, where: str) -> ModeSet:
    import pyuff

    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises many kinds on a malformed file
        raise SceneError(f"{where} is not a readable universal file: {exc}") from None
    if isinstance(sets, dict):
        sets = [sets]
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
        vals = np.asarray(s[comp], dtype=float)
        nn = np.asarray(s["node_nums"], dtype=np.int64)
        unknown = [int(n) for n in nn if int(n) not in pos]
        if unknown:
            raise SceneError(f"{where}: dataset 55 #{j + 1} (mode {s.get('mode_n')}) names node "
                             f"{unknown[0]}, which no dataset 2411 defines")
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
