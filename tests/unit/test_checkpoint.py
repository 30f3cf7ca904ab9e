"""Checkpoints and resume: a stopped run continues to results identical to an uninterrupted one,
and an interrupted run never leaves a half-written result."""

import os
import random
import signal
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from self_signal import start_stopping_itself

import roughvib
from roughvib.analysis.compare import band_level_errors, max_abs_db, relative_rms_error
from roughvib.api import resume, simulate
from roughvib.cli import main
from roughvib.scene import SceneError
from roughvib.solvers.checkpoint import CHECKPOINT_NAME, read_checkpoint, write_checkpoint

FAST = {"plate.max_frequency": 5000.0, "output.progress": False}


def _assert_as_without_checkpoints(a, scene):
    """Run ``scene`` without checkpoints and check that run ``a`` has the same outputs and
    events bit for bit; returns that run."""
    c = simulate(scene.with_overrides({"output.checkpoint_interval": 0.0}))
    for v in a.dataset.data_vars:
        np.testing.assert_array_equal(a.dataset[v].values, c.dataset[v].values, err_msg=v)
    pd.testing.assert_frame_equal(a.events, c.events)
    return c


def _assert_identical(a, b):
    for v in a.dataset.data_vars:
        np.testing.assert_array_equal(a.dataset[v].values, b.dataset[v].values, err_msg=v)
    pd.testing.assert_frame_equal(a.events, b.events)
    assert a.summary["energy_audit"] == b.summary["energy_audit"]
    assert a.summary["metrics"] == b.summary["metrics"]
    for key in ("steps", "residual_evaluations", "restarts", "events_total", "checkpoints"):
        assert a.summary["solver"][key] == b.summary["solver"][key], key


@pytest.mark.short_run
def test_resume_from_the_last_checkpoint_gives_identical_results(tmp_path):
    scene = roughvib.load_scene("paper", {**FAST, "output.duration": 0.03,
                                          "output.checkpoint_interval": 0.01})
    a = simulate(scene, checkpoint_dir=tmp_path)
    assert a.ok and a.summary["solver"]["checkpoints"] == 2
    cp = read_checkpoint(tmp_path)
    assert cp.t == pytest.approx(0.02, abs=1e-12) and cp.k == 2001
    b = resume(tmp_path)
    assert b.summary["solver"]["resumes"] == 1
    _assert_identical(a, b)
    # the checkpoint restarts IDA, so the run differs from one without checkpoints, but only
    # within the solver tolerance (rtol 1e-6): compared by velocity and
    # band levels rather than pointwise lightly damped plate modes, over the bands the default
    # tolerance resolves (above 30 dB re 1e-6 m/s^2, docs/theory.md; the 4 kHz plate band,
    # 60 dB below the peak, is 1.5-2 dB off a tight reference in both runs)
    c = simulate(scene.with_overrides({"output.checkpoint_interval": 0.0}))
    v = "block_tangential_velocity"
    assert relative_rms_error(a.dataset[v].values, c.dataset[v].values) < 1e-5
    for v in ("plate_vertical_acceleration", "block_vertical_acceleration"):
        fc, d = band_level_errors(a.dataset[v].values, c.dataset[v].values, 1e5, floor_db=30.0)
        assert np.isfinite(d).sum() >= 8, v
        assert max_abs_db(fc, d, 100.0, 5000.0) < 0.3, v


def test_checkpoint_errors_are_one_line(tmp_path, capsys):
    with pytest.raises(SceneError, match="no checkpoint to resume from"):
        resume(tmp_path)
    (tmp_path / CHECKPOINT_NAME).write_bytes(b"not a pickle")
    with pytest.raises(SceneError, match="not a roughvib checkpoint"):
        read_checkpoint(tmp_path)
    (tmp_path / CHECKPOINT_NAME).write_bytes(b"roughvib-checkpoint\n999 " + b"0" * 64
                                             + b" 5\nxxxxx")
    with pytest.raises(SceneError, match="format version 999"):
        read_checkpoint(tmp_path)
    assert main(["run", "--resume", str(tmp_path)]) == 2
    assert "format version 999" in capsys.readouterr().err
    # a new run into a directory holding a checkpoint must not overwrite it silently
    assert main(["run", "--out", str(tmp_path), "--set", "output.checkpoint_interval=0.01"]) == 2
    assert "--resume" in capsys.readouterr().err
    assert main(["run", "paper", "--resume", str(tmp_path)]) == 2
    with pytest.raises(SceneError, match=r"^solver.method = 'newmark' cannot run this scene: "
                                         r"output.checkpoint_interval = 0.01 s, and newmark "
                                         r"writes no checkpoints; use ida or adaptive-modal$"):
        roughvib.load_scene("paper", {"output.checkpoint_interval": 0.01,
                                      "solver.method": "newmark"})
    with pytest.raises(SceneError, match="checkpoint_interval must be 0 .off. or >= output.step"):
        roughvib.load_scene("paper", {"output.checkpoint_interval": 1e-6})


@pytest.mark.short_run
def test_resume_refuses_when_the_profile_file_changed(tmp_path, capsys):
    # the run reads a profile file; editing it afterwards must not pass unnoticed on resume
    from roughvib.physics.surface.roughness import build_profile

    base = roughvib.load_scene("paper")
    f = tmp_path / "profile.txt"
    np.savetxt(f, build_profile(base.roughness, base.block).z)
    text = f.read_text()
    scene = roughvib.load_scene("paper", {**FAST, "roughness.kind": "file",
                                          "roughness.path": str(f), "output.duration": 0.01,
                                          "output.checkpoint_interval": 0.005})
    out = tmp_path / "run"
    a = simulate(scene, checkpoint_dir=out)  # the API leaves the checkpoint in place
    assert a.ok
    recorded = read_checkpoint(out).inputs["roughness_file"]
    assert recorded == {"path": str(f), "sha256": a.summary["model"]["profile"]["sha256"]}
    lines = text.splitlines()
    lines[8000] = "1e-7"  # one sample under the block
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(SceneError, match=r"roughness.path .*profile.txt changed since the "
                                         r"checkpoint was written \(SHA-256 "):
        resume(out)
    capsys.readouterr()
    assert main(["run", "--resume", str(out), "--no-progress", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "changed since the checkpoint" in err
    f.unlink()
    with pytest.raises(SceneError, match="cannot be read .*restore it"):
        resume(out)
    f.write_text(text)  # restored: the resumed run is the uninterrupted one
    b = resume(out)
    _assert_identical(a, b)
    b.save(out)  # its own checkpoint does not refuse it, and goes with the saved run
    assert not (out / CHECKPOINT_NAME).exists() and roughvib.load_result(out).ok


def test_source_digest_sees_every_change_of_the_sources(tmp_path):
    from roughvib.solvers.checkpoint import source_digest

    (tmp_path / "pkg" / "sub").mkdir(parents=True)
    (tmp_path / "pkg" / "a.py").write_text("x = 1\n")
    (tmp_path / "pkg" / "sub" / "b.py").write_text("y = 2\n")
    d0 = source_digest(tmp_path / "pkg")
    assert d0 == source_digest(tmp_path / "pkg")  # deterministic
    (tmp_path / "pkg" / "sub" / "b.pyc").write_bytes(b"cache")  # not a source: no change
    (tmp_path / "pkg" / "data.txt").write_text("data")
    assert source_digest(tmp_path / "pkg") == d0
    (tmp_path / "pkg" / "a.py").write_text("x = 2\n")  # edited
    d1 = source_digest(tmp_path / "pkg")
    assert d1 != d0
    (tmp_path / "pkg" / "c.py").write_text("")  # added, even empty
    d2 = source_digest(tmp_path / "pkg")
    assert d2 != d1
    (tmp_path / "pkg" / "c.py").rename(tmp_path / "pkg" / "sub" / "c.py")  # moved
    assert source_digest(tmp_path / "pkg") not in (d0, d1, d2)


@pytest.mark.short_run
def test_resume_refuses_a_checkpoint_of_other_code(tmp_path, capsys):
    from roughvib.solvers.checkpoint import code_identity

    scene = roughvib.load_scene("paper", {**FAST, "plate.max_frequency": 2000.0,
                                          "output.duration": 0.004,
                                          "output.checkpoint_interval": 0.002})
    a = simulate(scene, checkpoint_dir=tmp_path)
    assert a.ok
    cp = read_checkpoint(tmp_path)
    recorded = cp.inputs["code"]
    assert recorded == code_identity() and len(recorded["roughvib_sources"]) == 64
    assert recorded["roughvib"] == roughvib.__version__

    def rewrite(code):
        cp.inputs["code"] = code
        if code is None:
            del cp.inputs["code"]
        write_checkpoint(tmp_path, cp)

    # the same version with edited sources (a checkout between two commits), another version,
    # another numba: each is refused, naming what changed
    for key, value, shown in [("roughvib_sources", "0" * 64, "roughvib_sources 000000000000..."),
                              ("roughvib", "0.0.1", "roughvib 0.0.1 then"),
                              ("numba", "0.1", "numba 0.1 then")]:
        rewrite({**recorded, key: value})
        with pytest.raises(SceneError, match="written by other code") as err:
            resume(tmp_path)
        assert shown in str(err.value) and "\n" not in str(err.value)
        capsys.readouterr()
        assert main(["run", "--resume", str(tmp_path), "--no-progress", "--quiet"]) == 2
        assert "written by other code" in capsys.readouterr().err
    rewrite(None)  # an older roughvib did not record its code
    with pytest.raises(SceneError, match="does not record the code that wrote it"):
        resume(tmp_path)
    rewrite(recorded)  # the code that wrote it resumes it
    _assert_identical(a, resume(tmp_path))
    # IDA's checkpoints also name scikit-sundae's version
    from importlib.metadata import version

    ida_dir = tmp_path / "ida"
    assert simulate(scene.with_overrides({"solver.method": "ida"}), checkpoint_dir=ida_dir).ok
    cp = read_checkpoint(ida_dir)
    code = cp.inputs["code"]
    assert code == {**recorded, "scikit-sundae": version("scikit-sundae")}
    cp.inputs["code"] = {**code, "scikit-sundae": "0.0"}
    write_checkpoint(ida_dir, cp)
    with pytest.raises(SceneError, match="scikit-sundae 0.0 then"):
        resume(ida_dir)


def _cli(*args):
    return [sys.executable, "-m", "roughvib.cli", "run", *args]


def _self_stopping_run(sig, where, count, *args):
    """``roughvib run *args`` in a child process that sends itself ``sig`` at the
    ``count``-th time its work passes ``where`` (:mod:`self_signal`)."""
    return start_stopping_itself(sig, where, count, "run", *args)


#: the checkpoints of these runs are 0.01 s apart; the signal comes from the run itself just
#: after the first one, so the run need not outlast the test's reaction
CHECKPOINT_STEP = 0.01
KILLED_SETS = ["--set", "output.duration=0.05", "--set", "plate.max_frequency=5000",
               "--set", f"output.checkpoint_interval={CHECKPOINT_STEP}", "--no-progress",
               "--quiet"]


@pytest.fixture(scope="module")
def straight_killed_sets(tmp_path_factory):
    """The uninterrupted run of :data:`KILLED_SETS` (deterministic), made once for both
    signals; the tests only read its files."""
    own = tmp_path_factory.mktemp("straight")
    with pytest.MonkeyPatch.context() as mp:  # in its own directory, as every test
        mp.chdir(own)
        assert main(["run", "--out", str(own / "run"), *KILLED_SETS]) == 0
    return own / "run"


@pytest.mark.parametrize("sig,code,word", [(signal.SIGTERM, 143, "terminated"),
                                           (signal.SIGINT, 130, "interrupted")])
def test_killed_cli_run_keeps_its_checkpoint_and_resumes_identically(tmp_path, sig, code, word,
                                                                     straight_killed_sets):
    killed = tmp_path / "killed"
    proc = _self_stopping_run(sig, "checkpoint", 1, "--out", str(killed), *KILLED_SETS)
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == code, err
    assert word in err and "--resume" in err and "Traceback" not in err
    assert not (killed / "result.nc").exists()  # nothing half-written
    assert read_checkpoint(killed).t == pytest.approx(CHECKPOINT_STEP, abs=1e-12)

    ok = subprocess.run(_cli("--resume", str(killed), "--no-progress", "--quiet"),
                        capture_output=True, text=True, timeout=600)
    assert ok.returncode == 0, ok.stderr
    assert not (killed / CHECKPOINT_NAME).exists()  # removed once the result is saved

    _assert_same_files(straight_killed_sets, killed)


def _assert_same_as_straight_run(straight, resumed, sets):
    """Run ``sets`` uninterrupted into ``straight``; its files must equal ``resumed``'s."""
    assert main(["run", "--out", str(straight), *sets]) == 0
    _assert_same_files(straight, resumed)


def _assert_same_files(straight, resumed):
    """The result, events and scene files of run directories ``straight`` and ``resumed`` are
    equal."""
    a = xr.load_dataset(straight / "result.nc", engine="h5netcdf")
    b = xr.load_dataset(resumed / "result.nc", engine="h5netcdf")
    for v in a.data_vars:
        np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)
    pd.testing.assert_frame_equal(pd.read_csv(straight / "events.csv"),
                                  pd.read_csv(resumed / "events.csv"))
    assert (straight / "scene.toml").read_text() == (resumed / "scene.toml").read_text()


@pytest.mark.short_run
def test_adaptive_modal_checkpoints_change_nothing_and_resume_identically(tmp_path):
    """adaptive-modal's checkpoints store all the state its step loop carries, so the run
    that writes them, the run resumed from the last one and a run without checkpoints are
    bit-identical (unlike IDA, which restarts at a checkpoint)."""
    scene = roughvib.load_scene("paper", {**FAST, "solver.method": "adaptive-modal",
                                          "output.duration": 0.03,
                                          "output.checkpoint_interval": 0.01})
    a = simulate(scene, checkpoint_dir=tmp_path)
    assert a.ok and a.summary["solver"]["checkpoints"] == 2
    assert read_checkpoint(tmp_path).k == 2001
    b = resume(tmp_path)
    assert b.summary["solver"]["resumes"] == 1
    _assert_identical(a, b)
    c = _assert_as_without_checkpoints(a, scene)
    assert a.summary["solver"]["steps"] == c.summary["solver"]["steps"]


@pytest.mark.short_run
def test_hermite_loop_checkpoints_end_a_pair(tmp_path):
    """The Hermite step's loop estimates its error over blocks of PAIR_ROWS (8) output
    intervals that start on rows divisible by 8: an interval of 1001 rows is rounded up to
    1008, so that a checkpoint ends a block, and the runs with, without and resumed are
    bit-identical."""
    from roughvib.solvers.adaptive_modal import PAIR_ROWS

    assert PAIR_ROWS == 8
    scene = roughvib.load_scene("paper", {**FAST, "solver.method": "adaptive-modal",
                                          "output.duration": 0.03,
                                          "output.checkpoint_interval": 0.01001})
    a = simulate(scene, checkpoint_dir=tmp_path)
    assert a.ok and a.summary["solver"]["checkpoints"] == 2
    assert read_checkpoint(tmp_path).k == 2 * 1008 + 1
    _assert_identical(a, resume(tmp_path))
    _assert_as_without_checkpoints(a, scene)


@pytest.mark.short_run
def test_adaptive_modal_resumes_a_coulomb_stick_phase_identically(tmp_path):
    """The set-valued law's regime (stick, the friction force that holds the block) is part of
    the checkpoint: resumed in the middle of a stick phase, the run is bit-identical to one
    without checkpoints."""
    scene = roughvib.load_scene("paper", {**FAST, "solver.method": "adaptive-modal",
                                          "friction.law": "coulomb", "output.duration": 0.05,
                                          "output.checkpoint_interval": 0.02})
    a = simulate(scene, checkpoint_dir=tmp_path)
    assert a.ok and a.summary["solver"]["checkpoints"] == 2
    cp = read_checkpoint(tmp_path)
    assert cp.regime.stick and cp.regime.branch == 0  # resumed while the block sticks
    b = resume(tmp_path)
    assert b.summary["solver"]["resumes"] == 1
    _assert_identical(a, b)
    _assert_as_without_checkpoints(a, scene)
    assert list(a.events["kind"]) == ["slip", "stick"]


def test_adaptive_modal_run_killed_at_a_random_point_resumes_identically(tmp_path):
    """SIGKILL (no handler runs) at a random checkpoint of the run, either in the integration
    just after it is in place or while it is written (its temporary file complete, the
    previous checkpoint not yet replaced): the resumed run equals an uninterrupted one bit for
    bit. The run sends the signal to itself, so it lands there however fast the run is."""
    # 400 output rows apart: the Hermite loop rounds a checkpoint interval up to a multiple
    # of 8 rows (test_hermite_loop_checkpoints_end_a_pair), 400 is one
    step, duration = 0.004, 0.1
    sets = ["--set", "solver.method=adaptive-modal", "--set", f"output.duration={duration}",
            "--set", f"output.checkpoint_interval={step}", "--no-progress", "--quiet"]
    n_cp = round(duration / step) - 1  # none at the end of the run
    where = random.choice(["checkpoint", "checkpoint-rename"])
    count = random.randint(1 if where == "checkpoint" else 2, n_cp)
    point = f"SIGKILL at {where} {count} of {n_cp}"
    killed = tmp_path / "killed"
    proc = _self_stopping_run(signal.SIGKILL, where, count, "--out", str(killed), *sets)
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == -signal.SIGKILL, (point, err)
    assert not (killed / "result.nc").exists(), point
    kept = count if where == "checkpoint" else count - 1
    assert read_checkpoint(killed).t == pytest.approx(kept * step, abs=1e-12), point
    temporary = [p.name for p in killed.iterdir() if p.name.startswith(".")]
    assert len(temporary) == (where == "checkpoint-rename"), (point, temporary)

    ok = subprocess.run(_cli("--resume", str(killed), "--no-progress", "--quiet"),
                        capture_output=True, text=True, timeout=600)
    assert ok.returncode == 0, (point, ok.stderr)
    assert not (killed / CHECKPOINT_NAME).exists(), point
    assert not [p.name for p in killed.iterdir() if p.name.startswith(".")], point
    _assert_same_as_straight_run(tmp_path / "straight", killed, sets)


def test_interrupted_run_without_checkpoints_writes_nothing(tmp_path):
    """Ctrl-C in the integration of a run without checkpoints: exit status 130, one line
    saying nothing was written, no file. The run sends SIGINT to itself the first time the
    solver reports progress, so the signal lands in the integration however fast it is."""
    out = tmp_path / "run"
    proc = _self_stopping_run(signal.SIGINT, "progress", 1, "--out", str(out),
                              "--set", "output.duration=0.3", "--set",
                              "plate.max_frequency=5000", "--quiet")
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 130, err
    assert "nothing was written" in err and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes are POSIX")
def test_a_checkpoint_that_is_a_named_pipe_is_refused_at_once(tmp_path):
    """--resume DIR with DIR/checkpoint.pkl a named pipe blocked forever on opening it. In a
    subprocess with a timeout: a regression fails instead of hanging the suite."""
    (tmp_path / "run").mkdir()
    os.mkfifo(tmp_path / "run" / "checkpoint.pkl")
    done = subprocess.run([sys.executable, "-m", "roughvib", "run", "--resume", "run"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr == ("roughvib: error: run/checkpoint.pkl: not a regular file, so not a "
                           "roughvib checkpoint; resume only a directory a roughvib run wrote "
                           "checkpoints into\n")


@pytest.mark.filterwarnings("ignore::roughvib.scene.ModelValidityWarning")  # 10 ms
def test_resume_refuses_when_the_directorys_scene_toml_was_edited(tmp_path, capsys):
    """--resume runs the scene stored in the checkpoint; an edited DIR/scene.toml (an earlier
    run's, which a user may take for the run's) used to be ignored silently. The checkpoint
    records its digest; a changed or new scene.toml refuses the resume in one line, the
    restored one (or none) resumes."""
    scene = roughvib.load_scene("paper", {**FAST, "output.duration": 0.01,
                                          "output.checkpoint_interval": 0.005})
    out = tmp_path / "run"
    out.mkdir()
    earlier = 'name = "paper"\n\n[block]\nmass = 0.221\n'
    (out / "scene.toml").write_text(earlier)
    a = simulate(scene, checkpoint_dir=out)  # the API leaves the checkpoint in place
    assert a.ok and read_checkpoint(out).inputs["directory_scene_toml"] != "absent"
    (out / "scene.toml").write_text(earlier.replace("0.221", "0.543"))
    with pytest.raises(SceneError, match=r"scene.toml changed since the checkpoint was written "
                                         r"\(SHA-256 \w+\.\.\. then, SHA-256 \w+\.\.\. now\): "
                                         r"--resume continues the scene stored in "):
        resume(out)
    capsys.readouterr()
    assert main(["run", "--resume", str(out), "--no-progress", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "run the edited scene as a new run" in err
    (out / "scene.toml").write_text(earlier)  # restored: resumes, as the uninterrupted run
    _assert_identical(a, resume(out))
    (out / "scene.toml").unlink()  # removed: nothing left to mislead
    resume(out)


@pytest.mark.filterwarnings("ignore::roughvib.scene.ModelValidityWarning")  # 10 ms
def test_a_scene_toml_that_appears_after_the_checkpoint_refuses_the_resume(tmp_path):
    scene = roughvib.load_scene("paper", {**FAST, "output.duration": 0.01,
                                          "output.checkpoint_interval": 0.005})
    out = tmp_path / "run"
    simulate(scene, checkpoint_dir=out)
    assert read_checkpoint(out).inputs["directory_scene_toml"] == "absent"
    (out / "scene.toml").write_text('name = "mine"\n')
    with pytest.raises(SceneError, match=r"\(absent then, SHA-256 \w+\.\.\. now\)"):
        resume(out)
