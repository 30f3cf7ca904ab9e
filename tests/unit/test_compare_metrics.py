"""Work-precision error metrics on synthetic inputs with known differences."""

import numpy as np
import pandas as pd
import pytest

from roughvib.analysis.compare import (
    band_level_errors,
    common_grid,
    match_events,
    max_abs_db,
    relative_rms_error,
)

FS = 1e5


def test_a_one_db_band_change_is_reported_as_one_db():
    rng = np.random.default_rng(0)
    x = rng.standard_normal(100_000)
    X = np.fft.rfft(x)
    f = np.fft.rfftfreq(x.size, 1 / FS)
    # raise the 1 kHz band (891-1122 Hz) by exactly 1 dB
    band = (f >= 1000 * 10 ** (-1 / 20)) & (f < 1000 * 10 ** (1 / 20))
    Y = X.copy()
    Y[band] *= 10 ** (1 / 20)
    y = np.fft.irfft(Y, x.size)
    # the change is exact per FFT bin, so only the untapered record measures it exactly (the
    # Hann taper smears the band edges over +-2 bins: 0.9997 dB)
    fc, d = band_level_errors(y, x, FS, window="boxcar")
    i = int(np.argmin(np.abs(fc - 1000)))
    assert d[i] == pytest.approx(1.0, abs=1e-9)
    assert np.nanmax(np.abs(np.delete(d, i))) < 1e-9
    assert max_abs_db(fc, d, 100, 20e3) == pytest.approx(1.0, abs=1e-9)
    assert max_abs_db(fc, d, 20e3, 50e3) < 1e-9


def test_shifted_events_are_reported_by_their_shift():
    ref = pd.DataFrame({"time": [0.01, 0.02, 0.05, 0.07], "kind": ["stick", "slip", "lift_off",
                                                                    "lift_off"],
                        "contact": pd.array([pd.NA, pd.NA, 0, 1], dtype="Int64")})
    run = ref.copy()
    run["time"] = run["time"] + np.array([2e-6, -3e-6, 1e-5, 0.0])
    extra = pd.DataFrame({"time": [0.09], "kind": ["touch_down"],
                          "contact": pd.array([1], dtype="Int64")})
    dt, unmatched = match_events(pd.concat([run, extra], ignore_index=True), ref)
    np.testing.assert_allclose(np.sort(dt), np.sort([2e-6, -3e-6, 1e-5, 0.0]), atol=1e-15)
    assert unmatched == 1
    # a different contact is not a partner
    run2 = ref.copy()
    run2.loc[3, "contact"] = 0
    _, un2 = match_events(run2, ref)
    assert un2 == 2


def test_relative_rms_error_and_common_grid():
    t = np.arange(1001) * 1e-5
    x = np.sin(2 * np.pi * 50 * t)
    assert relative_rms_error(1.01 * x, x) == pytest.approx(0.01)
    t2 = np.arange(101) * 1e-4
    a, b, dt = common_grid(t, t2)
    np.testing.assert_allclose(t[a], t2[b])
    assert dt == pytest.approx(1e-4)
    with pytest.raises(ValueError, match="not integer multiples"):
        common_grid(t, np.arange(10) * 2.5e-5)


def test_a_quiet_band_error_is_not_masked_by_a_loud_neighbour():
    """A 1 kHz tone 100 dB above a 12 kHz tone (both off the FFT bins); only the quiet tone
    differs, by 6.02 dB (doubled amplitude). With the Hann default the 12.5 kHz band reads
    the 6.02 dB; the rectangular window's 1/f^2 leakage of the loud tone swamps it."""
    t = np.arange(20_000) / FS
    loud = np.sin(2 * np.pi * 1003.7 * t)
    quiet = 1e-5 * np.sin(2 * np.pi * 12_011.3 * t)
    fc, d = band_level_errors(loud + 2 * quiet, loud + quiet, FS)
    j = int(np.argmin(np.abs(fc - 12_500)))
    assert d[j] == pytest.approx(20 * np.log10(2), abs=0.05)
    _, d_box = band_level_errors(loud + 2 * quiet, loud + quiet, FS, window="boxcar")
    assert abs(d_box[j]) < 1.0
