"""Run directories and checkpoints are untrusted input: whatever they hold, every command that
reads them answers with one line naming the file and exit status 2, never a traceback; an
edited summary.json is refused (its digest); a damaged checkpoint is refused before it is
unpickled. Also the small input checks of the CLI and the public writer of result.nc."""

from __future__ import annotations

import inspect
import json
import os
import pickle
import shutil
import signal
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from self_signal import start_stopping_itself

import roughvib
from roughvib.cli import main
from roughvib.results import (
    SUMMARY_DIGEST,
    MixedRunError,
    RunDirectoryError,
    load_result,
    read_summary,
    seal_summary,
)
from roughvib.scene import DESCRIPTION_MAX, SceneError, load_scene
from roughvib.solvers.checkpoint import (
    CHECKPOINT_NAME,
    Checkpoint,
    read_checkpoint,
    write_checkpoint,
)

SHORT = ["--set", "output.duration=0.004", "--set", "plate.max_frequency=3000",
         "--set", "output.progress=false"]
#: every command that reads a run directory
READERS = [["events"], ["events", "--json"], ["events", "--kind", "lift_off"],
           ["plot", "--figure", "velocity"], ["report"]]


@pytest.fixture(scope="module")
def saved_run(tmp_path_factory) -> Path:
    """One short real run, written by ``roughvib run`` (copied by each test that edits it)."""
    d = tmp_path_factory.mktemp("saved") / "run"
    assert main(["run", *SHORT, "--out", str(d), "--quiet"]) == 0
    return d


def _copy(saved: Path, tmp_path: Path, name: str = "run") -> Path:
    d = tmp_path / name
    shutil.copytree(saved, d)
    return d


def _edit_summary(d: Path, *, legacy: bool = False, **changes) -> None:
    """Change values of summary.json by hand; ``legacy`` also drops what older versions did
    not write (the file list, the run id, the digest)."""
    s = json.loads((d / "summary.json").read_text())
    if legacy:
        for k in ("files", "run_id", SUMMARY_DIGEST):
            s.pop(k, None)
    s.update(changes)
    (d / "summary.json").write_text(json.dumps(s, indent=2))


def _refused(argv: list[str], capsys, *needles: str) -> str:
    """Run a command that must be refused: exit 2, one line on stderr holding ``needles``."""
    assert main(argv) == 2, argv
    err = capsys.readouterr().err.strip()
    assert err.startswith("roughvib: error: ") and "\n" not in err, err
    assert "Traceback" not in err
    for n in needles:
        assert n in err, (n, err)
    return err


# --------------------------------------------------------------------------------------------
# summary.json: type and shape
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("text, needle", [
    ("[]", "must hold a JSON object, got an array"),
    ("null", "must hold a JSON object, got null"),
    ('"hello"', 'must hold a JSON object, got a string "hello"'),
    ("", "is not valid JSON (Expecting value at line 1 column 1)"),
    ("{oops", "is not valid JSON"),
    (b"\xff\xfe{}", "is not UTF-8 text"),
])
def test_a_summary_that_is_not_an_object_is_refused_by_every_command(saved_run, tmp_path,
                                                                     capsys, text, needle):
    d = _copy(saved_run, tmp_path)
    path = d / "summary.json"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    for cmd in READERS:
        _refused([*cmd, str(d)], capsys, f"{path}", needle)
    assert not (d / "report.html").exists() and not (d / "figures").exists()
    with pytest.raises(RunDirectoryError, match="summary.json"):
        load_result(d)


@pytest.mark.parametrize("changes, needle", [
    ({"metrics": "oops"}, 'metrics must be an object, got a string "oops"'),
    ({"metrics": {"stick_fraction": "x"}}, "metrics.stick_fraction must be a number or null"),
    ({"partial_result": {"t_end": "soon"}}, "partial_result.t_end must be a number or null"),
    ({"model": []}, "model must be an object, got an array"),
    ({"status": 3}, "status must be a string, got an integer 3"),
    ({"files": {"result.nc": 5}}, "files.result.nc must be an object"),
    ({"files": {"../../etc/passwd": {"bytes": 1, "sha256": "0"}}}, "which is not a file of a run"),
])
def test_a_value_of_the_wrong_type_names_the_field(saved_run, tmp_path, capsys, changes,
                                                   needle):
    d = _copy(saved_run, tmp_path)
    _edit_summary(d, legacy=True, **changes)  # no digest: the shape check alone
    for cmd in READERS:
        _refused([*cmd, str(d)], capsys, "summary.json", needle)


# --------------------------------------------------------------------------------------------
# summary.json: its digest
# --------------------------------------------------------------------------------------------

def test_the_saved_summary_carries_its_digest(saved_run):
    s = json.loads((saved_run / "summary.json").read_text())
    body = {k: v for k, v in s.items() if k != SUMMARY_DIGEST}
    canonical = json.dumps(body, sort_keys=True, separators=(",", ":")).encode()
    import hashlib

    assert s[SUMMARY_DIGEST] == hashlib.sha256(canonical).hexdigest()
    assert seal_summary(body) == s and read_summary(saved_run) == s
    r = load_result(saved_run)
    assert r.ok and r.summary[SUMMARY_DIGEST] == s[SUMMARY_DIGEST]


@pytest.mark.parametrize("changes", [
    {"status": "event_storm"},  # events and report used to disagree about this run
    {"metrics": {"stick_fraction": 0.5}},  # used to show in the report unremarked
    {"message": "edited"},
])
def test_an_edited_summary_is_refused_by_every_command(saved_run, tmp_path, capsys, changes):
    d = _copy(saved_run, tmp_path)
    s = json.loads((d / "summary.json").read_text())
    if "metrics" in changes:
        changes = {"metrics": {**s["metrics"], **changes["metrics"]}}
    _edit_summary(d, **changes)
    for cmd in READERS:
        _refused([*cmd, str(d)], capsys, f"{d / 'summary.json'} was changed after the run "
                                         f"wrote it", SUMMARY_DIGEST)
    with pytest.raises(RunDirectoryError, match="was changed after the run wrote it"):
        load_result(d, partial=True)
    # the same summary re-indented (not edited) still matches
    e = _copy(saved_run, tmp_path, "reindented")
    (e / "summary.json").write_text(json.dumps(s, indent=None, sort_keys=True))
    assert load_result(e).summary == s


def test_a_status_that_contradicts_the_files_is_refused(saved_run, tmp_path, capsys):
    # without a digest (an older roughvib, or a digest removed): the status against the files
    d = _copy(saved_run, tmp_path)
    s = json.loads((d / "summary.json").read_text())
    s.update(status="event_storm")
    s.pop(SUMMARY_DIGEST)
    (d / "summary.json").write_text(json.dumps(s))
    for cmd in READERS:
        _refused([*cmd, str(d)], capsys, "status 'event_storm' contradicts result.nc")
    _edit_summary(d, legacy=True)  # and without the file list: the files present
    _refused(["events", str(d)], capsys, "status 'event_storm' contradicts result.nc")
    _edit_summary(d, status="success")
    (d / "result.nc").unlink()
    _refused(["report", str(d)], capsys, "says the run succeeded, but result.nc is missing")


def _record(path: Path) -> Path:
    """A measured record (CSV) that ``validate`` could read: 0.1 s of a 1 kHz tone, 0.1 m/s^2
    amplitude, sampled at 50 kHz."""
    t = np.arange(5000) / 50e3
    lines = ["time [s],acceleration [m/s^2]"] + [f"{a:.9g},{b:.9g}" for a, b in
                                                  zip(t, 0.1 * np.sin(2e3 * np.pi * t),
                                                      strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_result_nc_beside_partial_nc_is_refused_by_every_command(saved_run, tmp_path, capsys):
    # a successful run with a partial.nc beside its result.nc (a copy by hand, another run's
    # file): one of the two is not the run's, and nothing reads the directory
    d = _copy(saved_run, tmp_path)
    shutil.copyfile(d / "result.nc", d / "partial.nc")
    record = _record(tmp_path / "lab.csv")
    rule = (f"{d} holds both result.nc and partial.nc: a run writes one of them (result.nc "
            f"when it succeeds, partial.nc when it fails)")
    for cmd in [*READERS, ["export", "--format", "csv"]]:
        _refused([*cmd, str(d)], capsys, rule, "remove partial.nc")
    _refused(["validate", str(d), str(record), "--signal", "plate"], capsys, rule)
    for partial in (False, True):
        with pytest.raises(RunDirectoryError, match="holds both result.nc and partial.nc"):
            load_result(d, partial=partial)
    assert sorted(os.listdir(d)) == sorted([*os.listdir(saved_run), "partial.nc"])
    # a failed run with a result.nc beside its partial.nc
    from test_output_safety import _result

    f = tmp_path / "failed"
    _result(2.0, ok=False).save(f)
    shutil.copyfile(f / "partial.nc", f / "result.nc")
    for cmd in READERS:
        _refused([*cmd, str(f)], capsys, f"{f} holds both result.nc and partial.nc",
                 "summary.json says 'event_storm', remove result.nc")


def test_a_directory_that_is_not_a_run_raises_roughvibs_error(tmp_path, capsys):
    from roughvib.results import NotARunError

    afile = tmp_path / "notes.txt"
    afile.write_text("x")
    empty = tmp_path / "empty"
    empty.mkdir()
    for path, why in ((tmp_path / "nothing", "no such directory"),
                      (afile, "a file; roughvib run writes a directory"),
                      (empty, "no summary.json")):
        with pytest.raises(NotARunError) as info:
            load_result(path)
        assert str(info.value) == f"{path} is not a roughvib result directory ({why})"
        # roughvib's own error (what the CLI refuses with), and still the built-in one that
        # load_result raised before, for code that catches that
        assert isinstance(info.value, RunDirectoryError)
        assert isinstance(info.value, FileNotFoundError)
        for cmd in READERS:
            _refused([*cmd, str(path)], capsys, f"{path} is not a roughvib result directory")
    assert sorted(os.listdir(tmp_path)) == ["empty", "notes.txt"]
    assert os.listdir(empty) == []


# --------------------------------------------------------------------------------------------
# the other files, when no file list covers them (an older roughvib)
# --------------------------------------------------------------------------------------------

def _first_time(path: Path, text: str) -> None:
    """Replace the time of the first event by ``text``."""
    lines = path.read_text().splitlines()
    lines[1] = text + lines[1][lines[1].index(","):]
    path.write_text("\n".join(lines) + "\n")


def _foreign_nc(path: Path) -> None:
    xr.Dataset({"a": ("x", [1.0, 2.0])}).to_netcdf(path, engine="h5netcdf")


@pytest.mark.parametrize("name, damage, needle", [
    ("result.nc", lambda p: p.write_bytes(p.read_bytes()[:1000]),
     "cannot be read as netCDF-4 (OSError: "),
    ("result.nc", lambda p: p.write_text("hello"), "cannot be read as netCDF-4"),
    ("result.nc", _foreign_nc, "has no time coordinate of increasing finite seconds"),
    ("events.csv", lambda p: p.write_text("garbage,x\n1,2\n"),
     "lacks the columns time, kind, contact, ... (9 more)"),
    ("events.csv", lambda p: p.write_bytes(b"\xff\xfe\x00"), "cannot be read as an event log"),
    ("events.csv", lambda p: _first_time(p, "soon"), "column time must hold numbers"),
    ("events.csv", lambda p: _first_time(p, "inf"), "column time must hold finite seconds"),
    ("scene.toml", lambda p: p.write_text("x = ["), "is not valid TOML"),
])
def test_a_damaged_or_foreign_file_is_refused_naming_it(saved_run, tmp_path, capsys, name,
                                                        damage, needle):
    d = _copy(saved_run, tmp_path)
    _edit_summary(d, legacy=True)
    assert load_result(d).ok  # read as before, unchecked against a list
    damage(d / name)
    with pytest.raises(RunDirectoryError, match=name.replace(".", r"\.")):
        load_result(d)
    for cmd in READERS:
        _refused([*cmd, str(d)], capsys, f"{d / name}", needle)


def test_with_a_file_list_a_changed_file_is_a_mixed_run(saved_run, tmp_path, capsys):
    d = _copy(saved_run, tmp_path)
    (d / "events.csv").write_text("garbage,x\n")
    with pytest.raises(MixedRunError):
        load_result(d)
    _refused(["events", str(d)], capsys, "events.csv is not the file run")


def test_a_new_run_into_a_directory_of_a_foreign_summary_is_refused(tmp_path, capsys):
    d = tmp_path / "notes"
    d.mkdir()
    (d / "summary.json").write_text("[]")
    _refused(["run", *SHORT, "--out", str(d)], capsys, "holds no roughvib run", "--overwrite")
    assert (d / "summary.json").read_text() == "[]"


# --------------------------------------------------------------------------------------------
# checkpoints and --resume
# --------------------------------------------------------------------------------------------

def _checkpoint() -> Checkpoint:
    return Checkpoint(scene_toml="", t=0.0, k=1, y=np.zeros(3), y_initial=np.zeros(3),
                      outputs=np.zeros((1, 2)), reg=np.zeros(1, np.int64), rf=np.zeros(1),
                      regime=None, events=[], stats={})


class _Marker:
    """Unpickling this creates a file: proof that a pickle was loaded."""

    def __init__(self, path: str):
        self.path = path

    def __reduce__(self):
        return (Path.touch, (Path(self.path),))


def test_a_checkpoint_round_trips_and_its_header_is_checked(tmp_path):
    path = write_checkpoint(tmp_path, _checkpoint())
    assert path.read_bytes().startswith(b"roughvib-checkpoint\n2 ")
    cp = read_checkpoint(tmp_path)
    assert isinstance(cp, Checkpoint) and cp.outputs.shape == (1, 2)


@pytest.mark.parametrize("case", ["user files", "empty", "random", "foreign pickle",
                                  "truncated", "damaged", "format 1", "ended run",
                                  "no directory"])
def test_resume_says_what_is_wrong_in_one_line(tmp_path, capsys, saved_run, case):
    d = tmp_path / "run"
    d.mkdir()
    cp = d / CHECKPOINT_NAME
    marker = tmp_path / "unpickled"
    rng = np.random.default_rng(1)
    needles: tuple[str, ...]
    if case == "user files":
        (d / "notes.txt").write_text("mine")
        needles = (f"--resume {d}: no {CHECKPOINT_NAME} there, nothing to resume",)
    elif case == "empty":
        cp.write_bytes(b"")
        needles = (f"{cp}: an empty file, not a roughvib checkpoint",)
    elif case == "random":
        cp.write_bytes(rng.bytes(300))
        needles = (f"{cp}: not a roughvib checkpoint",)
    elif case == "foreign pickle":
        cp.write_bytes(pickle.dumps(_Marker(str(marker))))
        needles = (f"{cp}: not a roughvib checkpoint",)
    elif case in ("truncated", "damaged"):
        write_checkpoint(d, _checkpoint())
        data = cp.read_bytes()
        if case == "truncated":
            cp.write_bytes(data[:-7])
            needles = (f"{cp}: a truncated or damaged roughvib checkpoint",)
        else:  # the header of a real checkpoint in front of a pickle that would run code
            head = data[:data.index(b"\n", len(b"roughvib-checkpoint\n")) + 1]
            evil = pickle.dumps(_Marker(str(marker)))
            n = int(head.split()[-1])
            cp.write_bytes(head + evil + b"\0" * (n - len(evil)))
            needles = (f"{cp}: a damaged roughvib checkpoint (its contents do not match the "
                       f"SHA-256",)
    elif case == "format 1":
        cp.write_bytes(pickle.dumps({"magic": "roughvib-checkpoint", "version": 1,
                                     "checkpoint": _Marker(str(marker))}))
        needles = (f"{cp}: checkpoint format version 1 (an older roughvib) cannot be resumed",)
    elif case == "ended run":
        d = _copy(saved_run, tmp_path, "ended")
        needles = (f"--resume {d}: the run there has ended (success",)
    else:
        d = tmp_path / "missing"
        needles = (f"--resume {d}: no such directory",)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    err = _refused(["run", "--resume", str(d)], capsys, *needles)
    assert "--overwrite" not in err
    assert not marker.exists()  # nothing was unpickled
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # nothing written
    if cp.exists() and case not in ("user files",):
        with pytest.raises(SceneError) as info:  # the Python API: the same one line
            roughvib.resume(d)
        assert "\n" not in str(info.value) and str(cp) in str(info.value)
        assert not marker.exists()


# --------------------------------------------------------------------------------------------
# small input checks
# --------------------------------------------------------------------------------------------

def test_small_cli_input_checks_refuse_in_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    _refused(["run", *SHORT, "--workers", "3"], capsys, "--workers", "without --seeds")
    _refused(["run", *SHORT, "--out", ""], capsys, "--out must name a path, got ''")
    _refused(["run", "--resume", ""], capsys, "--resume must name a path, got ''")
    _refused(["sweep", "paper-velocity", "--out", " "], capsys, "--out must name a path")
    _refused(["run", "--set", "output.duration=0.004\nplate.max_frequency=3000"], capsys,
             "--set takes one value on one line")
    _refused(["run", *SHORT, "--set", "solver.method=paper", "--verify"], capsys,
             "solver.method = 'paper' keeps none", "--verify")
    assert list(tmp_path.iterdir()) == []  # all refused before anything was written (runs/)


def test_the_description_has_a_documented_limit():
    ok = load_scene("paper", {"description": "x" * DESCRIPTION_MAX})
    assert len(ok.description) == DESCRIPTION_MAX
    with pytest.raises(SceneError) as info:
        load_scene("paper", {"description": "x" * (DESCRIPTION_MAX + 1)})
    assert str(info.value) == (f"description must have at most {DESCRIPTION_MAX} characters, "
                               f"got {DESCRIPTION_MAX + 1}")


def test_simulate_has_no_private_parameter():
    params = inspect.signature(roughvib.simulate).parameters
    assert not any(p.startswith("_") for p in params)
    assert list(params) == ["scene", "progress", "force_amplitude", "checkpoint_dir", "verify"]
    paper = load_scene("paper", {"solver.method": "paper", "output.duration": 0.004})
    with pytest.raises(SceneError, match="'paper' keeps none"):  # before any work
        roughvib.simulate(paper, verify=True)


def test_fits_csv_has_its_header_when_nothing_is_fitted(tmp_path):
    from roughvib.studies.sweep.report import FIT_COLUMNS, sweep_report
    from roughvib.studies.sweep.tables import _fit

    d = tmp_path / "sweep"
    d.mkdir()
    (d / "sweep.json").write_text(json.dumps({"name": "one", "base": "paper",
                                              "varied_keys": ["block.mass"], "seed_keys": []}))
    pd.DataFrame({"case": ["a"], "block.mass": [0.5], "status": ["success"], "message": [""],
                  "block_vertical_acceleration_level_db_re_1e-6": [80.0],
                  "plate_vertical_acceleration_level_db_re_1e-6": [70.0],
                  "block_tangential_velocity_rms": [0.01], "stick_fraction": [0.1],
                  "wall_time": [1.0]}).to_csv(d / "sweep.csv", index=False)
    sweep_report(d)
    text = (d / "report" / "fits.csv").read_text()
    assert text.splitlines() == [",".join(FIT_COLUMNS)]
    fitted = _fit(np.array([1.0, 2.0, 4.0]), np.array([0.0, 6.0, 12.0]), None)
    assert ["study", "x", "quantity", "group", *fitted] == FIT_COLUMNS  # a fit's own keys


# --------------------------------------------------------------------------------------------
# result.nc through public APIs
# --------------------------------------------------------------------------------------------

def test_a_built_dataset_is_saved_without_xarrays_private_store(saved_run, tmp_path,
                                                                monkeypatch):
    import xarray.backends as backends

    def refuse(*a, **k):
        raise AssertionError("xarray's private H5NetCDFStore used")

    r = load_result(saved_run)  # a Dataset, not the RunData of a fresh run
    first_id = r.summary["run_id"]
    monkeypatch.setattr(backends.H5NetCDFStore, "open", refuse)
    r.save(tmp_path / "again")
    monkeypatch.undo()  # reading goes through xarray's backend, as any reader's would
    again = load_result(tmp_path / "again")
    assert again.dataset.drop_attrs(deep=False).identical(r.dataset.drop_attrs(deep=False))
    raw = xr.open_dataset(tmp_path / "again" / "result.nc", engine="h5netcdf")
    assert raw["block_tangential_velocity"].attrs["units"] == "m s-1"
    assert raw.attrs["run_id"] == again.summary["run_id"] != first_id
    # a hand-made Dataset with text goes through the public to_netcdf
    odd = roughvib.Result(xr.Dataset({"note": ("time", np.array(["a", "b"]))},
                                     coords={"time": [0.0, 1.0]}), r.events,
                          {"format_version": 1, "status": "success"}, r.scene_toml)
    odd.save(tmp_path / "odd")
    assert list(xr.open_dataset(tmp_path / "odd" / "result.nc", engine="h5netcdf")["note"]
                .values) == ["a", "b"]


# --------------------------------------------------------------------------------------------
# a sweep stopped by SIGTERM
# --------------------------------------------------------------------------------------------

TINY = """
name = "tiny"
base = "paper"
[set]
"output.duration" = 0.003
"plate.max_frequency" = 2000.0
"solver.atol_acceleration" = 1e-5
[grid]
"roughness.seed" = [1, 2, 3, 4, 5, 6, 7, 8]
"""


@pytest.mark.parametrize(("signum", "code", "word"), [(signal.SIGTERM, 143, "terminated"),
                                                      (signal.SIGINT, 130, "interrupted")])
def test_a_sweep_stopped_by_a_signal_exits_with_one_line(tmp_path, signum, code, word):
    # SIGTERM to the command; SIGINT to its whole process group, as Ctrl-C in a terminal
    # sends it (the workers ignore it: the command stops them)
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY)
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(roughvib.__file__).parents[1]), os.environ.get("PYTHONPATH", "")])}
    # stopped while cases are queued and one is running (the cancelled tasks used to print
    # Dask worker warnings): the command sends the signal itself once the first case has
    # ended, so that it lands there however fast the cases run
    proc = start_stopping_itself(signum, "case", 1, "sweep", str(spec), "--out", str(out),
                                 "--workers", "1", "--no-progress", cwd=tmp_path,
                                 stdout=subprocess.PIPE, env=env, start_new_session=True,
                                 group=signum == signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == code, err
    assert err.strip().splitlines() == [
        f"roughvib: sweep {word}; completed cases are kept in {out}/cases, run the same "
        f"command again to resume"], err


def test_a_sweep_case_with_an_edited_summary_is_damaged_and_runs_again(saved_run, tmp_path):
    from roughvib.studies.sweep.run import _is_complete
    from roughvib.studies.sweep.spec import CASES_DIR, load_sweep
    from roughvib.studies.sweep.tables import collect_table

    spec = load_sweep({"name": "two", "base": "paper",
                       "grid": {"roughness.seed": [1, 2]}})
    a, b = (c.name for c in spec.cases())
    cases = tmp_path / CASES_DIR
    cases.mkdir()
    shutil.copytree(saved_run, cases / a)
    shutil.copytree(saved_run, cases / b)
    assert _is_complete(cases / a) and _is_complete(cases / b)
    _edit_summary(cases / b, message="edited")
    table = collect_table(spec, tmp_path).set_index("case")
    assert table.loc[a, "status"] == "success"
    assert table.loc[b, "status"] == "damaged"
    assert "was changed after the run wrote it" in table.loc[b, "message"]
    assert not _is_complete(cases / b)  # the next run of the sweep computes it again
    (cases / b / "summary.json").write_text("[]")
    assert collect_table(spec, tmp_path).set_index("case").loc[b, "status"] == "damaged"
