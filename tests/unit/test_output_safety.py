"""What a run may touch: the output directory is checked before any work, a run never deletes
or overwrites files it did not create, an earlier run is replaced as a whole (one directory
rename), a kill at any point leaves one complete run, concurrent runs are refused, and
load_result refuses a directory that mixes runs.

Most tests save small hand-made results (the file handling does not depend on the physics);
the command-line tests run 5 ms scenes with plate modes to 2 kHz."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from roughvib import rundir as rd_mod
from roughvib.cli import main
from roughvib.results import (
    EVENT_COLUMNS,
    FORMAT_VERSION,
    MixedRunError,
    Result,
    RunDirectoryError,
    load_result,
)
from roughvib.rundir import OutputError, RunDirectory
from roughvib.scene import Scene, scene_to_toml
from roughvib.solvers.checkpoint import CHECKPOINT_NAME, Checkpoint, write_checkpoint

TINY = ["--set", "output.duration=0.005", "--set", "plate.max_frequency=2000", "--no-progress",
        "--quiet"]


def _result(value: float, *, ok: bool = True, rows: int = 4, events: int = 1) -> Result:
    """A small result whose time series is ``value`` everywhere (tells runs apart)."""
    t = np.arange(rows) * 1e-5
    ds = xr.Dataset({"block_vertical_acceleration": ("time", np.full(rows, value))},
                    coords={"time": t})
    ev = pd.DataFrame([{c: (0.0 if c not in ("kind", "regime_before", "regime_after")
                            else "slip") for c in EVENT_COLUMNS}] * events,
                      columns=EVENT_COLUMNS)
    ev["contact"] = pd.array([1] * events, dtype="Int64")
    summary = {"format_version": FORMAT_VERSION, "status": "success" if ok else "event_storm",
               "message": "" if ok else "storm", "value": value}
    return Result(ds, ev, summary, scene_to_toml(Scene()))


def _value(directory: Path, partial: bool = False) -> float:
    r = load_result(directory, partial=partial)
    return float(r.dataset["block_vertical_acceleration"].values[0])


def _listing(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir()) if p.is_file()}


def _dotfiles(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if p.name.startswith("."))


# --------------------------------------------------------------------------------------------
# the rule: new, empty or an earlier roughvib run (replaced as a whole); others refused
# --------------------------------------------------------------------------------------------


def test_an_earlier_run_is_replaced_as_a_whole(tmp_path):
    out = tmp_path / "a" / "b" / "run"
    _result(1.0).save(out)  # parents are created
    assert _value(out) == 1.0 and sorted(os.listdir(out)) == [
        "events.csv", "result.nc", "scene.toml", "summary.json"]
    (out / "report.html").write_text("<html>report of run 1</html>")  # as roughvib report does
    (out / "figures").mkdir()
    (out / "figures" / "spectra.png").write_bytes(b"png")
    _result(2.0, ok=False, events=0).save(out)  # a failed run, no event log
    # nothing of the earlier run survives beside the new one: no result.nc, events.csv, report
    assert sorted(os.listdir(out)) == ["partial.nc", "scene.toml", "summary.json"]
    assert _value(out, partial=True) == 2.0
    summary = json.loads((out / "summary.json").read_text())
    assert sorted(summary["files"]) == ["partial.nc", "scene.toml"]
    assert _dotfiles(out.parent) == []  # no staging directory, no lock file left


def test_an_empty_directory_is_used(tmp_path):
    out = tmp_path / "empty"
    out.mkdir()
    _result(1.0).save(out)
    assert _value(out) == 1.0


def test_a_directory_of_other_files_is_refused_unless_overwrite(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes")
    (out / "result.nc").write_bytes(b"my own result.nc, not roughvib's")
    before = _listing(out)
    with pytest.raises(OutputError) as info:
        _result(1.0).save(out)
    msg = str(info.value)
    assert "\n" not in msg and "holds no roughvib run" in msg and "'notes.txt'" in msg
    assert "--overwrite" in msg
    assert _listing(out) == before and _dotfiles(tmp_path) == []
    # with overwrite, a failed run writes its files and removes nothing
    _result(2.0, ok=False).save(out, overwrite=True)
    after = _listing(out)
    assert after["notes.txt"] == b"my notes"
    assert after["result.nc"] == before["result.nc"]  # not the run's: kept
    with xr.open_dataset(out / "partial.nc", engine="h5netcdf") as ds:
        assert float(ds["block_vertical_acceleration"][0]) == 2.0
    # ... but a directory holding both a result.nc and a partial.nc is refused when read:
    # one of them is not the run's
    with pytest.raises(RunDirectoryError, match="holds both result.nc and partial.nc"):
        load_result(out, partial=True)
    # a later successful run replaces the files of the same names (and its own earlier
    # partial.nc and events.csv), nothing else
    _result(3.0).save(out, overwrite=True)
    assert _value(out) == 3.0
    assert (out / "notes.txt").read_text() == "my notes" and not (out / "partial.nc").exists()
    # a roughvib run beside other files is still refused without overwrite
    with pytest.raises(OutputError, match=r"holds files roughvib did not write \('notes.txt'\)"):
        _result(4.0).save(out)


def test_user_files_named_like_run_files_are_never_deleted_by_a_failed_run(tmp_path, capsys):
    # the old behaviour: a failed run into a directory deleted result.nc and events.csv there
    out = tmp_path / "data"
    out.mkdir()
    (out / "events.csv").write_text("my,events\n")
    assert main(["run", "--out", str(out), *TINY]) == 2
    assert "holds no roughvib run ('events.csv')" in capsys.readouterr().err
    assert (out / "events.csv").read_text() == "my,events\n"


def _checkpoint(directory: Path) -> None:
    z = np.zeros(1)
    write_checkpoint(directory, Checkpoint(scene_toml="", t=0.0, k=1, y=z, y_initial=z,
                                           outputs=z[None], reg=z, rf=z, regime=None, events=[],
                                           stats={}))


def test_the_checkpoint_of_an_unfinished_run_is_never_replaced(tmp_path):
    out = tmp_path / "long"
    _checkpoint(out)
    with pytest.raises(OutputError, match=r"holds the checkpoint of an unfinished run: "
                                          r"continue it with 'roughvib run --resume "):
        _result(1.0).save(out)
    with pytest.raises(OutputError, match="unfinished run"):
        _result(1.0).save(out, overwrite=True)
    assert os.listdir(out) == [CHECKPOINT_NAME]
    # the resumed run may: a failure keeps the checkpoint, a success removes it
    with RunDirectory(out, resume=True) as rd:
        _result(2.0, ok=False).save(rd)
    assert CHECKPOINT_NAME in os.listdir(out)
    with RunDirectory(out, resume=True) as rd:
        _result(3.0).save(rd)
    assert CHECKPOINT_NAME not in os.listdir(out) and _value(out) == 3.0


def test_without_a_swap_the_files_move_one_by_one(tmp_path, monkeypatch):
    # the output directory is the working directory: renaming it away would strand the shell
    out = tmp_path / "here"
    _result(1.0).save(out)
    (out / "notes.txt").write_text("mine")
    monkeypatch.chdir(out)
    _result(2.0, ok=False).save(".", overwrite=True)
    assert Path.cwd() == out and os.getcwd() == str(out)
    assert sorted(os.listdir(out)) == ["events.csv", "notes.txt", "partial.nc", "scene.toml",
                                       "summary.json"]  # the earlier result.nc went with its run
    assert _value(out, partial=True) == 2.0
    monkeypatch.chdir(tmp_path)
    # a parent that is not writable: lock and staging directory inside the output directory
    undo = _unwritable(tmp_path)
    if undo is None:
        pytest.skip("cannot make a directory unwritable for this process")
    try:
        _result(3.0).save(out, overwrite=True)
        assert _value(out) == 3.0 and (out / "notes.txt").read_text() == "mine"
        assert _dotfiles(out) == []
    finally:
        undo()


# --------------------------------------------------------------------------------------------
# atomic for the run as a whole
# --------------------------------------------------------------------------------------------


def test_failure_between_the_two_renames_keeps_the_earlier_run(tmp_path, monkeypatch):
    out = tmp_path / "run"
    _result(1.0).save(out)
    calls = []
    real = os.rename

    def rename(src, dst):
        calls.append((Path(src).name, Path(dst).name))
        if len(calls) == 3:  # (stage -> out fails: not empty), out -> .old, then stage -> out
            raise OSError("simulated crash")
        return real(src, dst)

    monkeypatch.setattr(rd_mod.os, "rename", rename)
    with pytest.raises(OSError, match="simulated crash"):
        _result(2.0).save(out)
    monkeypatch.undo()
    assert calls[1][0] == "run" and calls[1][1].startswith(".run.old-")
    # the crash left no output directory, the earlier run aside, and no staging directory
    # (the process survived here; a killed one leaves it, see the next test)
    assert not out.exists()
    assert [n for n in _dotfiles(tmp_path) if ".old-" in n]
    with pytest.raises(FileNotFoundError):
        load_result(out)
    # the next run into the directory restores the earlier run before it looks at it
    RunDirectory(out).open().close()
    assert _value(out) == 1.0 and _dotfiles(tmp_path) == []


@pytest.mark.parametrize("swap", [True, False])
def test_published_files_are_on_disk_before_their_names_are(tmp_path, monkeypatch, swap):
    # a rename is atomic in the name space only: every file must be flushed (fsync) before the
    # rename that publishes it, and the directory holding the new names after it
    out = tmp_path / "run"
    _result(1.0).save(out)
    if not swap:  # one file at a time: the directory holds a file roughvib did not write
        (out / "notes.txt").write_text("mine")
    log = []
    real_fsync, real_rename, real_replace = os.fsync, os.rename, os.replace

    def fsync(fd):
        log.append(("fsync", os.path.realpath(f"/proc/self/fd/{fd}")))
        return real_fsync(fd)

    def rename(src, dst):
        log.append(("rename", os.path.realpath(src), os.path.realpath(dst)))
        return real_rename(src, dst)

    def replace(src, dst):
        log.append(("rename", os.path.realpath(src), os.path.realpath(dst)))
        return real_replace(src, dst)

    if not Path("/proc/self/fd").is_dir():
        pytest.skip("needs /proc to name the flushed descriptors")
    monkeypatch.setattr(rd_mod.os, "fsync", fsync)
    monkeypatch.setattr(rd_mod.os, "rename", rename)
    monkeypatch.setattr(rd_mod.os, "replace", replace)
    _result(2.0).save(out, overwrite=not swap)
    monkeypatch.undo()
    assert _value(out) == 2.0
    synced = [e[1] for e in log if e[0] == "fsync"]
    publish = [i for i, e in enumerate(log) if e[0] == "rename"
               and os.path.realpath(e[2]).startswith(str(out.resolve()))]
    assert publish, log
    first = publish[0]
    stage = Path(log[first][1]) if swap else Path(log[first][1]).parent
    flushed_before = {Path(e[1]) for e in log[:first] if e[0] == "fsync"}
    files = ["events.csv", "result.nc", "scene.toml", "summary.json"]
    assert {stage / f for f in files} | {stage} <= flushed_before, (stage, synced)
    # the directory that received the names is flushed after the last publishing rename
    target = out.parent if swap else out
    assert ("fsync", str(target.resolve())) in log[publish[-1]:], log[publish[-1]:]


_KILL = textwrap.dedent("""
    import os, signal, sys
    import numpy as np
    sys.path.insert(0, {tests!r})
    from test_output_safety import _result
    from roughvib import results, rundir

    out, where = sys.argv[1], sys.argv[2]
    real = os.rename
    if where == "between-renames":
        def rename(src, dst):
            real(src, dst)
            if ".old-" in str(dst):
                os.kill(os.getpid(), signal.SIGKILL)
        rundir.os.rename = rename
    else:  # while writing the staging directory
        def write_netcdf(ds, path):
            os.kill(os.getpid(), signal.SIGKILL)
        results._write_netcdf = write_netcdf
    _result(2.0).save(out)
""")


@pytest.mark.parametrize("where", ["between-renames", "while-writing"])
def test_a_run_killed_while_saving_leaves_one_complete_run(tmp_path, where):
    out = tmp_path / "run"
    _result(1.0).save(out)
    code = _KILL.format(tests=str(Path(__file__).parent))
    proc = subprocess.run([sys.executable, "-c", code, str(out), where], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    left = _dotfiles(tmp_path)
    assert ".run.lock" in left  # the killed process could not remove its lock file ...
    if where == "between-renames":
        assert not out.exists() and [n for n in left if ".old-" in n]
    else:
        assert _value(out) == 1.0 and [n for n in left if ".tmp-" in n]
    # ... which does not block the next run; that run restores the earlier run (or deletes
    # the staging directory) and replaces it as a whole
    with RunDirectory(out) as rd:
        assert _value(out) == 1.0  # restored before anything else
        _result(3.0).save(rd)
    assert _value(out) == 3.0 and _dotfiles(tmp_path) == []


def test_load_result_refuses_a_directory_that_mixes_runs(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    _result(1.0).save(a)
    _result(2.0).save(b)
    mixed = tmp_path / "mixed"
    shutil.copytree(a, mixed)
    shutil.copy2(b / "result.nc", mixed / "result.nc")  # the kill between file moves of old
    with pytest.raises(MixedRunError) as info:
        load_result(mixed)
    msg = str(info.value)
    assert "\n" not in msg and "result.nc is not the file run" in msg and "mixes" in msg
    (mixed / "result.nc").unlink()
    with pytest.raises(MixedRunError, match="result.nc of run .* is missing"):
        load_result(mixed)
    shutil.copy2(a / "result.nc", mixed / "result.nc")
    assert _value(mixed) == 1.0
    # the same events.csv content of another run passes (same bytes), an edit does not
    with (mixed / "events.csv").open("a") as fh:
        fh.write("\n")
    with pytest.raises(MixedRunError, match="events.csv is not the file"):
        load_result(mixed)
    # a directory written before summaries listed their files is read as before
    legacy = tmp_path / "legacy"
    shutil.copytree(b, legacy)
    s = json.loads((legacy / "summary.json").read_text())
    del s["files"], s["run_id"], s["summary_sha256"]  # none of them existed then
    (legacy / "summary.json").write_text(json.dumps(s))
    assert _value(legacy) == 2.0


def test_run_id_is_in_the_summary_and_the_dataset(tmp_path):
    r = _result(1.0)
    r.save(tmp_path / "x")
    ds = xr.load_dataset(tmp_path / "x" / "result.nc", engine="h5netcdf")
    assert ds.attrs["run_id"] == r.summary["run_id"] == load_result(tmp_path / "x").summary[
        "run_id"]


# --------------------------------------------------------------------------------------------
# one run at a time
# --------------------------------------------------------------------------------------------


def test_concurrent_runs_into_one_directory_are_refused(tmp_path, capsys):
    out = tmp_path / "run"
    first = RunDirectory(out).open()
    try:
        with pytest.raises(OutputError) as info:
            RunDirectory(out).open()
        msg = str(info.value)
        assert "\n" not in msg
        assert msg.startswith(f"{out} is in use by another roughvib run (pid {os.getpid()} on ")
        assert main(["run", "--out", str(out), *TINY]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is in use by another roughvib run" in err
        _result(1.0).save(first)
    finally:
        first.close()
    _result(2.0).save(out)  # released
    assert _value(out) == 2.0


def test_without_file_locks_a_claim_file_locks_and_says_so(tmp_path, monkeypatch, capsys):
    # some network file systems refuse flock: the lock must still hold, and say how
    import errno
    import fcntl
    import warnings

    def no_flock(fd, op):
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr(fcntl, "flock", no_flock)
    out = tmp_path / "run"
    with pytest.warns(rd_mod.OutputWarning, match="has no file locks .No locks available.: "):
        first = RunDirectory(out).open()
    claim = tmp_path / ".run.lock.held"
    try:
        assert claim.read_text().startswith(f"pid {os.getpid()} on ")
        with pytest.raises(OutputError) as info:  # a second run is refused, naming the holder
            RunDirectory(out).open()
        msg = str(info.value)
        assert "\n" not in msg and f"(pid {os.getpid()} on " in msg
        assert f"remove {claim}" in msg
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rd_mod.OutputWarning)
            assert main(["run", "--out", str(out), *TINY]) == 2
        assert "is in use by another roughvib run" in capsys.readouterr().err
        _result(1.0).save(first)
    finally:
        first.close()
    assert not claim.exists() and _dotfiles(tmp_path) == []  # released
    # a claim left by a process of this host that has ended is taken over
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    import socket

    claim.write_text(f"pid {gone.stdout.strip()} on {socket.gethostname()} since then\n")
    with pytest.warns(rd_mod.OutputWarning):
        _result(2.0).save(out)
    assert _value(out) == 2.0 and not claim.exists()
    # one from another host is not (its process cannot be checked from here)
    claim.write_text("pid 1 on another-host since then\n")
    with pytest.raises(OutputError, match="in use by another roughvib run .pid 1 on another-host"):
        RunDirectory(out).open()
    assert claim.exists()
    # the command line shows the warning as one line
    claim.unlink()
    assert main(["run", "--out", str(out), *TINY]) == 0
    err = capsys.readouterr().err
    assert "roughvib: warning: " in err and "has no file locks" in err


# --------------------------------------------------------------------------------------------
# the command line: checks before any work, messages naming only files that exist
# --------------------------------------------------------------------------------------------


@pytest.fixture
def no_simulation(monkeypatch):
    """Fail the test if a run starts."""
    import roughvib.api
    import roughvib.simulation

    def simulate(*a, **k):
        raise AssertionError("the run started before its output directory was checked")

    # roughvib.api first: it resolves its names on first use, and would otherwise take the
    # stand-in from roughvib.simulation as its original and keep it after the test
    monkeypatch.setattr(roughvib.api, "simulate", simulate)
    monkeypatch.setattr(roughvib.simulation, "simulate", simulate)


def _unwritable(path: Path):
    """Make a directory unwritable and return the undo; None if this process can write it
    anyway (root without ``chattr``)."""
    path.chmod(0o555)
    undo = [lambda: path.chmod(0o755)]
    if os.access(path, os.W_OK) and shutil.which("chattr"):  # root: the immutable flag
        if subprocess.run(["chattr", "+i", str(path)], capture_output=True).returncode == 0:
            undo.insert(0, lambda: subprocess.run(["chattr", "-i", str(path)], check=True))
    if os.access(path, os.W_OK):
        for u in undo:
            u()
        return None
    return lambda: [u() for u in undo]


@pytest.mark.parametrize("checkpoints", [False, True])
def test_bad_output_paths_are_one_line_before_the_run(tmp_path, capsys, no_simulation,
                                                      checkpoints):
    sets = TINY + (["--set", "output.checkpoint_interval=0.001"] if checkpoints else [])
    afile = tmp_path / "file.txt"
    afile.write_text("x")
    cases = {
        str(afile): "exists and is not a directory",
        str(afile / "sub" / "run"): f"cannot be created: {afile} is a file, not a directory",
        "/proc/roughvib-no/such": "cannot be created",
        str(tmp_path / ("n" * 300) / "run"): "a name in it has 300 bytes, the filesystem "
                                             "allows 255",
        str(tmp_path / ("n" * 238)): "the directory name must have at most 237 bytes",
    }
    ro = tmp_path / "ro"
    ro.mkdir()
    undo = _unwritable(ro)
    if undo is not None:
        cases[str(ro / "run")] = f"cannot be created: {ro} is not writable"
    try:
        for out, fragment in cases.items():
            assert main(["run", "--out", out, *sets]) == 2, out
            err = capsys.readouterr().err
            assert err.startswith("roughvib: error: ") and fragment in err, err
            assert err.count("\n") == 1 and "Traceback" not in err
    finally:
        if undo is not None:
            undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt", "ro"]


def test_a_refused_output_path_costs_no_heavy_import(tmp_path):
    # "in under a second": the check runs before the solver stack is imported
    code = ("import sys; from roughvib.cli import main; "
            f"rc = main(['run', '--out', {str(tmp_path / 'f')!r}, '--set', "
            "'output.checkpoint_interval=0.01']); "
            "print(rc, sorted(m for m in ('numba', 'xarray', 'scipy', 'roughvib.simulation') "
            "if m in sys.modules))")
    (tmp_path / "f").write_text("")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.stdout.strip() == "2 []", proc.stdout + proc.stderr
    assert "exists and is not a directory" in proc.stderr


def test_default_output_is_under_runs_and_a_failed_run_names_only_its_files(
        tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "s.toml"
    scene.write_text('name = "tiny"\n')
    assert main(["run", str(scene), *TINY]) == 0
    out = tmp_path / "runs" / "tiny"
    assert (out / "result.nc").is_file() and _dotfiles(tmp_path / "runs") == []
    # a failed run (event storm) into it replaces it as a whole; stderr names what exists
    capsys.readouterr()
    assert main(["run", str(scene), *TINY, "--set", "solver.max_events=1",
                 "--set", "solver.event_window=1"]) == 1
    err = capsys.readouterr().err
    assert "holds an earlier run; this run replaces it" in err
    assert not (out / "result.nc").exists()
    last = err.strip().splitlines()[-1]
    named = [w for w in last.replace(",", " ").split() if w.startswith("runs/tiny/")]
    assert named and all(Path(w).exists() for w in named), last
    assert {Path(w).name for w in named} == {"summary.json", "partial.nc", "events.csv"}


def test_a_failed_run_without_data_names_only_its_summary(tmp_path, capsys, monkeypatch):
    import roughvib.api

    monkeypatch.setattr(roughvib.api, "simulate",
                        lambda *a, **k: _result(0.0, ok=False, rows=0, events=0))
    out = tmp_path / "run"
    assert main(["run", "--out", str(out), *TINY]) == 1
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last == f"roughvib: written: {out / 'summary.json'} (status, message, last events)"
    assert sorted(os.listdir(out)) == ["scene.toml", "summary.json"]
