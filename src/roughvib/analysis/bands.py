"""Octave and third-octave band levels by an IEC 61260-1:2014 class 1 filter bank.

This module owns the band-pass filter bank behind the band levels of a run (the run report,
Fig. 14, the seed-ensemble report) and :func:`band_levels`, the one entry point that gives
either those filtered levels (``method="filter"``) or the Hann-tapered FFT band sums of
:func:`roughvib.analysis.spectra.band_powers` (``method="fft"``).

The bank
--------
Mid-band frequencies are base-10 (IEC 61260-1:2014, 5.2-5.4): ``G = 10**(3/10)``,
``f_m = 1000 G**(x/b)`` Hz for bandwidth designator 1/b with b = 1 (octaves) or 3 (third
octaves), band edges ``f_m G**(±1/(2b))``. Each band is a digital Butterworth band-pass of
order 8 per band edge (16 poles), designed by :func:`scipy.signal.butter` in second-order
sections and run causally with :func:`scipy.signal.sosfilt` (a zero-phase pass would square
the response and put 6 dB instead of 3 dB at the band edges, outside the class 1 limits).

Class 1 sets a minimum selectivity and allows any beyond it. Six-pole bands, which meet the
minimum, attenuate the mid-band frequencies of their neighbours by only 18 to 21 dB: in a dip
next to a band 20 to 35 dB louder they read the loud band's skirt (up to 12 dB too high on the
``paper`` scene). At order 8 the third-octave filters attenuate their neighbours' mid-band
frequencies by 46 to 54 dB and the next ones by more than 90 dB, so a band reads a tone 35 dB
weaker than the tone in its neighbour within 0.35 dB, one 20 dB weaker within 0.01 dB (tested).
Order 6 (12 poles) would give 35 to 41 dB, a 3 dB error at 35 dB contrast.

The design bandwidth is not the nominal one: the -3 dB points sit slightly inside the band
edges, chosen so that the filter's normalized effective bandwidth (IEC 61260-1:2014, 5.11, the
integral of ``|H|**2 / Omega`` over ``Omega = f / f_m``) equals the reference bandwidth
``ln(G) / b`` of 5.12. With the -3 dB points on the edges a 16-pole Butterworth band is 0.6 %
(0.03 dB) too wide (a six-pole one 5 %, 0.2 dB), and band levels of broadband signals would read
that much high; with the correction the summed band powers of white noise equal its mean square
in the covered range (tested; the digital filters' effective bandwidths stay within 0.01 dB of
the reference). The relative attenuation at the band edge is 3.1 to 3.4 dB for third octaves,
3.1 to 3.8 dB for octaves (class 1 allows up to 5.3 dB just inside the edge and asks for at
least 1.2 dB just outside).

Low bands are filtered at a reduced rate (multirate): the record is low-pass filtered
(elliptic, zero phase with :func:`scipy.signal.sosfiltfilt`) and decimated by 2, repeatedly,
and each band is run at the lowest rate at which its upper edge lies below a quarter of that
rate (half its Nyquist frequency). A 16-pole band-pass for the 20 Hz band designed at
100 kHz would have poles within 3e-5 of the unit circle; at 97.7 Hz (ten halvings) it is well
conditioned. The anti-alias filters pass up to 0.28 of the rate after the halving (a band's
upper edge is at most 0.25 of it) and attenuate everything that folds by at least 180 dB (90 dB
each way): they add to the bands' selectivity and never limit it. :meth:`FilterBank.response`
gives each band's effective response from the input, the anti-alias stages and the aliasing of
each decimation included; the tests check it against the class 1 limits of IEC 61260-1:2014
Table 1 and for leakage from any frequency up to ``fs/2``, and also drive the bank itself with
tones at the normative frequencies and with two tones in neighbouring bands.

The bands above a quarter of the input rate (25, 31.5 and 40 kHz at 100 kHz) run at the
input rate, where the bilinear map widens their lower skirt; they are designed at order 12,
which gives them at least the selectivity of the others (at order 8 the 40 kHz band would
attenuate the 31.5 kHz mid-band frequency by only 34 dB).

Start-up and memory
-------------------
A sharper filter rings longer. :attr:`FilterBank.decay_time` gives, per band, the time in
which its slowest free oscillation falls by a factor e (8.7 dB): 0.38 s for the 20 Hz third
octave, 0.12 s at 63 Hz, 7.7 ms at 1 kHz, about 1.8 / B for a band of bandwidth B (the six-pole
bands: 0.7 / B). The filters start from the steady state of a constant input equal to the first
sample (:func:`scipy.signal.sosfilt_zi`), so an offset does not ring; the signal's own onset
does. ``settle`` [s] lets the samples before the analysis window drive the filters without being
averaged: the run's figures filter the record from t = 0 and average over the analysis window
only; a run's 0.14 s run-in is 1.2 decay times of the 63 Hz band. A band reads NaN when the
averaged stretch, of duration T, is short for its bandwidth B: ``B T < 4``, the rule of the
Hann-tapered FFT band sums (4 bins of width 1/T). On a 0.29 s window (two periods at 7 Hz) this
leaves out the bands below 63 Hz. Whatever happens within a few decay times before the window
(the run's own start, a lift-off in the run-in) still reaches the lowest bands: on a 1 s run of
``paper-100mms`` the plate's 40 Hz band, some 85 dB below the loudest band, reads 55 dB averaged
from 0.14 s (a lift-off at 0.10 s) and 42 dB averaged from 0.43 s (the six-pole band: 47 dB
both). For the bands below 63 Hz give a run-in of a few of their decay times.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import signal as sps

__all__ = ["MIN_BANDWIDTH_TIME", "BandLevels", "FilterBank", "band_levels",
           "design_filter_bank", "mid_band_frequencies"]

G = 10.0 ** (3.0 / 10.0)
"""Octave frequency ratio of the base-10 system (IEC 61260-1:2014, 5.2)."""

REFERENCE_FREQUENCY = 1000.0
"""Reference frequency f_r [Hz] of the mid-band series."""

BUTTERWORTH_ORDER = 8
"""Butterworth order per band edge (scipy's ``N`` of a band-pass: 2N poles in all). Eight
(16 poles) is the smallest order whose filters attenuate the mid-band frequencies of the
neighbouring bands by more than 44.6 dB, so that a band reads a tone 35 dB weaker than the
tone in its neighbour within 0.5 dB (module notes)."""

TOP_BUTTERWORTH_ORDER = 12
"""Smallest order per band edge of the bands that run at the input rate with their upper edge
above a quarter of it (25, 31.5 and 40 kHz at 100 kHz): the bilinear map widens their lower
skirt, and at order 8 the 40 kHz band attenuates the 31.5 kHz mid-band frequency by only
34 dB."""

MAX_ORDER = 12
"""Largest order per band edge :func:`design_filter_bank` accepts."""

FRACTIONS = (1, 3)
"""Bandwidth designators 1/b supported: octaves and third octaves."""

METHODS = ("filter", "fft")

# a band runs at the lowest rate R (fs / 2**k) at which its upper edge is <= this fraction of R
_EDGE_PER_RATE = 0.25
# anti-alias low-pass before each halving (elliptic, run forward and backward): pass band to
# this fraction of the input rate, ripple and stop-band attenuation of one pass [dB]
_AA_PASS = 0.14
_AA_ORDER = 10
_AA_RIPPLE_DB = 0.005
_AA_STOP_DB = 90.0
# relative tolerance on "upper edge <= fs/2": the edges carry round-off from 10**(x/10)
_EDGE_RTOL = 1e-12
MIN_BANDWIDTH_TIME = 4.0
"""Smallest product B T [-] of a band's nominal bandwidth B and the averaged duration T for
which the band is given a level (else NaN): the rule of the Hann-tapered FFT band sums, at
least 4 bins of width 1/T per band."""


# --------------------------------------------------------------------------------------------
# mid-band frequencies
# --------------------------------------------------------------------------------------------

def _check_fraction(fraction: int) -> int:
    if fraction not in FRACTIONS:
        raise ValueError(f"fraction must be 1 (octave) or 3 (third octave), got {fraction!r}")
    return int(fraction)


def mid_band_frequencies(fraction: int = 3, fmin: float = 20.0, fmax: float = 20e3
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Base-10 mid-band frequencies and band edges of IEC 61260-1:2014 in a range.

    Parameters
    ----------
    fraction : {1, 3}
        Bandwidth designator 1/b: 1 for octaves, 3 for third octaves.
    fmin, fmax : float
        Range of the nominal mid-band frequencies [Hz], ``0 < fmin <= fmax``. A band is
        included when its exact mid-band frequency lies within a quarter band of the range
        (the same as its nominal label lying in it: ``fmin=20`` includes the third octave
        labelled 20 Hz, exact 19.95 Hz).

    Returns
    -------
    nominal, exact, lower, upper : ndarray, shape (n_bands,)
        Nominal labels (31.5, 63, 125, ... for octaves), exact mid-band frequencies
        ``1000 G**(x/b)`` and band edges ``exact * G**(∓1/(2b))`` [Hz], increasing.
    """
    from roughvib.analysis.spectra import nominal_centre

    b = _check_fraction(fraction)
    if not (fmin > 0 and fmax >= fmin and math.isfinite(fmax)):
        raise ValueError(f"band range must satisfy 0 < fmin <= fmax < inf Hz, got "
                         f"fmin={fmin}, fmax={fmax}")
    # x/b = 10/3 log10(f/1000) / 1 ... exactly: log_G(f/1000) = 10 log10(f/1000) / 3
    lo = b * 10.0 * math.log10(fmin / REFERENCE_FREQUENCY) / 3.0
    hi = b * 10.0 * math.log10(fmax / REFERENCE_FREQUENCY) / 3.0
    x = np.arange(math.ceil(lo - 0.25), math.floor(hi + 0.25) + 1)
    # G**(x/b) as 10**(3x / (10 b)): for b = 3 this is 10**(x/10), the same doubles as the
    # third-octave bands of analysis.spectra
    exact = REFERENCE_FREQUENCY * 10.0 ** (3.0 * x / (10.0 * b))
    half = 10.0 ** (3.0 / (20.0 * b))
    nominal = nominal_centre(exact) if exact.size else exact.copy()
    return np.atleast_1d(nominal), exact, exact / half, exact * half


# --------------------------------------------------------------------------------------------
# design
# --------------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=8)
def _design_halfwidth(fraction: int, order: int) -> float:
    """Half-width ``h`` of the design pass band, ``Omega`` in [G**-h, G**h] at -3 dB.

    Chosen so that the analogue prototype's normalized effective bandwidth,
    ``integral |H(Omega)|**2 dOmega / Omega`` with
    ``|H|**2 = 1 / (1 + ((Omega - 1/Omega) / beta)**(2 order))``, equals ``ln(G) / b``
    (IEC 61260-1:2014, 5.11 and 5.12). In ``v = ln Omega`` the integrand is
    ``1 / (1 + (2 sinh v / beta)**(2 order))``.
    """
    from scipy import integrate, optimize

    target = math.log(G) / fraction

    def effective(beta: float) -> float:
        def f(v: float) -> float:
            return 1.0 / (1.0 + (2.0 * math.sinh(v) / beta) ** (2 * order))
        vmax = math.asinh(beta * 1e3)  # |H|^2 < 1e-18 beyond for order >= 3
        return 2.0 * integrate.quad(f, 0.0, vmax, limit=200, epsabs=0.0, epsrel=1e-12)[0]

    beta_nominal = G ** (0.5 / fraction) - G ** (-0.5 / fraction)
    beta = optimize.brentq(lambda bb: effective(bb) - target, 0.5 * beta_nominal,
                           beta_nominal, xtol=1e-14, rtol=1e-13)
    # Omega_h - 1/Omega_h = beta
    omega_h = 0.5 * (beta + math.sqrt(beta * beta + 4.0))
    return math.log(omega_h) / math.log(G)


@functools.lru_cache(maxsize=4)
def _aa_sos() -> np.ndarray:
    """Anti-alias low-pass of one halving, normalized to the input rate (fs = 1)."""
    return sps.ellip(_AA_ORDER, _AA_RIPPLE_DB, _AA_STOP_DB, _AA_PASS, btype="lowpass",
                     output="sos", fs=1.0)


def _fold(f: np.ndarray, rate: float) -> np.ndarray:
    """Frequency [Hz] at which a tone of frequency f appears when sampled at ``rate``."""
    r = np.mod(f, rate)
    return np.minimum(r, rate - r)


def _power_gain(sos: np.ndarray, f: np.ndarray, rate: float) -> np.ndarray:
    _, h = sps.sosfreqz(sos, worN=np.asarray(f, dtype=float), fs=rate)
    return h.real**2 + h.imag**2


@dataclass(frozen=True)
class FilterBank:
    """A designed multirate band-pass filter bank (see the module notes).

    Attributes
    ----------
    fs : float
        Input sampling rate [Hz].
    fraction : int
        Bandwidth designator 1/b (1 or 3).
    center_hz, exact_hz, lower_hz, upper_hz : ndarray, shape (n_bands,)
        Nominal and exact mid-band frequencies and nominal band edges [Hz].
    stage : ndarray of int, shape (n_bands,)
        Number of halvings before each band's filter: it runs at ``fs / 2**stage``.
    order : ndarray of int, shape (n_bands,)
        Butterworth order per band edge of each band (:data:`BUTTERWORTH_ORDER`, or at least
        :data:`TOP_BUTTERWORTH_ORDER` for the bands near ``fs/2``).
    band_sos : tuple of ndarray, each shape (order, 6)
        Each band's second-order sections at its own rate.
    aa_sos : ndarray, shape (n_sections, 6)
        The anti-alias low-pass of one halving, designed for an input rate of 1 (it is the
        same filter at every stage, scaled with the rate).
    """

    fs: float
    fraction: int
    center_hz: np.ndarray
    exact_hz: np.ndarray
    lower_hz: np.ndarray
    upper_hz: np.ndarray
    stage: np.ndarray
    order: np.ndarray
    band_sos: tuple
    aa_sos: np.ndarray

    @property
    def rates(self) -> np.ndarray:
        """Rate each band's filter runs at [Hz], shape (n_bands,)."""
        return self.fs / 2.0 ** self.stage

    @property
    def decay_time(self) -> np.ndarray:
        """Decay time of each band's filter [s], shape (n_bands,).

        The time in which the slowest free oscillation of the band-pass (its pole of largest
        modulus ``r`` at the band's rate ``R``: ``-1 / (R ln r)``) falls by a factor e in
        amplitude, 8.7 dB: a start-up or a burst before the averaged stretch has faded by
        ``8.7 settle / decay_time`` dB when the average begins. The anti-alias stages before
        a decimated band ring as well, but fade about three times faster.
        """
        out = np.empty(self.exact_hz.size)
        for j, (sos, rate) in enumerate(zip(self.band_sos, self.rates, strict=True)):
            r = max(float(np.max(np.abs(np.roots(section[3:])))) for section in sos)
            out[j] = -1.0 / (rate * math.log(r))
        return out

    def response(self, f: ArrayLike, bands: ArrayLike | None = None) -> np.ndarray:
        """Effective power gain from the input to each band's output at frequencies ``f``.

        A tone of frequency f at the input passes the anti-alias low-pass of each halving
        (forward and backward: power gain ``|H_aa|**4``), is folded into the lower rate's
        base band by the decimation, and meets the band's filter at the folded frequency.

        Parameters
        ----------
        f : array_like, shape (n_f,)
            Input frequencies [Hz], ``0 <= f <= fs/2``.
        bands : array_like of int, optional
            Indices of the bands wanted (default: all).

        Returns
        -------
        ndarray, shape (n_wanted, n_f)
            ``|output amplitude / input amplitude|**2`` [-] of a steady tone.
        """
        f = np.atleast_1d(np.asarray(f, dtype=float))
        idx = (np.arange(self.exact_hz.size) if bands is None
               else np.atleast_1d(np.asarray(bands, dtype=int)))
        out = np.empty((idx.size, f.size))
        n_stage = int(self.stage[idx].max()) + 1 if idx.size else 0
        gain = np.ones_like(f)
        fk = f.copy()
        for k in range(n_stage):
            rate = self.fs / 2.0**k
            for i in np.flatnonzero(self.stage[idx] == k):
                out[i] = gain * _power_gain(self.band_sos[idx[i]], fk, rate)
            if k + 1 < n_stage:
                gain = gain * _power_gain(self.aa_sos, fk / rate, 1.0) ** 2
                fk = _fold(fk, rate / 2.0)
        return out

    def relative_attenuation(self, omega: ArrayLike) -> np.ndarray:
        """Relative attenuation of each band at normalized frequencies ``omega`` [dB].

        ``ΔA(Omega) = A(Omega f_m) - A(f_m)`` with ``A = -10 lg(power gain)`` of
        :meth:`response` (IEC 61260-1:2014, formulas (7) and (8), reference at the exact
        mid-band frequency).

        Parameters
        ----------
        omega : array_like, shape (n_omega,)
            ``f / f_m`` [-], > 0. Frequencies above ``fs/2`` give ``+inf``.

        Returns
        -------
        ndarray, shape (n_bands, n_omega)
            [dB]
        """
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        out = np.full((self.exact_hz.size, omega.size), np.inf)
        for j, fm in enumerate(self.exact_hz):
            f = fm * omega
            ok = f <= self.fs / 2.0
            g = self.response(np.concatenate(([fm], f[ok])), [j])[0]
            with np.errstate(divide="ignore"):
                out[j, ok] = 10.0 * np.log10(g[0] / g[1:])
        return out

    def mean_squares(self, x: ArrayLike, *, settle: float = 0.0) -> np.ndarray:
        """Mean square of each band's output [unit^2].

        Parameters
        ----------
        x : array_like, shape (..., n)
            Signal at ``fs``, time along the last axis.
        settle : float
            Time [s] at the start of the record that drives the filters but is not averaged.

        Returns
        -------
        ndarray, shape (..., n_bands)
            Mean square of each band's output after ``settle``; NaN for a band whose
            averaged stretch of duration T is too short for its nominal bandwidth B,
            ``B T < 4`` (:data:`MIN_BANDWIDTH_TIME`).
        """
        x = np.asarray(x, dtype=float)
        out = np.full(x.shape[:-1] + (self.exact_hz.size,), np.nan)
        n_stage = int(self.stage.max()) + 1 if self.stage.size else 0
        xk = x
        for k in range(n_stage):
            rate = self.fs / 2.0**k
            skip = math.ceil(settle * rate - 1e-9)
            for j in np.flatnonzero(self.stage == k):
                span = (xk.shape[-1] - skip) / rate
                if span * (self.upper_hz[j] - self.lower_hz[j]) < MIN_BANDWIDTH_TIME:
                    continue
                y = _sosfilt_from_rest(self.band_sos[j], xk)
                tail = y[..., skip:]
                out[..., j] = np.mean(tail * tail, axis=-1)
            if k + 1 < n_stage:
                xk = _halve(self.aa_sos, xk)
        return out


def _sosfilt_from_rest(sos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Causal filtering that starts in the steady state of a constant input ``x[..., 0]``."""
    zi = sps.sosfilt_zi(sos)  # (n_sections, 2)
    zi = zi.reshape(zi.shape[0], *([1] * (x.ndim - 1)), 2) * x[..., 0][None, ..., None]
    y, _ = sps.sosfilt(sos, x, axis=-1, zi=zi)
    return y


def _halve(aa: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Low-pass (zero phase) and keep every second sample."""
    if x.shape[-1] > 3 * (2 * aa.shape[0] + 1):
        y = sps.sosfiltfilt(aa, x, axis=-1)
    else:  # too short for the padding: the bands of this record read NaN anyway
        y = x
    return y[..., ::2]


def design_filter_bank(fs: float, *, fraction: int = 3, fmin: float = 20.0,
                       fmax: float | None = None, order: int = BUTTERWORTH_ORDER
                       ) -> FilterBank:
    """Design the multirate IEC 61260-1 class 1 filter bank for a sampling rate.

    Parameters
    ----------
    fs : float
        Sampling rate [Hz], > 0.
    fraction : {1, 3}
        Octave (1) or third-octave (3) bands.
    fmin, fmax : float
        Range of the nominal mid-band frequencies [Hz] (see :func:`mid_band_frequencies`).
        ``fmax=None``: up to the highest band whose upper edge is at most ``fs/2``; bands
        above that are dropped in any case.
    order : int
        Butterworth order per band edge, 3 to :data:`MAX_ORDER` (2 ``order`` poles per
        band); the bands whose upper edge lies above ``fs/4`` get at least
        :data:`TOP_BUTTERWORTH_ORDER`. The default :data:`BUTTERWORTH_ORDER` is the bank of
        :func:`band_levels`. Every order from 3 to 12 meets class 1; ``order=3`` gives
        six-pole bands, which attenuate the neighbouring bands' mid-band frequencies by only
        18 to 21 dB.

    Returns
    -------
    FilterBank
    """
    if not (fs > 0 and math.isfinite(fs)):
        raise ValueError(f"fs must be a finite rate > 0 Hz, got {fs}")
    if isinstance(order, bool) or not isinstance(order, int | np.integer) or not (
            3 <= order <= MAX_ORDER):
        raise ValueError(f"order must be an integer from 3 to {MAX_ORDER}, got {order!r}")
    b = _check_fraction(fraction)
    top = fs / 2.0 if fmax is None else min(float(fmax), fs / 2.0)
    if not fmin > 0:
        raise ValueError(f"fmin must be > 0 Hz, got {fmin}")
    nominal, exact, lower, upper = mid_band_frequencies(b, fmin, max(top, fmin))
    keep = upper <= fs / 2.0 * (1.0 + _EDGE_RTOL)
    nominal, exact, lower, upper = nominal[keep], exact[keep], lower[keep], upper[keep]
    # stage k: the largest k with upper <= _EDGE_PER_RATE * fs / 2**k (0 for the top bands)
    with np.errstate(divide="ignore"):
        k = np.floor(np.log2(_EDGE_PER_RATE * fs / upper) + 1e-12)
    stage = np.maximum(k, 0).astype(int)
    orders = np.where(k < 0, max(int(order), TOP_BUTTERWORTH_ORDER), int(order)).astype(int)
    rate = fs / 2.0**stage
    sos = []
    for fm, n, r in zip(exact, orders, rate, strict=True):
        h = _design_halfwidth(b, int(n))
        # the design edges lie inside the nominal ones, so below fs/2 for every kept band
        sos.append(sps.butter(int(n), [fm * G**-h, fm * G**h], btype="bandpass",
                              output="sos", fs=r))
    return FilterBank(fs=float(fs), fraction=b, center_hz=nominal, exact_hz=exact,
                      lower_hz=lower, upper_hz=upper, stage=stage, order=orders,
                      band_sos=tuple(sos), aa_sos=_aa_sos())


@functools.lru_cache(maxsize=16)
def _cached_bank(fs: float, fraction: int, fmin: float, fmax: float | None) -> FilterBank:
    """:func:`design_filter_bank`, kept for repeated calls (private: never handed out)."""
    return design_filter_bank(fs, fraction=fraction, fmin=fmin, fmax=fmax)


# --------------------------------------------------------------------------------------------
# band levels
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class BandLevels:
    """Band levels of a signal (:func:`band_levels`).

    Attributes
    ----------
    center_hz : ndarray, shape (n_bands,)
        Nominal mid-band frequencies [Hz] (labels: 20, 25, 31.5, ...).
    exact_hz : ndarray, shape (n_bands,)
        Exact mid-band frequencies ``1000 G**(x/b)`` [Hz].
    level_db : ndarray, shape (..., n_bands)
        ``10 lg(mean_square / reference**2)`` [dB re reference]: the level of the rms in the
        band. ``-inf`` for zero power, NaN where the record is too short for the band.
    mean_square : ndarray, shape (..., n_bands)
        Mean square of the signal in each band [unit^2].
    method : str
        ``"filter"`` or ``"fft"``.
    """

    center_hz: np.ndarray
    exact_hz: np.ndarray
    level_db: np.ndarray
    mean_square: np.ndarray
    method: str


def _fft_mean_squares(x: np.ndarray, fs: float, lower: np.ndarray, upper: np.ndarray
                      ) -> np.ndarray:
    """Hann-tapered FFT band sums (analysis.spectra.band_powers), NaN below 4 bins per band."""
    from roughvib.analysis.spectra import band_powers

    n = x.shape[-1]
    if n < 8:
        return np.full(x.shape[:-1] + (lower.size,), np.nan)
    pw = band_powers(x, fs, lower, upper, axis=-1, detrend="constant", window="hann")
    f = np.fft.rfftfreq(n, 1.0 / fs)
    nbins = np.searchsorted(f, upper, side="left") - np.searchsorted(f, lower, side="left")
    pw[..., nbins < 4] = np.nan
    return pw


def band_levels(signal: ArrayLike, fs: float, *, fraction: int = 3, fmin: float = 20.0,
                fmax: float | None = None, method: str = "filter", reference: float = 1e-6,
                settle: float = 0.0) -> BandLevels:
    """Octave or third-octave band levels of a signal.

    ``method="filter"``: the IEC 61260-1:2014 class 1 multirate filter bank of
    :func:`design_filter_bank` (module notes); the level of a band is that of the rms of its
    filter's output. ``method="fft"``: the Hann-tapered FFT band sums of
    :func:`roughvib.analysis.spectra.band_powers` (mean removed, periodic Hann window scaled
    to unit mean square, bins with ``lower <= f < upper``; bands holding fewer than 4 bins
    are NaN), the method of the accuracy contract's band levels.

    Parameters
    ----------
    signal : array_like, shape (n,) or (..., n)
        Uniformly sampled signal, time along the last axis [unit, e.g. m/s^2].
    fs : float
        Sampling rate [Hz] (1e5 for the 1e-5 s output grid).
    fraction : {1, 3}
        Octave (1) or third-octave (3) bands.
    fmin, fmax : float
        Range of the nominal mid-band frequencies [Hz]; ``fmax=None`` goes up to the highest
        band whose upper edge is at most ``fs/2`` (40 kHz at 100 kHz); bands above ``fs/2``
        are dropped in any case.
    method : {'filter', 'fft'}
        See above.
    reference : float
        Reference of the levels [unit], > 0; 1e-6 (m/s^2) by default.
    settle : float
        Time [s], >= 0, at the start of the record that is left out of the levels: with
        ``filter`` it drives the filters (their start-up) without being averaged, with
        ``fft`` it is dropped before the transform.

    Returns
    -------
    BandLevels
        ``level_db`` and ``mean_square`` of shape ``signal.shape[:-1] + (n_bands,)``; NaN for a
        band too narrow for the averaged stretch of duration T: ``B T < 4`` with B its
        nominal bandwidth (``filter``), fewer than 4 FFT bins in the band (``fft``).
    """
    if method not in METHODS:
        raise ValueError(f"method must be 'filter' or 'fft', got {method!r}")
    if not (reference > 0 and math.isfinite(reference)):
        raise ValueError(f"reference must be > 0, got {reference}")
    if not (settle >= 0 and math.isfinite(settle)):
        raise ValueError(f"settle must be >= 0 s, got {settle}")
    x = np.asarray(signal, dtype=float)
    if x.ndim == 0 or x.shape[-1] < 2:
        raise ValueError(f"band levels need a signal of at least 2 samples along its last "
                         f"axis, got shape {x.shape}")
    bank = _cached_bank(float(fs), fraction, float(fmin), None if fmax is None else float(fmax))
    if method == "filter":
        ms = bank.mean_squares(x, settle=settle)
    else:
        skip = math.ceil(settle * fs - 1e-9)
        ms = _fft_mean_squares(x[..., skip:], fs, bank.lower_hz, bank.upper_hz)
    with np.errstate(divide="ignore", invalid="ignore"):
        lev = 10.0 * np.log10(ms / reference**2)
    return BandLevels(center_hz=bank.center_hz.copy(), exact_hz=bank.exact_hz.copy(),
                      level_db=lev, mean_square=ms, method=method)
