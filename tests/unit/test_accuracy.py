"""The accuracy contract's measurement on synthetic runs with known deviations: bands within
and outside the dynamic range, a band the tested run lost, shifted and unmatched events,
velocity and energy limits, the verdict and its one-line form."""

import math

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from roughvib.analysis.accuracy import (
    CONTRACT,
    band_deviations,
    contract_ratio,
    measure_accuracy,
    verdict_line,
)
from roughvib.analysis.compare import band_level_errors, max_abs_db
from roughvib.results import Result

FS = 1e5
N = 20_000  # 0.2 s
T = np.arange(N) / FS


def _tone(f, amp):
    return amp * np.sin(2 * np.pi * f * T + 0.3)


def _run(block, plate, v=None, events=None, energy=1e-9):
    ds = xr.Dataset({"block_vertical_acceleration": ("time", block),
                     "plate_vertical_acceleration": ("time", plate),
                     "block_tangential_velocity": ("time", np.cos(2 * np.pi * 7 * T)
                                                   if v is None else v)},
                    coords={"time": T})
    ev = events if events is not None else pd.DataFrame(
        {"time": [0.05, 0.1], "kind": ["lift_off", "touch_down"],
         "contact": pd.array([0, 0], dtype="Int64")})
    return Result(ds, ev, {"status": "success", "energy_audit": {"relative_residual": energy}},
                  "")


# the plate carries a loud 1 kHz tone and a tone 60 dB below it at 10 kHz; the block a loud
# 500 Hz tone and one 90 dB below it at 20 kHz (outside the 80 dB range)
PLATE = _tone(1003.7, 1.0) + _tone(10_031.0, 1e-3)
BLOCK = _tone(503.1, 1.0) + _tone(20_017.0, 10**-4.5)


def _measure(run, ref=None):
    return measure_accuracy(run, ref or _run(BLOCK, PLATE), period=math.inf, transient=0.0,
                            reference_label="synthetic")


def test_identical_runs_pass_with_zero_deviation():
    acc = _measure(_run(BLOCK, PLATE))
    assert acc["verdict"] == "pass" and acc["failures"] == []
    assert acc["bands"]["plate"]["deviation_db"] == pytest.approx(0.0, abs=1e-9)
    assert acc["events"] == {"matched": 2, "unmatched": 0, "max_dt": 0.0}
    assert contract_ratio(acc) == pytest.approx(1e-3)  # the energy audit, 1e-9 / 1e-6
    assert verdict_line(acc).startswith("PASS against synthetic: block")


def test_a_quiet_band_within_the_range_fails_by_its_deviation():
    # the 10 kHz tone, 60 dB below the loudest band, doubled: +6.02 dB in the 10 kHz band
    acc = _measure(_run(BLOCK, _tone(1003.7, 1.0) + _tone(10_031.0, 2e-3)))
    p = acc["bands"]["plate"]
    assert p["worst_band_hz"] == pytest.approx(1e4, rel=1e-6)
    assert p["deviation_db"] == pytest.approx(20 * np.log10(2), abs=0.05)
    assert acc["verdict"] == "fail"
    assert any("plate band 10 kHz" in f for f in acc["failures"])
    assert "FAIL" in verdict_line(acc)


def test_a_band_below_the_dynamic_range_is_not_checked():
    # the 20 kHz block tone lies 90 dB below the loudest block band: changing it is no failure
    acc = _measure(_run(_tone(503.1, 1.0) + _tone(20_017.0, 10**-3.5), PLATE))
    assert acc["verdict"] == "pass"
    checked = [f for f, _, _ in acc["bands"]["block"]["per_band"]]
    assert not any(abs(f - 2e4) < 1e3 for f in checked)
    assert any(abs(f - 500) < 30 for f in checked)
    # ... while the same change 60 dB down (inside the range) is checked
    b = band_deviations(_tone(503.1, 1.0) + _tone(20_017.0, 2e-3),
                        _tone(503.1, 1.0) + _tone(20_017.0, 1e-3), FS)
    assert b["worst_band_hz"] == pytest.approx(19952.6, rel=1e-3)
    assert CONTRACT.dynamic_range_db == 80.0


def test_a_band_the_run_lost_is_the_largest_possible_error():
    # the tested run lost all of its plate signal: every checked band is -inf dB
    acc = _measure(_run(BLOCK, np.zeros(N)))
    assert acc["bands"]["plate"]["deviation_db"] == "-inf"
    assert acc["verdict"] == "fail"
    assert contract_ratio(acc) == math.inf
    b = band_deviations(np.zeros(N), PLATE, FS)
    assert b["worst_deviation_db"] == -math.inf
    # the work-precision metric says the same: inf, not a skipped NaN
    fc, d = band_level_errors(np.zeros(N), PLATE, FS)
    assert max_abs_db(fc, d, 100.0, 50e3) == math.inf
    # a NaN in the tested record is no better than a lost band
    bad = PLATE.copy()
    bad[100] = np.nan
    assert abs(band_deviations(bad, PLATE, FS)["worst_deviation_db"]) == math.inf


def test_event_times_velocity_and_energy_limits():
    ref = _run(BLOCK, PLATE)
    shifted = ref.events.copy()
    shifted["time"] += np.array([2e-6, 0.0])
    acc = _measure(_run(BLOCK, PLATE, events=shifted), ref)
    assert acc["events"]["max_dt"] == pytest.approx(2e-6, rel=1e-6)
    assert acc["verdict"] == "fail" and "event times" in acc["failures"][0]
    extra = pd.concat([ref.events, pd.DataFrame({"time": [0.15], "kind": ["lift_off"],
                                                 "contact": pd.array([1], dtype="Int64")})],
                      ignore_index=True)
    acc = _measure(_run(BLOCK, PLATE, events=extra), ref)
    assert acc["events"]["unmatched"] == 1 and acc["verdict"] == "fail"
    v = ref.dataset["block_tangential_velocity"].values
    assert _measure(_run(BLOCK, PLATE, v=v * (1 + 5e-5)), ref)["verdict"] == "pass"
    acc = _measure(_run(BLOCK, PLATE, v=v * (1 + 2e-4)), ref)
    assert acc["velocity_rel_rms"] == pytest.approx(2e-4, rel=1e-6)
    assert acc["verdict"] == "fail"
    acc = _measure(_run(BLOCK, PLATE, energy=-3e-6), ref)
    assert acc["verdict"] == "fail" and "energy audit" in acc["failures"][0]


@pytest.mark.parametrize("missing", [None, float("nan")])
def test_a_run_without_an_energy_audit_cannot_pass(missing):
    """The paper scheme keeps no energy audit (None in a loaded summary, NaN in a fresh
    one): that item of the contract cannot be shown to hold, so the verdict is a fail with a
    reason, not a crash or a pass."""
    acc = _measure(_run(BLOCK, PLATE, energy=missing))
    assert acc["verdict"] == "fail" and acc["failures"] == [
        "the run has no energy audit (its method keeps none)"]
    assert acc["energy_rel_residual"] is None and contract_ratio(acc) == math.inf
    assert verdict_line(acc).endswith("energy n/a")
