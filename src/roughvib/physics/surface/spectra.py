"""The model spectra of the synthetic surfaces and their moments (docs/theory.md).

Spectral conventions: wavenumbers k are angular [rad/m]; a one-sided profile PSD G(k)
[m^2/(rad/m)] integrates to the variance, ``integral_0^inf G dk = rms^2``; an isotropic areal
PSD S2(``|k|``) [m^2/(rad/m)^2] integrates over the plane to the variance. Profile spectral
moments are ``m_n = integral k^n G(k) dk``: m0 = rms^2, m2 = (rms slope)^2, m4 = (rms
curvature)^2.
"""

from __future__ import annotations

import math

import numpy as np

from roughvib.scene import Roughness

__all__ = ["areal_psd", "band_psd", "spectral_moments"]


def _band(r: Roughness, shortest: float | None = None) -> tuple[float, float, float]:
    """(k_L, k_0, k_H) [rad/m]; ``shortest`` [m] resolves an ``"auto"`` tail limit (0: a tail
    without end, k_H = inf)."""
    lam = r.shortest_wavelength if shortest is None else shortest
    if isinstance(lam, str):
        raise ValueError("roughness.shortest_wavelength is 'auto': pass the resolved limit "
                         "(roughvib.physics.surface.field.input_band)")
    return (2.0 * np.pi / r.longest_wavelength, 2.0 * np.pi / r.rolloff_wavelength,
            2.0 * np.pi / lam if lam > 0 else math.inf)


def _power_integral(p: float, a: float, b: float) -> float:
    """integral_a^b k^p dk (0 if b <= a)."""
    if b <= a:
        return 0.0
    if abs(p + 1.0) < 1e-12:
        return math.log(b / a)
    return (b ** (p + 1.0) - a ** (p + 1.0)) / (p + 1.0)


def _shape_moment(n: float, kl: float, k0: float, kh: float, q: float) -> float:
    """integral over [kl, kh] of k^n * shape(k), shape = 1 below k0 and (k/k0)^-q above."""
    flat = _power_integral(n, kl, min(k0, kh))
    tail = k0**q * _power_integral(n - q, max(k0, kl), kh)
    return flat + tail


def _psd_shape(k: np.ndarray, roughness: Roughness, q: float, shortest: float | None = None
               ) -> tuple[np.ndarray, tuple[float, float, float]]:
    """Band-limited shape: 1 for k_L <= k < k_0, (k/k_0)^-q up to k_H, 0 outside; and the
    band (k_L, k_0, k_H) [rad/m]."""
    kl, k0, kh = _band(roughness, shortest)
    k = np.asarray(k, dtype=float)
    g = np.zeros_like(k)
    band = (k >= kl * (1.0 - 1e-12)) & (k <= kh * (1.0 + 1e-12))  # band edges included
    g[band] = np.where(k[band] < k0, 1.0, (k[band] / k0) ** (-q))
    return g, (kl, k0, kh)


def band_psd(k: np.ndarray, roughness: Roughness, rms: float | None = None, *,
             shortest: float | None = None) -> np.ndarray:
    """One-sided profile PSD G(k) of the synthetic profiles (docs/theory.md).

    G = C for k_L <= k < k_0, C (k/k_0)^-(1+2H) for k_0 <= k <= k_H, zero outside, with
    k_L, k_0, k_H = 2 pi / (longest, rolloff, shortest wavelength).

    Parameters
    ----------
    k : array_like
        Angular wavenumber [rad/m].
    roughness : Roughness
        Band and Hurst exponent.
    rms : float, optional
        Normalise so that ``integral G dk = rms**2`` [m]; default ``C = 1`` (shape only).
    shortest : float, optional
        k_H = 2 pi / shortest [m]; default ``roughness.shortest_wavelength`` (a number).

    Returns
    -------
    ndarray, shape of ``k``
        [m^2/(rad/m)] (or the dimensionless shape).
    """
    q = 1.0 + 2.0 * roughness.hurst
    g, (kl, k0, kh) = _psd_shape(k, roughness, q, shortest)
    if rms is not None:
        g *= rms**2 / _shape_moment(0.0, kl, k0, kh, q)
    return g


def areal_psd(k: np.ndarray, roughness: Roughness, rms: float | None = None, *,
              shortest: float | None = None) -> np.ndarray:
    """Isotropic areal PSD S2(``|k|``) of the raw surface (docs/theory.md).

    The same band and roll-off as :func:`band_psd` with the areal exponent: S2 = C for
    ``k_L <= |k| < k_0``, ``C (|k|/k_0)^-(2+2H)`` up to k_H, zero outside. A profile cut through
    such a surface has G(k) ~ k^-(1+2H) above k_0, like :func:`band_psd`.

    Parameters
    ----------
    k : array_like
        ``|k|`` [rad/m].
    roughness : Roughness
    rms : float, optional
        Normalise so that the integral over the wavenumber plane is ``rms**2`` [m].
    shortest : float, optional
        As for :func:`band_psd`.

    Returns
    -------
    ndarray, shape of ``k``
        [m^2/(rad/m)^2] (or the shape).
    """
    q = 2.0 + 2.0 * roughness.hurst
    s, (kl, k0, kh) = _psd_shape(k, roughness, q, shortest)
    if rms is not None:
        s *= rms**2 / (2.0 * np.pi * _shape_moment(1.0, kl, k0, kh, q))
    return s


def spectral_moments(roughness: Roughness, rms: float | None = None, *, areal: bool = False,
                     shortest: float | None = None) -> tuple[float, float, float]:
    """Profile spectral moments m0, m2, m4 of the model surface (closed form).

    Parameters
    ----------
    roughness : Roughness
        Band and Hurst exponent.
    rms : float, optional
        rms height [m]; default ``roughness.raw_rms`` (the raw surface feeds the contact
        stiffness, docs/theory.md).
    areal : bool
        False: the profile PSD :func:`band_psd`. True: a profile along x through the isotropic
        surface :func:`areal_psd` (the ``reduce_3d`` surface), m_n = integral kx^n S2 d^2k,
        which with the angular means <cos^2> = 1/2 and <cos^4> = 3/8 is m2 = ``<|k|^2> / 2``,
        m4 = ``3 <|k|^4> / 8`` over S2.

    Returns
    -------
    m0, m2, m4 : float
        [m^2], [-], [1/m^2].
    """
    sigma = roughness.raw_rms if rms is None else rms
    kl, k0, kh = _band(roughness, shortest)
    if not areal:
        q = 1.0 + 2.0 * roughness.hurst
        i0, i2, i4 = (_shape_moment(n, kl, k0, kh, q) for n in (0.0, 2.0, 4.0))
        return sigma**2, sigma**2 * i2 / i0, sigma**2 * i4 / i0
    q = 2.0 + 2.0 * roughness.hurst
    j1, j3, j5 = (_shape_moment(n, kl, k0, kh, q) for n in (1.0, 3.0, 5.0))
    return sigma**2, sigma**2 * 0.5 * j3 / j1, sigma**2 * 0.375 * j5 / j1


