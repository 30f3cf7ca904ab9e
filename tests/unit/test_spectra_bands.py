"""Spectra on synthetic signals with known content: band placement, Parseval, noise density."""

import numpy as np
import pytest

from roughvib.analysis.spectra import (
    add_noise_floor,
    band_levels,
    band_powers,
    narrowband_psd,
    nominal_centre,
    third_octave_bands,
    total_level,
)

FS = 1e5


def test_band_centres_and_edges_follow_iec_base10():
    fc, lo, hi = third_octave_bands(20, 50e3)
    assert fc[0] == pytest.approx(1000 * 10 ** (-17 / 10))
    assert np.any(np.isclose(fc, 1000.0))
    np.testing.assert_allclose(hi[:-1], lo[1:])                     # contiguous
    np.testing.assert_allclose(hi / lo, 10 ** 0.1)                   # third octave width
    labels = [nominal_centre(f) for f in fc]
    assert labels[:5] == [20, 25, 31.5, 40, 50] and 40000 in labels and 50000 in labels


@pytest.mark.parametrize("f0", [1000.0, 3981.071705534972, 20e3])
def test_sine_lands_in_its_band_at_its_level(f0):
    n = 100_000  # 1 s: integer cycles for these frequencies within 1e-6
    t = np.arange(n) / FS
    f0 = round(f0)  # an integer number of cycles in the record
    A = 0.3
    fc, lev = band_levels(A * np.sin(2 * np.pi * f0 * t), FS)
    i = int(np.argmax(lev))
    _, lo, hi = third_octave_bands(20, 50e3)
    assert lo[i] <= f0 < hi[i]
    assert lev[i] == pytest.approx(20 * np.log10(A / np.sqrt(2) / 1e-6), abs=0.01)
    others = np.delete(lev, i)
    assert np.all(others[np.isfinite(others)] < lev[i] - 30)


def test_parseval_band_powers_sum_to_mean_square():
    rng = np.random.default_rng(0)
    x = rng.standard_normal(50_000)
    # band-limit to the covered range [lo_0, hi_-1) by zeroing other FFT bins
    fc, lo, hi = third_octave_bands(20, 40e3)
    X = np.fft.rfft(x)
    f = np.fft.rfftfreq(x.size, 1 / FS)
    X[(f < lo[0]) | (f >= hi[-1])] = 0
    y = np.fft.irfft(X, x.size)
    pw = band_powers(y, FS, lo, hi)
    assert pw.sum() == pytest.approx(np.mean((y - y.mean()) ** 2), rel=1e-10)


def test_white_noise_density_and_band_slope():
    rng = np.random.default_rng(1)
    sigma = 0.2
    x = rng.normal(0, sigma, 400_000)
    f, p = narrowband_psd(x, FS, resolution=100.0)
    band = (f > 1e3) & (f < 40e3)
    # one-sided density sigma^2 / (fs/2); Welch average of ~800 segments: ~3.5 % per bin
    assert np.mean(p[band]) == pytest.approx(sigma**2 / (FS / 2), rel=0.01)
    fc, lev = band_levels(x, FS, fmin=1e3, fmax=40e3)
    slope = np.polyfit(np.arange(fc.size), lev, 1)[0]
    assert slope == pytest.approx(1.0, abs=0.1)  # bandwidth grows 10^(1/10) per band


def test_one_db_amplitude_change_is_one_db_in_every_band():
    rng = np.random.default_rng(2)
    x = rng.standard_normal(20_000)
    _, a = band_levels(x, FS, fmin=100)
    _, b = band_levels(x * 10 ** (1 / 20), FS, fmin=100)
    ok = np.isfinite(a)
    np.testing.assert_allclose(b[ok] - a[ok], 1.0, atol=1e-9)


def test_total_level_and_noise_floor():
    t = np.arange(10_000) / FS
    x = np.sqrt(2) * 1e-3 * np.sin(2 * np.pi * 1000 * t)
    assert total_level(x) == pytest.approx(60.0, abs=1e-6)  # 1e-3 rms re 1e-6
    y = add_noise_floor(np.zeros(200_000), FS, 1e-3, seed=4)
    assert np.std(y) == pytest.approx(1e-3, rel=0.01)
    np.testing.assert_array_equal(y, add_noise_floor(np.zeros(200_000), FS, 1e-3, seed=4))


@pytest.mark.parametrize("window", ["boxcar", "hann"])
def test_a_band_160_db_below_the_total_is_measured(window):
    """Per-band sums, not differences of a cumulative sum: those lose a band ~130 dB below the
    total power to round-off. Two tones with whole numbers of cycles in the record."""
    fs, n = 1e5, 100_000
    t = np.arange(n) / fs
    x = np.sin(2 * np.pi * 1000.0 * t) + 1e-8 * np.sin(2 * np.pi * 10_000.0 * t)
    fc, lev = band_levels(x, fs, fmin=20.0, fmax=20e3, window=window)
    i = int(np.argmin(np.abs(fc - 10_000.0)))
    expected = 20 * np.log10(1e-8 / np.sqrt(2) / 1e-6)  # -43.0 dB re 1e-6
    assert lev[i] == pytest.approx(expected, abs=0.01)


def test_unknown_window_is_refused():
    with pytest.raises(ValueError, match="window must be one of boxcar, hann"):
        band_levels(np.ones(16), 1e3, window="kaiser")
