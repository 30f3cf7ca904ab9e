"""Structures: the vibrating body under the block, as a component chosen by ``plate.kind``.

* :mod:`.base`: the interface :class:`~.base.Structure` (its numbered contract is in
  docs/architecture.md);
* :mod:`.plate`: the built-ins ``modal`` (simply supported plate) and ``rigid``;
* :mod:`.imported`: ``imported``, mass-normalised modes from a file;
* :mod:`.exchange`: the modes exchange format (``.npz``, universal file), read and write.

:data:`STRUCTURES` maps each ``plate.kind`` to its builder; :func:`build_structure` makes the
scene's structure (``model/system.py`` calls it once, at assembly).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from roughvib.physics.structures.base import Structure
from roughvib.physics.structures.imported import EXPORT_FACTOR, ImportedModes
from roughvib.physics.structures.plate import RigidBase, SimplySupportedPlate
from roughvib.scene import Plate

__all__ = ["EXPORT_FACTOR", "STRUCTURES", "Structure", "build_structure", "default_grid",
           "export_modes"]

#: ``plate.kind`` -> builder ``(plate, base_dir) -> Structure``
STRUCTURES: dict[str, Callable[[Plate, Path], Structure]] = {
    "modal": lambda plate, base_dir: SimplySupportedPlate(plate),
    "rigid": lambda plate, base_dir: RigidBase(plate),
    "imported": ImportedModes.from_scene_plate,
}


def build_structure(plate: Plate, base_dir: str | Path = ".") -> Structure:
    """The structure component a scene's plate section names.

    Parameters
    ----------
    plate : Plate
        ``plate.kind`` selects the component (:data:`STRUCTURES`).
    base_dir : str or Path
        The scene file's folder (relative ``plate.modes_file`` paths start there).

    Returns
    -------
    Structure
    """
    return STRUCTURES[plate.kind](plate, Path(base_dir))


def default_grid(plate: Plate, max_frequency: float | None = None) -> tuple[int, int]:
    """Export grid (NX, NY) with ten nodes per shortest bending wavelength of the simply
    supported plate up to ``max_frequency`` [Hz] (default ``plate.max_frequency``), at least
    11 x 11 (interpolation error: docs/structures.md)."""
    import math

    f = plate.max_frequency if max_frequency is None else float(max_frequency)
    c = math.sqrt(plate.bending_stiffness / plate.mass_per_area)
    lam = 2.0 * math.pi / math.sqrt(2.0 * math.pi * f / c)
    return (max(11, int(math.ceil(10.0 * plate.length / lam)) + 1),
            max(11, int(math.ceil(10.0 * plate.width / lam)) + 1))


def export_modes(plate: Plate, base_dir: str | Path = ".", *,
                 grid: tuple[int, int] | None = None,
                 max_frequency: float | None = None):
    """The scene's structure in the exchange format: its modes at the nodes of a grid.

    Parameters
    ----------
    plate : Plate
        The scene's plate section (``plate.kind`` selects the structure).
    base_dir : str or Path
        The scene file's folder (for ``plate.modes_file``).
    grid : (int, int), optional
        Nodes along x and y, uniform over [0, plate.length] x [0, plate.width], edges
        included. Default: :func:`default_grid` of the scene's plate (ten nodes per shortest
        bending wavelength of the *simulated* modes, to ``plate.max_frequency``: the modes
        above it only enter the residual compliance, where the interpolation error of the
        coarser sampling is negligible) for the built-in plate, the file's own nodes for
        imported modes.
    max_frequency : float, optional
        Export the modes up to this frequency [Hz]. Default: ``EXPORT_FACTOR`` (2) times
        ``plate.max_frequency``. The modes above the scene's cut are not simulated by a scene
        that imports the file with the same cut; they give its residual compliance
        (docs/structures.md). ``plate.max_frequency`` itself exports the simulated modes
        only.

    Returns
    -------
    ModeSet

    Raises
    ------
    SceneError
        The structure has no modes (a rigid base) or a grid with fewer than 2 nodes per side.
    """
    import dataclasses

    import numpy as np

    from roughvib.physics.structures.exchange import ModeSet
    from roughvib.scene import SceneError

    if plate.kind == "rigid":
        raise SceneError("plate.kind = 'rigid' has no modes to export, got 'rigid'")
    scene_plate = plate
    fmax = EXPORT_FACTOR * plate.max_frequency if max_frequency is None else max_frequency
    plate = dataclasses.replace(plate, max_frequency=float(fmax))
    structure = build_structure(plate, base_dir)
    if structure.n_modes == 0:
        raise SceneError(f"plate.max_frequency leaves no mode to export, got "
                         f"{plate.max_frequency} Hz")
    if grid is None and isinstance(structure, ImportedModes):
        nodes = structure.nodes
    else:
        nx, ny = grid if grid is not None else default_grid(scene_plate)
        if min(nx, ny) < 2:
            raise SceneError(f"--grid must have at least 2 nodes along x and y, got {nx} {ny}")
        X, Y = np.meshgrid(np.linspace(0.0, plate.length, int(nx)),
                           np.linspace(0.0, plate.width, int(ny)), indexing="ij")
        nodes = np.column_stack([X.ravel(), Y.ravel()])
    return ModeSet(frequency=structure.omega / (2.0 * np.pi), nodes=nodes,
                   shapes=structure.shapes(nodes), damping_ratio=structure.damping_ratio)
