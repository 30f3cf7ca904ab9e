"""The built-in structures: the simply supported plate (``plate.kind = "modal"``) and the rigid
base (``"rigid"``), as :class:`~roughvib.physics.structures.base.Structure` components.

The plate's modes, shapes and exact residual compliance come from
:mod:`roughvib.physics.plate`; here they are mass-normalised (shape / sqrt(M), M = rho h a b / 4)
and given area means in closed form.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from roughvib.physics.plate import mode_shapes, plate_modes, residual_compliance
from roughvib.physics.structures.base import Structure, as_points
from roughvib.scene import Plate

__all__ = ["RigidBase", "SimplySupportedPlate", "PATCH_RESIDUAL_FACTOR"]

#: the area-mean residual compliance of the plate sums the truncated modes up to this many
#: times the larger of plate.max_frequency and the frequency whose bending wavelength is the
#: patch's smaller side; the area means fall off so fast above it that doubling the factor
#: changes the sum by less than 1e-3 (tests/physics/test_structures.py)
PATCH_RESIDUAL_FACTOR = 16.0


def _interval_mean_sin(k: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Mean of sin(k u) over [lo, hi]: (cos(k lo) - cos(k hi)) / (k (hi - lo)), shape of k."""
    return (np.cos(k * lo) - np.cos(k * hi)) / (k * (hi - lo))


def _interval_mean_cos(k: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Mean of k cos(k u) over [lo, hi]: (sin(k hi) - sin(k lo)) / (hi - lo), shape of k."""
    return (np.sin(k * hi) - np.sin(k * lo)) / (hi - lo)


class SimplySupportedPlate(Structure):
    """The simply supported Kirchhoff plate of ``scene.plate`` (``plate.kind = "modal"``).

    Parameters
    ----------
    plate : Plate
        Geometry, material, loss factor and ``max_frequency`` (the modes kept).
    """

    radiation = True
    residual = ("exact: the static Green's function (Levy series) minus the kept modes; over "
                "an area patch the truncated modes' area means (converged to 1e-3)")

    def __init__(self, plate: Plate) -> None:
        self.plate = plate
        self.modes = plate_modes(plate)
        self.omega = self.modes.omega
        self.damping_ratio = self.modes.damping_ratio
        self._scale = 1.0 / math.sqrt(self.modes.modal_mass)
        self.name = (f"simply supported plate {plate.length} x {plate.width} x "
                     f"{plate.thickness} m, {self.n_modes} modes to {plate.max_frequency:g} Hz")

    def _k(self) -> tuple[np.ndarray, np.ndarray]:
        return (self.modes.n * (math.pi / self.plate.length),
                self.modes.m * (math.pi / self.plate.width))

    def shapes(self, points: ArrayLike) -> np.ndarray:
        x, y = as_points(points).T
        return mode_shapes(self.modes, x, y) * self._scale

    def slopes(self, points: ArrayLike) -> np.ndarray:
        x, y = as_points(points).T
        a, b = self._k()
        return (a[:, None] * np.cos(np.outer(a, x)) * np.sin(np.outer(b, y)) * self._scale)

    def residual_compliance(self, points: ArrayLike) -> np.ndarray:
        """Exact: the static Green's function minus the kept modes (physics/plate.py)."""
        return residual_compliance(self.plate, self.modes, as_points(points))

    def max_shape(self) -> np.ndarray:
        return np.full(self.n_modes, self._scale)

    def patch_shapes(self, centre: ArrayLike, size: ArrayLike) -> np.ndarray:
        """Closed form: the mean of sin(a x) sin(b y) over the rectangle is the product of
        (cos(k u1) - cos(k u2)) / (k (u2 - u1)) along both sides."""
        return self._patch_sin(self.modes, centre, size) * self._scale

    def patch_slopes(self, centre: ArrayLike, size: ArrayLike) -> np.ndarray:
        (cx, cy), (lx, ly) = centre, size
        a, b = self._k()
        return (_interval_mean_cos(a, cx - lx / 2, cx + lx / 2)
                * _interval_mean_sin(b, cy - ly / 2, cy + ly / 2) * self._scale)

    def _patch_sin(self, modes, centre: ArrayLike, size: ArrayLike) -> np.ndarray:
        (cx, cy), (lx, ly) = centre, size
        a = modes.n * (math.pi / self.plate.length)
        b = modes.m * (math.pi / self.plate.width)
        return (_interval_mean_sin(a, cx - lx / 2, cx + lx / 2)
                * _interval_mean_sin(b, cy - ly / 2, cy + ly / 2))

    def patch_residual_compliance(self, centre: ArrayLike, size: ArrayLike,
                                  factor: float = PATCH_RESIDUAL_FACTOR) -> float:
        """The truncated modes' series sum psi_r^2 / (M omega_r^2) over the modes between
        ``plate.max_frequency`` and ``factor`` times the larger of it and the frequency whose
        bending wavelength equals the patch's smaller side (psi: the area mean of the unit
        shape); above that the area means fall off so fast that the rest is negligible (see
        :data:`PATCH_RESIDUAL_FACTOR`)."""
        # the area means fall off only above the frequency whose bending wavelength is the
        # patch's smaller side: sum to factor times the larger of it and the cut
        c = math.sqrt(self.plate.bending_stiffness / self.plate.mass_per_area)
        f_patch = c * (2.0 * math.pi / min(size)) ** 2 / (2.0 * math.pi)
        full = plate_modes(self.plate, factor * max(self.plate.max_frequency, f_patch))
        extra = full.omega > self.omega[-1] * (1.0 + 1e-12) if self.n_modes else slice(None)
        psi = self._patch_sin(full, centre, size)[extra]
        return float(np.sum(psi**2 / (full.modal_mass * full.omega[extra] ** 2)))


class RigidBase(Structure):
    """An immovable base (``plate.kind = "rigid"``): no modes, no compliance."""

    name = "rigid base (no modes)"

    def __init__(self, plate: Plate | None = None) -> None:
        self.omega = np.zeros(0)
        self.damping_ratio = np.zeros(0)

    def shapes(self, points: ArrayLike) -> np.ndarray:
        return np.zeros((0, as_points(points).shape[0]))

    def slopes(self, points: ArrayLike) -> np.ndarray:
        return np.zeros((0, as_points(points).shape[0]))

    def max_shape(self) -> np.ndarray:
        return np.zeros(0)

    def patch_shapes(self, centre: ArrayLike, size: ArrayLike) -> np.ndarray:
        return np.zeros(0)

    def patch_slopes(self, centre: ArrayLike, size: ArrayLike) -> np.ndarray:
        return np.zeros(0)
