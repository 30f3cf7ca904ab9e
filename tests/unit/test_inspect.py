"""Inspecting runs: events, plot and report of a failed run, event kinds, the regime notation,
the integer contact column, the regime time series and the provenance in result.nc, a closed
output pipe, ``--version``, ``dir(roughvib)``."""

import base64
import dataclasses
import io
import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import roughvib
from roughvib.cli import main
from roughvib.results import EVENT_COLUMNS, EVENT_KINDS, REGIME_NOTATION, Result, load_result
from roughvib.scene import Scene, scene_to_toml

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src" / "roughvib"

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
    """Three contacts on a random surface, each lifting off on its own, 10 ms, completes.

    Not a sinusoid: the contact points sit on the surface's highest maxima, which on a
    sinusoid are whole wavelengths apart, so all contacts are in phase and must open and close
    together (adaptive-modal does; IDA split them apart by round-off at the simultaneous
    events, which this test used to take for different phases)."""
    out = tmp_path_factory.mktemp("bouncing") / "run"
    # the hand-set contact (paper-handset): the contact module would scale the stiffness with
    # the prescribed speed and change which contacts bounce apart
    assert main(["run", "paper-handset", "--out", str(out), "--quiet", *BOUNCING,
                 "--set", "contact.points=3", "--set", "roughness.kind=synthetic",
                 "--set", "excitation.velocity=0.3", "--set", "output.duration=0.01"]) == 0
    return out


def _banner(err: str, run_dir: Path) -> None:
    lines = [ln for ln in err.splitlines() if "FAILED" in ln]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"roughvib: note: {run_dir} holds a FAILED run (event_storm at t")
    assert "partial.nc" in lines[0] and "Traceback" not in err


# --------------------------------------------------------------------------------------------
# failed runs
# --------------------------------------------------------------------------------------------


def test_events_of_a_failed_run(failed_run, capsys):
    log = pd.read_csv(failed_run / "events.csv")
    assert main(["events", str(failed_run)]) == 0
    cap = capsys.readouterr()
    _banner(cap.err, failed_run)
    # the phase table counts every logged lift-off, also the one at the failure itself
    header, row, per_contact = cap.out.splitlines()
    assert header.split()[0] == "cycle"
    n_lift = int((log["kind"] == "lift_off").sum())
    assert n_lift == 2 and int(row.split()[5]) == n_lift
    assert int(row.split()[7]) == 1  # the storm guard
    assert per_contact.startswith(f"lift-offs per contact: 0: {n_lift} ")
    assert main(["events", str(failed_run), "--kind", "event_storm", "--json"]) == 0
    cap = capsys.readouterr()
    _banner(cap.err, failed_run)
    (storm,) = json.loads(cap.out)["events"]
    assert storm["kind"] == "event_storm" and storm["contact"] is None


def test_plot_of_a_failed_run(failed_run, tmp_path, capsys):
    png = tmp_path / "events.png"
    assert main(["plot", str(failed_run), "--figure", "events", "--out", str(png)]) == 0
    cap = capsys.readouterr()
    _banner(cap.err, failed_run)
    assert cap.out.strip() == str(png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5_000


def test_report_of_a_failed_run_shows_its_partial_record(failed_run, tmp_path, capsys):
    html = tmp_path / "r.html"
    assert main(["report", str(failed_run), "--out", str(html), "--dpi", "30"]) == 0
    cap = capsys.readouterr()
    _banner(cap.err, failed_run)
    text = html.read_text(encoding="utf-8")
    banner = re.findall(r"<div class='banner' role='alert'>(.*?)</div>", text, flags=re.S)
    assert len(banner) == 1 and "This run FAILED (event_storm at t = " in banner[0]
    assert text.index("class='banner'") < text.index("<h2")  # at the top of the page
    pngs = [base64.b64decode(b) for b in re.findall(r'src="data:image/png;base64,([^"]+)"',
                                                    text)]
    assert len(pngs) >= 3 and all(p[:4] == b"\x89PNG" and len(p) > 1000 for p in pngs)
    assert "id='phases'" in text and "id='last-events'" in text
    # the last-events table: contact as an integer, empty for the block-level storm
    last = text[text.index("id='last-events'"):text.index("id='phases'")]
    assert "<td>0</td>" in last and "0.0</td>" not in last and "nan" not in last.lower()


def test_failed_run_without_any_record_is_one_line(tmp_path, capsys):
    summary = {"format_version": 1, "status": "ida_error", "message": "IDA failed at t = 0",
               "scene": "paper"}
    Result(xr.Dataset(), pd.DataFrame(columns=EVENT_COLUMNS), summary,
           scene_to_toml(Scene())).save(tmp_path / "bad")
    for cmd in (["events"], ["plot", "--figure", "events"]):
        assert main([cmd[0], str(tmp_path / "bad"), *cmd[1:]]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "stopped before its first output sample" in err


# --------------------------------------------------------------------------------------------
# event kinds, regime notation, the contact column
# --------------------------------------------------------------------------------------------


def test_unknown_kind_is_one_line_listing_the_kinds(failed_run, capsys):
    assert main(["events", str(failed_run), "--kind", "stick", "--kind", "bogus"]) == 2
    cap = capsys.readouterr()
    assert cap.out == "" and len(cap.err.strip().splitlines()) == 1
    assert cap.err.startswith("roughvib: error: --kind must be one of ")
    assert cap.err.strip().endswith("got 'bogus'")
    assert all(k in cap.err for k in EVENT_KINDS)


def test_every_kind_a_solver_logs_is_documented():
    from roughvib.solvers.fixed_step import EV_KINDS

    # the contacts' transitions are the model's, the friction roots' each law module's
    sources = [SRC / "model/regimes.py", *(SRC / "physics/friction").glob("*.py")]
    text = "\n".join(p.read_text() for p in sources)
    written = set(re.findall(r'Transition\("(\w+)"', text))
    for pair in re.findall(r'"(\w+)" if regime\.stick else "(\w+)"', text):
        written |= set(pair)
    written |= set(EV_KINDS) | {"event_storm"}
    assert "event_storm" in (SRC / "solvers/events.py").read_text()
    assert written == set(EVENT_KINDS)


def test_events_help_explains_kinds_and_regime_notation(capsys):
    with pytest.raises(SystemExit):
        main(["events", "--help"])
    out = capsys.readouterr().out
    assert REGIME_NOTATION in out and "closed=1111011111 b=+1 s=-1 slip" in out
    assert all(re.search(rf"^  {k} +\S", out, flags=re.M) for k in EVENT_KINDS)


def test_docs_explain_every_kind_and_the_notation():
    text = (ROOT / "docs" / "events.md").read_text()
    for kind in EVENT_KINDS:
        assert re.search(rf"^\| `{kind}` \| \S", text, flags=re.M), kind
    for token in ("closed=1111011111 b=+1 s=-1 slip", "closed=111 slip+", "`b=`", "`s=`",
                  "contact_closed", "stick(time)", "scene_toml", "solver_<key>"):
        assert token in text, token
    assert "docs/events.md" in (ROOT / "README.md").read_text()
    assert "events.md" in (ROOT / "docs" / "quickstart.md").read_text()


def test_events_csv_contact_is_an_integer_column(bouncing_run, failed_run):
    for run in (bouncing_run, failed_run):
        raw = pd.read_csv(run / "events.csv", dtype=str, keep_default_na=False)
        contact = raw["contact"]
        block = raw["kind"].isin(["stick", "slip", "event_storm", "latch_flip",
                                  "friction_branch"])
        assert (contact[block] == "").all()
        assert contact[~block].str.fullmatch(r"\d+").all() and (~block).any()
        ev = load_result(run, partial=True).events
        assert ev["contact"].dtype == "Int64"
        assert ev["contact"].isna().tolist() == block.tolist()


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


# --------------------------------------------------------------------------------------------
# pipes, version, public names
# --------------------------------------------------------------------------------------------


def test_closed_output_pipe_ends_quietly(failed_run):
    """``roughvib events DIR --json | head -1``: the reader is gone before roughvib writes."""
    r, w = os.pipe()
    os.close(r)  # the reader went away early
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    try:
        p = subprocess.run([sys.executable, "-m", "roughvib", "events", str(failed_run),
                            "--json"], stdout=w, stderr=subprocess.PIPE, text=True, env=env,
                           timeout=300)
    finally:
        os.close(w)
    assert p.returncode == 141, p.stderr
    assert "Traceback" not in p.stderr and "BrokenPipe" not in p.stderr


def test_broken_pipe_while_writing_is_handled(failed_run, monkeypatch, capsys):
    class Gone(io.StringIO):
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(sys, "stdout", Gone())
    assert main(["events", str(failed_run), "--json"]) == 141


def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"roughvib {roughvib.__version__}"
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project.get("version", roughvib.__version__) == roughvib.__version__


def test_dir_lists_the_public_api():
    names = dir(roughvib)
    assert set(roughvib.__all__) <= set(names) and "simulate" in names
    for name in roughvib.__all__:
        assert getattr(roughvib, name) is not None
