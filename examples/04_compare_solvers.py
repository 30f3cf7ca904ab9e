"""
Comparing solvers
=================

Every solver runs the same model and returns the same :class:`~roughvib.results.Result`, so
switching is one key, ``solver.method``. This example runs the first 20 ms of the paper scene
with the plate modes cut at 10 kHz (to keep it short) with four solvers and measures each
against a tight IDA reference: the third-octave band levels of the plate acceleration, the
relative rms error of the tangential velocity and the times of the matched events.
``roughvib compare`` does the same over ladders of tolerances and steps (docs: solvers).
"""

import time
import warnings

import matplotlib.pyplot as plt
import numpy as np

import roughvib
from roughvib.analysis.compare import band_level_errors, match_events, relative_rms_error
from roughvib.scene import ModelValidityWarning
from roughvib.views.figures import plot_band_comparison

BASE = {"output.duration": 0.02, "output.transient": 0.0, "plate.max_frequency": 10e3,
        "output.progress": False}
RUNS = {
    "reference (ida, rtol 1e-9)": {"solver.method": "ida", "solver.rtol": 1e-9,
                                   "solver.atol_acceleration": 1e-11},
    "ida (draft preset)": {"solver.method": "ida", "solver.accuracy": "draft"},
    "adaptive-modal (default)": {"solver.method": "adaptive-modal"},
    "exact-modal, 2.5 us": {"solver.method": "exact-modal", "solver.step": 2.5e-6},
    "paper scheme, 10 us": {"solver.method": "paper", "solver.step": 1e-5},
}

# 20 ms is less than one excitation period (1/7 s): the summary levels of such a run average
# over part of a cycle, and roughvib says so with a ModelValidityWarning. This example measures
# its errors over the same 20 ms of every run and reads no summary level, so it silences that
# one warning, for these runs only.
results = {}
with warnings.catch_warnings():
    warnings.filterwarnings("ignore", "the analysis window", ModelValidityWarning)
    for label, settings in RUNS.items():
        t0 = time.perf_counter()
        results[label] = roughvib.simulate(roughvib.load_scene("paper", {**BASE, **settings}))
        print(f"{label:28s} {time.perf_counter() - t0:6.2f} s  {results[label].status}")

# %%
# Errors against the reference. The band levels are compared where the reference band lies
# above 30 dB re 1e-6 m/s². ``roughvib run --verify`` and ``roughvib compare`` judge a run by
# the accuracy contract instead (:func:`roughvib.analysis.accuracy.measure_accuracy`, docs:
# accuracy).
ref_label, *others = results
ref = results[ref_label]
fs = 1.0 / float(ref.dataset["time"][1] - ref.dataset["time"][0])  # output grid: 1e5 Hz
for label in others:
    r = results[label]
    fc, d = band_level_errors(r.dataset["plate_vertical_acceleration"].values,
                              ref.dataset["plate_vertical_acceleration"].values, fs,
                              floor_db=30.0)
    v = relative_rms_error(r.dataset["block_tangential_velocity"].values,
                           ref.dataset["block_tangential_velocity"].values)
    dt, unmatched = match_events(r.events, ref.events)
    worst_dt = np.max(np.abs(dt)) if dt.size else float("nan")
    print(f"{label:28s} plate bands: max {np.nanmax(np.abs(d)):.2g} dB, "
          f"velocity: {v:.1e}, events: max |dt| {worst_dt:.1e} s, {unmatched} unmatched")

# %%
# The plate's third-octave spectra of all runs on one plot.
plot_band_comparison(list(results.values()), list(results), quantity="plate")
plt.show()
