"""Spectra of time signals and roughness profiles: third-octave bands, narrow band, noise floor.

Third-octave bands use the IEC 61260-1 base-10 system: exact centres f_c = 1000 * 10^(k/10) Hz,
edges f_c * 10^(±1/20). ``band_levels`` splits the one-sided power spectrum of the whole record
(rectangular window, mean removed) into the bands by summing FFT bin powers, so the band powers
add up to the signal's mean square exactly (Parseval), which the tests check. A bin belongs to
the band with lower <= f < upper. Levels are in dB re 1e-6 m/s^2 unless another reference is
given.
"""

from __future__ import annotations

import numpy as np
from scipy import signal as sps

__all__ = ["add_noise_floor", "band_levels", "band_powers", "narrowband_psd", "nominal_centre",
           "third_octave_bands", "total_level", "wavenumber_spectrum"]

_NOMINAL = [1.0, 1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0]


def third_octave_bands(fmin: float = 20.0, fmax: float = 50e3
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Base-10 third-octave bands whose nominal centres lie in [fmin, fmax].

    Returns
    -------
    centres, lower, upper : ndarray
        Exact centre and edge frequencies [Hz].
    """
    # half a band of tolerance: fmin = 20 Hz includes the band labelled 20 Hz (19.95 Hz)
    k0 = int(np.ceil(10 * np.log10(fmin / 1000.0) - 0.5))
    k1 = int(np.floor(10 * np.log10(fmax / 1000.0) + 0.5))
    k = np.arange(k0, k1 + 1)
    fc = 1000.0 * 10.0 ** (k / 10.0)
    return fc, fc * 10 ** (-1 / 20), fc * 10 ** (1 / 20)


def nominal_centre(f: float) -> float:
    """The nominal label of an exact base-10 third-octave centre (e.g. 3981 Hz -> 4000)."""
    e = int(np.floor(np.log10(f) + 1e-9))
    m = f / 10.0**e
    best = min(_NOMINAL + [10.0], key=lambda x: abs(np.log10(x / m)))
    return float(best * 10.0**e)


def band_powers(x: np.ndarray, fs: float, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Mean-square power of x in each band [unit^2], from the one-sided FFT of the record."""
    x = np.asarray(x, dtype=float)
    x = x - x.mean()
    n = x.size
    X = np.fft.rfft(x)
    p = np.abs(X) ** 2 / n**2
    p[1:] *= 2.0
    if n % 2 == 0:
        p[-1] /= 2.0  # Nyquist bin appears once
    f = np.fft.rfftfreq(n, 1.0 / fs)
    lo_idx = np.searchsorted(f, lower, side="left")
    hi_idx = np.searchsorted(f, upper, side="left")
    c = np.concatenate([[0.0], np.cumsum(p)])
    return c[hi_idx] - c[lo_idx]


def band_levels(x: np.ndarray, fs: float, *, fmin: float = 20.0, fmax: float = 50e3,
                ref: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Third-octave band levels of a signal.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Signal (e.g. acceleration [m/s^2]) on a uniform grid.
    fs : float
        Sampling rate [Hz]. Bands whose upper edge exceeds fs/2 are dropped.
    fmin, fmax : float
        Range of band centres [Hz].
    ref : float
        Reference of the levels (1e-6 m/s^2 by default).

    Returns
    -------
    centres : ndarray [Hz]
    levels : ndarray [dB re ref]
        ``-inf`` for a band without power; NaN for a band that holds no FFT bin (record too
        short for its bandwidth).
    """
    fc, lo, hi = third_octave_bands(fmin, fmax)
    keep = hi <= fs / 2 * (1 + 1e-12)
    fc, lo, hi = fc[keep], lo[keep], hi[keep]
    pw = band_powers(x, fs, lo, hi)
    n = np.asarray(x).size
    df = fs / n
    has_bin = np.floor((hi - 1e-12) / df) >= np.ceil(lo / df)
    with np.errstate(divide="ignore"):
        lev = 10.0 * np.log10(pw / ref**2)
    lev[~has_bin] = np.nan
    return fc, lev


def total_level(x: np.ndarray, ref: float = 1e-6) -> float:
    """Overall level 20 log10(rms(x - mean) / ref) [dB re ref]."""
    x = np.asarray(x, dtype=float)
    r = float(np.sqrt(np.mean((x - x.mean()) ** 2)))
    return 20.0 * np.log10(r / ref) if r > 0 else -np.inf


def narrowband_psd(x: np.ndarray, fs: float, *, resolution: float = 50.0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """One-sided power spectral density by Welch's method.

    Hann window, 50 % overlap, segment length fs/resolution samples (at most the record), so the
    bin spacing is ``resolution`` Hz and the noise bandwidth 1.5 x that.

    Returns
    -------
    f : ndarray [Hz]
    psd : ndarray [unit^2/Hz]
    """
    x = np.asarray(x, dtype=float)
    nper = int(min(x.size, max(8, round(fs / resolution))))
    return sps.welch(x, fs=fs, window="hann", nperseg=nper, noverlap=nper // 2,
                     detrend="constant", scaling="density")


def add_noise_floor(x: np.ndarray, fs: float, rms: float, seed: int = 0) -> np.ndarray:
    """x plus white Gaussian noise of the given rms (simulated accelerometer floor, Fig. 14).

    Sampled at ``fs`` [Hz], the noise is white up to fs/2; ``rms`` in the unit of x, seeded.
    """
    rng = np.random.default_rng(seed)
    return np.asarray(x, dtype=float) + rng.normal(0.0, rms, size=np.asarray(x).size)


def wavenumber_spectrum(z: np.ndarray, dx: float, *, resolution: float | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """One-sided wavenumber PSD of a profile (Welch, Hann).

    Parameters
    ----------
    z : ndarray
        Heights [m] on a uniform grid.
    dx : float
        Spacing [m].
    resolution : float, optional
        Bin spacing in cycles per metre (default: record length / 8).

    Returns
    -------
    k : ndarray
        Wavenumber [rad/m].
    psd : ndarray
        [m^2 / (rad/m)].
    """
    z = np.asarray(z, dtype=float)
    fs = 1.0 / dx
    res = resolution if resolution is not None else 8.0 / (z.size * dx)
    f, p = narrowband_psd(z, fs, resolution=res)
    return 2 * np.pi * f, p / (2 * np.pi)
