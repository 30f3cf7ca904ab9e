"""Measured topography in instrument formats, read through the optional SurfaceTopography
package (``pip install roughvib[topography]``).

This module owns the boundary to that package: which files it reads (:func:`uses_topography`,
by ``roughness.format``, the file suffix and the file's first bytes), and
:func:`read_topography_map`, which returns the heights of a file in metres on its uniform grid.
Everything after that (cropping to the block width, the 3-D to 2-D span average, the functional
filter, the summit statistics) is the same as for a plain-text trace matrix and lives in
:mod:`roughvib.physics.surface.roughness`. SurfaceTopography is imported only here and only
when such a file is read, so roughvib runs without it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from roughvib.scene import SceneError

__all__ = ["BINARY_SIGNATURES", "INSTRUMENT_SUFFIXES", "TopographyMap", "read_topography_map",
           "uses_topography"]

#: file suffixes that ``roughness.format = "auto"`` hands to SurfaceTopography (instrument and
#: exchange formats); anything else (.txt, .csv, .dat, .asc, ...) goes to the text reader
INSTRUMENT_SUFFIXES = frozenset({
    "sdf", "x3p", "sur", "datx", "opd", "opdx", "plu", "plux", "al3d", "nms", "os3d", "zon",
    "vk3", "vk4", "vk6", "vk7", "mnt", "tmd", "lext", "gwy", "ibw", "mdt", "mi", "frt",
    "wsxm", "zmg", "ezd", "oir", "poir", "spm", "nid", "jpk", "qep", "bcr", "bcrf", "hgt",
})

_INSTALL = "pip install 'roughvib[topography]'"


#: leading bytes of the binary exchange formats SurfaceTopography reads, whatever the file's
#: suffix: netCDF classic, 64-bit offset and 64-bit data (the exchange format of
#: contact.engineering, written by SurfaceTopography's ``to_netcdf``) and HDF5 (netCDF-4)
BINARY_SIGNATURES = (b"CDF\x01", b"CDF\x02", b"CDF\x05", b"\x89HDF\r\n\x1a\n")


def uses_topography(path: str | Path, fmt: str, *, base_dir: str | Path = ".") -> bool:
    """Whether a profile file is read through SurfaceTopography.

    Parameters
    ----------
    path : str or Path
        The file. ``fmt = "auto"`` looks at its suffix (:data:`INSTRUMENT_SUFFIXES`) and, if
        it exists, at its first bytes (:data:`BINARY_SIGNATURES`: netCDF or HDF5, whatever the
        suffix).
    fmt : {"auto", "text", "topography"}
        ``roughness.format``.
    base_dir : str or Path
        Directory a relative ``path`` is resolved against.
    """
    if fmt != "auto":
        return fmt == "topography"
    p = Path(path)
    if p.suffix.lower().lstrip(".") in INSTRUMENT_SUFFIXES:
        return True
    if not p.is_absolute():
        p = Path(base_dir) / p
    try:
        with p.open("rb") as fh:
            head = fh.read(8)
    except OSError:
        return False  # the text reader names the problem
    return head.startswith(BINARY_SIGNATURES)


@dataclass(frozen=True)
class TopographyMap:
    """Heights of an instrument file on its uniform grid, in SI units.

    Attributes
    ----------
    z : ndarray, shape (nx,) or (nx, ny)
        Heights [m]; axis 0 is the file's x axis, the sliding direction.
    dx : float
        Grid spacing along x [m].
    dy : float or None
        Spacing across (y) [m]; None for a line scan.
    reader : str
        SurfaceTopography's name of the format that read it.
    """

    z: np.ndarray
    dx: float
    dy: float | None
    reader: str


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:300] or type(exc).__name__


def read_topography_map(path: str | Path, *, base_dir: str | Path = ".") -> TopographyMap:
    """Read an instrument file (SDF, X3P, .sur, .datx, ...) with SurfaceTopography.

    The file's own units and pixel sizes are used (converted to metres); the default channel
    of a multi-channel file is read.

    Parameters
    ----------
    path : str or Path
        The file; relative paths are relative to ``base_dir``.
    base_dir : str or Path
        Directory relative paths are resolved against.

    Returns
    -------
    TopographyMap

    Raises
    ------
    SceneError
        SurfaceTopography is not installed, the file cannot be read, it has no physical size
        or unit, it holds undefined (missing) points, or it is a non-uniform line scan. One
        line naming the file.
    """
    p = Path(path)
    if not p.is_absolute():
        p = Path(base_dir) / p
    where = f"roughness.path {p}"
    try:
        import SurfaceTopography as st
    except ImportError:
        raise SceneError(f"{where} is an instrument file (roughness.format = 'topography'), "
                         f"which needs the optional SurfaceTopography package: {_INSTALL}, "
                         f"got it not installed") from None
    if not p.is_file():
        raise SceneError(f"{where} cannot be read: no such file, got path {str(path)!r}")
    try:
        with st.open_topography(str(p)) as reader:
            top = reader.topography()
            name = type(reader).__name__
    except Exception as exc:  # the readers raise many kinds; name the first line
        raise SceneError(f"{where} cannot be read by SurfaceTopography: {_one_line(exc)}, "
                         f"got {p.stat().st_size} bytes") from None
    if not getattr(top, "is_uniform", True):
        raise SceneError(f"{where} is a non-uniform line scan; resample it to a uniform grid "
                         f"first, got {top.nb_grid_pts} points")
    if getattr(top, "has_undefined_data", False):
        n_bad = int(np.sum(~np.isfinite(np.ma.filled(top.heights(), np.nan))))
        raise SceneError(f"{where} has undefined (missing) points; fill them first (e.g. "
                         f"SurfaceTopography's interpolate_undefined_data), got {n_bad} of "
                         f"{int(np.prod(top.nb_grid_pts))}")
    if top.unit is None:
        raise SceneError(f"{where} gives no length unit, so its heights cannot be converted "
                         f"to metres, got unit None")
    try:
        top = top.to_unit("m")
    except Exception as exc:
        raise SceneError(f"{where}: the unit {top.unit!r} cannot be converted to m "
                         f"({_one_line(exc)}), got unit {top.unit!r}") from None
    z = np.asarray(np.ma.filled(top.heights(), np.nan), dtype=float)
    if not np.all(np.isfinite(z)):
        raise SceneError(f"{where} has NaN or infinite heights, got "
                         f"{int(np.sum(~np.isfinite(z)))} of {z.size}")
    pix = np.atleast_1d(np.asarray(top.pixel_size, dtype=float))
    dx = float(pix[0])
    dy = float(pix[1]) if z.ndim == 2 and pix.size > 1 else None
    if not (dx > 0 and (dy is None or dy > 0)):
        raise SceneError(f"{where} has no positive pixel size, got {tuple(pix)} m")
    return TopographyMap(z=z, dx=dx, dy=dy, reader=name)
