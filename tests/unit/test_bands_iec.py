"""The band filter bank of analysis.bands against IEC 61260-1:2014 class 1, and its levels.

Acceptance limits: IEC 61260-1:2014, Table 1 (relative attenuation of octave-band filters at
the normalized frequencies Omega = G**0, G**(±1/8), G**(±1/4), G**(±3/8), G**(±1/2) just
inside and just outside the band edge, G**(±1), G**(±2), G**(±3), G**(±4); class 1 column).
The standard itself was not at hand; the numbers are those of its transcription in the
phonometry project's compliance module (BS EN 61260-1:2014 Table 1, pages 15-16), whose
IEC 61260:1995 column also matches the 1995 class 1 limits of an independent transcription
(ASCEE's octave-band limit lines). Fractional-octave breakpoints follow 5.10.3, formula (9):
Omega_b = 1 + (G**(1/(2b)) - 1) / (G**(1/2) - 1) * (Omega_1 - 1); the low side mirrors the
high side (formula (10)); between breakpoints the limits are linear in lg(Omega) (5.10.6).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from roughvib.analysis import bands
from roughvib.analysis.spectra import band_powers

G = 10.0 ** 0.3

# IEC 61260-1:2014 Table 1, class 1, octave bands: (exponent x of Omega = G**x, min, max) [dB]
# pass band (up to just inside the edge, x = 1/2-): min -0.4 dB throughout
_PASS_MAX = ((0.0, 0.4), (1 / 8, 0.5), (1 / 4, 0.7), (3 / 8, 1.4), (1 / 2, 5.3))
_PASS_MIN = -0.4
# stop band (just outside the edge, x = 1/2+, and beyond): max +inf
_STOP_MIN = ((1 / 2, 1.2), (1.0, 16.6), (2.0, 40.5), (3.0, 60.0), (4.0, 70.0))


def _breakpoint(x: float, b: int) -> float:
    """Formula (9) of IEC 61260-1:2014: octave breakpoint G**x for bandwidth 1/b."""
    return 1.0 + (G ** (0.5 / b) - 1.0) / (G**0.5 - 1.0) * (G**x - 1.0)


def class1_limits(omega: np.ndarray, b: int) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) class 1 relative attenuation [dB] at normalized frequencies ``omega``."""
    om = np.where(omega < 1.0, 1.0 / omega, omega)
    lg = np.log10(om)
    px = np.log10([_breakpoint(x, b) for x, _ in _PASS_MAX])
    sx = np.log10([_breakpoint(x, b) for x, _ in _STOP_MIN])
    inside = om <= _breakpoint(0.5, b)
    lo = np.where(inside, _PASS_MIN, np.interp(lg, sx, [v for _, v in _STOP_MIN]))
    hi = np.where(inside, np.interp(lg, px, [v for _, v in _PASS_MAX]), np.inf)
    return lo, hi


def _normative_omegas(b: int) -> np.ndarray:
    """The normative frequencies of Table 1 for bandwidth 1/b, both sides, edges +- 1e-6."""
    xs = [0.0, 1 / 8, 1 / 4, 3 / 8, 1.0, 2.0, 3.0, 4.0]
    hi = [_breakpoint(x, b) for x in xs]
    edge = _breakpoint(0.5, b)
    hi += [edge * (1 - 1e-6), edge * (1 + 1e-6)]
    hi = np.array(sorted(set(hi)))
    return np.concatenate((1.0 / hi[::-1][:-1], hi))


def _dense_omegas(b: int) -> np.ndarray:
    """A fine grid from G**-4 to G**4 mapped to bandwidth 1/b (catches a limit between
    breakpoints)."""
    x = np.linspace(0.0, 4.0, 801)
    hi = np.array([_breakpoint(v, b) for v in x])
    return np.concatenate((1.0 / hi[::-1][:-1], hi))


def _check_class1(bank: bands.FilterBank, omega: np.ndarray) -> float:
    """Smallest margin [dB] to the class 1 limits over all bands and ``omega``; asserts > 0.

    Frequencies above fs/2 carry no signal (relative attenuation +inf): they meet every
    minimum and are skipped for the maxima, which only exist inside the pass band."""
    att = bank.relative_attenuation(omega)
    lo, hi = class1_limits(omega, bank.fraction)
    margin_lo = att - lo[None, :]
    with np.errstate(invalid="ignore"):  # inf - inf where no signal reaches
        margin_hi = np.where(np.isinf(att), np.inf, hi[None, :] - att)
    margin = np.minimum(margin_lo, margin_hi)
    worst = float(np.min(margin))
    j, i = np.unravel_index(np.argmin(margin), att.shape)
    assert worst > 0, (f"band {bank.center_hz[j]} Hz at Omega = {omega[i]:.5f}: relative "
                       f"attenuation {att[j, i]:.3f} dB outside [{lo[i]}, {hi[i]}] dB")
    return worst


@pytest.mark.parametrize("fs", [1e5, 48e3])
@pytest.mark.parametrize("b", [3, 1])
def test_every_band_meets_class1_table1_limits_including_decimation(fs, b):
    # the effective response of each band: anti-alias stages, folding by each halving, and
    # the band's filter at its own rate
    bank = bands.design_filter_bank(fs, fraction=b, fmin=20.0)
    assert bank.stage.max() >= 6  # the low bands really run decimated
    _check_class1(bank, _normative_omegas(b))
    _check_class1(bank, _dense_omegas(b))


@pytest.mark.parametrize("order", [3, bands.MAX_ORDER])
def test_the_other_orders_design_filter_bank_accepts_meet_class1_too(order):
    bank = bands.design_filter_bank(1e5, fraction=3, fmin=20.0, order=order)
    assert bank.order.min() == order
    _check_class1(bank, _dense_omegas(3))


@pytest.mark.parametrize("order", [2, 13, 8.0, True])
def test_an_order_outside_3_to_12_is_refused(order):
    with pytest.raises(ValueError, match="order must be an integer from 3 to 12"):
        bands.design_filter_bank(1e5, order=order)


def test_the_limits_as_transcribed_reject_a_filter_that_is_too_wide():
    # a check that can fail: the same bank with the octave design put on third-octave
    # centres attenuates the third-octave breakpoint of G**1 by 0.02 dB (needs >= 16.6 dB)
    bank = bands.design_filter_bank(1e5, fraction=3, fmin=100.0, fmax=1000.0)
    wide = bands.design_filter_bank(1e5, fraction=1, fmin=125.0, fmax=500.0)
    fake = bands.FilterBank(fs=bank.fs, fraction=3, center_hz=wide.center_hz,
                            exact_hz=wide.exact_hz, lower_hz=wide.lower_hz,
                            upper_hz=wide.upper_hz, stage=wide.stage, order=wide.order,
                            band_sos=wide.band_sos,
                            aa_sos=wide.aa_sos)
    with pytest.raises(AssertionError):
        _check_class1(fake, _normative_omegas(3))


@pytest.mark.parametrize("fs", [1e5, 48e3])
@pytest.mark.parametrize("b", [3, 1])
def test_no_frequency_far_from_a_band_reaches_it_through_the_decimation(fs, b):
    # Table 1 ends at G**(±4) with 70 dB; a decimated band also hears every frequency that
    # folds onto it, so the anti-alias stages must keep all of 0 ... fs/2 beyond G**(±4)
    # (mapped, formula (9)) at least 70 dB down: checked on a grid dense in both lg f and f
    bank = bands.design_filter_bank(fs, fraction=b, fmin=20.0)
    f = np.unique(np.concatenate((np.geomspace(1.0, fs / 2, 6001),
                                  np.linspace(0.0, fs / 2, 6001)[1:])))
    gain = bank.response(f)
    centre = bank.response(bank.exact_hz).diagonal()
    far = _breakpoint(4.0, b)
    for j, fm in enumerate(bank.exact_hz):
        out = (f > fm * far) | (f < fm / far)
        with np.errstate(divide="ignore"):
            att = 10 * np.log10(centre[j] / gain[j, out])
        assert att.min() >= 70.0, (bank.center_hz[j], f[out][np.argmin(att)], att.min())


# Selectivity. A band next to a band C dB louder reads its own power plus the loud band's
# power times its filter's gain there: with the attenuation A [dB] of a band at its
# neighbours' mid-band frequencies, a tone C dB weaker than the tone in the neighbouring band
# reads 10 lg(1 + 10**((C - A) / 10)) dB high. The bank is designed for A >= 44.6 dB, which
# keeps that error below 0.5 dB up to C = 35 dB (and below 0.015 dB at C = 20 dB).
_NEIGHBOUR_ATTENUATION_DB = 44.6


def _leakage_error_db(contrast_db: float, attenuation_db: float) -> float:
    return 10 * math.log10(1 + 10 ** ((contrast_db - attenuation_db) / 10))


@pytest.mark.parametrize("fs", [1e5, 48e3])
def test_every_third_octave_attenuates_its_neighbours_mid_band_frequencies(fs):
    bank = bands.design_filter_bank(fs, fraction=3, fmin=20.0)
    att = bank.relative_attenuation(np.array([G ** (-1 / 3), G ** (1 / 3)]))
    att = att[np.isfinite(att)]  # the top band has no neighbour above fs/2
    assert att.min() >= _NEIGHBOUR_ATTENUATION_DB, att.min()
    assert _leakage_error_db(35.0, att.min()) < 0.5


def _two_tone_error(bank: bands.FilterBank, weak: int, strong: int, contrast_db: float,
                    duration: float, settle: float) -> float:
    """Level of band ``weak`` minus the level its own tone reads alone [dB], with a tone
    ``contrast_db`` louder at the mid-band frequency of band ``strong``."""
    fs = bank.fs
    amp = 0.01
    alone = _tone(bank.exact_hz[weak], fs, duration, amp, phase=0.3)
    x = alone + _tone(bank.exact_hz[strong], fs, duration, amp * 10 ** (contrast_db / 20),
                      phase=1.1)
    ms = bank.mean_squares(np.stack((x, alone)), settle=settle)[:, weak]
    # the tone alone reads its rms within 0.1 dB (the pass-band ripple of the anti-alias
    # stages adds up over the halvings)
    assert abs(10 * math.log10(ms[1] / (amp**2 / 2))) < 0.1
    return 10 * math.log10(ms[0] / ms[1])


@pytest.mark.parametrize(("weak", "strong"), [
    (25.0, 31.5), (500.0, 400.0), (500.0, 630.0), (1250.0, 1000.0), (2500.0, 2000.0),
    (31500.0, 40000.0), (40000.0, 31500.0)])
@pytest.mark.parametrize("contrast_db", [20.0, 35.0])
def test_a_weak_tone_next_to_a_strong_one_reads_its_own_level(weak, strong, contrast_db):
    # the dips of the paper scene: a band between bands 20 to 35 dB louder (block 500 Hz,
    # 1250 Hz, plate 2500 Hz), decimated bands, and the top bands at the input rate. Run-in
    # of > 9 decay times: the strong tone's onset has faded by > 78 dB; the weak band reads
    # what the weak tone reads alone within the leakage bound of the design, plus 0.02 dB
    # for the beat of the two tones over the finite average
    fs = 1e5
    bank = bands.design_filter_bank(fs, fmin=min(weak, strong), fmax=max(weak, strong))
    j_weak = int(np.flatnonzero(bank.center_hz == weak)[0])
    j_strong = int(np.flatnonzero(bank.center_hz == strong)[0])
    assert abs(j_weak - j_strong) == 1
    duration, settle = (6.0, 3.0) if weak < 100 else (0.5, 0.2)
    assert settle > 9 * bank.decay_time.max()
    err = _two_tone_error(bank, j_weak, j_strong, contrast_db, duration, settle)
    bound = _leakage_error_db(contrast_db, _NEIGHBOUR_ATTENUATION_DB) + 0.02
    assert -0.02 < err < bound, (err, bound)


def test_six_pole_bands_fail_the_two_tone_test():
    # the test above can fail: the six-pole bands (order 3), class 1 as well, attenuate the
    # neighbour's mid-band frequency by 18 to 21 dB and read the 500 Hz band 3 dB high at
    # 20 dB contrast, 16 dB high at 35 dB (the paper block's 500 Hz dip read 12 dB high)
    fs = 1e5
    old = bands.design_filter_bank(fs, fmin=400.0, fmax=500.0, order=3)
    att = old.relative_attenuation(np.array([G ** (-1 / 3)]))[1, 0]  # 500 Hz band at 400 Hz
    assert 18.0 < att < 21.0
    for contrast_db in (20.0, 35.0):
        err = _two_tone_error(old, 1, 0, contrast_db, 0.5, 0.2)
        assert err > _leakage_error_db(contrast_db, _NEIGHBOUR_ATTENUATION_DB) + 2.0, err
        # ... and by the amount its response predicts
        assert err == pytest.approx(_leakage_error_db(contrast_db, att), abs=0.05)


def _tone(f: float, fs: float, duration: float, amp: float = 1.0, phase: float = 0.3
          ) -> np.ndarray:
    t = np.arange(round(duration * fs)) / fs
    return amp * np.sin(2 * np.pi * f * t + phase)


@pytest.mark.parametrize("centre", [20.0, 1000.0, 40e3])
def test_tones_through_the_bank_meet_class1_at_the_normative_frequencies(centre):
    # the bank itself (decimation, aliasing, filter start-up) driven by steady tones: the
    # level in band `centre` of a tone at Omega f_m, relative to the tone at f_m
    fs = 1e5
    duration, settle = (5.0, 2.5) if centre < 100 else (0.4, 0.2)
    omega = _normative_omegas(3)
    omega = omega[omega * bands.mid_band_frequencies(3, centre, centre)[1][0] < fs / 2]
    att = []
    for om in np.concatenate(([1.0], omega)):
        fm = bands.mid_band_frequencies(3, centre, centre)[1][0]
        r = bands.band_levels(_tone(om * fm, fs, duration), fs, fmin=centre, fmax=centre,
                              settle=settle)
        att.append(float(r.mean_square[0]))
    att = 10 * np.log10(att[0] / np.array(att[1:]))
    lo, hi = class1_limits(omega, 3)
    # a tone's own level is measured, not modelled: allow 0.02 dB for the finite average
    assert np.all(att >= lo - 0.02), list(zip(omega, att, lo, strict=True))
    assert np.all(att <= hi + 0.02), list(zip(omega, att, hi, strict=True))


@pytest.mark.parametrize("b", [3, 1])
def test_effective_bandwidth_within_class1(b):
    # IEC 61260-1:2014 5.12: 10 lg(B_e / B_r) within ±0.4 dB for class 1, B_r = ln(G) / b,
    # B_e = integral of 10**(-ΔA/10) dOmega / Omega (5.11)
    bank = bands.design_filter_bank(1e5, fraction=b, fmin=20.0)
    v = np.linspace(-4 * math.log(G) / b, 4 * math.log(G) / b, 8001)
    att = bank.relative_attenuation(np.exp(v))
    be = np.trapezoid(np.where(np.isinf(att), 0.0, 10 ** (-att / 10)), v, axis=1)
    dev = 10 * np.log10(be / (math.log(G) / b))
    assert np.all(np.abs(dev) < 0.4), dev
    # the design aims at 0 (module notes); the digital filters, decimated or next to fs/2,
    # stay within 0.05 dB of it
    assert np.all(np.abs(dev) < 0.05), dev


@pytest.mark.parametrize("centre", [20.0, 31.5, 500.0, 1000.0, 6300.0, 40e3])
def test_tone_at_mid_band_reads_its_rms_and_neighbours_are_attenuated(centre):
    fs = 1e5
    fm = bands.mid_band_frequencies(3, centre, centre)[1][0]
    amp = 0.3  # rms 0.3/sqrt 2
    duration, settle = (6.0, 3.0) if centre < 100 else (0.5, 0.1)
    r = bands.band_levels(_tone(fm, fs, duration, amp), fs, fmin=centre / 1.6,
                          fmax=centre * 1.6, settle=settle)
    j = int(np.argmin(np.abs(r.exact_hz - fm)))
    assert r.center_hz[j] == centre
    expected = 20 * math.log10(amp / math.sqrt(2) / 1e-6)
    assert abs(r.level_db[j] - expected) < 0.1
    # the neighbours sit at Omega = G**(±1/3): class 1 asks for the interpolated minimum
    lo, _ = class1_limits(np.array([G ** (-1 / 3), G ** (1 / 3)]), 3)
    for jj, need in ((j - 1, lo[0]), (j + 1, lo[1])):
        if 0 <= jj < r.exact_hz.size:
            assert expected - r.level_db[jj] >= need, (r.center_hz[jj], need)


def test_20hz_band_at_100khz_is_stable_and_reads_the_tone():
    # without decimation the 16-pole 20 Hz band-pass at 100 kHz has poles 2.5e-5 from the
    # unit circle; in the bank it runs at 100 kHz / 2**10
    fs = 1e5
    bank = bands.design_filter_bank(fs, fmin=20.0, fmax=20.0)
    assert bank.center_hz.tolist() == [20.0]
    assert bank.rates[0] < 1000.0
    for sos in bank.band_sos:
        poles = np.concatenate([np.roots(s[3:]) for s in sos])
        assert np.all(np.abs(poles) < 0.99)
    fm = bank.exact_hz[0]
    x = _tone(fm, fs, 6.0, 2.0) + _tone(3000.0, fs, 6.0, 5.0)
    r = bands.band_levels(x, fs, fmin=20.0, fmax=20.0, settle=3.0)
    assert np.isfinite(r.level_db).all()
    assert abs(r.level_db[0] - 20 * math.log10(2.0 / math.sqrt(2) / 1e-6)) < 0.1


def _covered_mean_square(x: np.ndarray, fs: float, lo: float, hi: float) -> float:
    """Mean square of x between lo and hi [Hz] (rectangular-window FFT bin sums, Parseval)."""
    return float(band_powers(x, fs, [lo], [hi], window="boxcar")[0])


@pytest.mark.parametrize("colour", ["white", "pink"])
def test_band_powers_add_up_to_the_mean_square_of_noise_in_the_covered_range(colour):
    # Parseval through the bank: the bands tile [lower edge of the first, upper edge of the
    # last]; with the effective bandwidth equal to the nominal one the summed mean squares
    # equal the noise's mean square in that range. Tolerance: 0.1 dB (2.3 %): the spill of
    # the outer bands' skirts beyond the range, and the statistical scatter of 4 s of noise
    fs = 2e4
    rng = np.random.default_rng(7)
    n = int(4.0 * fs)
    w = rng.standard_normal(n)
    if colour == "pink":
        f = np.fft.rfftfreq(n, 1 / fs)
        spec = np.fft.rfft(w) / np.sqrt(np.maximum(f, 1.0))
        w = np.fft.irfft(spec, n)
    settle = 1.0
    r = bands.band_levels(w, fs, fmin=100.0, fmax=5000.0, settle=settle)
    lo = r.exact_hz[0] * G ** (-1 / 6)
    hi = r.exact_hz[-1] * G ** (1 / 6)
    ms = _covered_mean_square(w[int(settle * fs):], fs, lo, hi)
    ratio_db = 10 * math.log10(np.sum(r.mean_square) / ms)
    assert abs(ratio_db) < 0.1, ratio_db


def test_white_noise_reads_its_density_times_the_bandwidth_in_every_band():
    # closed form: white noise of variance sigma**2 sampled at fs has the one-sided density
    # sigma**2 / (fs/2); a band of effective bandwidth B holds sigma**2 B / (fs/2). The design
    # makes the effective bandwidth the nominal one, f_upper - f_lower (for the analogue
    # prototype of order 8, integral |H|**2 df is 0.0004 dB from it; the digital filters stay
    # within 0.01 dB). Tolerance per band: 4.5 standard deviations of a mean square of noise
    # averaged over B T, 4.34 / sqrt(B T) dB each (0.14 dB at 1 kHz, 0.02 dB at 40 kHz in
    # 4 s), plus those 0.01 dB
    fs, sigma, settle, duration = 1e5, 0.3, 0.5, 4.0
    x = np.random.default_rng(11).normal(0.0, sigma, int((settle + duration) * fs))
    r = bands.band_levels(x, fs, fmin=1000.0, settle=settle)
    _, _, lo, hi = bands.mid_band_frequencies(3, 1000.0, 40e3)
    assert r.exact_hz.size == lo.size == 17
    expected = sigma**2 * (hi - lo) / (fs / 2)
    dev = 10 * np.log10(r.mean_square / expected)
    tol = 4.5 * 10 / math.log(10) / np.sqrt((hi - lo) * duration) + 0.01
    assert np.all(np.abs(dev) < tol), list(zip(r.center_hz, dev, tol, strict=True))


def _steep_noise(fs: float, duration: float, knee: float, slope_db: float, floor_db: float,
                 seed: int) -> np.ndarray:
    """Gaussian noise with a flat density up to ``knee`` [Hz], then falling ``slope_db`` per
    third octave (density ~ f**(-slope_db)) down to ``floor_db`` below the flat part."""
    n = int(duration * fs)
    spec = np.fft.rfft(np.random.default_rng(seed).standard_normal(n))
    f = np.fft.rfftfreq(n, 1.0 / fs)
    with np.errstate(divide="ignore"):
        db = -slope_db * 10 * np.log10(np.maximum(f, knee) / knee)
    return np.fft.irfft(spec * 10 ** (np.maximum(db, floor_db) / 20), n)


def test_filter_follows_the_fft_band_sums_down_a_steep_spectrum():
    # a density falling 20 dB per third octave (60 dB per octave) over 100 dB from 4 kHz: the
    # filter bank and the Hann-tapered FFT band sums read the same bands. What a filter adds
    # is its skirts' share of the louder side: for this spectrum the bank's own response
    # (FilterBank.response) predicts at most +0.16 dB; the two estimators of the same noise
    # scatter by about 0.1 dB (B T >= 1800 here). Tolerance 0.5 dB per band, where the six-pole
    # bands read up to 25 dB high
    fs, settle = 1e5, 0.5
    x = _steep_noise(fs, 4.5, 4000.0, 20.0, -100.0, seed=4)
    kw = {"fmin": 2000.0, "fmax": 20e3, "settle": settle}
    filt = bands.band_levels(x, fs, **kw)
    fft = bands.band_levels(x, fs, method="fft", **kw)
    diff = filt.level_db - fft.level_db
    assert np.ptp(fft.level_db) > 80.0  # the spectrum does fall
    assert np.all(np.abs(diff) < 0.5), list(zip(filt.center_hz, diff, strict=True))
    old = bands.design_filter_bank(fs, fmin=2000.0, fmax=20e3, order=3)
    old_diff = 10 * np.log10(old.mean_squares(x, settle=settle) / fft.mean_square)
    assert old_diff.max() > 10.0


@pytest.mark.parametrize("centre", [63.0, 1000.0, 40e3])
def test_decay_time_is_how_fast_a_band_forgets(centre):
    # after its input stops, a band's output decays with its slowest pole: the energy left
    # after t falls by 8.69 dB (a factor e**2 in power) per decay time. A burst of noise,
    # then silence; the energy of the output averaged from 4 to 14 decay times after the
    # burst, on a straight line in dB against t. Two poles of nearly equal damping beat in the
    # tail: 3 % tolerance. (The anti-alias stages ring too, but fade some 25 dB per decay
    # time of a 16-pole band; next to a six-pole band they are as slow and the test would
    # not hold for it.)
    fs = 1e5
    bank = bands.design_filter_bank(fs, fmin=centre, fmax=centre)
    tau = float(bank.decay_time[0])
    burst, end = 0.3, 0.3 + 40 * tau
    x = np.zeros(int(end * fs))
    x[:int(burst * fs)] = np.random.default_rng(5).standard_normal(int(burst * fs))
    rate = float(bank.rates[0])
    # whole samples at the band's rate from 4 to 14 decay times after the burst
    t = np.round(np.arange(4.0, 15.0, 2.0) * tau * rate) / rate
    energy = [bank.mean_squares(x, settle=burst + tt)[0] * (end - burst - tt) for tt in t]
    slope = np.polyfit(t / tau, 10 * np.log10(energy), 1)[0]
    assert slope == pytest.approx(-20 / math.log(10), rel=0.03)
    if centre < 1e4:
        # about 1.8 / B for the 16-pole bands (0.7 / B for the six-pole ones)
        bw = float(bank.upper_hz[0] - bank.lower_hz[0])
        assert 1.6 < tau * bw < 2.0


def test_filter_and_fft_agree_on_broadband_noise_and_fft_is_the_spectra_band_sum():
    fs = 1e5
    rng = np.random.default_rng(3)
    x = rng.standard_normal(int(4.0 * fs))
    rf = bands.band_levels(x, fs, fmin=1000.0, settle=0.2)
    rt = bands.band_levels(x, fs, fmin=1000.0, method="fft", settle=0.2)
    assert rf.method == "filter" and rt.method == "fft"
    np.testing.assert_array_equal(rf.exact_hz, rt.exact_hz)
    # each FFT band is band_powers of the Hann-tapered record (the same function)
    direct = band_powers(x[int(0.2 * fs):], fs, rt.exact_hz * G ** (-1 / 6),
                         rt.exact_hz * G ** (1 / 6), window="hann")
    np.testing.assert_allclose(rt.mean_square, direct, rtol=1e-12)
    # white noise: two estimators of the same band power, each with a statistical scatter
    # of about 4.3 / sqrt(B T) dB, <= 0.15 dB above 1 kHz in 3.8 s (B T >= 880): no band
    # apart by more than 1 dB, and no bias between the methods beyond 0.1 dB on average
    diff = rf.level_db - rt.level_db
    assert np.max(np.abs(diff)) < 1.0
    assert abs(np.mean(diff)) < 0.1


def test_two_dimensional_input_gives_the_rows_levels():
    fs = 1e4
    x = np.stack([_tone(1000.0, fs, 0.5, 1.0), _tone(250.0, fs, 0.5, 0.1)])
    r = bands.band_levels(x, fs, fmin=100.0, fmax=2000.0, settle=0.1)
    assert r.level_db.shape == (2, r.center_hz.size)
    for row in range(2):
        one = bands.band_levels(x[row], fs, fmin=100.0, fmax=2000.0, settle=0.1)
        np.testing.assert_allclose(r.mean_square[row], one.mean_square, rtol=1e-12)


def test_octave_bands_and_labels():
    nom, exact, lo, hi = bands.mid_band_frequencies(1, 31.5, 16000.0)
    assert nom.tolist() == [31.5, 63, 125, 250, 500, 1000, 2000, 4000, 8000, 16000]
    np.testing.assert_allclose(exact[5], 1000.0)
    np.testing.assert_allclose(hi / lo, G)
    nom3, exact3, lo3, hi3 = bands.mid_band_frequencies(3, 20.0, 20e3)
    assert nom3[0] == 20.0 and nom3[-1] == 20000.0 and nom3.size == 31
    np.testing.assert_allclose(hi3[:-1], lo3[1:], rtol=1e-13)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"fraction": 2}, "fraction must be 1"), ({"method": "welch"}, "method must be"),
    ({"reference": 0.0}, "reference must be > 0"), ({"settle": -1.0}, "settle must be >= 0"),
])
def test_bad_arguments_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        bands.band_levels(np.ones(100), 1e4, **kwargs)


def test_bands_too_narrow_for_the_averaged_stretch_read_nan():
    # B T < 4 reads NaN, as a band with fewer than 4 bins does in the FFT band sums: in
    # 0.3 s the 20 Hz band (B = 4.6 Hz) is out, the 63 Hz band (B = 14.6 Hz) is in
    fs = 1e4
    x = _tone(63.0, fs, 0.4) + _tone(20.0, fs, 0.4)
    r = bands.band_levels(x, fs, fmin=20.0, fmax=63.0, settle=0.1)
    assert r.center_hz.tolist() == [20.0, 25.0, 31.5, 40.0, 50.0, 63.0]
    bw_t = 0.3 * r.exact_hz * (G ** (1 / 6) - G ** (-1 / 6))
    np.testing.assert_array_equal(np.isnan(r.level_db), bw_t < 4.0)
    assert np.isnan(r.level_db[0]) and np.isfinite(r.level_db[-1])
