"""
A small parameter sweep
=======================

A sweep runs many variants of one scene, on a local pool of worker processes or as tasks on a
:mod:`dask.distributed` cluster, and collects their metrics in one table. Here the paper scene
is run at three friction velocities (10, 20 and 40 mm/s rms); the sweep report fits the total
levels against the measured velocity, in dB per doubling of the velocity, which is how the
paper states its velocity exponent. To keep the example short, each case simulates only 20 ms
with the plate modes cut at 3 kHz, on a Dask cluster of two threads inside this process; the
paper's own study is the built-in sweep ``roughvib sweep paper-velocity`` (docs: sweeps).
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
from dask.distributed import Client

from roughvib.studies.sweep import run_sweep, sweep_report

sweep = {
    "name": "velocity-demo",
    "base": "paper",
    "set": {"output.duration": 0.02, "output.transient": 0.0,
            "plate.max_frequency": 3000.0, "output.progress": False},
    "grid": {"excitation.target_rms_velocity": [0.01, 0.02, 0.04]},
}
out = Path(tempfile.mkdtemp()) / "velocity-demo"
with Client(processes=False, n_workers=1, threads_per_worker=2,
            dashboard_address=":0") as client:  # any free port: no clash with another cluster
    run = run_sweep(sweep, out, client=client, progress=False)
print(f"ran {run.ran}, failed {run.failed}, skipped {run.skipped}")

# %%
# One row per case, as in ``sweep.csv``: the varied value, the status and the main metrics.
cols = ["excitation.target_rms_velocity", "status", "block_tangential_velocity_rms",
        "block_vertical_acceleration_level_db_re_1e-6",
        "plate_vertical_acceleration_level_db_re_1e-6", "stick_fraction"]
print(run.table[cols].to_string(index=False))

# %%
# The sweep report (``roughvib sweep-report DIR``): Markdown, a self-contained HTML page, the
# fits and one figure per study. Over 20 ms the levels are those of the start transient, not
# of the steady motion the paper measures, so the slopes here only show the mechanics.
report = sweep_report(out)
print(pd.read_csv(report.parent / "fits.csv")[["quantity", "db_per_doubling",
                                                "exponent_power"]].to_string(index=False))
fig, ax = plt.subplots(figsize=(10, 4))
ax.imshow(plt.imread(report.parent / "velocity.png"))
ax.set_axis_off()
plt.show()
