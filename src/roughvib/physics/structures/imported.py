"""Modes from a file (``plate.kind = "imported"``): a finite-element or measured modal model.

The file (docs/structures.md, :mod:`~roughvib.physics.structures.exchange`) gives
mass-normalised vertical shapes at scattered nodes. Between the nodes a shape is interpolated by
a local cubic least-squares fit (moving least squares) to the :data:`NEIGHBOURS` nearest nodes,
weighted by (1 - (d / d_max)^2)^2; the fit also gives the x-slope. A point outside the convex
hull of the nodes is refused. Measured error on the built-in plate's 393 modes to 50 kHz
exported on a uniform grid (docs/structures.md): largest error 0.4 % of a shape's maximum at a
2.5 mm spacing (about 10 nodes per shortest bending wavelength), 2.7e-4 at 1.25 mm.

The file's modes above ``plate.max_frequency`` are not simulated; their static part,
sum phi_r(a) phi_r(b) / omega_r^2, is the residual compliance (``ImportedModes.residual``
says which modes and about how much of the exact residual they miss).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from roughvib.physics.structures.base import Structure, as_points
from roughvib.physics.structures.exchange import ModeSet, read_modes
from roughvib.scene import Plate, SceneError

__all__ = ["EXPORT_FACTOR", "ImportedModes", "NEIGHBOURS"]

#: ``roughvib modes export`` (:func:`~roughvib.physics.structures.export_modes`) writes the
#: modes up to this many times ``plate.max_frequency``: those above the cut are not simulated
#: by the scene that imports the file but give its residual compliance. For a thin plate the
#: sum over the modes to N times the cut holds 1 - 1/N of the exact residual (the modal density
#: is constant, the terms fall as 1/omega^2); 2 halves the event-time error of the paper run
#: that no residual leaves (7.0e-6 s to 3.6e-6 s, docs/structures.md) for twice the file.
EXPORT_FACTOR = 2.0

#: nodes in each local fit (a full cubic in x, y has 10 coefficients)
NEIGHBOURS = 20
_POWERS = tuple((i, j) for i in range(4) for j in range(4 - i))  # x^i y^j, i + j <= 3


class ImportedModes(Structure):
    """Mass-normalised modes read from ``plate.modes_file`` (or given as a mode set).

    Parameters
    ----------
    plate : Plate
        ``max_frequency`` cuts the modes (those above it only feed the residual compliance),
        ``loss_factor`` gives zeta = loss_factor / 2 where the file has no damping ratios.
    modes : roughvib.physics.structures.exchange.ModeSet
        The file's content (:func:`~roughvib.physics.structures.exchange.read_modes`).
    source : str
        The file, for messages.
    """

    def __init__(self, plate: Plate, modes: ModeSet, source: str = "modes") -> None:
        self.source = source
        keep = modes.frequency <= plate.max_frequency * (1.0 + 1e-12)
        self._set = modes
        self._keep = keep
        self.omega = 2.0 * math.pi * modes.frequency[keep]
        zeta = (modes.damping_ratio if modes.damping_ratio is not None
                else np.full(len(modes), plate.loss_factor / 2.0))
        if np.any(zeta >= 1.0):
            raise SceneError(f"plate.loss_factor must be < 2 for imported modes without "
                             f"damping_ratio (underdamped modes), got {plate.loss_factor}")
        self.damping_ratio = zeta[keep]
        self._nodes = modes.nodes
        self._tree = None
        self._hull = None
        self.name = (f"imported modes from {source}: {int(keep.sum())} of {len(modes)} modes to "
                     f"{plate.max_frequency:g} Hz at {modes.nodes.shape[0]} nodes")
        self.residual, self.notes = self._describe_residual(plate)
        span = np.ptp(modes.nodes, axis=0)
        self._spacing = math.sqrt(float(np.prod(span)) / modes.nodes.shape[0]) \
            if span.min() > 0 else float(span.max()) / modes.nodes.shape[0]

    @classmethod
    def from_scene_plate(cls, plate: Plate, base_dir: str | Path) -> ImportedModes:
        """Read ``plate.modes_file`` (relative to ``base_dir``, the scene file's folder)."""
        path = Path(plate.modes_file)
        if not path.is_absolute():
            path = Path(base_dir) / path
        return cls(plate, read_modes(path), source=repr(plate.modes_file))

    @property
    def nodes(self) -> np.ndarray:
        """The file's nodes (x, y) [m], shape (N, 2)."""
        return self._nodes

    # ---- interpolation ---------------------------------------------------------------------
    def _check_inside(self, pts: np.ndarray) -> None:
        from scipy.spatial import ConvexHull

        if self._hull is None:
            hull = ConvexHull(self._nodes)
            self._hull = hull.equations
        tol = 1e-9 * max(1.0, float(np.abs(self._nodes).max()))
        # each facet of the hull is a row (n_x, n_y, c): inside means n . p + c <= 0
        nx, ny, offsets = self._hull.T
        normals = np.column_stack([nx, ny])
        outside = np.flatnonzero((pts @ normals.T + offsets).max(axis=1) > tol)
        if outside.size:
            x, y = pts[outside[0]]
            raise SceneError(f"plate.modes_file {self.source}: point ({x:.6g}, {y:.6g}) m lies "
                             f"outside the convex hull of the file's nodes; the block, its "
                             f"contact area and plate.observation_position must lie on the "
                             f"structure")

    def _fit(self, pts: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Local cubic least-squares fits at each point: (value, x-slope), each (R, P)."""
        from scipy.spatial import cKDTree

        if self._tree is None:
            self._tree = cKDTree(self._nodes)
        k = min(NEIGHBOURS, self._nodes.shape[0])
        dist, idx = self._tree.query(pts, k)
        dist = dist.reshape(len(pts), k)
        idx = idx.reshape(len(pts), k)
        R = values.shape[0]
        val = np.empty((R, len(pts)))
        dx = np.empty((R, len(pts)))
        for p in range(len(pts)):
            h = max(float(dist[p].max()), 1e-300)
            u = (self._nodes[idx[p]] - pts[p]) / h
            ux, uy = u.T
            V = np.column_stack([ux ** i * uy ** j for i, j in _POWERS])
            w = (1.0 - (dist[p] / (1.01 * h)) ** 2) ** 2
            coef, *_ = np.linalg.lstsq(V * w[:, None], (values[:, idx[p]] * w).T, rcond=1e-10)
            val[:, p] = coef[0]           # the (0, 0) power
            dx[:, p] = coef[_POWERS.index((1, 0))] / h
        return val, dx

    def _at(self, points: ArrayLike, which: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pts = as_points(points)
        self._check_inside(pts)
        return self._fit(pts, self._set.shapes[which])

    def shapes(self, points: ArrayLike) -> np.ndarray:
        shapes, _ = self._at(points, self._keep)
        return shapes

    def slopes(self, points: ArrayLike) -> np.ndarray:
        _, slopes = self._at(points, self._keep)
        return slopes

    def max_shape(self) -> np.ndarray:
        return np.abs(self._set.shapes[self._keep]).max(axis=1)

    def quadrature_order(self, size: ArrayLike) -> int:
        """Two points per node spacing along the longer side, 8 to 48."""
        return int(np.clip(2 * math.ceil(max(size) / self._spacing) + 2, 8, 48))

    # ---- residual compliance from the file's modes above max_frequency ------------------
    def _describe_residual(self, plate: Plate) -> tuple[str, tuple[str, ...]]:
        """The summary's line on the residual compliance and the validity notes."""
        cut = plate.max_frequency
        extra = self._set.frequency[~self._keep]
        if extra.size == 0:
            note = (f"plate.modes_file {self.source} holds no modes above plate.max_frequency "
                    f"= {cut:g} Hz, so the imported structure has no residual compliance (the "
                    f"static compliance of the modes left out); write modes beyond the cut "
                    f"into the file ('roughvib modes export' writes them to "
                    f"{EXPORT_FACTOR:g} x plate.max_frequency)")
            return (f"none: the file holds no modes above plate.max_frequency = {cut:g} Hz",
                    (note,) if plate.residual_compliance else ())
        ratio = cut / float(extra[-1])
        return (f"the file's {extra.size} modes from {extra[0]:.6g} to {extra[-1]:.6g} Hz "
                f"(above plate.max_frequency = {cut:g} Hz), sum of phi_r(a) phi_r(b) / "
                f"omega_r^2; the modes above {extra[-1]:.6g} Hz are missing from it: about "
                f"f_cut/f_last = {ratio:.2g} of the full residual for a thin plate, "
                f"(f_cut/f_last)^1.5 = {ratio ** 1.5:.2g} for a beam"), ()

    def _extra(self) -> np.ndarray:
        return ~self._keep

    def residual_compliance(self, points: ArrayLike) -> np.ndarray | None:
        """sum over the file's modes above ``plate.max_frequency`` of
        phi_r(i) phi_r(j) / omega_r^2; None when the file holds none."""
        extra = self._extra()
        if not extra.any():
            return None
        phi = self._at(points, extra)[0]
        w2 = (2.0 * math.pi * self._set.frequency[extra]) ** 2
        return (phi / w2[:, None]).T @ phi

    def patch_residual_compliance(self, centre: ArrayLike, size: ArrayLike) -> float | None:
        extra = self._extra()
        if not extra.any():
            return None
        from roughvib.physics.structures.base import gauss_rectangle

        pts, w = gauss_rectangle(centre, size, self.quadrature_order(size))
        psi = self._at(pts, extra)[0] @ w
        w2 = (2.0 * math.pi * self._set.frequency[extra]) ** 2
        return float(np.sum(psi**2 / w2))
