"""Spectra of time signals and roughness profiles: third-octave bands, narrow band, noise floor.

This module owns every frequency-domain reduction of a result or a profile.

Third-octave bands follow the IEC 61260-1 base-10 system: exact centres
``f_c = 1000 * 10**(k/10)`` Hz (integer k), edges ``f_c * 10**(±1/20)``, so neighbouring bands
share an edge and each band is 10**(1/10) (≈ 1.259) times wider than the one below it.
:func:`band_levels` splits the one-sided power spectrum of the *whole record* (rectangular
window) into these bands by summing FFT bin powers. Without a taper no power is lost or
counted twice, so the band powers add up to the mean square of the signal's content in the
covered range exactly (Parseval); the tests check this to 1e-10. The price is the leakage of a
rectangular window: a tone that does not complete an integer number of cycles in the record
spreads power into its neighbours, at a level that falls off with the number of bins between
the tone and the band (for a 1 s record and a 1 kHz tone half-way between two bins: -31.5 dB
in the adjacent band, 0.008 dB lost from its own). For the broadband responses of a rough
contact this is usually immaterial, but where the spectrum spans a large dynamic range (quiet
bands far above a loud low-frequency line; the figures and the report) use
``window="hann"``: leakage then falls as 1/f^6 (measured: 8 dB of leakage against -59 dB in a
quiet band of a truncated 1 s record), at the price of needing 4 bins per band.

Units: time signals in their own unit (accelerations [m/s^2], levels in dB re 1e-6 m/s^2 by
default), profiles in metres (levels in dB re 1 µm), frequencies in Hz, wavenumbers in rad/m.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy import signal as sps

__all__ = ["add_noise_floor", "band_levels", "band_powers", "narrowband_psd", "nominal_centre",
           "third_octave_bands", "total_level", "wavenumber_band_levels", "wavenumber_spectrum"]

# nominal mantissas x100 of the ten base-10 bands in a decade (IEC 61260-1, Annex E); kept as
# integers so that e.g. 315 / 10 gives the same double as the literal 31.5
_NOMINAL_X100 = (100, 125, 160, 200, 250, 315, 400, 500, 630, 800)

# relative tolerance on "upper edge <= fs/2": the edges carry round-off from 10**(k/10)
_EDGE_RTOL = 1e-12


# --------------------------------------------------------------------------------------------
# band definitions
# --------------------------------------------------------------------------------------------

def _band_index(f: ArrayLike) -> np.ndarray:
    """Integer k of the base-10 band whose exact centre is nearest to f (k = 0 at 1 unit)."""
    return np.rint(10.0 * np.log10(np.asarray(f, dtype=float))).astype(int)


def third_octave_bands(fmin: float = 20.0, fmax: float = 50e3
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Base-10 third-octave bands whose nominal centres lie in [fmin, fmax].

    Parameters
    ----------
    fmin, fmax : float
        Range of the nominal centre frequencies [Hz], ``0 < fmin <= fmax``. A band is included
        when its exact centre lies within a quarter band (a factor 10**(1/40) ≈ 1.06) of the
        range, which is the same as its nominal label lying in the range: ``fmin=20`` includes
        the band labelled 20 Hz whose exact centre is 19.95 Hz.

    Returns
    -------
    centres, lower, upper : ndarray, shape (n_bands,)
        Exact centre frequencies ``1000 * 10**(k/10)`` and band edges ``centres * 10**(∓1/20)``
        [Hz], in increasing order. ``upper[i] == lower[i + 1]`` up to round-off.

    Raises
    ------
    ValueError
        If the range is empty or not positive.
    """
    if not (fmin > 0 and fmax >= fmin and math.isfinite(fmax)):
        raise ValueError(f"third-octave range must satisfy 0 < fmin <= fmax < inf Hz, got "
                         f"fmin={fmin}, fmax={fmax}")
    k0 = math.ceil(10.0 * math.log10(fmin / 1000.0) - 0.25)
    k1 = math.floor(10.0 * math.log10(fmax / 1000.0) + 0.25)
    k = np.arange(k0, k1 + 1)
    fc = 1000.0 * 10.0 ** (k / 10.0)
    return fc, fc * 10.0 ** (-1.0 / 20.0), fc * 10.0 ** (1.0 / 20.0)


def nominal_centre(f: ArrayLike) -> float | np.ndarray:
    """Nominal label of the base-10 third-octave band nearest to ``f``.

    The labels are the IEC series ..., 20, 25, 31.5, 40, 50, 63, 80, 100, 125, 160, ...
    (e.g. 3981.07 Hz -> 4000, 31.62 Hz -> 31.5). The rule works in any unit and any decade,
    so it also labels wavelength bands (0.0316 m -> 0.0315 m).

    Parameters
    ----------
    f : float or array_like
        Exact centre(s) (or any frequency inside the band) [Hz or any unit], > 0.

    Returns
    -------
    float or ndarray
        Nominal label(s), same unit and shape as ``f``.
    """
    arr = np.asarray(f, dtype=float)
    if np.any(~(arr > 0)):
        raise ValueError("nominal_centre needs frequencies > 0")
    k = _band_index(arr)
    mant = np.asarray(_NOMINAL_X100, dtype=float)[np.mod(k, 10)]
    e = np.floor_divide(k, 10) - 2  # label = mantissa_x100 * 10**e
    # multiply by a positive power of ten, divide by the negative one: both correctly rounded
    out = np.where(e >= 0, mant * 10.0 ** np.maximum(e, 0), mant / 10.0 ** np.maximum(-e, 0))
    return float(out) if out.ndim == 0 else out


# --------------------------------------------------------------------------------------------
# FFT band sums
# --------------------------------------------------------------------------------------------

def _detrended(x: np.ndarray, axis: int, detrend: str | None) -> np.ndarray:
    if detrend is None or detrend == "none":
        return x
    if detrend not in ("constant", "linear"):
        raise ValueError(f"detrend must be 'constant', 'linear' or None, got {detrend!r}")
    return sps.detrend(x, axis=axis, type=detrend)


def _one_sided_power(x: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Bin frequencies [Hz] and one-sided bin powers [unit^2] along the last axis.

    ``p.sum(-1) == mean(x**2, -1)`` (Parseval): interior bins carry 2 |X_j|^2 / n^2, the DC bin
    and (for even n) the Nyquist bin carry |X_j|^2 / n^2 because they have no mirror image.
    """
    n = x.shape[-1]
    X = np.fft.rfft(x, axis=-1)
    p = (X.real**2 + X.imag**2) / float(n) ** 2
    last = p.shape[-1] if n % 2 else p.shape[-1] - 1
    p[..., 1:last] *= 2.0
    return np.fft.rfftfreq(n, 1.0 / fs), p


_WINDOWS = ("boxcar", "hann")


def _band_sums(x: ArrayLike, fs: float, lower: np.ndarray, upper: np.ndarray, axis: int,
               detrend: str | None, window: str = "boxcar") -> tuple[np.ndarray, np.ndarray]:
    """Band powers (bands on the last axis) and the number of FFT bins in each band."""
    if not fs > 0:
        raise ValueError(f"fs must be > 0 Hz, got {fs}")
    if window not in _WINDOWS:
        raise ValueError(f"window must be one of {', '.join(_WINDOWS)}, got {window!r}")
    x = np.moveaxis(np.asarray(x, dtype=float), axis, -1)
    if x.shape[-1] < 2:
        raise ValueError(f"a spectrum needs at least 2 samples along axis {axis}, "
                         f"got {x.shape[-1]}")
    lower = np.atleast_1d(np.asarray(lower, dtype=float))
    upper = np.atleast_1d(np.asarray(upper, dtype=float))
    xd = _detrended(x, -1, detrend)
    if window == "hann":
        # periodic Hann, rescaled to unit mean square so that band powers stay unbiased
        w = sps.get_window("hann", x.shape[-1], fftbins=True)
        xd = xd * (w / np.sqrt(np.mean(w * w)))
    f, p = _one_sided_power(xd, fs)
    # bin j belongs to the band with lower <= f_j < upper
    i_lo = np.searchsorted(f, lower, side="left")
    i_hi = np.searchsorted(f, upper, side="left")
    # an explicit sum per band: differences of a cumulative sum lose bands more than about
    # 130 dB below the total power to round-off
    pw = np.stack([p[..., a:b].sum(axis=-1) for a, b in zip(i_lo, i_hi, strict=True)],
                  axis=-1)
    return pw, i_hi - i_lo


def band_powers(x: ArrayLike, fs: float, lower: ArrayLike, upper: ArrayLike, *,
                axis: int = -1, detrend: str | None = "constant",
                window: str = "boxcar") -> np.ndarray:
    """Mean-square content of ``x`` in arbitrary frequency bands, from the one-sided FFT.

    The whole record is transformed, with a rectangular window by default or a periodic Hann
    window rescaled to unit mean square (``window="hann"``: leakage falls as 1/f^6 instead of
    1/f^2, so quiet bands next to loud ones are measured, at the cost of a main lobe of ±2
    bins). FFT bin j (frequency
    ``j fs / n``) belongs to a band when ``lower <= f_j < upper`` (half-open, so a bin on a
    shared edge is counted once, in the upper band). Interior bins carry twice their two-sided
    power; the DC bin and, for an even record length, the Nyquist bin carry it once. A band
    that holds no bin gets 0.

    Parameters
    ----------
    x : array_like, shape (..., n, ...)
        Signal on a uniform grid, time along ``axis`` [unit].
    fs : float
        Sampling rate [Hz].
    lower, upper : array_like, shape (n_bands,)
        Band edges [Hz].
    axis : int
        Time axis of ``x``.
    detrend : {'constant', 'linear', None}
        Removed from the record before the transform. A constant only changes the DC bin,
        so it changes no band with ``lower > 0``; a linear trend changes all bins.
    window : {'boxcar', 'hann'}
        Taper of the record (see above).

    Returns
    -------
    ndarray, shape of ``x`` with ``axis`` replaced by n_bands
        Band powers [unit^2]. For a signal whose content lies inside the bands they sum to
        ``mean(x**2)`` exactly (after detrending; for ``hann``, of the tapered record).
    """
    pw, _ = _band_sums(x, fs, np.asarray(lower), np.asarray(upper), axis, detrend, window)
    return np.moveaxis(pw, -1, axis)


def _power_to_db(power: np.ndarray, ref: float) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(power / ref**2)


def band_levels(x: ArrayLike, fs: float, *, fmin: float = 20.0, fmax: float = 50e3,
                ref: float = 1e-6, axis: int = -1, detrend: str | None = "constant",
                window: str = "boxcar") -> tuple[np.ndarray, np.ndarray]:
    """Third-octave band levels of a signal, from FFT bin powers summed per band.

    The method is :func:`band_powers` on the bands of :func:`third_octave_bands`: the whole
    record with a rectangular window (Parseval-exact; see the module notes on leakage), bins
    assigned by ``lower <= f < upper``, the DC bin in no band (every band has ``lower > 0``),
    the Nyquist bin counted once. Bands whose upper edge exceeds fs/2 are dropped (at
    fs = 100 kHz the highest band kept is 40 kHz, upper edge 44.7 kHz).

    Parameters
    ----------
    x : array_like, shape (..., n, ...)
        Signal on a uniform grid, time along ``axis`` (e.g. acceleration [m/s^2]).
    fs : float
        Sampling rate [Hz] (1e5 for the 1e-5 s output grid).
    fmin, fmax : float
        Range of the nominal band centres [Hz].
    ref : float
        Reference value of the levels [unit]; 1e-6 (m/s^2) by default.
    axis : int
        Time axis of ``x``; the bands replace it in the output.
    detrend : {'constant', 'linear', None}
        Trend removed before the transform (see :func:`band_powers`).
    window : {'boxcar', 'hann'}
        Taper (see :func:`band_powers`). Use ``hann`` for spectra with a large dynamic range
        (the rectangular window's leakage fills quiet bands); it needs at least 4 bins per
        band, i.e. a record longer than about 4 / (0.23 fmin) (0.9 s for 20 Hz).

    Returns
    -------
    centres : ndarray, shape (n_bands,)
        Exact band centres [Hz].
    levels : ndarray, shape of ``x`` with ``axis`` replaced by n_bands
        ``10 log10(band power / ref**2)`` [dB re ref]. ``-inf`` for a band with zero power;
        ``NaN`` for a band that holds no FFT bin (fewer than 4 with ``hann``: the record, of
        duration n/fs, is too short for the band's width), so that such bands never pass
        for measured silence.
    """
    if not ref > 0:
        raise ValueError(f"ref must be > 0, got {ref}")
    fc, lo, hi = third_octave_bands(fmin, fmax)
    keep = hi <= fs / 2.0 * (1.0 + _EDGE_RTOL)
    fc, lo, hi = fc[keep], lo[keep], hi[keep]
    pw, nbins = _band_sums(x, fs, lo, hi, axis, detrend, window)
    lev = _power_to_db(pw, ref)
    lev[..., nbins < (4 if window == "hann" else 1)] = np.nan
    return fc, np.moveaxis(lev, -1, axis)


def total_level(x: ArrayLike, ref: float = 1e-6, fmin: float | None = None,
                fmax: float | None = None, fs: float | None = None, *, axis: int = -1
                ) -> float | np.ndarray:
    """Overall level ``20 log10(rms / ref)`` of the mean-removed signal [dB re ref].

    Without ``fmin``/``fmax`` the rms is taken in the time domain. With either, the mean square
    is the sum of the one-sided FFT bin powers with ``fmin <= f < fmax`` (the same rule as
    :func:`band_powers`; a missing limit is open), which needs ``fs``.

    Parameters
    ----------
    x : array_like, shape (..., n, ...)
        Signal, time along ``axis`` [unit].
    ref : float
        Reference [unit]; 1e-6 (m/s^2) by default.
    fmin, fmax : float, optional
        Frequency limits [Hz].
    fs : float, optional
        Sampling rate [Hz]; required with ``fmin`` or ``fmax``.
    axis : int
        Time axis.

    Returns
    -------
    float or ndarray
        Level [dB re ref] (a float for a 1-D signal); ``-inf`` for a constant signal.
    """
    if not ref > 0:
        raise ValueError(f"ref must be > 0, got {ref}")
    x = np.asarray(x, dtype=float)
    if fmin is None and fmax is None:
        xm = x - x.mean(axis=axis, keepdims=True)
        ms = np.mean(xm * xm, axis=axis)
    else:
        if fs is None:
            raise ValueError("total_level needs fs [Hz] when fmin or fmax is given")
        lo = -np.inf if fmin is None else float(fmin)
        hi = np.inf if fmax is None else float(fmax)
        ms = band_powers(x, fs, [lo], [hi], axis=axis)
        ms = np.take(ms, 0, axis=axis)
    lev = _power_to_db(np.asarray(ms), ref)
    return float(lev) if lev.ndim == 0 else lev


# --------------------------------------------------------------------------------------------
# narrow band and noise
# --------------------------------------------------------------------------------------------

def narrowband_psd(x: ArrayLike, fs: float, *, resolution: float = 50.0,
                   ref: float | None = None, axis: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """One-sided power spectral density by Welch's method.

    Segments of ``nperseg = round(fs / resolution)`` samples (at most the record; at least 8),
    a periodic Hann window, 50 % overlap, the mean of each segment removed, the periodograms
    averaged. The bin spacing is ``fs / nperseg`` (= ``resolution`` when fs/resolution is an
    integer, and coarser when the record is shorter than one segment); the Hann window's
    equivalent noise bandwidth is 1.5 bins, so a tone of rms A shows as a peak density
    ``A**2 / (1.5 fs / nperseg)`` while a broadband density is unbiased. White noise of
    variance s**2 gives ``s**2 / (fs / 2)``.

    Parameters
    ----------
    x : array_like, shape (..., n, ...)
        Signal, time along ``axis`` [unit].
    fs : float
        Sampling rate [Hz].
    resolution : float
        Requested bin spacing [Hz].
    ref : float, optional
        If given, the density is returned as ``10 log10(psd / ref**2)`` [dB re ref^2/Hz].
    axis : int
        Time axis; the frequencies replace it in the output.

    Returns
    -------
    f : ndarray, shape (nperseg // 2 + 1,)
        Frequencies [Hz], 0 ... fs/2.
    psd : ndarray
        Density [unit^2/Hz] (or [dB re ref^2/Hz]).
    """
    if not (fs > 0 and resolution > 0):
        raise ValueError(f"fs and resolution must be > 0 Hz, got fs={fs}, "
                         f"resolution={resolution}")
    x = np.asarray(x, dtype=float)
    nper = int(min(x.shape[axis], max(8, round(fs / resolution))))
    f, p = sps.welch(x, fs=fs, window="hann", nperseg=nper, noverlap=nper // 2,
                     detrend="constant", scaling="density", axis=axis)
    if ref is not None:
        if not ref > 0:
            raise ValueError(f"ref must be > 0, got {ref}")
        p = _power_to_db(p, ref)
    return f, p


def add_noise_floor(x: ArrayLike, fs: float, rms: float,
                    seed: int | np.random.Generator = 0, *,
                    band: tuple[float, float] | None = None, axis: int = -1) -> np.ndarray:
    """Return ``x`` plus zero-mean Gaussian noise of exactly the given rms.

    Models the electrical noise floor of the mass accelerometer's measuring chain (the
    simulated floor of the paper's Fig. 14). The noise is white from 0 to fs/2 (band-limited
    by the sampling) or, with ``band``, restricted to ``f_lo <= f < f_hi`` by zeroing FFT bins
    outside the band. It is then scaled so that its realised rms along ``axis`` equals ``rms``
    (so the floor's band levels sit at ``rms**2 * bandwidth / (band width of the noise)`` in
    expectation, with the usual scatter of a random signal).

    Parameters
    ----------
    x : array_like, shape (..., n, ...)
        Clean signal [unit], time along ``axis``.
    fs : float
        Sampling rate [Hz].
    rms : float
        Noise rms [unit], >= 0.
    seed : int or numpy.random.Generator
        Seed or generator; the same seed gives the same noise.
    band : (float, float), optional
        Noise band [Hz].
    axis : int
        Time axis; each channel gets its own noise of the given rms.

    Returns
    -------
    ndarray, shape of ``x``
        Noisy signal (a new array).
    """
    if not rms >= 0:
        raise ValueError(f"noise rms must be >= 0, got {rms}")
    if not fs > 0:
        raise ValueError(f"fs must be > 0 Hz, got {fs}")
    x = np.asarray(x, dtype=float)
    if rms == 0 or x.size == 0:
        return x.copy()
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    noise = rng.standard_normal(np.moveaxis(x, axis, -1).shape)
    n = noise.shape[-1]
    if band is not None:
        f_lo, f_hi = band
        if not 0 <= f_lo < f_hi:
            raise ValueError(f"noise band must satisfy 0 <= f_lo < f_hi Hz, got {band}")
        f = np.fft.rfftfreq(n, 1.0 / fs)
        inside = (f >= f_lo) & (f < f_hi)
        if not inside.any():
            raise ValueError(f"noise band {band} Hz holds no FFT bin of a {n}-sample record "
                             f"at {fs} Hz")
        noise = np.fft.irfft(np.fft.rfft(noise, axis=-1) * inside, n, axis=-1)
    noise -= noise.mean(axis=-1, keepdims=True)
    scale = np.sqrt(np.mean(noise * noise, axis=-1, keepdims=True))
    noise *= rms / np.where(scale > 0, scale, 1.0)
    return x + np.moveaxis(noise, -1, axis)


# --------------------------------------------------------------------------------------------
# roughness profiles
# --------------------------------------------------------------------------------------------

def wavenumber_spectrum(z: ArrayLike, dx: float, *, resolution: float | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """One-sided wavenumber power spectral density of a profile (Welch, Hann, 50 % overlap).

    Same estimator as :func:`narrowband_psd`, with the sample spacing in metres and the
    frequency axis converted to angular wavenumber ``k = 2 pi / wavelength``. The density is
    normalised so that ``sum(psd) * dk`` is the profile's variance (minus the mean removed per
    segment), i.e. ``integral psd dk = rms**2``.

    Parameters
    ----------
    z : array_like, shape (n,)
        Heights [m] on a uniform grid.
    dx : float
        Grid spacing [m].
    resolution : float, optional
        Requested bin spacing ``dk`` [rad/m]. Default: 8 bins across the record's own
        spacing, ``dk = 2 pi * 8 / (n dx)`` (segments of n/8 samples, 15 of them with overlap).

    Returns
    -------
    k : ndarray, shape (n_k,)
        Angular wavenumber [rad/m], 0 ... pi/dx.
    psd : ndarray, shape (n_k,)
        Density [m^2/(rad/m)].
    """
    if not dx > 0:
        raise ValueError(f"dx must be > 0 m, got {dx}")
    z = np.asarray(z, dtype=float)
    n = z.shape[-1]
    dk = resolution if resolution is not None else 2.0 * np.pi * 8.0 / (n * dx)
    if not dk > 0:
        raise ValueError(f"resolution must be > 0 rad/m, got {resolution}")
    # spatial frequency nu = k / (2 pi) [1/m]; density per rad/m = density per (1/m) / (2 pi)
    nu, p = narrowband_psd(z, 1.0 / dx, resolution=dk / (2.0 * np.pi))
    return 2.0 * np.pi * nu, p / (2.0 * np.pi)


def wavenumber_band_levels(z: ArrayLike, dx: float, *, lambda_min: float | None = None,
                           lambda_max: float | None = None, ref: float = 1e-6,
                           detrend: str | None = "constant", axis: int = -1
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Third-octave band levels of a profile in wavelength bands [dB re 1 µm].

    The bands are the base-10 series applied to wavelength: exact centres ``10**(k/10)`` m
    (nominal labels 0.04, 0.0315, 0.025, ... m, see :func:`nominal_centre`), edges
    ``centre * 10**(±1/20)``. Equivalently they are base-10 third-octave bands of the spatial
    frequency ``1/wavelength`` [1/m], and the band powers are FFT bin sums exactly as in
    :func:`band_powers` (rectangular window, Parseval-exact). A bin of wavelength L belongs to
    the band with ``lower < L <= upper`` (the half-open rule in 1/L). Level
    ``10 log10(band mean square / ref**2)``, the usual rail/wheel roughness level
    (ISO 3095, EN 15610) with ref = 1 µm.

    Parameters
    ----------
    z : array_like, shape (..., n, ...)
        Heights [m] on a uniform grid along ``axis``.
    dx : float
        Spacing [m].
    lambda_min, lambda_max : float, optional
        Range of nominal centre wavelengths [m]. Default: from 2 dx to the record length
        ``n dx``. Bands whose shortest wavelength is below 2 dx (beyond the Nyquist
        wavenumber) are dropped.
    ref : float
        Reference [m]; 1e-6 by default.
    detrend : {'constant', 'linear', None}
        Trend removed first (a linear one removes a tilt of the trace).
    axis : int
        Axis of the profile; the bands replace it in the output.

    Returns
    -------
    wavelengths : ndarray, shape (n_bands,)
        Exact centre wavelengths [m], in *decreasing* order (increasing wavenumber, like the
        frequency bands a contact sliding at constant speed turns them into: f = v / L).
    levels : ndarray
        [dB re ref]; ``-inf`` for zero power, ``NaN`` for a band that holds no FFT bin
        (wavelengths near or beyond the record length).
    """
    if not dx > 0:
        raise ValueError(f"dx must be > 0 m, got {dx}")
    if not ref > 0:
        raise ValueError(f"ref must be > 0 m, got {ref}")
    n = np.asarray(z).shape[axis]
    lmin = 2.0 * dx if lambda_min is None else float(lambda_min)
    lmax = n * dx if lambda_max is None else float(lambda_max)
    if not 0 < lmin <= lmax:
        raise ValueError(f"wavelength range must satisfy 0 < lambda_min <= lambda_max m, got "
                         f"lambda_min={lmin}, lambda_max={lmax}")
    # the band of wavelength centre L is the band of spatial-frequency centre 1/L
    nu_c, nu_lo, nu_hi = third_octave_bands(1000.0 / lmax, 1000.0 / lmin)
    nu_c, nu_lo, nu_hi = nu_c / 1000.0, nu_lo / 1000.0, nu_hi / 1000.0
    keep = nu_hi <= 0.5 / dx * (1.0 + _EDGE_RTOL)
    nu_c, nu_lo, nu_hi = nu_c[keep], nu_lo[keep], nu_hi[keep]
    pw, nbins = _band_sums(z, 1.0 / dx, nu_lo, nu_hi, axis, detrend)
    lev = _power_to_db(pw, ref)
    lev[..., nbins == 0] = np.nan
    # 1/nu_c re-rounds: give the centres exactly as 10**(k/10)
    k = _band_index(1.0 / nu_c)
    return 10.0 ** (k / 10.0), np.moveaxis(lev, -1, axis)
