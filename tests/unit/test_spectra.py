"""Spectra and levels on synthetic signals whose content is known in closed form."""

import math

import numpy as np
import pytest

from roughvib.analysis.levels import (
    global_tangential_stiffness,
    level_db,
    rms,
    stick_fraction,
    velocity_exponent,
    whole_period_window,
)
from roughvib.analysis.spectra import (
    add_noise_floor,
    band_levels,
    band_powers,
    narrowband_psd,
    nominal_centre,
    third_octave_bands,
    total_level,
    wavenumber_band_levels,
    wavenumber_spectrum,
)

FS = 1e5  # the 1e-5 s output grid
REF = 1e-6

# IEC 61260-1 nominal mid-band frequencies, 20 Hz ... 50 kHz
IEC_NOMINAL = [20, 25, 31.5, 40, 50, 63, 80, 100, 125, 160, 200, 250, 315, 400, 500, 630, 800,
               1000, 1250, 1600, 2000, 2500, 3150, 4000, 5000, 6300, 8000, 10000, 12500, 16000,
               20000, 25000, 31500, 40000, 50000]


# ------------------------------------------------------------------------------ band definition

def test_band_centres_and_edges_follow_the_iec_base10_formula():
    fc, lo, hi = third_octave_bands(20, 50e3)
    k = np.arange(-17, 18)  # 20 Hz is k = -17, 50 kHz is k = +17 relative to 1 kHz
    np.testing.assert_allclose(fc, 1000.0 * 10.0 ** (k / 10), rtol=1e-14)
    np.testing.assert_allclose(lo, fc * 10 ** (-1 / 20), rtol=1e-14)
    np.testing.assert_allclose(hi, fc * 10 ** (1 / 20), rtol=1e-14)
    np.testing.assert_allclose(hi[:-1], lo[1:], rtol=1e-13)        # contiguous
    np.testing.assert_allclose(np.sqrt(lo * hi), fc, rtol=1e-13)   # geometric centres
    np.testing.assert_allclose(hi / lo, 10 ** 0.1, rtol=1e-13)     # a third of a decade
    assert [nominal_centre(f) for f in fc] == IEC_NOMINAL
    np.testing.assert_array_equal(nominal_centre(fc), IEC_NOMINAL)
    # nominal labels are within 1.2 % of the exact centres
    assert np.max(np.abs(np.array(IEC_NOMINAL) / fc - 1)) < 0.012


def test_band_range_is_by_nominal_centre():
    fc, _, _ = third_octave_bands(100, 1000)
    assert nominal_centre(fc[0]) == 100 and nominal_centre(fc[-1]) == 1000
    fc, _, _ = third_octave_bands(110, 1100)  # 125 ... 1000
    assert nominal_centre(fc[0]) == 125 and nominal_centre(fc[-1]) == 1000
    assert nominal_centre(0.0316) == pytest.approx(0.0315) and nominal_centre(12589) == 12500
    with pytest.raises(ValueError):
        third_octave_bands(0, 100)


# ---------------------------------------------------------------------------------- band levels

@pytest.mark.parametrize("label", [100, 1000, 4000, 20000, 40000])
def test_sine_at_a_band_centre_lands_in_its_band_at_its_level(label):
    n = 100_000                       # 1 s record: bin spacing 1 Hz
    fc_all, _, _ = third_octave_bands(20, 50e3)
    fc = fc_all[np.asarray(IEC_NOMINAL) == label][0]
    f0 = round(fc)                    # integer number of cycles in the record
    A = 0.3
    t = np.arange(n) / FS
    centres, lev = band_levels(A * np.sin(2 * np.pi * f0 * t + 0.4), FS)
    i = int(np.argmin(np.abs(centres - fc)))
    assert lev[i] == pytest.approx(20 * np.log10(A / np.sqrt(2) / REF), abs=0.1)
    assert np.nanargmax(lev) == i
    for j in (i - 1, i + 1):
        if 0 <= j < lev.size:
            assert lev[j] <= lev[i] - 30


def test_bands_above_nyquist_are_dropped_and_empty_bands_are_nan():
    x = np.random.default_rng(0).standard_normal(1000)  # 10 ms: bin spacing 100 Hz
    fc, lev = band_levels(x, FS)
    _, _, hi = third_octave_bands(20, 50e3)
    assert fc.size == np.count_nonzero(hi <= FS / 2)
    assert nominal_centre(fc[-1]) == 40000
    # a band narrower than the 100 Hz bin spacing may hold no bin: NaN, not -inf
    width = fc * (10 ** 0.05 - 10 ** -0.05)
    lo, hi = fc * 10 ** -0.05, fc * 10 ** 0.05
    has_bin = np.floor((hi - 1e-9) / 100.0) >= np.ceil(lo / 100.0)
    assert np.all(np.isnan(lev[~has_bin])) and np.all(np.isfinite(lev[has_bin]))
    assert np.all(width[~has_bin] < 100.0)
    assert nominal_centre(fc[np.argmax(has_bin)]) <= 500


def test_white_noise_psd_density_and_band_slope():
    sigma, n = 0.2, 400_000
    x = np.random.default_rng(1).normal(0.0, sigma, n)

    # Welch density of white noise: sigma^2 / (fs/2). Tolerance from the estimator's spread:
    # K segments (50 % Hann overlap: variance factor 1 + 2 * 0.167^2 = 1.056 per bin), and M
    # neighbouring bins whose Hann-windowed powers correlate with 4/9 (adjacent) and 1/36
    # (next): mean over M bins has relative std sqrt(1.056 * 1.944 / (K M)). Allow 5 sigma.
    f, p = narrowband_psd(x, FS, resolution=100.0)
    nper = round(FS / 100.0)
    K = (n - nper) // (nper // 2) + 1
    sel = (f >= 1e3) & (f <= 40e3)
    M = np.count_nonzero(sel)
    rel_sd = math.sqrt(1.056 * (1 + 2 * 4 / 9 + 2 / 36) / (K * M))
    assert f[1] - f[0] == pytest.approx(100.0)
    assert np.mean(p[sel]) == pytest.approx(sigma**2 / (FS / 2), rel=5 * rel_sd)

    # Band levels: each band holds M_b independent FFT bins with mean power 2 sigma^2 / n and
    # relative std 1 (exponential), so its level scatters by (10/ln 10)/sqrt(M_b) dB.
    fc, lev = band_levels(x, FS, fmin=100, fmax=40e3)
    lo, hi = fc * 10 ** -0.05, fc * 10 ** 0.05
    df = FS / n
    Mb = np.ceil(hi / df) - np.ceil(lo / df)
    expected = 10 * np.log10(Mb * 2 * sigma**2 / n / REF**2)
    np.testing.assert_array_less(np.abs(lev - expected), 5 * (10 / np.log(10)) / np.sqrt(Mb))
    # hence 1 dB per band: each band is 10**(1/10) times wider than the one below. The fitted
    # slope scatters by sqrt(sum(c_i^2 s_i^2)) / sum(c_i^2), c_i = i - mean(i), s_i as above.
    i = np.arange(fc.size)
    c = i - i.mean()
    sd_slope = np.sqrt(np.sum(c**2 * (10 / np.log(10)) ** 2 / Mb)) / np.sum(c**2)
    assert np.polyfit(i, expected, 1)[0] == pytest.approx(1.0, abs=1e-3)  # bin rounding only
    assert np.polyfit(i, lev, 1)[0] == pytest.approx(1.0, abs=5 * sd_slope + 1e-3)


def test_parseval_band_powers_sum_to_the_mean_square():
    # a sum of sines on FFT bins inside the covered range (20 Hz ... 40 kHz band edges):
    # its mean square is sum(A^2 / 2) exactly
    n = 50_000
    df = FS / n
    fc, lo, hi = third_octave_bands(20, 40e3)
    rng = np.random.default_rng(3)
    # the first and last bin of every band (the edge rule) and random bins in between
    first, stop = np.ceil(lo / df).astype(int), np.ceil(hi / df).astype(int)
    bins = np.unique(np.concatenate([first, stop - 1, rng.integers(first[0], stop[-1], 100)]))
    amp = rng.uniform(0.1, 1.0, bins.size) / np.sqrt(bins.size)
    phase = rng.uniform(0, 2 * np.pi, bins.size)
    t = np.arange(n) / FS
    x = np.zeros(n)
    for j, a, ph in zip(bins, amp, phase, strict=True):
        x += a * np.cos(2 * np.pi * j * df * t + ph)
    pw = band_powers(x, FS, lo, hi)
    ms = np.sum(amp**2) / 2
    assert np.mean(x**2) == pytest.approx(ms, rel=1e-10)
    assert pw.sum() == pytest.approx(ms, rel=1e-10)
    _, lev = band_levels(x, FS, fmin=20, fmax=40e3)
    assert np.sum(10 ** (lev / 10)) * REF**2 == pytest.approx(ms, rel=1e-10)
    assert total_level(x) == pytest.approx(10 * np.log10(ms / REF**2), abs=1e-9)


def test_parseval_with_a_nyquist_bin_and_odd_length():
    rng = np.random.default_rng(4)
    for n in (1024, 1023):
        x = rng.standard_normal(n)
        x -= x.mean()
        pw = band_powers(x, FS, [1e-3], [FS])  # one band holding every non-DC bin
        assert pw[0] == pytest.approx(np.mean(x**2), rel=1e-12)


def test_one_db_amplitude_change_is_one_db_in_every_band():
    x = np.random.default_rng(2).standard_normal(20_000)
    _, a = band_levels(x, FS, fmin=100)
    _, b = band_levels(x * 10 ** (1 / 20), FS, fmin=100)
    ok = np.isfinite(a)
    assert ok.sum() > 20
    np.testing.assert_allclose(b[ok] - a[ok], 1.0, atol=1e-9)


def test_axis_argument_matches_one_channel_at_a_time():
    x = np.random.default_rng(5).standard_normal((3, 4000))
    fc, lev = band_levels(x, FS, fmin=500)
    _, lev_t = band_levels(x.T, FS, fmin=500, axis=0)
    assert lev.shape == (3, fc.size) and lev_t.shape == (fc.size, 3)
    for c in range(3):
        np.testing.assert_array_equal(lev[c], band_levels(x[c], FS, fmin=500)[1])
    np.testing.assert_allclose(lev_t.T, lev, rtol=0, atol=1e-12)


def test_total_level_time_domain_and_band_limited():
    n = 10_000
    t = np.arange(n) / FS
    lo_tone = np.sqrt(2) * 1e-3 * np.sin(2 * np.pi * 1000 * t)   # 1e-3 rms: 60 dB re 1e-6
    hi_tone = np.sqrt(2) * 1e-2 * np.sin(2 * np.pi * 20000 * t)  # 1e-2 rms: 80 dB re 1e-6
    x = 5.0 + lo_tone + hi_tone                                   # the mean is removed
    assert total_level(lo_tone) == pytest.approx(60.0, abs=1e-9)
    assert total_level(x) == pytest.approx(10 * np.log10((1e-6 + 1e-4) / REF**2), abs=1e-9)
    assert total_level(x, fmax=5e3, fs=FS) == pytest.approx(60.0, abs=1e-9)
    assert total_level(x, fmin=5e3, fs=FS) == pytest.approx(80.0, abs=1e-9)
    assert total_level(np.full(10, 3.0)) == -np.inf
    with pytest.raises(ValueError, match="fs"):
        total_level(x, fmin=5e3)


def test_narrowband_psd_in_db_and_tone_peak_uses_the_hann_enbw():
    n = 100_000
    t = np.arange(n) / FS
    A = 2.0
    f, p = narrowband_psd(A * np.sin(2 * np.pi * 5000 * t), FS, resolution=50.0)
    assert f[1] - f[0] == pytest.approx(50.0)
    i = int(np.argmin(np.abs(f - 5000)))
    assert p[i] == pytest.approx(A**2 / 2 / (1.5 * 50.0), rel=1e-6)   # ENBW 1.5 bins
    # the window's density integrates to the tone's mean square
    assert np.sum(p) * 50.0 == pytest.approx(A**2 / 2, rel=1e-6)
    _, p_db = narrowband_psd(A * np.sin(2 * np.pi * 5000 * t), FS, resolution=50.0, ref=REF)
    assert p_db[i] == pytest.approx(10 * np.log10(p[i] / REF**2), abs=1e-9)


def test_noise_floor_rms_band_and_seed():
    x = np.zeros(200_000)
    y = add_noise_floor(x, FS, 1e-3, seed=4)
    assert rms(y) == pytest.approx(1e-3, rel=1e-12) and abs(np.mean(y)) < 1e-15
    np.testing.assert_array_equal(y, add_noise_floor(x, FS, 1e-3, seed=4))
    assert not np.array_equal(y, add_noise_floor(x, FS, 1e-3, seed=5))
    gen = np.random.default_rng(4)
    np.testing.assert_array_equal(y, add_noise_floor(x, FS, 1e-3, seed=gen))
    # band-limited: all power inside [10, 20) kHz
    yb = add_noise_floor(x, FS, 1e-3, seed=6, band=(10e3, 20e3))
    assert rms(yb) == pytest.approx(1e-3, rel=1e-12)
    inside = band_powers(yb, FS, [10e3], [20e3])[0]
    assert inside == pytest.approx(1e-6, rel=1e-10)
    # a floor adds to the signal, leaving it otherwise untouched
    s = np.sin(2 * np.pi * 1000 * np.arange(x.size) / FS)
    np.testing.assert_allclose(add_noise_floor(s, FS, 1e-3, seed=4) - s, y, atol=1e-15)


# ------------------------------------------------------------------------------------ profiles

def test_wavenumber_band_level_of_a_sinusoidal_profile():
    dx, n = 10e-6, 16_000             # 0.16 m trace, 10 um spacing
    wl = 0.16 / 160                   # 1 mm: 160 whole wavelengths; the 1 mm band
    a = 5e-6
    z = a * np.sin(2 * np.pi * np.arange(n) * dx / wl)
    lam, lev = wavenumber_band_levels(z, dx)
    assert np.all(np.diff(lam) < 0)                               # decreasing wavelength
    assert lam.min() >= 2 * dx * 10 ** 0.05 * (1 - 1e-12)           # above the Nyquist band
    i = int(np.argmin(np.abs(lam - 1e-3)))
    assert lam[i] == pytest.approx(1e-3, rel=1e-12) and nominal_centre(lam[i]) == 1e-3
    assert lev[i] == pytest.approx(20 * np.log10(a / np.sqrt(2) / 1e-6), abs=1e-9)
    assert np.nanmax(np.delete(lev, i)) < lev[i] - 30


def test_wavenumber_spectrum_integrates_to_the_variance():
    dx, n = 10e-6, 16_000
    z = np.random.default_rng(7).normal(0.0, 2e-6, n)
    k, p = wavenumber_spectrum(z, dx)
    dk = k[1] - k[0]
    assert dk == pytest.approx(2 * np.pi * 8 / (n * dx))
    assert k[-1] == pytest.approx(np.pi / dx)
    # white profile: density sigma^2 / (pi / dx); 15 segments x ~1000 bins, 5 sigma ~ 2 %
    assert np.sum(p) * dk == pytest.approx(np.var(z), rel=0.02)
    assert np.mean(p[1:-1]) == pytest.approx((2e-6) ** 2 / (np.pi / dx), rel=0.02)


# -------------------------------------------------------------------------------------- levels

def test_rms_and_level_db():
    assert rms([3.0, -3.0, 3.0, -3.0]) == 3.0
    assert level_db(1e-3) == pytest.approx(60.0)
    assert level_db(2.0, ref=1.0) == pytest.approx(20 * math.log10(2))
    assert level_db(0.0) == -math.inf
    with pytest.raises(ValueError):
        rms([])


@pytest.mark.parametrize("slope", [9.0, 10.5, 12.0])
def test_velocity_exponent_returns_the_known_slope(slope):
    v = np.array([0.01, 0.02, 0.04, 0.1])
    lev = 70.0 + slope * np.log2(v / 0.01)
    s, n, se = velocity_exponent(v, lev)
    assert s == pytest.approx(slope, abs=1e-10) and se == pytest.approx(0.0, abs=1e-10)
    assert n == pytest.approx(slope / (10 * math.log10(2)))          # power basis
    res = velocity_exponent(v, lev, basis="amplitude")
    assert res.exponent == pytest.approx(slope / (20 * math.log10(2)))
    assert res.db_per_doubling == pytest.approx(slope, abs=1e-10)


def test_velocity_exponent_from_amplitudes_and_its_stderr():
    # mean square proportional to v^3: 3 on the power basis is 9.03 dB per doubling
    v = np.geomspace(0.01, 0.1, 6)
    lev = [level_db(math.sqrt(7.0 * vi**3)) for vi in v]
    s, n, _ = velocity_exponent(v, lev)
    assert n == pytest.approx(3.0, abs=1e-10) and s == pytest.approx(3 * 10 * math.log10(2))
    # residuals +-d alternating on 4 points: OLS stderr by hand
    x = np.array([0.0, 1.0, 2.0, 3.0])
    d = 0.5
    y = 60 + 10 * x + d * np.array([1, -1, -1, 1])   # orthogonal to [1, x]: slope stays 10
    s, _, se = velocity_exponent(2.0**x, y)
    assert s == pytest.approx(10.0, abs=1e-12)
    assert se == pytest.approx(math.sqrt(4 * d**2 / 2 / np.sum((x - x.mean()) ** 2)))
    with pytest.raises(ValueError):
        velocity_exponent([0.01, 0.01], [1.0, 2.0])


def test_stick_fraction_on_a_constructed_velocity():
    v = np.array([0.0, 1e-4, -4.9e-4, 5e-4, -1e-3, 2e-2, np.nan, -0.3])
    # 3 of the 7 finite samples have |v| < 5e-4
    assert stick_fraction(v, 5e-4) == pytest.approx(3 / 7)
    assert stick_fraction(np.zeros(5), 1e-9) == 1.0
    assert math.isnan(stick_fraction([np.nan], 1e-3))
    with pytest.raises(ValueError):
        stick_fraction(v, 0.0)


def test_whole_period_window_takes_whole_periods_after_the_transient():
    dt = 1e-5
    t = np.arange(37_000) * dt        # 0.37 s
    w = whole_period_window(t, 0.1, 0.05)
    assert t[w.start] == pytest.approx(0.05)
    assert w.stop - w.start == 30_000  # 3 whole periods of 10 000 samples in 0.32 s
    # exactly 3 periods after a zero transient
    w = whole_period_window(np.arange(30_000) * dt, 0.1, 0.0)
    assert (w.start, w.stop) == (0, 30_000)
    # not one period fits: everything after the transient
    w = whole_period_window(t[:12_000], 0.1, 0.05)
    assert (w.start, w.stop) == (5_000, 12_000)
    # no periodicity
    assert whole_period_window(t, math.inf, 0.1) == slice(10_000, t.size)
    assert whole_period_window(t, 0.0, 0.0) == slice(0, t.size)
    with pytest.raises(ValueError, match="longer than the record"):
        whole_period_window(t, 0.1, 1.0)


def test_global_tangential_stiffness_is_nan_below_the_guard():
    dt = 1e-5
    t = np.arange(20_000) * dt
    w, X, k = 2 * np.pi * 7.0, 2e-4, 3e5
    x = X * np.sin(w * t)
    v = X * w * np.cos(w * t)
    T = 0.3 + k * x                    # a linear spring: dT/dx = k wherever it is defined
    guard = 1e-3
    kt = global_tangential_stiffness(T, x, v, dt, v_guard=guard)
    slow = np.abs(v) < guard
    assert slow.any() and (~slow).any()
    assert np.all(np.isnan(kt[slow]))
    np.testing.assert_allclose(kt[~slow], k, rtol=1e-9)
    # without a velocity the guard uses dx/dt; a constant force (pure slip) gives 0
    kt0 = global_tangential_stiffness(np.full_like(x, 0.3), x, None, dt, v_guard=guard)
    assert np.all(kt0[~np.isnan(kt0)] == 0.0) and np.isnan(kt0).sum() == pytest.approx(
        slow.sum(), abs=4)
