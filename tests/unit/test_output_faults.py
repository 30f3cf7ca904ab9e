"""Every command that writes files: a path the user named is not replaced without --overwrite,
an output folder that cannot be used is one line (exit 2), and a full disk is one line naming
the path and the space (exit 1), with nothing half-written left behind and no crash.

The full disk is made three ways: a file system of 2 MB (``mount -t tmpfs``, skipped where this
process may not mount), the free-space probe reporting too little (the checks before writing),
and a file that is a link to ``/dev/full`` (every write to it fails with ENOSPC: the error
path of the write itself)."""

from __future__ import annotations

import errno
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import roughvib
from roughvib import rundir
from roughvib.cli import main
from roughvib.cli.args import parse_sets
from roughvib.results import expected_result_bytes, load_result
from roughvib.rundir import OutputError, WriteError, claim_files, output_folder, write_file

SHORT = ["--set", "output.duration=0.004", "--set", "plate.max_frequency=3000",
         "--set", "output.progress=false"]
pytestmark = pytest.mark.filterwarnings("ignore::roughvib.scene.ModelValidityWarning")


@pytest.fixture(scope="module")
def saved_run(tmp_path_factory) -> Path:
    """One short real run (``roughvib run``); tests that write into it copy it first."""
    d = tmp_path_factory.mktemp("saved") / "run"
    assert main(["run", *SHORT, "--out", str(d), "--quiet"]) == 0
    return d


def _copy(saved: Path, tmp_path: Path) -> Path:
    d = tmp_path / "run"
    shutil.copytree(saved, d)
    return d


def _one_line(capsys, code: int, status: int, *needles: str) -> str:
    """The command's exit status is ``status`` and stderr one line holding ``needles``."""
    err = capsys.readouterr().err.strip()
    assert code == status, err
    assert err.startswith("roughvib: error: ") and "\n" not in err, err
    assert "Traceback" not in err
    for n in needles:
        assert n in err, (n, err)
    return err


def _leftovers(directory: Path) -> list[str]:
    """Temporary files of an interrupted write (``.<stem>.tmp-<id><suffix>``), anywhere."""
    return sorted(str(p) for p in directory.rglob(".*tmp-*"))


# --------------------------------------------------------------------------------------------
# a path the user named is not replaced without --overwrite
# --------------------------------------------------------------------------------------------

def test_report_plot_and_export_refuse_a_named_file_that_exists(saved_run, tmp_path, capsys):
    run = _copy(saved_run, tmp_path)
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes")
    picture = tmp_path / "mine.png"
    picture.write_bytes(b"my picture")
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "other.csv").write_text("my other measurement")
    scene = load_result(run).summary["scene"]
    (lab / f"{scene}.csv").write_text("my measurement")
    cases = [(["report", str(run), "--out", str(notes), "--dpi", "20"], notes),
             (["plot", str(run), "--figure", "velocity", "--out", str(picture)], picture),
             (["export", str(run), "--format", "csv", "--out", str(lab)], lab / f"{scene}.csv")]
    for argv, path in cases:
        before = path.read_bytes()
        _one_line(capsys, main(argv), 2, f"{path} exists", "--overwrite")
        assert path.read_bytes() == before
    assert _leftovers(tmp_path) == []
    # --overwrite replaces them
    for (argv, path), start in zip(cases, (b"<!DOCTYPE html>", b"\x89PNG", b"time [s],"),
                                   strict=True):
        assert main([*argv, "--overwrite"]) == 0, capsys.readouterr().err
        assert path.read_bytes().startswith(start), path
    assert (lab / "other.csv").read_text() == "my other measurement"  # another name


def test_the_default_files_in_the_run_directory_are_replaced(saved_run, tmp_path, capsys):
    # report.html, figures/ and export/ are roughvib's own files in the run directory
    run = _copy(saved_run, tmp_path)
    (run / "report.html").write_text("an earlier report")
    (run / "figures").mkdir()
    (run / "figures" / "velocity.png").write_text("an earlier figure")
    assert main(["report", str(run), "--dpi", "20"]) == 0, capsys.readouterr().err
    assert (run / "report.html").read_text().startswith("<!DOCTYPE html>")
    for argv in (["plot", str(run), "--figure", "velocity"],
                 ["export", str(run), "--format", "wav"]):
        assert main(argv) == 0 and main(argv) == 0, capsys.readouterr().err
    assert (run / "figures" / "velocity.png").read_bytes().startswith(b"\x89PNG")
    assert len(list((run / "export").glob("*.wav"))) == 3


def test_modes_export_refuses_an_existing_file(tmp_path, capsys):
    out = tmp_path / "m.npz"
    out.write_bytes(b"my modes")
    argv = ["modes", "export", "paper", str(out), "--max-frequency", "2000", "--grid", "11",
            "9"]
    _one_line(capsys, main(argv), 2, f"{out} exists", "--overwrite")
    assert out.read_bytes() == b"my modes"
    assert main([*argv, "--overwrite"]) == 0
    with np.load(out) as npz:  # the modes of the plate up to 2 kHz: 191 Hz first
        assert npz["frequency"][0] == pytest.approx(191.061, rel=1e-5)
    assert _leftovers(tmp_path) == []


def test_surface_and_compare_refuse_files_of_their_names_in_out(tmp_path, capsys,
                                                                monkeypatch):
    import roughvib.studies.compare

    def run_study(*a, **k):
        raise AssertionError("the study started before --out was checked")

    monkeypatch.setattr(roughvib.studies.compare, "run_study", run_study)
    out = tmp_path / "out"
    out.mkdir()
    (out / "profile.csv").write_text("my profile")
    (out / "work_precision.md").write_text("my notes")
    _one_line(capsys, main(["surface", "paper", "--out", str(out)]), 2,
              f"{out / 'profile.csv'} exists", "--overwrite")
    _one_line(capsys, main(["compare", "paper", "--out", str(out)]), 2,
              f"{out / 'work_precision.md'} exists", "--overwrite")
    assert (out / "profile.csv").read_text() == "my profile"
    assert sorted(p.name for p in out.iterdir()) == ["profile.csv", "work_precision.md"]
    assert main(["surface", "paper", "--out", str(out), "--set", "plate.max_frequency=2000",
                 "--overwrite"]) == 0
    assert (out / "profile.csv").read_text().startswith("# roughvib surface report")
    assert (out / "work_precision.md").read_text() == "my notes"


def test_a_path_that_is_a_directory_is_refused_even_with_overwrite(tmp_path):
    (tmp_path / "x.html").mkdir()
    with pytest.raises(OutputError, match="is a directory"):
        claim_files([tmp_path / "x.html"], overwrite=True)


# --------------------------------------------------------------------------------------------
# an output folder that cannot be used: one line, exit 2, as for run --out
# --------------------------------------------------------------------------------------------

def _mount_tmpfs(where: Path, options: str) -> bool:
    """Mount a tmpfs at ``where``; False where this process may not (not root, a container
    without the capability, no mount command)."""
    where.mkdir(parents=True, exist_ok=True)
    if shutil.which("mount") is None:
        return False
    try:
        proc = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)],
                              capture_output=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return False
    return proc.returncode == 0


@pytest.fixture
def mounts():
    """Mount tmpfs file systems for one test (skipped where mounting is not permitted);
    unmounted after it."""
    made: list[Path] = []

    def mount(where: Path, options: str) -> Path:
        if not _mount_tmpfs(where, options):
            pytest.skip("mount -t tmpfs is not permitted here")
        made.append(where)
        return where

    yield mount
    for where in reversed(made):
        subprocess.run(["umount", "-l", str(where)], capture_output=True, timeout=30)


@pytest.mark.parametrize("fmt", ["csv", "wav", "uff"])
def test_export_into_an_unusable_folder_is_one_line(saved_run, tmp_path, capsys, fmt):
    afile = tmp_path / "file.txt"
    afile.write_text("x")
    cases = {str(afile): "exists and is not a directory",
             str(afile / "sub"): f"cannot be created: {afile} is not a directory",
             "/proc/roughvib-no/such": "cannot be created"}
    for out, fragment in cases.items():
        _one_line(capsys, main(["export", str(saved_run), "--format", fmt, "--out", out]), 2,
                  f"--out {out} ", fragment)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt"]


def test_export_onto_a_read_only_file_system_is_one_line(saved_run, tmp_path, capsys, mounts):
    ro = mounts(tmp_path / "ro", "size=1m,ro")
    for fmt in ("csv", "wav", "uff"):
        _one_line(capsys, main(["export", str(saved_run), "--format", fmt, "--out", str(ro)]),
                  2, f"--out {ro} is not writable (a read-only file system)")
        _one_line(capsys, main(["export", str(saved_run), "--format", fmt, "--out",
                                str(ro / "sub")]), 2,
                  f"--out {ro / 'sub'} cannot be created: Read-only file system")


def test_output_folder_is_made_with_its_parents(tmp_path):
    assert output_folder(tmp_path / "a" / "b").is_dir()


# --------------------------------------------------------------------------------------------
# a full disk: one line naming the path and the space, exit 1, nothing left, no crash
# --------------------------------------------------------------------------------------------

def test_the_estimate_of_a_run_is_its_time_series(saved_run, tmp_path):
    # the bytes of every variable along time in the file xarray reads back, counted
    # independently of the estimate; with a fixed contact count the two are equal
    out = tmp_path / "three"
    assert main(["run", *SHORT, "--set", "contact.points=3", "--out", str(out),
                 "--quiet"]) == 0
    scene = roughvib.load_scene(str(out / "scene.toml"))
    with xr.open_dataset(out / "result.nc", engine="h5netcdf") as ds:
        along_time = sum(v.nbytes for v in ds.variables.values() if "time" in v.dims)
        assert ds.sizes["contact"] == 3
    assert expected_result_bytes(scene) == along_time
    assert along_time < (out / "result.nc").stat().st_size < along_time + 100_000
    # "auto" contacts count as one (the count is known once the profile is built): a lower
    # bound
    auto = roughvib.load_scene("paper", parse_sets(SHORT[1::2]))
    assert auto.contact.points == "auto"
    with xr.open_dataset(saved_run / "result.nc", engine="h5netcdf") as ds:
        assert expected_result_bytes(auto) <= sum(v.nbytes for v in ds.variables.values()
                                                  if "time" in v.dims)


def test_a_run_that_cannot_fit_is_refused_before_it_starts(tmp_path, capsys, monkeypatch):
    import roughvib.api

    def simulate(*a, **k):
        raise AssertionError("the run started although its result cannot fit")

    monkeypatch.setattr(roughvib.api, "simulate", simulate)
    monkeypatch.setattr(rundir, "free_space", lambda path: 1000)
    out = tmp_path / "sub" / "run"
    need = expected_result_bytes(roughvib.load_scene("paper", parse_sets(SHORT[1::2])))
    err = _one_line(capsys, main(["run", *SHORT, "--out", str(out)]), 1,
                    f"{out}: no room for the run's time series alone",
                    f"({rundir.format_bytes(need)} needed, 1 kB free)")
    assert "free some space or write elsewhere" in err
    assert list(tmp_path.iterdir()) == []  # no directory, no lock, no staging directory


def test_commands_refuse_to_write_what_cannot_fit(saved_run, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(rundir, "free_space", lambda path: 10)
    run = _copy(saved_run, tmp_path)
    before = sorted(os.listdir(run))
    for argv in (["export", str(run), "--format", "csv", "--out", str(tmp_path / "e")],
                 ["export", str(run), "--format", "wav", "--out", str(tmp_path / "e")],
                 ["export", str(run), "--format", "uff", "--out", str(tmp_path / "e")]):
        _one_line(capsys, main(argv), 1, f"{tmp_path / 'e'}: no room for the ",
                  "needed, 10 bytes free")
    assert os.listdir(tmp_path / "e") == []
    # the run's own save checks before it writes too
    r = load_result(run)
    with pytest.raises(WriteError, match=r"no room for the run's time series \(.* needed, "
                                         r"10 bytes free\)") as info:
        r.save(tmp_path / "again")
    assert info.value.errno == errno.ENOSPC and isinstance(info.value, OSError)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e", "run"]
    assert sorted(os.listdir(run)) == before


@pytest.fixture
def dev_full(monkeypatch):
    """Every file that :func:`write_file` (and so every command) writes is a link to
    ``/dev/full``: the write fails with ENOSPC, as on a full disk."""
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    real = rundir._tmp_name

    def tmp_name(path):
        tmp = real(path)
        os.symlink("/dev/full", tmp)
        return tmp

    monkeypatch.setattr(rundir, "_tmp_name", tmp_name)


def test_a_failed_write_is_one_line_and_leaves_nothing(saved_run, tmp_path, capsys, dev_full):
    run = _copy(saved_run, tmp_path)
    notes = tmp_path / "notes.html"
    for argv, path in ((["report", str(run), "--out", str(notes), "--dpi", "20"], notes),
                       (["plot", str(run), "--figure", "spectra"],
                        run / "figures" / "spectra.png"),
                       (["export", str(run), "--format", "csv"], run / "export")):
        err = _one_line(capsys, main(argv), 1, f"cannot write {path}",
                        "No space left on device", "needed", "free)")
        assert "free some space or write elsewhere" in err
    assert not notes.exists() and not (run / "figures" / "spectra.png").exists()
    assert _leftovers(tmp_path) == [] and list((run / "export").iterdir()) == []
    with pytest.raises(WriteError, match="No space left on device") as info:
        write_file(tmp_path / "x.txt", lambda tmp: tmp.write_text("x"))
    assert info.value.errno == errno.ENOSPC
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_a_run_onto_a_full_file_system_ends_with_one_line(saved_run, tmp_path, capsys, mounts,
                                                         monkeypatch):
    small = mounts(tmp_path / "small", "size=2m")
    (small / "filler").write_bytes(b"\0" * (2 * 1024 * 1024 - 16 * 1024))  # 16 kB left
    free = shutil.disk_usage(small).free
    scene = roughvib.load_scene("paper", parse_sets(SHORT[1::2]))
    assert free < expected_result_bytes(scene) < (saved_run / "result.nc").stat().st_size
    # with the check before the run: refused before it starts
    _one_line(capsys, main(["run", *SHORT, "--out", str(small / "run"), "--quiet"]), 1,
              f"{small / 'run'}: no room for the run's time series alone")
    # without the checks, the writes meet the full disk: one line, no crash, nothing left;
    # in a process of its own, where a crash shows as a negative return code (SIGSEGV, when
    # HDF5 wrote the file itself and its close failed)
    proc = subprocess.run([sys.executable, "-c", _FULL, "run", *SHORT, "--out",
                           str(small / "run"), "--quiet"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 1, (proc.returncode, proc.stderr)
    lines = [ln for ln in proc.stderr.splitlines() if not ln.startswith("roughvib: warning")]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert lines[0].startswith(f"roughvib: error: cannot write the run's files into "
                               f"{small / 'run'}: No space left on device (")
    assert sorted(p.name for p in small.iterdir()) == ["filler"]
    # the other writers on the full disk, with and without their checks
    for checks in (True, False):
        if not checks:
            monkeypatch.setattr(rundir, "check_room", lambda *a, **k: None)
        for argv in (["report", str(saved_run), "--out", str(small / "r.html"), "--dpi", "20"],
                     ["export", str(saved_run), "--format", "csv", "--out", str(small / "e")],
                     ["plot", str(saved_run), "--figure", "spectra", "--out",
                      str(small / "s.png")]):
            _one_line(capsys, main(argv), 1, str(small), "needed, ", " free")
    assert sorted(p.name for p in small.iterdir() if p.name != "e") == ["filler"]
    assert list((small / "e").iterdir()) == []


# ``roughvib`` in a process of its own, with the checks before writing switched off
_FULL = textwrap.dedent("""
    import sys
    from roughvib import results, rundir
    results.check_room = rundir.check_room = lambda *a, **k: None
    from roughvib.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def test_a_write_error_that_reaches_the_command_line_is_one_line(tmp_path, capsys,
                                                                  monkeypatch):
    # an OSError of a write that the code which wrote did not turn into a WriteError (a
    # library's own write) reaches the command line
    import roughvib.api

    def failing(*error):
        def simulate(*a, **k):
            raise OSError(*error)
        return simulate

    argv = ["run", *SHORT, "--out", str(tmp_path / "run")]
    monkeypatch.setattr(roughvib.api, "simulate", failing(errno.ENOSPC, "No space left on "
                                                          "device"))
    _one_line(capsys, main(argv), 1, "a write failed: No space left on device (the error "
                                     "does not name the file); free some space")
    monkeypatch.setattr(roughvib.api, "simulate", failing(errno.EROFS, "Read-only file system",
                                                          "/mnt/x/checkpoint.pkl"))
    _one_line(capsys, main(argv), 1, "cannot write /mnt/x/checkpoint.pkl: Read-only file "
                                     "system")
    # any other OSError is not a failed write: not hidden behind one
    monkeypatch.setattr(roughvib.api, "simulate", failing(errno.EBADF, "Bad file descriptor"))
    with pytest.raises(OSError, match="Bad file descriptor"):
        main(argv)
    assert not (tmp_path / "run").exists()


def test_a_checkpoint_onto_a_full_disk_is_one_line_naming_it(tmp_path, capsys, monkeypatch):
    """The second checkpoint of a run meets a full disk (its temporary file is a link to
    /dev/full): the run ends with one line naming the checkpoint, its size and the space
    free, and the first checkpoint stays intact for --resume."""
    import tempfile as real_tempfile
    from types import SimpleNamespace

    from roughvib.solvers import checkpoint
    from roughvib.solvers.checkpoint import CHECKPOINT_NAME, read_checkpoint

    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    calls = []

    def mkstemp(prefix, dir):
        calls.append(prefix)
        if len(calls) == 1:
            return real_tempfile.mkstemp(prefix=prefix, dir=dir)
        tmp = os.path.join(dir, f"{prefix}full")
        os.symlink("/dev/full", tmp)
        return os.open(tmp, os.O_WRONLY), tmp

    monkeypatch.setattr(checkpoint, "tempfile", SimpleNamespace(mkstemp=mkstemp))
    out = tmp_path / "run"
    argv = ["run", *SHORT, "--set", "output.checkpoint_interval=0.001", "--out", str(out)]
    assert main(argv) == 1
    # the short run's warnings about its window aside, one line
    err = [ln for ln in capsys.readouterr().err.splitlines()
           if not ln.startswith("roughvib: warning: ")]
    assert len(err) == 1 and re.fullmatch(
        rf"roughvib: error: cannot write {re.escape(str(out / CHECKPOINT_NAME))}: No space "
        rf"left on device \([\d.]+ (?:[kMG]B|bytes) needed, [\d.]+ (?:[kMG]B|bytes) free\); "
        rf"free some space or write elsewhere", err[0]), err
    assert len(calls) == 2
    assert sorted(p.name for p in out.iterdir()) == [CHECKPOINT_NAME]  # no temporary file
    first = read_checkpoint(out)  # intact: its digest is checked
    assert 0 < first.t < 0.004
    # the same through the function itself: a WriteError (an OSError) with the write's errno
    with pytest.raises(WriteError) as info:
        checkpoint.write_checkpoint(tmp_path / "again", first)
    assert info.value.errno == errno.ENOSPC and "\n" not in str(info.value)
    assert str(info.value).startswith(f"cannot write {tmp_path / 'again' / CHECKPOINT_NAME}: ")
    assert os.listdir(tmp_path / "again") == []


def test_a_resume_that_cannot_fit_is_refused_before_it_starts(tmp_path, capsys, monkeypatch):
    """--resume checks the free space for the checkpoint's scene as a new run does; the
    checkpoint stays, and the same resume runs once there is room."""
    import roughvib.api
    from roughvib.solvers import adaptive_modal
    from roughvib.solvers.checkpoint import CHECKPOINT_NAME

    real = adaptive_modal.write_checkpoint

    def write_then_interrupt(directory, cp):  # a run stopped after its first checkpoint
        real(directory, cp)
        raise KeyboardInterrupt

    out = tmp_path / "run"
    with monkeypatch.context() as m:
        m.setattr(adaptive_modal, "write_checkpoint", write_then_interrupt)
        assert main(["run", *SHORT, "--set", "output.checkpoint_interval=0.001", "--out",
                     str(out), "--quiet"]) == 130
    capsys.readouterr()
    saved = (out / CHECKPOINT_NAME).read_bytes()
    scene = roughvib.load_scene("paper", parse_sets([*SHORT[1::2],
                                                     "output.checkpoint_interval=0.001"]))
    need = expected_result_bytes(scene)
    with monkeypatch.context() as m:
        m.setattr(rundir, "free_space", lambda path: 1000)
        m.setattr(roughvib.api, "resume", lambda *a, **k: pytest.fail("the resume started"))
        _one_line(capsys, main(["run", "--resume", str(out)]), 1,
                  f"{out}: no room for the run's time series alone "
                  f"({rundir.format_bytes(need)} needed, 1 kB free)")
    assert os.listdir(out) == [CHECKPOINT_NAME]
    assert (out / CHECKPOINT_NAME).read_bytes() == saved
    assert main(["run", "--resume", str(out), "--quiet"]) == 0
    assert load_result(out).ok and not (out / CHECKPOINT_NAME).exists()


# --------------------------------------------------------------------------------------------
# the studies' files: compare's tables, the sweep report, the ensemble tables
# --------------------------------------------------------------------------------------------

class _QuickWorker:
    """compare's worker process stood in for: every job succeeds at once, nothing is drawn."""

    def run(self, job, timeout):
        return {"status": "success", "wall_time": 0.01}

    def close(self):
        pass


def test_compare_refuses_a_file_in_the_way_and_writes_complete_tables_or_none(
        tmp_path, monkeypatch, dev_full):
    import roughvib.studies.compare as cmp

    scene = roughvib.load_scene("paper", parse_sets(SHORT[1::2]))
    study = dict(budget=60.0, methods=("exact-modal",), steps=(1e-5,), presets=False,
                 progress=False)
    (tmp_path / "wp").write_text("mine")

    class NoWorker(_QuickWorker):
        def run(self, job, timeout):
            raise AssertionError("the study started although its folder is a file")

    monkeypatch.setattr(cmp, "_Worker", NoWorker)
    with pytest.raises(OutputError, match=rf"^{re.escape(str(tmp_path / 'wp'))} exists and "
                                          rf"is not a directory"):
        cmp.run_study(scene, tmp_path / "wp", **study)
    assert (tmp_path / "wp").read_text() == "mine"
    # every file written is a link to /dev/full: the first table fails in one line
    monkeypatch.setattr(cmp, "_Worker", _QuickWorker)
    with pytest.raises(WriteError) as info:
        cmp.run_study(scene, tmp_path / "wp2", **study)
    msg = str(info.value)
    assert msg.startswith(f"cannot write {tmp_path / 'wp2' / 'work_precision.csv'}: No space "
                          f"left on device (") and "\n" not in msg
    assert list((tmp_path / "wp2").iterdir()) == [] and _leftovers(tmp_path) == []
    # the figure (drawn in the worker) the same way
    from test_work_precision_view import _table

    from roughvib.views.work_precision import plot_work_precision

    with pytest.raises(WriteError, match=rf"^cannot write {re.escape(str(tmp_path / 'f.png'))}"
                                         rf": No space left on device"):
        plot_work_precision(_table(), tmp_path / "f.png", "test")
    assert _leftovers(tmp_path) == [] and not (tmp_path / "f.png").exists()


def _sweep_directory(d: Path) -> Path:
    """The two files the sweep report reads, of a velocity sweep over two seeds (made by
    hand: the report needs no case directories without an ensemble)."""
    import json

    d.mkdir()
    v = np.array([0.01, 0.02, 0.01, 0.02])
    seeds = [1, 1, 2, 2]
    pd.DataFrame({
        "case": [f"v{x}_s{s}" for x, s in zip(v, seeds, strict=True)], "status": "success",
        "message": "", "excitation.target_rms_velocity": v, "roughness.seed": seeds,
        "block_vertical_acceleration_level_db_re_1e-6": 80 + 30 * np.log10(v / 0.01),
        "plate_vertical_acceleration_level_db_re_1e-6": 70 + 30 * np.log10(v / 0.01),
        "block_tangential_velocity_rms": v, "stick_fraction": 0.0, "wall_time": 1.0,
    }).to_csv(d / "sweep.csv", index=False)
    (d / "sweep.json").write_text(json.dumps({
        "name": "v", "base": "paper", "varied_keys": ["excitation.target_rms_velocity",
                                                      "roughness.seed"],
        "seed_keys": ["roughness.seed"]}))
    return d


def test_sweep_report_refuses_a_file_in_the_way_and_a_full_disk_in_one_line(
        tmp_path, capsys, monkeypatch, request):
    from roughvib.studies.sweep import report as sweep_report_module
    from roughvib.studies.sweep.ensemble import EnsembleTables

    d = _sweep_directory(tmp_path / "sweep")
    # no ensemble section (it would read the case directories)
    monkeypatch.setattr(sweep_report_module, "ensemble_tables", lambda directory: None)
    assert main(["sweep-report", str(d)]) == 0  # the files of the sweep are a report
    capsys.readouterr()
    made = sorted(p.name for p in (d / "report").iterdir())
    assert {"report.md", "report.html", "fits.csv", "velocity.png"} <= set(made)
    shutil.rmtree(d / "report")
    (d / "report").write_text("mine")
    _one_line(capsys, main(["sweep-report", str(d)]), 2,
              f"{d / 'report'} exists and is not a directory")
    assert (d / "report").read_text() == "mine"
    (d / "report").unlink()
    # a full disk: one line naming the file, nothing half-written
    request.getfixturevalue("dev_full")
    _one_line(capsys, main(["sweep-report", str(d)]), 1,
              f"cannot write {d / 'report' / 'velocity.png'}: No space left on device")
    assert list((d / "report").iterdir()) == [] and _leftovers(tmp_path) == []
    # the ensemble's tables and figure
    spread = {"n": 2, "mean": 80.0, "std": 1.0, "min": 79.0, "max": 81.0}
    ens = EnsembleTables(
        runs=pd.DataFrame([{"case": "a", "group": "all", "roughness.seed": 1}]),
        levels=pd.DataFrame([{"group": "all", "level": "block", **spread, "range": 2.0}]),
        bands=pd.DataFrame([{"group": "all", "level": w, "centre": 1000.0, **spread}
                            for w in ("block", "plate")]),
        seed_key="roughness.seed", group_keys=[])
    from roughvib.studies.sweep.ensemble import ensemble_blocks
    from roughvib.views.ensemble import ensemble_figure

    with pytest.raises(WriteError, match=rf"^cannot write "
                                         rf"{re.escape(str(d / 'report' / 'ensemble_levels.csv'))}"
                                         rf": No space left on device"):
        ensemble_blocks(ens, d / "report")
    with pytest.raises(WriteError, match=rf"^cannot write "
                                         rf"{re.escape(str(d / 'report' / 'ensemble.png'))}"):
        ensemble_figure(ens.bands, d / "report" / "ensemble.png")
    assert list((d / "report").iterdir()) == [] and _leftovers(tmp_path) == []
