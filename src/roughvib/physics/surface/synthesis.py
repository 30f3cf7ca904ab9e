"""Synthesis of the band-limited surfaces on a grid: a seeded profile, and the span average of
a seeded isotropic 2-D surface across the block's width (docs/theory.md, "From a surface to a
profile"). The default synthetic input is the field of :mod:`roughvib.physics.surface.field`;
these are the ``reduce_3d`` surface and its building blocks.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from roughvib.physics.surface.spectra import _band, areal_psd, band_psd
from roughvib.scene import Roughness, SceneError

__all__ = ["cbrt2_positions", "span_average", "synthesize_profile", "synthesize_span_averages",
           "trapezoid_weights", "uniform_positions"]

# kx rows of the 2-D synthesis handled per chunk: bounds the memory to a few MB; fixed so that
# the random stream (and with it the surface of a seed) does not depend on anything else
_KX_CHUNK = 128
# traces per chunk when summing the trace weights in the ky domain
_TRACE_CHUNK = 256


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
    """Seeded random-phase synthesis of a profile with the PSD
    :func:`~roughvib.physics.surface.spectra.band_psd` on a grid (no filter).

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
    never see each other's periodic image), a^2 proportional to
    :func:`~roughvib.physics.surface.spectra.areal_psd`, normalised so that the surface
    variance is exactly ``rms**2``.

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


