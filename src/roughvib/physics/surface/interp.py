"""Piecewise-polynomial interpolants of a roughness profile on a uniform grid.

The solver needs the profile height z(s), its slope z'(s) and curvature z''(s) at arbitrary
s inside its residual, so the interpolant is stored as per-cell Taylor coefficients on the
uniform grid and evaluated by a numba kernel with one index computation and a Horner sum:

    z(s) = sum_k c[j, k] u**k ,   j = floor((s - s0) / dx),   u = s - (s0 + j dx)

``linear`` is C0 (the paper-like interpolation whose slope jumps at every node excite the
high frequencies, docs/theory.md), ``cubic`` a C2 not-a-knot spline (default) and ``quintic``
a C4 spline for convergence checks.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from roughvib._cache import array_digest, cached_arrays, code_fingerprint

__all__ = ["build_coefficients", "cached_coefficients", "profile_eval", "profile_eval_many"]

_DEGREE = {"linear": 1, "cubic": 3, "quintic": 5}


def build_coefficients(z: np.ndarray, dx: float, kind: str = "cubic") -> np.ndarray:
    """Per-cell Taylor coefficients of the interpolant of a uniformly sampled profile.

    Parameters
    ----------
    z : ndarray, shape (n,)
        Heights at s0 + j dx [m], n >= 6.
    dx : float
        Grid spacing [m].
    kind : {"linear", "cubic", "quintic"}

    Returns
    -------
    ndarray, shape (n - 1, degree + 1)
        ``c[j, k]``: coefficient of u**k in cell j [m / m**k].
    """
    z = np.asarray(z, dtype=float)
    if z.ndim != 1 or z.size < 6:
        raise ValueError(f"profile must be 1-D with at least 6 samples, got shape {z.shape}")
    if kind not in _DEGREE:
        raise ValueError(f"interpolation must be one of {sorted(_DEGREE)}, got {kind!r}")
    n = z.size
    if kind == "linear":
        c = np.empty((n - 1, 2))
        c[:, 0] = z[:-1]
        c[:, 1] = np.diff(z) / dx
        return c
    # scipy.interpolate (which imports scipy.optimize and scipy.linalg) only for the splines
    from scipy.interpolate import CubicSpline, make_interp_spline

    s = np.arange(n) * dx
    if kind == "cubic":
        spl = CubicSpline(s, z, bc_type="not-a-knot")
        # CubicSpline pieces sit exactly on the grid cells: highest power first
        return np.ascontiguousarray(spl.c[::-1].T)
    spl = make_interp_spline(s, z, k=5)
    deg = 5
    c = np.empty((n - 1, deg + 1))
    left = s[:-1]
    fact = 1.0
    for k in range(deg + 1):
        if k > 0:
            fact *= k
        # the derivative just right of each node picks the polynomial piece of that cell
        c[:, k] = spl(left, nu=k) / fact
    return c


def cached_coefficients(z: np.ndarray, dx: float, kind: str = "cubic"
                        ) -> tuple[np.ndarray, str]:
    """:func:`build_coefficients` through the on-disk cache (``roughvib._cache``).

    The splines need ``scipy.interpolate``, whose import (with scipy.optimize, linalg and
    special) costs a short run more than the spline itself; the coefficients of a profile are
    therefore stored once, keyed by the profile's SHA-256, ``dx``, ``kind`` and this module's
    code, and read back exactly. ``linear`` needs no scipy and is computed directly.

    Returns
    -------
    coefficients : ndarray, shape (n - 1, degree + 1)
        Bit-identical to ``build_coefficients(z, dx, kind)``.
    cache : {"hit", "miss", "off", "not used"}
    """
    if kind == "linear":
        return build_coefficients(z, dx, kind), "not used"
    z = np.asarray(z, dtype=float)
    arrays, status = cached_arrays(
        "profile-interpolant", {"z": array_digest(z), "dx": float(dx), "kind": kind},
        lambda: {"c": build_coefficients(z, dx, kind)}, code=code_fingerprint([__file__]))
    return arrays["c"], status


@njit(cache=True)
def profile_eval(c, s0, dx, s):
    """Height, slope and curvature of the interpolant at one coordinate.

    Parameters
    ----------
    c : ndarray, shape (ncell, degree + 1)
        Coefficients from :func:`build_coefficients`.
    s0, dx : float
        Coordinate of the first node and spacing [m].
    s : float
        Profile coordinate [m]; outside the grid the end cells are extrapolated.

    Returns
    -------
    z, dz, d2z : float
        [m], [-], [1/m].
    """
    ncell = c.shape[0]
    deg = c.shape[1] - 1
    j = int(np.floor((s - s0) / dx))
    if j < 0:
        j = 0
    elif j > ncell - 1:
        j = ncell - 1
    u = s - (s0 + j * dx)
    z = c[j, deg]
    dz = deg * c[j, deg]
    d2z = deg * (deg - 1) * c[j, deg]
    for k in range(deg - 1, -1, -1):
        z = z * u + c[j, k]
        if k >= 1:
            dz = dz * u + k * c[j, k]
        if k >= 2:
            d2z = d2z * u + k * (k - 1) * c[j, k]
    return z, dz, d2z


@njit(cache=True)
def profile_eval_many(c, s0, dx, s):
    """Vectorised :func:`profile_eval`: returns (z, dz, d2z) arrays of the shape of ``s``."""
    flat = s.ravel()
    z = np.empty(flat.size)
    dz = np.empty(flat.size)
    d2z = np.empty(flat.size)
    for i in range(flat.size):
        z[i], dz[i], d2z[i] = profile_eval(c, s0, dx, flat[i])
    return z.reshape(s.shape), dz.reshape(s.shape), d2z.reshape(s.shape)
