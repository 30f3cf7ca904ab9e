"""Sweeps: file format, case names, a small sweep, kill and resume, a failing case, the
scheduler address, the report.

Most sweeps run as Dask tasks on one 2-worker LocalCluster (processes, one thread each) shared by
the module, standing in for a cluster given by address; the others run on the sweep's own local
pool (no Dask). The sweeps use 0.01 s runs with plate modes to 3 kHz (about 1 s per case once a
worker has loaded the kernels).
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from browser import inspect_page
from self_signal import start_stopping_itself

import roughvib
from roughvib.cli.sweep import add_parsers
from roughvib.scene import SceneError
from roughvib.studies import sweep as sw
from roughvib.studies.sweep import pool as sw_pool
from roughvib.studies.sweep import run as sw_run
from roughvib.studies.sweep.spec import old_case_name

distributed = pytest.importorskip("dask.distributed")

FAST = {"output.duration": 0.01, "plate.max_frequency": 3000.0,
        "solver.atol_acceleration": 1e-5}
SET_TOML = "\n".join(f'"{k}" = {v!r}' for k, v in FAST.items())
SMALL = f"""
name = "small"
base = "paper"
[set]
{SET_TOML}
[grid]
"excitation.target_rms_velocity" = [0.01, 0.02]
"roughness.seed" = [1, 2]
"""
VARIABLE_TIME = ("wall_time", "solver_wall_time")


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="roughvib")
    add_parsers(p.add_subparsers(dest="command"))
    return p


def _stamp(case_dir: Path) -> dict[str, tuple[int, int]]:
    """Inode and mtime of a case directory and its files."""
    out = {".": (case_dir.stat().st_ino, case_dir.stat().st_mtime_ns)}
    for f in sorted(case_dir.iterdir()):
        st = f.stat()
        out[f.name] = (st.st_ino, st.st_mtime_ns)
    return out


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, env=dict(sw.THREAD_ENV)) as cluster, \
            distributed.Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def small_run(client, tmp_path_factory):
    root = tmp_path_factory.mktemp("small")
    spec = _write(root / "small.toml", SMALL)
    run = sw.run_sweep(spec, root / "out", client=client, progress=False)
    return spec, run


# --------------------------------------------------------------------------------------------
# sweep files and case names
# --------------------------------------------------------------------------------------------


def test_grid_is_the_product_in_file_order_and_names_are_stable_and_safe(tmp_path):
    spec = sw.load_sweep(_write(tmp_path / "s.toml", SMALL))
    cases = spec.cases()
    assert spec.dims == ("excitation.target_rms_velocity", "roughness.seed")
    assert spec.shape == (2, 2)
    assert [tuple(c.values.values()) for c in cases] == [(0.01, 1), (0.01, 2), (0.02, 1),
                                                         (0.02, 2)]
    assert [c.index for c in cases] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    names = [c.name for c in cases]
    assert len(set(names)) == 4
    for n in names:  # nothing a shell needs quoted, not hidden, not an option
        assert all(ch.isalnum() or ch in "._+-" for ch in n) and n[0] not in ".-"
        assert shlex.quote(n) == n
    assert names[1].startswith("target_rms_velocity-0.01__seed-2__")
    # same file again, nested-table spelling, extended grid: existing names unchanged
    nested = SMALL.replace('"excitation.target_rms_velocity" = [0.01, 0.02]',
                           "excitation.target_rms_velocity = [0.01, 0.02, 0.04]")
    again = sw.load_sweep(_write(tmp_path / "n.toml", nested)).cases()
    assert [c.name for c in again][:4] == names and len(again) == 6
    # another base (a fixed value changed): new names
    other = sw.load_sweep(_write(tmp_path / "o.toml",
                                 SMALL.replace('"output.duration" = 0.01',
                                               '"output.duration" = 0.02')))
    assert not set(names) & {c.name for c in other.cases()}


def test_cases_expected_to_take_longest_get_the_highest_priority():
    """Cases start longest first (simulated time, then sliding speed); the others keep the
    order of the grid (equal priority)."""
    spec = sw.load_sweep("paper-velocity")
    cases = spec.cases()
    rank = sw_run._longest_first(spec.base, cases)
    by_v = {}
    for c in cases:
        by_v.setdefault(c.values["excitation.target_rms_velocity"], set()).add(rank[c.name])
    assert all(len(r) == 1 for r in by_v.values())  # the seeds of one velocity: equal
    order = sorted(by_v, key=lambda v: -next(iter(by_v[v])))
    assert order == [0.1, 0.04, 0.02, 0.01]
    # a longer case outranks a faster one; an ensemble (only seeds vary): all equal
    mixed = sw.load_sweep({"name": "m", "base": "paper", "case": [
        {"output.duration": 0.4, "excitation.target_rms_velocity": 0.01},
        {"output.duration": 0.2, "excitation.target_rms_velocity": 0.1}]})
    r = sw_run._longest_first(mixed.base, mixed.cases())
    assert [r[c.name] for c in mixed.cases()] == [1, 0]
    seeds = sw.load_sweep({"name": "e", "base": "paper", "grid": {"roughness.seed": [1, 2, 3]}})
    assert set(sw_run._longest_first(seeds.base, seeds.cases()).values()) == {0}


def test_grid_and_case_list_combine_and_case_keys_fill_from_the_base(tmp_path):
    spec = sw.load_sweep({"base": "paper", "grid": {"roughness.seed": [1, 2]},
                          "case": [{"block.mass": 0.543}, {"friction.mu_slip": 0.2}]})
    assert spec.dims == ("roughness.seed", "case") and spec.shape == (2, 2)
    assert spec.varied_keys == ["roughness.seed", "block.mass", "friction.mu_slip"]
    assert spec.base_value("block.mass") == roughvib.load_scene("paper").block.mass
    assert [c.values for c in spec.cases()][1] == {"roughness.seed": 1,
                                                    "friction.mu_slip": 0.2}


def test_a_laws_own_key_is_swept_and_checked_against_the_base_law():
    spec = sw.load_sweep({"base": "paper", "set": {"friction.law": "lugre"},
                          "grid": {"friction.parameters.sigma0": [1e5, 4e5]}})
    assert spec.base_value("friction.parameters.sigma0") == 1e5  # the law's default
    scenes = [spec.base.with_overrides(c.values) for c in spec.cases()]
    assert [s.friction.parameters["sigma0"] for s in scenes] == [1e5, 4e5]
    assert scenes[1].friction.parameters["sigma1"] == 100.0  # the others keep their defaults
    with pytest.raises(SceneError, match=r"^grid.friction.parameters.sigma0 is not a known key "
                                         r"of friction.parameters for this base scene \(known: "
                                         r"a1, a2, hysteresis_velocity, latch_velocity\)$"):
        sw.load_sweep({"base": "paper", "grid": {"friction.parameters.sigma0": [1e5]}})


@pytest.mark.parametrize("text,fragment", [
    ('[grid]\n"block.colour" = [1, 2]', "grid.block.colour is not a known key of [block]"),
    ('[grid]\n"blok.mass" = [1, 2]', "grid.blok.mass is not a scene key"),
    ('[grid]\n"block.mass" = 0.3', "grid.block.mass must be a non-empty list"),
    ('[grid]\n"block.mass" = []', "grid.block.mass must be a non-empty list"),
    ('[grid]\n"block.mass" = [0.3, 0.3]', "grid.block.mass has the value 0.3 more than once"),
    ('[grid]\n"block.mass" = [0.3]\n[[case]]\n"block.mass" = 0.2',
     "case[0].block.mass is also a grid key"),
    ('[[case]]\n"block.mass" = 0.2\n[[case]]\n"block.mass" = 0.2', "case[1] repeats case[0]"),
    ('[set]\n"block.mass" = -1\n[grid]\n"roughness.seed" = [1]', "block.mass must be > 0 kg"),
    ('bas = "paper"\n[grid]\n"roughness.seed" = [1]', "bas is not a sweep file key"),
    ('base = "nope"\n[grid]\n"roughness.seed" = [1]', "base: scene 'nope' is neither"),
    ('base = "paper"', "a sweep file needs a [grid] table or [[case]] entries"),
    ('[grid\n', "is not valid TOML"),
    (f'[grid]\n"block.mass" = [0.2, 1{"0" * 400}]',
     "grid.block.mass must be a number within the range of a 64-bit integer or float, got an "
     "integer of 401 digits"),
    (f'[[case]]\n"plate.block_position" = [1{"0" * 400}, 0.1]',
     "case[0].plate.block_position must be a number within the range"),
    (f'[set]\n"block.mass" = 1{"0" * 400}\n[grid]\n"roughness.seed" = [1]',
     "set: block.mass must be a finite number kg, got 1.000e+400"),
    (b'name = "caf\xe9"\n', "sweep file .* must be UTF-8 text (save it as UTF-8), got byte 0xe9"),
])
def test_bad_sweep_files_raise_one_line_scene_errors(tmp_path, text, fragment):
    path = tmp_path / "bad.toml"
    if isinstance(text, bytes):
        path.write_bytes(text)
        fragment = fragment.replace(".*", str(path))
    else:
        _write(path, text)
    with pytest.raises(SceneError) as info:
        sw.load_sweep(path)
    assert fragment in str(info.value)
    assert "\n" not in str(info.value)


def test_a_sweep_file_with_a_byte_order_mark_is_read(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + SMALL.encode())
    assert sw.load_sweep(path).grid == sw.load_sweep(_write(tmp_path / "s.toml", SMALL)).grid


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes are POSIX")
def test_a_sweep_file_that_is_a_named_pipe_or_a_directory_says_so(tmp_path):
    """A FIFO was called "neither a built-in sweep nor an existing file"; it exists and is no
    regular file. In a subprocess with a timeout, so that a regression to reading the pipe
    fails instead of hanging the suite."""
    os.mkfifo(tmp_path / "fifo.toml")
    (tmp_path / "dir.toml").mkdir()
    for name, kind in (("fifo.toml", "a named pipe (FIFO)"), ("dir.toml", "a directory")):
        done = subprocess.run([sys.executable, "-m", "roughvib", "sweep", name], cwd=tmp_path,
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 2, done.stderr
        assert done.stderr == (f"roughvib: error: sweep file {name} must be a regular file, "
                               f"got {kind}\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.toml", "fifo.toml"]


def test_builtin_paper_velocity_sweep():
    assert "paper-velocity" in sw.builtin_sweeps()
    spec = sw.load_sweep("paper-velocity")
    assert spec.grid["excitation.target_rms_velocity"] == [0.01, 0.02, 0.04, 0.1]
    assert spec.base == roughvib.load_scene("paper")
    assert spec.to_json()["seed_keys"] == ["roughness.seed"]
    with pytest.raises(SceneError, match="neither a built-in sweep"):
        sw.load_sweep("no-such-sweep")


def test_sweep_nc_written_without_xarray_decodes_as_xarrays_own_file(tmp_path):
    # sweep.nc is written with h5netcdf directly (no dask imports); xarray's own writer of the
    # same contents is the reference: grid and case list, a text key, a failed case (NaN)
    from roughvib.studies.sweep.tables import METRICS, _dataset_parts, _write_sweep_nc

    spec = sw.load_sweep({"name": "c", "base": "paper", "grid": {"roughness.seed": [1, 2]},
                          "case": [{"block.mass": 0.3, "solver.method": "ida"},
                                   {"block.mass": -1.0}]})
    cases = spec.cases()
    table = pd.DataFrame({"case": [c.name for c in cases],
                          "status": ["success", "input_error"] * 2,
                          "message": ["", "block.mass must be > 0 kg, got -1"] * 2,
                          "wall_time": [1.5, np.nan, 2.5, np.nan]})
    for i, col in enumerate(METRICS):
        table[col] = [float(i), np.nan, -float(i), np.nan]
    coords, data, attrs = _dataset_parts(spec, table)
    _write_sweep_nc(tmp_path / "direct.nc", coords, data, attrs)
    xr.Dataset(data, coords=coords, attrs=attrs).to_netcdf(tmp_path / "xarray.nc",
                                                           engine="h5netcdf")
    direct = xr.load_dataset(tmp_path / "direct.nc", engine="h5netcdf")
    xr.testing.assert_identical(direct, xr.load_dataset(tmp_path / "xarray.nc",
                                                        engine="h5netcdf"))
    assert list(direct["solver.method"].values) == ["ida", "auto"]
    assert direct["status"].dims == ("roughness.seed", "case")
    assert np.isnan(direct["wall_time"].values[0, 1])


def test_units_of_scene_keys_come_from_the_scene_docstrings():
    assert sw.scene_key_units("block.mass") == "kg"
    assert sw.scene_key_units("excitation.target_rms_velocity") == "m/s"
    assert sw.scene_key_units("plate.width") == "m"
    assert sw.scene_key_units("friction.mu_stick") == "1"
    assert sw.scene_key_units("roughness.seed") is None


# --------------------------------------------------------------------------------------------
# the scheduler and the local cluster
# --------------------------------------------------------------------------------------------


class _Connected(Exception):
    pass


def test_scheduler_address_is_passed_to_dask_client(monkeypatch, tmp_path):
    seen = []

    class FakeClient:
        def __init__(self, address=None, *a, **kw):
            seen.append(address)
            raise _Connected

    def no_local_pool(*a, **kw):
        raise AssertionError("a local pool was started although a scheduler was given")

    monkeypatch.setattr(distributed, "Client", FakeClient)
    monkeypatch.setattr(sw_pool, "LocalPool", no_local_pool)
    monkeypatch.setattr(sw_run, "_probe", lambda address: None)  # no scheduler at head:8786
    spec = _write(tmp_path / "s.toml", SMALL)
    args = _parser().parse_args(["sweep", str(spec), "--out", str(tmp_path / "out"),
                                 "--scheduler", "tcp://head:8786", "--no-progress"])
    with pytest.raises(_Connected):
        args.func(args)
    assert seen == ["tcp://head:8786"]


def test_an_unreachable_scheduler_is_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    args = _parser().parse_args(["sweep", str(_write(tmp_path / "s.toml", SMALL)), "--out",
                                 str(out), "--scheduler", "tcp://127.0.0.1:1", "--no-progress"])
    with pytest.raises(SceneError) as info:  # main() prints it as one line, exit status 2
        args.func(args)
    assert str(info.value).startswith("--scheduler tcp://127.0.0.1:1: cannot connect (")
    assert "\n" not in str(info.value) and not out.exists()
    with pytest.raises(SceneError, match="--scheduler must be an address like tcp://host:8786"):
        sw.run_sweep(tmp_path / "s.toml", out, scheduler="tcp://127.0.0.1:port")


def test_a_second_sweep_into_the_same_directory_is_refused(tmp_path):
    from roughvib.rundir import DirectoryLock, OutputError

    out = tmp_path / "out"
    out.mkdir()
    spec = _write(tmp_path / "s.toml", SMALL)
    with DirectoryLock(out / ".sweep.lock", str(out), "sweep"):  # as a running sweep holds it
        with pytest.raises(OutputError) as info:
            sw.run_sweep(spec, out, workers=1, progress=False)
        msg = str(info.value)
        assert msg.startswith(f"{out} is in use by another sweep (pid {os.getpid()} on ")
        assert "\n" not in msg
        # the first sweep's token (which its workers check) is untouched
        assert not (out / ".sweep-token").exists() and not (out / "sweep.json").exists()


def test_a_task_never_recomputes_a_complete_case_and_cleans_dead_workers_tmp(tmp_path):
    # Dask re-runs the tasks of a killed worker, finished ones too: the task must check
    spec = sw.load_sweep(_write(tmp_path / "s.toml", SMALL))
    case = spec.cases()[0]
    cases = tmp_path / "out" / "cases"
    cases.mkdir(parents=True)
    (cases.parent / ".sweep-token").write_text("t0")
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    tag = sw_run._host_tag()
    stale = cases / f".{case.name}.tmp-{tag}-{dead.pid}-0123456789ab"
    alive = cases / f".{case.name}.tmp-{tag}-{os.getppid()}-0123456789ab"
    for d in (stale, alive):
        d.mkdir()
        (d / "summary.json").write_text("{}")
    first = sw_run._run_case(spec.base, case.name, case.values, str(cases), "t0")
    assert first["status"] == "success"
    assert not stale.exists() and alive.exists()  # only the dead process's directory goes
    before = _stamp(cases / case.name)
    again = sw_run._run_case(spec.base, case.name, case.values, str(cases), "t0")
    assert again["message"] == "complete on disk, not recomputed"
    assert again["wall_time"] == first["wall_time"]
    assert _stamp(cases / case.name) == before


def test_local_pool_has_single_threaded_workers_at_most_one_per_case(monkeypatch, tmp_path):
    seen = {}

    def fake_pool(workers, **kw):
        seen.update(kw, workers=workers)
        raise _Connected

    monkeypatch.setattr(sw_pool, "LocalPool", fake_pool)
    monkeypatch.setattr(distributed, "Client", fake_pool)  # no Dask without a scheduler
    for workers, expected in ((3, 3), (9, 4)):  # SMALL has 4 cases
        with pytest.raises(_Connected):
            sw.run_sweep(_write(tmp_path / "s.toml", SMALL), tmp_path / "out",
                         workers=workers, progress=False)
        assert seen["workers"] == expected
        assert seen["env"]["NUMBA_NUM_THREADS"] == "1" and seen["env"]["OMP_NUM_THREADS"] == "1"
    with pytest.raises(SceneError, match="workers must be >= 1, got 0"):
        sw.run_sweep(tmp_path / "s.toml", tmp_path / "out", workers=0)


# --------------------------------------------------------------------------------------------
# running sweeps
# --------------------------------------------------------------------------------------------


@pytest.mark.short_run
def test_small_sweep_completes_and_its_table_is_right(small_run, tmp_path):
    spec_path, run = small_run
    out = run.directory
    assert (run.skipped, run.ran, run.failed) == (0, 4, 0)
    table = pd.read_csv(out / "sweep.csv")
    assert list(table["excitation.target_rms_velocity"]) == [0.01, 0.01, 0.02, 0.02]
    assert list(table["roughness.seed"]) == [1, 2, 1, 2]
    assert (table["status"] == "success").all()
    assert (table["wall_time"] > 0).all()
    for _, row in table.iterrows():
        case = out / "cases" / row["case"]
        summary = json.loads((case / "summary.json").read_text())
        scene = tomllib.loads((case / "scene.toml").read_text())
        assert scene["roughness"]["seed"] == row["roughness.seed"]
        assert summary["calibration"]["target_rms_velocity"] == \
            row["excitation.target_rms_velocity"]
        m = summary["metrics"]
        for col in ("block_vertical_acceleration_level_db_re_1e-6",
                    "plate_vertical_acceleration_level_db_re_1e-6", "stick_fraction",
                    "block_tangential_velocity_rms"):
            assert row[col] == pytest.approx(m[col], rel=1e-11)
        assert row["force_amplitude"] == pytest.approx(summary["force_amplitude"], rel=1e-11)
        assert row["steps"] == summary["solver"]["steps"]
        assert (case / "result.nc").is_file() and (case / "case.json").is_file()
    # faster driving: larger friction velocity for both seeds
    v = table.set_index(["excitation.target_rms_velocity", "roughness.seed"])[
        "block_tangential_velocity_rms"]
    assert v[(0.02, 1)] > 1.5 * v[(0.01, 1)] and v[(0.02, 2)] > 1.5 * v[(0.01, 2)]
    # one case recomputed here, in this process, from the scene it should have run
    direct = roughvib.simulate(roughvib.load_scene(
        "paper", {**FAST, "excitation.target_rms_velocity": 0.02, "roughness.seed": 2}),
        progress=False)
    row = table.iloc[3]
    for col in ("block_vertical_acceleration_level_db_re_1e-6",
                "plate_vertical_acceleration_level_db_re_1e-6"):
        assert row[col] == pytest.approx(direct.summary["metrics"][col], rel=1e-9)
    # sweep.nc: metrics on the grid's dimensions, with units
    ds = xr.load_dataset(out / "sweep.nc", engine="h5netcdf")
    assert ds["block_vertical_acceleration_level_db_re_1e-6"].dims == (
        "excitation.target_rms_velocity", "roughness.seed")
    assert ds["excitation.target_rms_velocity"].attrs["units"] == "m/s"
    assert ds["block_vertical_acceleration_level_db_re_1e-6"].attrs["units"] == \
        "dB re 1e-6 m s-2"
    sel = ds.sel({"excitation.target_rms_velocity": 0.02, "roughness.seed": 2})
    assert float(sel["plate_vertical_acceleration_level_db_re_1e-6"]) == pytest.approx(
        row["plate_vertical_acceleration_level_db_re_1e-6"], rel=1e-11)
    assert str(sel["case_name"].values) == row["case"]
    # a second run finds everything complete and touches nothing
    before = {c: _stamp(out / "cases" / c) for c in table["case"]}
    again = sw.run_sweep(spec_path, out, progress=False)
    assert (again.skipped, again.ran, again.failed) == (4, 0, 0)
    assert {c: _stamp(out / "cases" / c) for c in table["case"]} == before


def _completed(cases_dir: Path) -> set[str]:
    done = set()
    if not cases_dir.is_dir():
        return done
    for d in cases_dir.iterdir():
        if d.name.startswith("."):
            continue
        try:
            if json.loads((d / "summary.json").read_text())["status"] == "success":
                done.add(d.name)
        except (OSError, ValueError, KeyError):
            pass
    return done


def test_killed_sweep_resumes_without_rerunning_completed_cases(small_run, client, tmp_path):
    spec = _write(tmp_path / "small.toml", SMALL)
    out = tmp_path / "out"
    # SIGKILL to the whole process group (the command and its local pool's workers), sent by
    # the command itself once its first case has ended: the kill lands between cases however
    # fast they run (a test polling for a finished case could miss the last one)
    proc = start_stopping_itself(signal.SIGKILL, "case", 1, "sweep", str(spec), "--out",
                                 str(out), "--workers", "2", "--no-progress", group=True,
                                 start_new_session=True, stdout=subprocess.DEVNULL)
    try:
        _, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL, err
    done = _completed(out / "cases")
    assert 1 <= len(done) < 4
    stamps = {c: _stamp(out / "cases" / c) for c in done}

    run = sw.run_sweep(spec, out, client=client, progress=False)
    assert (run.skipped, run.ran, run.failed) == (len(done), 4 - len(done), 0)
    assert {c: _stamp(out / "cases" / c) for c in done} == stamps
    assert not [p.name for p in (out / "cases").iterdir() if p.name.startswith(".")]
    resumed = pd.read_csv(out / "sweep.csv").drop(columns=list(VARIABLE_TIME))
    reference = pd.read_csv(small_run[1].directory / "sweep.csv").drop(
        columns=list(VARIABLE_TIME))
    pd.testing.assert_frame_equal(resumed, reference)


@pytest.mark.parametrize("pool", ["dask", "local"])
def test_killing_a_worker_recomputes_no_finished_case(client, tmp_path, pool, monkeypatch):
    # a killed worker loses the results it held; Dask would recompute them (4 of 12 cases
    # ran twice in the report of issue 18): finished cases must stay untouched on disk. The
    # local pool starts a new worker and gives it the case the killed one was running.
    # The worker is killed when the sweep counts its first ended case, from the sweep's own
    # progress counter: before the sweep goes on, however fast the cases run
    from roughvib import _progress

    spec = _write(tmp_path / "small.toml", SMALL)
    out = tmp_path / "out"
    stamps: dict = {}
    count = _progress.NoProgress.update

    def update(self, n=1):
        count(self, n)
        if stamps:
            return
        done = _completed(out / "cases")
        stamps.update({c: _stamp(out / "cases" / c) for c in done})
        pid = json.loads((out / "cases" / sorted(done)[0] / "case.json").read_text())["pid"]
        os.kill(pid, signal.SIGKILL)  # the worker that ran a finished case

    monkeypatch.setattr(_progress.NoProgress, "update", update)
    run = sw.run_sweep(spec, out, client=client if pool == "dask" else None, workers=2,
                       progress=False)
    assert stamps, "no case ended"
    assert run.failed == 0 and run.ran == 4
    assert {c: _stamp(out / "cases" / c) for c in stamps} == stamps
    assert not [p.name for p in (out / "cases").iterdir() if p.name.startswith(".")]


def test_case_directories_of_the_old_names_are_adopted_not_recomputed(small_run, client,
                                                                      tmp_path):
    """A sweep run by roughvib 0.1 named its cases ``key=value,...-hash``; resuming renames
    them to today's names (recorded in case.json) and runs nothing again."""
    spec_path, run = small_run
    spec = sw.load_sweep(spec_path)
    out = tmp_path / "old"
    (out / "cases").mkdir(parents=True)
    olds = {}
    for case in spec.cases():
        old = old_case_name(spec.base, case.values, spec.varied_keys)
        assert "=" in old and "," in old and old.endswith(case.name[-10:])
        shutil.copytree(run.directory / "cases" / case.name, out / "cases" / old)
        olds[case.name] = old
    notes = []
    again = sw.run_sweep(spec_path, out, client=client, progress=False, log=notes.append)
    assert (again.skipped, again.ran, again.failed) == (4, 0, 0)
    assert sorted(p.name for p in (out / "cases").iterdir()) == sorted(olds)
    for new, old in olds.items():
        info = json.loads((out / "cases" / new / "case.json").read_text())
        assert info["renamed_from"] == old and info["name"] == new
    assert any(n.startswith("renamed 4 case directories of an older roughvib") and
               "nothing recomputed" in n for n in notes)
    assert list(again.table["case"]) == [c.name for c in spec.cases()]
    assert (again.table["status"] == "success").all()


def test_invalid_case_fails_alone_with_its_message(client, tmp_path, capsys):
    text = f"""
base = "paper"
[set]
{SET_TOML}
[[case]]
"block.mass" = 0.3
[[case]]
"block.mass" = -1.0
"""
    spec = _write(tmp_path / "cases.toml", text)
    out = tmp_path / "out"
    args = _parser().parse_args(["sweep", str(spec), "--out", str(out), "--scheduler",
                                 client.scheduler.address, "--no-progress"])
    assert args.func(args) == 1  # some cases failed
    printed = capsys.readouterr().out
    with pytest.raises(SceneError) as expected:
        roughvib.load_scene("paper", {**FAST, "block.mass": -1.0})
    table = pd.read_csv(out / "sweep.csv")
    assert list(table["status"]) == ["success", "input_error"]
    assert table.loc[1, "message"] == str(expected.value)
    assert str(expected.value) in printed
    assert np.isnan(table.loc[1, "block_vertical_acceleration_level_db_re_1e-6"])
    assert np.isfinite(table.loc[0, "block_vertical_acceleration_level_db_re_1e-6"])
    failed_dir = out / "cases" / table.loc[1, "case"]
    assert json.loads((failed_dir / "summary.json").read_text())["status"] == "input_error"
    assert roughvib.load_result(failed_dir).status == "input_error"
    ds = xr.load_dataset(out / "sweep.nc", engine="h5netcdf")
    assert ds["status"].dims == ("case",)
    assert list(ds["block.mass"].values) == [0.3, -1.0]
    assert ds["block.mass"].attrs["units"] == "kg"
    # re-run: the failed case runs again (and fails again), the good one is kept
    ok_stamp = _stamp(out / "cases" / table.loc[0, "case"])
    failed_inode = failed_dir.stat().st_ino
    run = sw.run_sweep(spec, out, client=client, progress=False)
    assert (run.skipped, run.ran, run.failed) == (1, 1, 1)
    assert _stamp(out / "cases" / table.loc[0, "case"]) == ok_stamp
    assert failed_dir.stat().st_ino != failed_inode


# --------------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------------


def test_report_fits_db_per_doubling_per_seed(small_run, capsys):
    out = small_run[1].directory
    args = _parser().parse_args(["sweep-report", str(out)])
    assert args.func(args) == 0
    md = Path(capsys.readouterr().out.strip())
    assert md == out / "report" / "report.md"
    png = out / "report" / "velocity.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (out / "report" / "load.png").exists()
    fits = pd.read_csv(out / "report" / "fits.csv")
    table = pd.read_csv(out / "sweep.csv")
    for quantity, col in (("block level", "block_vertical_acceleration_level_db_re_1e-6"),
                          ("plate level", "plate_vertical_acceleration_level_db_re_1e-6")):
        slopes = [np.polyfit(np.log2(g["block_tangential_velocity_rms"]), g[col], 1)[0]
                  for _, g in table.groupby("roughness.seed")]
        f = fits[fits["quantity"] == quantity].iloc[0]
        assert f["n_seeds"] == 2
        assert f["db_per_doubling"] == pytest.approx(np.mean(slopes), rel=1e-5)
        assert f["ci_low"] < f["db_per_doubling"] < f["ci_high"]
        assert f"{f['db_per_doubling']:.2f}" in md.read_text()
    html = (out / "report" / "report.html").read_text()
    assert "dB per doubling" in html and 'src="velocity.png"' not in html
    # self-contained like the run report: the study figure and (two roughness seeds) the
    # ensemble figure are embedded, byte for byte
    uris = re.findall(r'<img src="data:image/png;base64,([^"]+)"', html)
    ens = out / "report" / "ensemble.png"
    assert [base64.b64decode(u, validate=True) for u in uris] == [png.read_bytes(),
                                                                   ens.read_bytes()]
    assert "](velocity.png)" in md.read_text()  # the Markdown keeps its link to the file


def test_report_in_headless_chromium(small_run, tmp_path):
    out = small_run[1].directory
    page = out / "report" / "report.html"
    if not page.exists():
        sw.sweep_report(out)
    seen = inspect_page(page, tmp_path)
    assert seen["ready"] == "complete" and seen["title"].startswith("Sweep report")
    assert [img["alt"] for img in seen["images"]] == ["velocity.png", "ensemble.png"]
    for img in seen["images"]:
        assert img["decoded"] and img["width"] > 0 and img["height"] > 0, img
        assert img["inked_pixels"] > 100, img  # not a blank picture
        assert img["shown_width"] > 0 and img["shown_height"] > 0, img
    assert seen["links"] and all(link["href"].startswith("#") and link["resolves"]
                                 and link["shown"] for link in seen["links"]), seen["links"]


def test_report_of_a_directory_that_is_no_sweep_is_a_one_line_error(tmp_path):
    args = _parser().parse_args(["sweep-report", str(tmp_path)])
    with pytest.raises(SceneError, match="is not a sweep directory"):
        args.func(args)


def test_sweep_commands_have_help_with_examples(capsys):
    for cmd in (["sweep", "--help"], ["sweep-report", "--help"]):
        with pytest.raises(SystemExit) as info:
            _parser().parse_args(cmd)
        assert info.value.code == 0
        assert "example" in capsys.readouterr().out
    args = _parser().parse_args(["sweep", "--list"])
    assert args.func(args) == 0
    assert capsys.readouterr().out.startswith("paper-velocity")
