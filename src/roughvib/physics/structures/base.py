"""The structure component's interface: what the model needs from the body under the block.

A structure is linear, and the model sees it only through its modes (docs/structures.md and the
numbered contract in docs/architecture.md): angular frequencies, damping ratios and
**mass-normalised** shapes (modal mass 1 kg, shapes in 1/sqrt(kg)) at the points where the
contacts and the observer meet it, optionally a residual static compliance at those points.
``model/system.py`` turns these into the flat arrays the kernels read, once, at assembly.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
from numpy.typing import ArrayLike

from roughvib.scene import SceneError

__all__ = ["Structure", "as_points", "check_frequencies", "gauss_rectangle"]


def as_points(points: ArrayLike) -> np.ndarray:
    """Points as a float array of shape (P, 2) (a single (x, y) pair gives P = 1).

    Raises
    ------
    ValueError
        ``points`` is not of shape (P, 2) or (2,).
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1:
        pts = pts[None, :]
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (P, 2), got {np.shape(points)}")
    return pts


def gauss_rectangle(centre: ArrayLike, size: ArrayLike, n: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights of an axis-parallel rectangle (n x n points).

    Parameters
    ----------
    centre : array_like, shape (2,)
        Centre (x, y) [m].
    size : array_like, shape (2,)
        Side lengths along x and y [m].
    n : int
        Points per axis (exact for polynomials of degree 2n - 1 in each coordinate).

    Returns
    -------
    points : ndarray, shape (n * n, 2)
        Quadrature points [m].
    weights : ndarray, shape (n * n,)
        Weights of the area *mean* (they sum to 1) [-].
    """
    t, w = np.polynomial.legendre.leggauss(int(n))
    cx, cy = (float(c) for c in centre)
    lx, ly = (float(s) for s in size)
    X, Y = np.meshgrid(cx + 0.5 * lx * t, cy + 0.5 * ly * t, indexing="ij")
    W = np.outer(w, w) / 4.0
    return np.column_stack([X.ravel(), Y.ravel()]), W.ravel()


class Structure(ABC):
    """A linear structure seen through R mass-normalised modes (docs/architecture.md).

    Attributes
    ----------
    name : str
        One line for logs and summaries (``"simply supported plate, 393 modes to 50 kHz"``).
    omega : ndarray, shape (R,)
        Angular natural frequencies [rad/s], finite, > 0 (no rigid-body modes), ascending.
    damping_ratio : ndarray, shape (R,)
        Modal viscous damping ratios zeta_r [-], finite, in [0, 1).
    radiation : bool
        Whether the structure defines a radiating surface (a plate in a baffle: sound power
        from the surface velocity). No output of roughvib uses it yet; a structure without a
        surface (a rigid base, modes known only at points) says ``False``.
    residual : str
        One line on the residual compliance it gives and its truncation error, for the run
        summary (``summary["model"]["residual_compliance"]``); ``"none"`` when it gives none.
    notes : tuple of str
        One-line validity notes (a residual compliance that is missing although
        ``plate.residual_compliance`` asks for one); assembly issues them as
        :class:`~roughvib.scene.ModelValidityWarning` and keeps them in the summary.
    """

    name: str = ""
    radiation: bool = False
    residual: str = "none"
    notes: tuple[str, ...] = ()
    omega: np.ndarray
    damping_ratio: np.ndarray

    @property
    def n_modes(self) -> int:
        """R, the number of modes."""
        return int(np.size(self.omega))

    # ---- what every structure provides ---------------------------------------------------
    @abstractmethod
    def shapes(self, points: ArrayLike) -> np.ndarray:
        """Mass-normalised vertical mode shapes at points [1/sqrt(kg)].

        Parameters
        ----------
        points : array_like, shape (P, 2)
            Coordinates (x, y) in the plate's frame [m] (that of ``plate.block_position``).

        Returns
        -------
        ndarray, shape (R, P)

        Raises
        ------
        SceneError
            A point where the structure is not defined (one line naming it).
        """

    @abstractmethod
    def slopes(self, points: ArrayLike) -> np.ndarray:
        """x-derivatives of the mode shapes at points [1/(m sqrt(kg))], shape (R, P)."""

    def residual_compliance(self, points: ArrayLike) -> np.ndarray | None:
        """Static compliance of the modes the structure leaves out, between points [m/N].

        Returns
        -------
        ndarray, shape (P, P), symmetric positive semi-definite, or None
            None: the structure knows none (the model then uses zero).
        """
        return None

    def max_shape(self) -> np.ndarray:
        """Largest ``|shape_r|`` over the structure [1/sqrt(kg)], shape (R,): the
        displacement per unit modal coordinate that scales the modes' tolerances."""
        return np.ones(self.n_modes)

    # ---- area means: quadrature by default, a structure may give closed forms ------------
    def quadrature_order(self, size: ArrayLike) -> int:
        """Gauss-Legendre points per axis of the area means over a patch of ``size`` [m]."""
        return 24

    def patch_shapes(self, centre: ArrayLike, size: ArrayLike) -> np.ndarray:
        """Mode shapes averaged over an axis-parallel rectangle [1/sqrt(kg)], shape (R,).

        Parameters
        ----------
        centre : array_like, shape (2,)
            Centre of the patch (x, y) [m].
        size : array_like, shape (2,)
            Its sides along x and y [m].
        """
        pts, w = gauss_rectangle(centre, size, self.quadrature_order(size))
        return self.shapes(pts) @ w

    def patch_slopes(self, centre: ArrayLike, size: ArrayLike) -> np.ndarray:
        """x-slopes of the shapes averaged over the rectangle [1/(m sqrt(kg))], shape (R,)."""
        pts, w = gauss_rectangle(centre, size, self.quadrature_order(size))
        return self.slopes(pts) @ w

    def patch_residual_compliance(self, centre: ArrayLike, size: ArrayLike) -> float | None:
        """Residual compliance between two evenly spread unit loads on the rectangle [m/N]:
        the area mean of the displacement under a unit force spread evenly over it.
        None: the structure knows none."""
        return None


def check_frequencies(frequency: np.ndarray, where: str) -> None:
    """Refuse zero, negative or non-finite natural frequencies in one line.

    Raises
    ------
    SceneError
        Naming ``where`` (the file and array) and the first bad mode (1-based).
    """
    bad = np.flatnonzero(~np.isfinite(frequency) | (frequency <= 0.0))
    if bad.size:
        i = int(bad[0])
        f = float(frequency[i])
        if f == 0.0:
            raise SceneError(f"{where}: mode {i + 1} has frequency 0 Hz; rigid-body modes are "
                             f"not supported (the block rests on the structure), remove them")
        raise SceneError(f"{where}: every frequency must be finite and > 0 Hz, got {f} Hz "
                         f"for mode {i + 1}")
