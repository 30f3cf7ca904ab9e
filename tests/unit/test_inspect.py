"""Inspecting runs: the regime time series and the provenance in result.nc."""

import dataclasses
import re
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import roughvib
from roughvib.cli import main
from roughvib.results import load_result

ROOT = Path(__file__).resolve().parents[2]

# a block pushed at 0.1 m/s over a 10 um sinusoid on a rigid base: the contacts lift off and
# touch down every few milliseconds (Feldmann law unused: the tangential motion is prescribed)
BOUNCING = ["--set", "plate.kind=rigid", "--set", "roughness.kind=sinusoid",
            "--set", "roughness.amplitude=10e-6", "--set", "excitation.kind=prescribed",
            "--set", "excitation.velocity=0.1", "--set", "excitation.amplitude=0.0",
            "--set", "excitation.target_rms_velocity=none", "--set", "output.progress=false"]


@pytest.fixture(scope="module")
def failed_run(tmp_path_factory):
    """One contact, storm guard at 2 events: fails with event_storm after about 3.6 ms."""
    out = tmp_path_factory.mktemp("failed") / "run"
    code = main(["run", "--out", str(out), "--quiet", *BOUNCING, "--set", "contact.points=1",
                 "--set", "roughness.wavelength=0.5e-3", "--set", "solver.max_events=2",
                 "--set", "solver.event_window=0.1", "--set", "output.duration=0.03"])
    assert code == 1
    assert (out / "partial.nc").exists() and not (out / "result.nc").exists()
    return out


@pytest.fixture(scope="module")
def bouncing_run(tmp_path_factory):
    """Three contacts at different phases of the sinusoid, 10 ms, completes."""
    out = tmp_path_factory.mktemp("bouncing") / "run"
    assert main(["run", "--out", str(out), "--quiet", *BOUNCING, "--set", "contact.points=3",
                 "--set", "roughness.wavelength=0.73e-3", "--set", "output.duration=0.01"]) == 0
    return out


# --------------------------------------------------------------------------------------------
# result.nc: regime series and provenance
# --------------------------------------------------------------------------------------------


def test_contact_closed_agrees_with_the_log_and_the_forces(bouncing_run):
    ds = xr.load_dataset(bouncing_run / "result.nc", engine="h5netcdf")
    closed = ds["contact_closed"]
    assert closed.dims == ("time", "contact") and closed.dtype == np.int8
    assert closed.attrs["units"] == "1" and "closed" in closed.attrs["long_name"]
    assert closed.attrs["flag_meanings"] == "open closed"
    c = closed.values
    t = ds["time"].values
    # an open contact carries no force, a loaded one is closed
    f = ds["contact_force"].values
    assert np.array_equal(c == 1, f > 0)
    assert 0 < c.mean() < 1 and len({tuple(col) for col in c.T}) >= 2
    # each regime_after string of the log, on the first sample after its events
    ev = pd.read_csv(bouncing_run / "events.csv")
    times = np.unique(ev["time"])  # contacts in phase switch at the same instant
    checked = 0
    for i, te in enumerate(times):
        j = np.searchsorted(t, te, side="right")
        if j == t.size or (i + 1 < times.size and times[i + 1] <= t[j]):
            continue
        after = ev[ev["time"] == te]["regime_after"].iloc[-1]
        digits = re.match(r"closed=(\d+) ", after).group(1)
        assert "".join(map(str, c[j])) == digits, (te, after)
        checked += 1
    assert checked >= 3 and len(ev) >= 10
    # prescribed motion: no friction model, the block never sticks
    assert (ds["stick"].values == 0).all() and "prescribed" in ds["stick"].attrs["comment"]


def test_result_nc_says_how_it_was_made(bouncing_run):
    ds = xr.load_dataset(bouncing_run / "result.nc", engine="h5netcdf")
    assert ds.attrs["roughvib_version"] == roughvib.__version__
    assert "scikit-sundae" in ds.attrs["software"]
    scene = roughvib.load_scene(bouncing_run / "scene.toml")
    assert ds.attrs["scene_toml"] == (bouncing_run / "scene.toml").read_text()
    assert tomllib.loads(ds.attrs["scene_toml"])["contact"]["points"] == 3
    for f in dataclasses.fields(scene.solver):  # every field of the section, generically
        value = getattr(scene.solver, f.name)
        got = ds.attrs[f"solver_{f.name}"]
        if isinstance(value, bool) or value is None:
            assert got == str(value).lower() if value is not None else got == "none"
        else:
            assert got == value, f.name


def test_failed_run_partial_nc_has_the_regime_series(failed_run):
    part = load_result(failed_run, partial=True)
    ds = part.dataset
    assert np.array_equal(ds["contact_closed"].values[:, 0] == 1,
                          ds["contact_force"].values[:, 0] > 0)
    assert ds.attrs["status"] == "event_storm" and ds.attrs["solver_max_events"] == 2
