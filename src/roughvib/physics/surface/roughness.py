"""Roughness profiles (the kinematic input), their spectra, and the choice of contact points.

This module owns the roughness input (docs/theory.md): everything between the ``[roughness]``
scene section and the uniform-grid height profile z(s) (positive up) the solver interpolates.

``build_profile`` makes a :class:`Profile` from one of

* ``none``: a flat profile (zeros);
* ``sinusoid``: z = amplitude cos(2 pi (s - s_centre) / wavelength), a crest under the block
  centre (not filtered);
* ``synthetic``: seeded spectral synthesis (random phases, amplitudes from the target PSD, one
  real inverse FFT) of a profile with the band-limited self-affine PSD
  :func:`band_psd`, functionally filtered and then rescaled to ``rms`` exactly;
* ``synthetic`` with ``reduce_3d``: an isotropic 2-D surface of rms ``raw_rms`` with the areal
  PSD :func:`areal_psd`, span-averaged across the block width (docs/theory.md,
  :func:`synthesize_span_averages`); the reduction (about -23 dB over 40 mm) is the physics,
  so the result is not rescaled;
* ``file``: a measured profile (:func:`read_measured`): a text file (:func:`read_profile_file`:
  one column of heights, two columns (x, z) or a matrix of parallel traces) or an instrument
  file (SDF, X3P, .sur, .datx, ... through the optional SurfaceTopography package); a matrix
  of traces or a map is span-averaged like the synthetic surface.

The functional filter over the block length (docs/theory.md, :func:`functional_filter`) is
``highpass`` 1 - sinc(kL/2) (reading 2, default), ``block-lowpass`` sinc(kL/2) (reading 1,
with a warning) or ``none``. It is applied to ``synthetic`` and ``file`` profiles.

Spectral conventions: wavenumbers k are angular [rad/m]; a one-sided profile PSD G(k)
[m^2/(rad/m)] integrates to the variance, ``integral_0^inf G dk = rms^2``; an isotropic areal
PSD S2(``|k|``) [m^2/(rad/m)^2] integrates over the plane to the variance. Profile spectral
moments are ``m_n = integral k^n G(k) dk``: m0 = rms^2, m2 = (rms slope)^2, m4 = (rms
curvature)^2.
"""

from __future__ import annotations

import hashlib
import math
import re
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from roughvib.physics.surface.field import (
    PAPER_SHORTEST_WAVELENGTH,
    DiscretePSD,
    InputBand,
    SurfaceSpectrum,
    hertz_filter,
    synthetic_spectrum,
)
from roughvib.scene import SANE_BOUNDS, Block, Roughness, SceneError, user_stacklevel

__all__ = [
    "MeasuredProfile",
    "Profile",
    "areal_psd",
    "band_psd",
    "build_profile",
    "cbrt2_positions",
    "functional_filter",
    "profile_statistics",
    "read_measured",
    "read_profile_file",
    "select_contacts",
    "span_average",
    "spectral_moments",
    "synthesize_profile",
    "synthesize_span_averages",
    "trapezoid_weights",
    "uniform_positions",
]

_UNITS = {"m": 1.0, "um": 1e-6, "nm": 1e-9}
#: the paper's profile grid [m]: the grid of the kinds sampled on a plain grid when
#: ``roughness.spacing`` is "auto" (and of a one-column file, see read_profile_file)
PAPER_SPACING = 10e-6

# kx rows of the 2-D synthesis handled per chunk: bounds the memory to a few MB; fixed so that
# the random stream (and with it the surface of a seed) does not depend on anything else
_KX_CHUNK = 128
# traces per chunk when summing the trace weights in the ky domain
_TRACE_CHUNK = 256
# x steps of a two-column file may deviate this much from the mean spacing (printing x with
# six significant digits already costs a few per mille at 0.16 m / 10 um)
_X_STEP_RTOL = 0.01


# --------------------------------------------------------------------------------------------
# the profile
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Profile:
    """The kinematic input profile on a uniform grid.

    Attributes
    ----------
    z : ndarray, shape (n,)
        Heights [m], positive up, after the 3-D -> 2-D reduction and the functional filter.
    dx : float
        Grid spacing [m].
    s0 : float
        Profile coordinate of ``z[0]`` [m].
    s_centre : float
        Profile coordinate under the block centre at t = 0 (the grid point in the middle of
        the trace) [m].
    stats : dict
        Always: ``kind``, ``n``, ``length`` [m], realised ``rms`` [m], ``rms_slope`` [-],
        ``rms_curvature`` [1/m], ``derivatives`` (how slope and curvature were taken),
        ``filter``. ``synthetic``: ``seed``, ``target_rms`` [m]. ``reduce_3d`` and trace
        matrices: ``raw_rms`` [m], ``reduced_rms`` [m] (before the filter), ``reduction_db``
        [dB], ``n_traces``; see :func:`build_profile`.
    """

    z: np.ndarray
    dx: float
    s0: float
    s_centre: float
    stats: dict = field(default_factory=dict)
    #: a measured surface's raw spectrum (DiscretePSD of its traces before span averaging and
    #: filtering), for the statistical contact; None for the model surfaces
    raw_spectrum: object = field(default=None, repr=False, compare=False)
    #: True when z holds one period of a periodic field (the synthetic surfaces)
    periodic: bool = False

    @property
    def s(self) -> np.ndarray:
        """Profile coordinates [m], shape (n,)."""
        return self.s0 + np.arange(self.z.size) * self.dx

    @property
    def length(self) -> float:
        """Covered length (n - 1) dx [m]."""
        return (self.z.size - 1) * self.dx


def profile_statistics(z: np.ndarray, dx: float, *, periodic: bool = False) -> dict:
    """rms height, rms slope and rms curvature of a profile.

    Parameters
    ----------
    z : ndarray, shape (n,)
        Heights [m].
    dx : float
        Spacing [m].
    periodic : bool
        True for a band-limited periodic profile (spectral synthesis): slope and curvature are
        taken spectrally, which is exact and comparable with sqrt(m2), sqrt(m4). Otherwise
        first and second differences (they under-read content near the grid's Nyquist
        wavenumber: -0.6 dB in slope at 5 points per wavelength).

    Returns
    -------
    dict
        ``rms`` [m] (about the mean), ``rms_slope`` [-], ``rms_curvature`` [1/m],
        ``derivatives`` ("spectral" or "finite-difference").
    """
    z = np.asarray(z, dtype=float)
    zc = z - z.mean() if z.size else z
    rms = float(np.sqrt(np.mean(zc**2))) if z.size else 0.0
    if periodic and z.size >= 3:
        n = z.size
        k = 2.0 * np.pi * np.fft.rfftfreq(n, dx)
        p = np.abs(np.fft.rfft(zc)) ** 2
        w = np.full(k.size, 2.0)
        w[0] = 1.0
        if n % 2 == 0:
            w[-1] = 1.0
        scale = 1.0 / n**2
        slope = math.sqrt(float(np.sum(w * p * k**2)) * scale)
        curv = math.sqrt(float(np.sum(w * p * k**4)) * scale)
        how = "spectral"
    else:
        d1 = np.diff(z) / dx
        d2 = np.diff(z, 2) / dx**2
        slope = float(np.sqrt(np.mean(d1**2))) if d1.size else 0.0
        curv = float(np.sqrt(np.mean(d2**2))) if d2.size else 0.0
        how = "finite-difference"
    return {"rms": rms, "rms_slope": slope, "rms_curvature": curv, "derivatives": how}


# --------------------------------------------------------------------------------------------
# model spectra and moments (docs/theory.md)
# --------------------------------------------------------------------------------------------


def _band(r: Roughness, shortest: float | None = None) -> tuple[float, float, float]:
    """(k_L, k_0, k_H) [rad/m]; ``shortest`` [m] resolves an ``"auto"`` tail limit."""
    lam = r.shortest_wavelength if shortest is None else shortest
    if isinstance(lam, str):
        raise ValueError("roughness.shortest_wavelength is 'auto': pass the resolved limit "
                         "(roughvib.physics.surface.field.input_band)")
    return (2.0 * np.pi / r.longest_wavelength, 2.0 * np.pi / r.rolloff_wavelength,
            2.0 * np.pi / lam)


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
    band = (k >= kl) & (k <= kh)
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


# --------------------------------------------------------------------------------------------
# synthesis
# --------------------------------------------------------------------------------------------


def _n_points(r: Roughness) -> int:
    return int(round(r.trace_length / r.spacing)) + 1


def _synthesize_raw(r: Roughness) -> np.ndarray:
    n = _n_points(r)
    rng = np.random.default_rng(r.seed)
    k = 2 * np.pi * np.fft.rfftfreq(n, r.spacing)
    psd = band_psd(k, r)
    if not np.any(psd > 0):
        raise SceneError(f"roughness.trace_length ({r.trace_length} m) holds no wavenumber of "
                         f"the band [{r.shortest_wavelength}, {r.longest_wavelength}] m, got "
                         f"{r.trace_length} m")
    spec = np.sqrt(psd) * np.exp(2j * np.pi * rng.random(k.size))
    return np.fft.irfft(spec, n)


def synthesize_profile(roughness: Roughness, rms: float | None = None) -> np.ndarray:
    """Seeded random-phase synthesis of a profile with the PSD :func:`band_psd` (no filter).

    Amplitudes sqrt(G(k_j)) on the FFT bins k_j = 2 pi j / (n dx) of the band, phases uniform
    from ``numpy.random.default_rng(roughness.seed)``, one real inverse FFT.
    The amplitudes are deterministic, so every realisation has exactly the target power in
    every bin; the heights are Gaussian by the central limit theorem (thousands of
    components). The profile is periodic over n dx.

    Parameters
    ----------
    roughness : Roughness
        ``spacing``, ``trace_length`` (n = round(trace_length / spacing) + 1 points), band,
        ``hurst``, ``seed``.
    rms : float, optional
        Rescale to this rms [m]; default ``roughness.rms``.

    Returns
    -------
    ndarray, shape (n,)
        Zero-mean heights [m].
    """
    z = _synthesize_raw(roughness)
    z = z - z.mean()
    target = roughness.rms if rms is None else rms
    zr = float(np.sqrt(np.mean(z**2)))
    return z * (target / zr) if zr > 0 else z


def trapezoid_weights(y: np.ndarray) -> np.ndarray:
    """Trapezoidal quadrature weights of sorted, possibly uneven positions.

    Parameters
    ----------
    y : ndarray, shape (m,)
        Strictly increasing positions [m].

    Returns
    -------
    ndarray, shape (m,)
        Weights [m], summing to y[-1] - y[0] (one position: weight 1).
    """
    y = np.asarray(y, dtype=float)
    if y.size == 1:
        return np.ones(1)
    g = np.diff(y)
    if np.any(g <= 0):
        raise ValueError(f"trace positions must increase strictly, got {y}")
    w = np.empty(y.size)
    w[0] = g[0] / 2
    w[-1] = g[-1] / 2
    w[1:-1] = (g[:-1] + g[1:]) / 2
    return w


def uniform_positions(width: float, spacing: float) -> np.ndarray:
    """Equally spaced trace positions across a width, centred on y = 0.

    Parameters
    ----------
    width : float
        Span [m].
    spacing : float
        Requested pitch [m]; the actual pitch is width / round(width / spacing).

    Returns
    -------
    ndarray, shape (m,)
        Positions [m] from -width/2 to +width/2, both included.
    """
    m = max(1, int(round(width / spacing)))
    return np.linspace(-width / 2, width / 2, m + 1)


def cbrt2_positions(width: float, first_spacing: float) -> np.ndarray:
    """The paper's trace layout: separations from one edge growing by 2^(1/3) per trace.

    Positions (from the edge) 0, d, d 2^(1/3), d 2^(2/3), ... below the width, and the far
    edge; returned centred on y = 0. This samples separations on a 1/3-octave grid, which is
    what the spanwise *coherence* integral of a Remington-type averaging needs. As a direct
    spatial average with trapezoidal weights it is dominated by the few widely spaced traces
    at the far edge (38 traces for d = 10 um over 40 mm, effective number of independent
    traces (sum w)^2 / sum w^2 = 9.9, i.e. only about -10 dB); see
    :func:`synthesize_span_averages` for the layout used by default.

    Parameters
    ----------
    width : float
        Span [m].
    first_spacing : float
        Smallest separation d [m].

    Returns
    -------
    ndarray, shape (m,)
        Increasing positions [m] in [-width/2, width/2].
    """
    if not 0 < first_spacing < width:
        raise ValueError(f"first_spacing must be in (0, width={width}) m, got {first_spacing}")
    r = 2.0 ** (1.0 / 3.0)
    pos = [0.0]
    d = first_spacing
    while d < width * (1.0 - 1e-9):
        pos.append(d)
        d *= r
    pos.append(width)
    return np.asarray(pos) - width / 2


def span_average(traces: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Span average of parallel traces with trapezoidal weights.

    Parameters
    ----------
    traces : ndarray, shape (n, m)
        Heights [m]: n sections along the sliding direction, m traces.
    y : ndarray, shape (m,)
        Strictly increasing trace positions across the width [m].

    Returns
    -------
    ndarray, shape (n,)
        z_2D(s) = sum_j w_j z(s, y_j) / sum_j w_j [m].
    """
    traces = np.asarray(traces, dtype=float)
    w = trapezoid_weights(y)
    if traces.ndim != 2 or traces.shape[1] != w.size:
        raise ValueError(f"traces must have shape (n, {w.size}), got {traces.shape}")
    return traces @ (w / w.sum())


def _weight_transform(ky: np.ndarray, y: np.ndarray, w: np.ndarray, *,
                      direct: bool = False) -> np.ndarray:
    """v(ky) = sum_j w_j exp(i ky y_j) / sum_j w_j, shape (n_ky,).

    Equally spaced positions with trapezoidal weights (the default layout, thousands of
    traces) use the closed geometric sum; anything else (or ``direct``) sums in chunks.
    """
    y = np.asarray(y, dtype=float)
    w = np.asarray(w, dtype=float)
    g = np.diff(y)
    uniform = (not direct and y.size > 2 and np.all(g > 0)
               and np.max(np.abs(g - g.mean())) <= 1e-9 * g.mean()
               and np.allclose(w, trapezoid_weights(y), rtol=1e-12, atol=0.0))
    if uniform:
        d = float(g.mean())
        m = y.size - 1
        th = ky * d
        e = np.exp(1j * th)
        small = np.abs(np.angle(e)) < 1e-9
        den = np.where(small, 1.0, 1.0 - e)
        geo = np.where(small, m + 1.0, (1.0 - np.exp(1j * th * (m + 1))) / den)
        v = d * np.exp(1j * ky * y[0]) * (geo - 0.5 * (1.0 + np.exp(1j * th * m)))
        return v / w.sum()
    v = np.zeros(ky.size, dtype=complex)
    for j0 in range(0, y.size, _TRACE_CHUNK):
        v += np.exp(1j * np.outer(ky, y[j0:j0 + _TRACE_CHUNK])) @ w[j0:j0 + _TRACE_CHUNK]
    return v / w.sum()


def synthesize_span_averages(roughness: Roughness,
                             layouts: Mapping[str, tuple[np.ndarray, np.ndarray]],
                             rms: float | None = None) -> tuple[dict[str, np.ndarray], dict]:
    """Weighted averages of parallel traces of a seeded isotropic 2-D Gaussian surface.

    The surface is the random-phase sum z(s, y) = sum a(k) cos(kx s + ky y + phi) over the
    half-plane kx > 0 of a periodic grid: kx the FFT bins of the trace (period n dx), ky a grid
    of period P_y = 2 max(span of the layouts, longest wavelength) (so two traces of a layout
    never see each other's periodic image), a^2 proportional to :func:`areal_psd`, normalised
    so that the surface variance is exactly ``rms**2``.

    Why not a 2-D FFT: the default surface is 16001 x (0.08 m / 25 um) = 5e7 complex values
    (0.8 GB) although only averages across the block are needed. Averaging is linear, so each
    layout's average is formed in the (kx, ky) domain, c(kx) = sum_ky Z(kx, ky) v(ky) with
    v(ky) = sum_j w_j exp(i ky y_j) / sum_j w_j, chunk by chunk over kx (only kx <= k_H carry
    power, and per kx only the ky inside the disc ``|k|`` <= k_H), and one inverse FFT per layout
    gives the profile. The result is exactly the average of the traces of that periodic
    surface at the given (arbitrary, not gridded) positions; memory stays at a few MB and the
    default case (4001 traces) takes about 2 s of CPU.

    Parameters
    ----------
    roughness : Roughness
        ``spacing``, ``trace_length``, band, ``hurst``, ``seed``.
    layouts : mapping of str to (y, w)
        Named trace sets: positions y (m,) [m] and weights w (m,) [-]; ``([0.0], [1.0])`` is
        the single trace on the centre line.
    rms : float, optional
        Surface rms [m]; default ``roughness.raw_rms``.

    Returns
    -------
    profiles : dict of str to ndarray, shape (n,)
        The weighted average of each layout [m].
    info : dict
        ``period_y`` [m], ``n_kx``, ``n_ky``, ``surface_rms`` [m].
    """
    r = roughness
    sigma = r.raw_rms if rms is None else rms
    n = _n_points(r)
    dx = r.spacing
    kl, _k0, kh = _band(r)
    kx = 2.0 * np.pi * np.fft.rfftfreq(n, dx)
    nkx = int(np.searchsorted(kx, kh, side="right"))
    if n % 2 == 0:
        nkx = min(nkx, kx.size - 1)  # the Nyquist bin of an even trace cannot hold a phase
    span = max((float(np.ptp(y)) for y, _ in layouts.values()), default=0.0)
    period_y = 2.0 * max(span, r.longest_wavelength)
    dky = 2.0 * np.pi / period_y
    mky = int(math.ceil(kh / dky))
    ky = dky * np.arange(-mky, mky + 1)

    names = list(layouts)
    vmat = np.column_stack([_weight_transform(ky, *layouts[name]) for name in names])
    rng = np.random.default_rng(r.seed)
    coef = np.zeros((kx.size, len(names)), dtype=complex)
    var = 0.0
    ky2 = ky**2
    # rows are drawn whole and in order, so the surface of a seed does not depend on the chunk
    # size; only the ky inside the disc |k| <= k_H of the chunk's first row are evaluated
    for i0 in range(1, nkx, _KX_CHUNK):
        i1 = min(i0 + _KX_CHUNK, nkx)
        u = rng.random((i1 - i0, ky.size))
        cols = np.flatnonzero(ky2 <= kh**2 - kx[i0] ** 2 + 1e-9 * kh**2)
        kk = np.sqrt(kx[i0:i1, None] ** 2 + ky2[None, cols])
        amp = np.sqrt(areal_psd(kk, r))
        var += 0.5 * float(np.sum(amp**2))
        coef[i0:i1] = (amp * np.exp(2j * np.pi * u[:, cols])) @ vmat[cols]
    if var <= 0.0:
        raise SceneError(f"roughness.trace_length ({r.trace_length} m) holds no wavenumber of "
                         f"the band [{r.shortest_wavelength}, {r.longest_wavelength}] m, got "
                         f"{r.trace_length} m")
    scale = sigma / math.sqrt(var)
    # z = Re sum_kx c e^{i kx s} = irfft(c n / 2)
    out = {name: np.fft.irfft(coef[:, j] * (scale * n / 2.0), n)
           for j, name in enumerate(names)}
    info = {"period_y": period_y, "n_kx": nkx - 1, "n_ky": int(ky.size),
            "surface_rms": float(sigma)}
    return out, info


# --------------------------------------------------------------------------------------------
# functional filter (docs/theory.md)
# --------------------------------------------------------------------------------------------


def functional_filter(z: np.ndarray, dx: float, kind: str, length: float, *,
                      periodic: bool = True) -> np.ndarray:
    """Apply the functional (contact) filter over the block length.

    ``highpass``: H(k) = 1 - sinc(kL/2), the profile minus its running mean over the block
    length (reading 2, removes wavelengths longer than L). ``block-lowpass``: H = sinc(kL/2),
    the literal reading 1 (warns: it removes almost all short-wavelength input).
    ``none``: unchanged.

    Parameters
    ----------
    z : ndarray, shape (n,)
        Heights [m].
    dx : float
        Spacing [m].
    kind : {"highpass", "block-lowpass", "none"}
    length : float
        Block length L [m].
    periodic : bool
        True: the profile is periodic over n dx (synthesis), filter its FFT. False (measured
        data): filter the even extension [z, z reversed] instead, which has no jump at the
        ends, and keep the first half.

    Returns
    -------
    ndarray, shape (n,)
    """
    if kind == "none":
        return np.asarray(z, dtype=float).copy()
    z = np.asarray(z, dtype=float)
    n = z.size
    ext = z if periodic else np.concatenate([z, z[::-1]])
    m = ext.size
    h = functional_gain(2 * np.pi * np.fft.rfftfreq(m, dx), kind, length)
    return np.fft.irfft(np.fft.rfft(ext) * h, m)[:n]


def functional_gain(k: np.ndarray, kind: str, length: float) -> np.ndarray:
    """Gain of the functional filter over the block length at angular wavenumbers k.

    ``highpass``: 1 - sinc(kL/2); ``block-lowpass``: sinc(kL/2) (warns, see
    :func:`functional_filter`); ``none``: 1.

    Parameters
    ----------
    k : ndarray
        [rad/m].
    kind : {"highpass", "block-lowpass", "none"}
    length : float
        Block length L [m].

    Returns
    -------
    ndarray, shape of ``k``
        [-].
    """
    if kind not in ("highpass", "block-lowpass", "none"):
        raise ValueError(f"filter must be 'highpass', 'block-lowpass' or 'none', got {kind!r}")
    if kind == "none":
        return np.ones_like(np.asarray(k, dtype=float))
    sinc = np.sinc(np.asarray(k, dtype=float) * length / 2 / np.pi)  # sin(pi x)/(pi x)
    if kind == "highpass":
        return 1.0 - sinc
    warnings.warn("roughness.filter = 'block-lowpass' is the literal sinc low-pass over the "
                  "block length: it removes almost all short-wavelength input "
                  "(docs/theory.md)", stacklevel=user_stacklevel())
    return sinc


# --------------------------------------------------------------------------------------------
# measured files
# --------------------------------------------------------------------------------------------


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
    scale = _UNITS[units]
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
    data = np.array(rows, dtype=float) * scale
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
    dx = spacing
    if x is not None:
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
    _check_scale(z, dx if x is not None else None, f"{where} (units = {units!r})", units)
    n = z.shape[0]
    if min_length is not None and (n - 1) * dx < min_length:
        why = f" ({min_length_reason})" if min_length_reason else ""
        raise SceneError(f"{where} line {lines[-1]}: too few points for the stroke plus the "
                         f"block length: need a length >= {min_length:.6g} m{why}, got {n} "
                         f"points x {dx:.6g} m = {(n - 1) * dx:.6g} m")
    return MeasuredProfile(z=z, dx=float(dx), y=y, layout=layout, path=p,
                           last_line=lines[-1], sha256=hashlib.sha256(raw).hexdigest())


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


# --------------------------------------------------------------------------------------------
# build the profile
# --------------------------------------------------------------------------------------------


def _check_filtered(before: np.ndarray, after: np.ndarray, r: Roughness, length: float) -> None:
    """Refuse a functional filter that removed the whole profile (a block shorter than every
    wavelength of the profile: ``highpass`` then leaves zero heights)."""
    peak = float(np.max(np.abs(before))) if before.size else 0.0
    if peak > 0 and not float(np.max(np.abs(after))) > 1e-12 * peak:
        raise SceneError(f"roughness.filter = {r.filter!r} over block.length = {length:g} m "
                         f"removes the whole profile (the block must be longer than the "
                         f"profile's shortest wavelengths), got block.length {length:g} m")


def _reduction_db(reduced: np.ndarray, raw_rms: float) -> float:
    rr = float(np.sqrt(np.mean((reduced - reduced.mean()) ** 2)))
    if raw_rms <= 0 or rr <= 0:
        return float("-inf") if raw_rms > 0 else float("nan")
    return 20.0 * math.log10(rr / raw_rms)


def synthetic_field(roughness: Roughness, block_length: float, shortest: float,
                    spot_radius: float | None = None) -> tuple[SurfaceSpectrum, dict]:
    """The synthetic input surface as a field (docs/theory.md, "The input field").

    The bins of :func:`~roughvib.physics.surface.field.synthetic_spectrum` with the PSD
    :func:`band_psd` carried down to ``shortest``, over the period ``trace_length``;
    functionally filtered (:func:`functional_gain`); scaled so that its rms is
    ``roughness.rms`` exactly; then, with ``spot_radius``, seen through the contact filter.

    Parameters
    ----------
    roughness : Roughness
    block_length : float
        L of the functional filter [m].
    shortest : float
        Tail limit lambda_min [m].
    spot_radius : float, optional
        Contact-filter radius a [m]; None: unfiltered.

    Returns
    -------
    spectrum : SurfaceSpectrum
        The input field.
    stats : dict
        ``seed``, ``target_rms`` [m], ``shortest_wavelength`` [m], ``n_bins``,
        ``spot_radius`` [m] or None, ``contact_filter``, ``filtered_rms`` [m] (after the
        contact filter), ``surface_rms_slope`` [-] (before it).

    Raises
    ------
    SceneError
        No bin of the band fits the trace, or the functional filter removes them all.
    """
    r = roughness
    spec = synthetic_spectrum(lambda k: band_psd(k, r, shortest=shortest), r.trace_length,
                              shortest, r.seed)
    if not spec.variance() > 0:
        raise SceneError(f"roughness.trace_length ({r.trace_length} m) holds no wavenumber of "
                         f"the band [{shortest:.3g}, {r.longest_wavelength}] m, got "
                         f"{r.trace_length} m")
    k = spec.wavenumbers
    spec = spec.with_gain(functional_gain(k, r.filter, block_length))
    var = spec.variance()
    if not var > 0:
        raise SceneError(f"roughness.filter = {r.filter!r} over block.length = "
                         f"{block_length:g} m removes the whole profile (the block must be "
                         f"longer than the profile's shortest wavelengths), got block.length "
                         f"{block_length:g} m")
    spec = spec.with_gain(r.rms / math.sqrt(var))
    surface_slope = math.sqrt(spec.moments()[1])
    if spot_radius is not None:
        spec = spec.with_gain(hertz_filter(k * spot_radius))
    stats = {"seed": r.seed, "target_rms": r.rms, "shortest_wavelength": float(shortest),
             "n_bins": spec.n_bins, "spot_radius": spot_radius,
             "contact_filter": "none" if spot_radius is None else "hertz",
             "filtered_rms": math.sqrt(spec.variance()),
             "surface_rms_slope": surface_slope}
    return spec, stats


def _contact_filtered(z: np.ndarray, dx: float, spot_radius: float | None, *,
                      periodic: bool) -> np.ndarray:
    """A sampled profile seen through the contact filter (none for ``spot_radius`` None);
    not periodic: the even extension is filtered, as in :func:`functional_filter`."""
    if spot_radius is None:
        return z
    n = z.size
    ext = z if periodic else np.concatenate([z, z[::-1]])
    k = 2 * np.pi * np.fft.rfftfreq(ext.size, dx)
    return np.fft.irfft(np.fft.rfft(ext) * hertz_filter(k * spot_radius), ext.size)[:n]


def _numeric_band(r: Roughness) -> Roughness:
    """The section with ``"auto"`` band keys replaced for the kinds sampled on a plain grid
    (none, sinusoid, the span-averaged surface): the paper's 50 um band and 10 um grid."""
    from dataclasses import replace

    out = r
    if isinstance(out.shortest_wavelength, str):
        out = replace(out, shortest_wavelength=PAPER_SHORTEST_WAVELENGTH)
    if isinstance(out.spacing, str):
        out = replace(out, spacing=PAPER_SPACING)
    return out


def build_profile(roughness: Roughness, block: Block, base_dir: str | Path = ".", *,
                  stroke: float | None = None, band: InputBand | None = None,
                  spot_radius: float | None = None) -> Profile:
    """Build the kinematic input profile of a scene.

    Parameters
    ----------
    roughness : Roughness
        The ``[roughness]`` section.
    block : Block
        Length (functional filter, minimum profile length) and width (span averaging).
    base_dir : str or Path
        Directory relative file paths are resolved against (``Scene.base_dir``).
    stroke : float, optional
        Peak-to-peak tangential travel of the block [m]; the profile must cover
        block.length + stroke. Default: block.length (the profile then spans at least two
        block lengths). The solver checks the actual travel again at run time.
    band : InputBand, optional
        The resolved tail limit and grid (:func:`~roughvib.physics.surface.field.input_band`);
        needed by a synthetic surface (``reduce_3d`` off), which is then the field of
        :func:`synthetic_field` sampled over one period (``trace_length``) on a grid no
        coarser than ``band.spacing``.
    spot_radius : float, optional
        Radius a of the contact spots [m]: the input is the surface seen through the contact
        filter :func:`~roughvib.physics.surface.field.hertz_filter` of ``k a``. None: no
        contact filter. ``sinusoid`` and ``none`` are never filtered (test inputs).

    Returns
    -------
    Profile
        ``s0 = 0``, ``s_centre`` the middle grid point. ``reduce_3d`` adds to ``stats``:
        ``raw_rms`` (surface rms), ``raw_trace_rms`` (one trace on the centre line),
        ``reduced_rms`` (span average before the filter), ``reduction_db``,
        ``reduction_db_cbrt2`` (the same surface averaged over the paper's 2^(1/3) layout, for
        reference), ``n_traces``, ``trace_pitch``. A trace matrix adds ``raw_rms`` (mean trace
        rms), ``reduced_rms``, ``reduction_db``, ``n_traces``.

    Raises
    ------
    SceneError
        Unreadable or malformed files, profiles shorter than the block plus the stroke.
    """
    r = roughness
    raw_spectrum = None
    bl = block.length
    stroke = bl if stroke is None else float(stroke)
    min_len = bl + stroke
    reason = f"block.length {bl:g} m + stroke {stroke:g} m"
    stats: dict = {"kind": r.kind}
    periodic = False
    if r.kind == "file":
        meas = read_measured(r, block, base_dir, min_length=min_len, min_length_reason=reason)
        dx = meas.dx
        stats.update(path=str(meas.path), layout=meas.layout, sha256=meas.sha256)
        if meas.z.ndim == 2:
            traces = meas.z - meas.z.mean(axis=0)
            y = meas.y if meas.y is not None else np.linspace(-block.width / 2,
                                                              block.width / 2,
                                                              traces.shape[1])
            z = span_average(traces, y)
            raw = float(np.mean(np.sqrt(np.mean(traces**2, axis=0))))
            stats.update(n_traces=int(traces.shape[1]), raw_rms=raw,
                         reduced_rms=float(np.sqrt(np.mean(z**2))),
                         reduction_db=_reduction_db(z, raw),
                         trace_span=float(np.ptp(y)))
        else:
            z = meas.z.copy()
        # moments of the raw measured surface (before span averaging and filtering) feed the
        # statistical contact model (contact.stiffness = "auto", docs/theory.md)
        raw_traces = meas.z if meas.z.ndim == 2 else meas.z[:, None]
        per = [profile_statistics(raw_traces[:, j], dx) for j in range(raw_traces.shape[1])]
        stats["raw_moments"] = tuple(float(np.mean([p[key] ** 2 for p in per]))
                                     for key in ("rms", "rms_slope", "rms_curvature"))
        raw_spectrum = _raw_spectrum(raw_traces, dx)
        if r.filter != "none":
            raw_z = z
            z = functional_filter(z - z.mean(), dx, r.filter, bl, periodic=False)
            _check_filtered(raw_z - raw_z.mean(), z, r, bl)
        z = _contact_filtered(z, dx, spot_radius, periodic=False)
    elif r.kind == "synthetic" and not r.reduce_3d:
        if band is None:
            raise ValueError("build_profile needs the resolved input band of a synthetic "
                             "surface (roughvib.physics.surface.field.input_band)")
        if r.trace_length < min_len * (1.0 - 1e-12):
            raise SceneError(f"roughness.trace_length must cover the stroke plus the block "
                             f"length ({reason} = {min_len:.6g} m), got {r.trace_length} m")
        periodic = True
        spec, info = synthetic_field(r, bl, band.shortest_wavelength, spot_radius)
        z, dx = spec.sample(band.spacing)
        stats.update(info)
    else:
        r = _numeric_band(r)
        dx = r.spacing
        n = _n_points(r)
        if (n - 1) * dx < min_len * (1.0 - 1e-12):
            raise SceneError(f"roughness.trace_length must cover the stroke plus the block "
                             f"length ({reason} = {min_len:.6g} m), got {r.trace_length} m")
        if r.kind == "none":
            z = np.zeros(n)
        elif r.kind == "sinusoid":
            s = np.arange(n) * dx
            z = r.amplitude * np.cos(2 * np.pi * (s - s[n // 2]) / r.wavelength)
        else:
            periodic = True
            raw_z = _reduce_3d(r, block, stats)
            z = functional_filter(raw_z - raw_z.mean(), dx, r.filter, bl)
            _check_filtered(raw_z - raw_z.mean(), z, r, bl)
            z = _contact_filtered(z, dx, spot_radius, periodic=True)
            stats.update(seed=r.seed)
    if not np.all(np.isfinite(z)):  # the interpolant (spline) needs finite heights
        raise SceneError(f"roughness.kind = {r.kind!r} gives a profile with non-finite heights "
                         f"(check roughness.rms, amplitude, raw_rms and the band), got "
                         f"{int(np.count_nonzero(~np.isfinite(z)))} of {z.size} samples")
    n = z.size
    stats.update(n=int(n), length=float((n - 1) * dx), filter=r.filter)
    stats.update(profile_statistics(z, dx, periodic=periodic))
    s_centre = (n // 2) * dx
    return Profile(z=np.ascontiguousarray(z, dtype=float), dx=float(dx), s0=0.0,
                   s_centre=float(s_centre), stats=stats, raw_spectrum=raw_spectrum,
                   periodic=periodic)


def _raw_spectrum(traces: np.ndarray, dx: float) -> DiscretePSD:
    """Mean power per FFT bin of measured traces (n, m), mean removed: the raw spectrum the
    statistical contact counts summits on (docs/theory.md)."""
    t = traces - traces.mean(axis=0)
    n = t.shape[0]
    p = np.abs(np.fft.rfft(t, axis=0)) ** 2 * (2.0 / n**2)
    p[0] = 0.0
    if n % 2 == 0:
        p[-1] *= 0.5  # the Nyquist bin is real: counted once
    return DiscretePSD(k=2.0 * np.pi * np.fft.rfftfreq(n, dx), power=p.mean(axis=1))


def contact_filtered_profile(profile: Profile, spot_radius: float | None) -> Profile:
    """The profile seen through the contact filter of spots of ``spot_radius`` [m] (None:
    unchanged). A periodic field is filtered exactly through its FFT, a measured profile
    through its even extension (:func:`functional_filter`); ``stats`` gains
    ``spot_radius`` and ``contact_filter`` and the rms, slope and curvature of the result."""
    if spot_radius is None:
        return profile
    z = _contact_filtered(profile.z, profile.dx, spot_radius, periodic=profile.periodic)
    stats = dict(profile.stats, spot_radius=float(spot_radius), contact_filter="hertz")
    stats.update(profile_statistics(z, profile.dx, periodic=profile.periodic))
    from dataclasses import replace

    return replace(profile, z=np.ascontiguousarray(z), stats=stats)


def _reduce_3d(r: Roughness, block: Block, stats: dict) -> np.ndarray:
    """Span average of the 2-D surface over the block width, traces at the profile spacing.

    ``roughness.trace_layout = "uniform"`` (default) uses a trace pitch equal to
    ``roughness.spacing`` (10 um), far below the spanwise correlation length of the band
    (>= 50 um), so the trapezoidal average is the continuous width average of docs/theory.md
    (-23 dB for the default surface, the analytic value is -23.1 dB). ``"cbrt2"`` uses the
    paper's 2^(1/3) layout (about -10 dB; see :func:`cbrt2_positions`). Both reductions of the
    same surface are reported in ``stats``.
    """
    width = block.width
    if r.raw_rms == 0.0:
        stats.update(raw_rms=0.0, reduced_rms=0.0, reduction_db=float("nan"))
        return np.zeros(_n_points(r))
    yu = uniform_positions(width, r.spacing)
    yc = cbrt2_positions(width, r.spacing)
    layouts = {"uniform": (yu, trapezoid_weights(yu)),
               "cbrt2": (yc, trapezoid_weights(yc)),
               "centre": (np.zeros(1), np.ones(1))}
    out, info = synthesize_span_averages(r, layouts)
    z = out[r.trace_layout]
    used = yu if r.trace_layout == "uniform" else yc
    stats.update(raw_rms=r.raw_rms,
                 raw_trace_rms=float(np.sqrt(np.mean(out["centre"] ** 2))),
                 reduced_rms=float(np.sqrt(np.mean(z**2))),
                 reduction_db=_reduction_db(z, r.raw_rms),
                 reduction_db_uniform=_reduction_db(out["uniform"], r.raw_rms),
                 reduction_db_cbrt2=_reduction_db(out["cbrt2"], r.raw_rms),
                 trace_layout=r.trace_layout, n_traces=int(used.size),
                 trace_pitch=float(used[1] - used[0]), period_y=info["period_y"])
    return z


# --------------------------------------------------------------------------------------------
# contact points (docs/theory.md)
# --------------------------------------------------------------------------------------------


def _ranked(idx: np.ndarray, z: np.ndarray, s: np.ndarray, s_centre: float, tie: float
            ) -> np.ndarray:
    """idx sorted by height (highest first); heights within ``tie`` rank by distance to the
    centre, then by position, so equal crests (a sinusoid) are taken from the centre out."""
    if idx.size == 0:
        return idx
    zq = np.round((z[idx].max() - z[idx]) / tie)
    order = np.lexsort((s[idx], np.abs(s[idx] - s_centre), zq))
    return idx[order]


def select_contacts(profile: Profile, n: int, window_length: float, min_separation: float
                    ) -> np.ndarray:
    """Profile coordinates of the n highest local maxima under the block, sorted.

    Rules, in order:

    1. The window is ``|s - s_centre| <= window_length / 2`` (grid points).
    2. Flat window (height range below 1e-12 of the largest ``|z|``, or exactly zero, e.g. kind
       ``none``): n points equally spaced with equal gaps to each other and to the window
       edges, ``s_centre + linspace(-w/2, w/2, n + 2)[1:-1]`` (n = 1: the centre).
       ``min_separation`` is not applied.
    3. Otherwise the local maxima (z[i] >= z[i-1] and z[i] > z[i+1], neighbours taken from the
       whole profile) are ranked by height; heights equal within 1e-9 of the window's height
       range rank by distance to the centre (so on ``sinusoid`` one contact sits exactly at
       the centre crest). Greedily, a maximum is taken if it is at least ``min_separation``
       from every point already taken.
    4. If fewer than n maxima qualify, the remaining points are the highest other grid points
       of the window that respect the separation (a ``UserWarning`` says so): on a smooth
       long-wave profile they sit on the flanks next to the crests and carry no static load.

    Parameters
    ----------
    profile : Profile
    n : int
        Number of contact points N_c (>= 1).
    window_length : float
        Block length [m].
    min_separation : float
        Minimum distance between two chosen points [m].

    Returns
    -------
    ndarray, shape (n,)
        Sorted profile coordinates [m] (grid points, except in the flat case).

    Raises
    ------
    SceneError
        n < 1, or not even rule 4 finds n points ``min_separation`` apart in the window.
    """
    if n < 1:
        raise SceneError(f"contact.points must be >= 1, got {n}")
    s = profile.s
    z = profile.z
    half = window_length / 2
    sc = profile.s_centre
    inside = np.flatnonzero(np.abs(s - sc) <= half + 1e-9 * profile.dx)
    if inside.size == 0:
        raise SceneError(f"block.length must cover at least one profile point, got "
                         f"{window_length} m")
    zi = z[inside]
    zrange = float(np.ptp(zi))
    if zrange == 0.0 or zrange <= 1e-12 * float(np.max(np.abs(zi))):
        return sc + np.linspace(-half, half, n + 2)[1:-1]
    tie = 1e-9 * zrange
    i = inside[(inside > 0) & (inside < z.size - 1)]
    cand = i[(z[i] >= z[i - 1]) & (z[i] > z[i + 1])]
    tol = 1e-9 * profile.dx
    chosen: list[int] = []

    def take(order: np.ndarray) -> None:
        for j in order:
            if len(chosen) == n:
                return
            if not chosen or np.min(np.abs(s[chosen] - s[j])) >= min_separation - tol:
                chosen.append(int(j))

    take(_ranked(cand, z, s, sc, tie))
    if len(chosen) < n:
        n_max = len(chosen)
        rest = np.setdiff1d(inside, np.asarray(chosen, dtype=int))
        take(_ranked(rest, z, s, sc, tie))
        if len(chosen) < n:
            raise SceneError(f"contact.points: only {len(chosen)} points at least "
                             f"contact.min_separation = {min_separation} m apart were found in "
                             f"the block window of {window_length} m (highest first); lower "
                             f"contact.points or contact.min_separation, got {n}")
        warnings.warn(f"only {n_max} local maxima at least {min_separation} m apart under the "
                      f"block; the other {n - n_max} contact points are the highest remaining "
                      f"profile points", stacklevel=user_stacklevel())
    return np.sort(s[chosen])
