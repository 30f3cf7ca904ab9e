"""CLI contract (exit codes, messages, files) and the result files (units, round trip)."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from roughvib.cli import main
from roughvib.results import VARIABLES, load_result

ROOT = Path(__file__).resolve().parents[2]
SHORT = ["--set", "output.duration=0.004", "--set", "plate.max_frequency=3000",
         "--set", "output.progress=false"]


def test_readme_has_two_setup_commands_and_ci_runs_both_in_order():
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```bash\n(.*?)\n```", text, flags=re.S)
    run_cmd, test_cmd = blocks[0].strip(), blocks[1].strip()
    assert "roughvib run" in run_cmd and "pip install -e ." in run_cmd
    assert "pytest" in test_cmd and "[test]" in test_cmd
    head = text.split("## ")[0]
    assert head.count("```bash") == 2
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    # CI runs the first command, then the second, in the same clone, as a newcomer does
    assert run_cmd in ci and test_cmd in ci
    assert ci.index(run_cmd) < ci.index(test_cmd)


def test_scenes_command_lists_builtins(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("paper ")
    assert any(line.startswith("paper-heavy-100mms") for line in out)


def test_every_command_has_help_with_an_example(capsys):
    for cmd in (["--help"], ["run", "--help"], ["scenes", "--help"], ["events", "--help"],
                ["plot", "--help"], ["compare", "--help"], ["surface", "--help"],
                ["report", "--help"], ["sweep", "--help"], ["sweep-report", "--help"]):
        with pytest.raises(SystemExit) as info:
            main(cmd)
        assert info.value.code == 0
        assert "example" in capsys.readouterr().out


@pytest.mark.parametrize("args,fragment", [
    (["run", "--set", "plate.thickness=-0.003"], "plate.thickness must be > 0 m, got -0.003"),
    (["run", "--set", "block.colour=1"], "block.colour is not a known key of [block]"),
    (["run", "no-such-scene"], "neither a built-in scene"),
    (["run", "--set", "block.mass"], "--set expects section.key=value"),
    (["events", "no/such/dir"], "not a roughvib result directory"),
    (["run", "--set", "roughness.kind=file", "--set", "roughness.path=no_such_trace.txt"],
     "no_such_trace.txt"),
    (["surface", "--set", "contact.model=jkr"], "contact.model"),
])
def test_bad_input_exits_2_with_one_line(args, fragment, capsys, tmp_path):
    extra = ["--out", str(tmp_path / "x")] if args[0] == "run" else []
    assert main(args + extra) == 2
    err = capsys.readouterr().err.strip()
    assert fragment in err and "Traceback" not in err and len(err.splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_bad_scene_file_via_subprocess_has_no_traceback(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text("[plate]\nthickness = -1\n")
    p = subprocess.run([sys.executable, "-m", "roughvib.cli", "run", str(f)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert p.stderr.strip() == "roughvib: error: plate.thickness must be > 0 m, got -1"


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "paper"
    assert main(["run", "--out", str(out), "--quiet", *SHORT]) == 0
    return out


def test_run_writes_self_describing_files(run_dir):
    for name in ("result.nc", "events.csv", "summary.json", "scene.toml"):
        assert (run_dir / name).exists()
    ds = xr.open_dataset(run_dir / "result.nc")
    for name, (units, _) in VARIABLES.items():
        assert ds[name].attrs["units"] == units
    assert ds["time"].attrs["units"] == "s"
    assert ds["contact_force"].dims == ("time", "contact")
    assert "positive downward" in ds.attrs["convention"]
    np.testing.assert_allclose(np.diff(ds["time"].values), 1e-5, rtol=1e-9)
    ds.close()
    ev = pd.read_csv(run_dir / "events.csv")
    assert list(ev.columns[:3]) == ["time", "kind", "contact"]
    summary = json.loads((run_dir / "summary.json").read_text())
    for key in ("steps", "residual_evaluations", "jacobian_evaluations", "restarts",
                "wall_time"):
        assert key in summary["solver"]
    assert summary["status"] == "success"
    assert summary["force_amplitude"] > 0
    assert "energy_audit" in summary and "events_by_kind" in summary


def test_resolved_scene_repeats_the_run(run_dir, tmp_path):
    """scene.toml carries the calibrated T0: running it again gives the same result."""
    text = (run_dir / "scene.toml").read_text()
    assert "calibrated for target_rms_velocity" in text
    again = tmp_path / "again"
    assert main(["run", str(run_dir / "scene.toml"), "--out", str(again), "--quiet"]) == 0
    a = xr.open_dataset(run_dir / "result.nc")
    b = xr.open_dataset(again / "result.nc")
    np.testing.assert_array_equal(a["block_vertical_acceleration"].values,
                                  b["block_vertical_acceleration"].values)
    a.close()
    b.close()


def test_load_result_round_trip(run_dir):
    r = load_result(run_dir)
    assert r.ok
    assert r.to_dataset()["normal_force"].attrs["units"] == "N"
    assert len(r.events) == len(pd.read_csv(run_dir / "events.csv"))


def test_load_result_rejects_other_versions(tmp_path):
    (tmp_path / "summary.json").write_text(json.dumps({"format_version": 99}))
    with pytest.raises(ValueError, match="format version 99 is not supported"):
        load_result(tmp_path)
    with pytest.raises(FileNotFoundError, match="not a roughvib result directory"):
        load_result(tmp_path / "nothing")


def test_failed_run_exits_1_and_writes_nothing_partial(tmp_path, capsys):
    """An event storm (guard at 2 events) fails cleanly: summary.json with status, no nc."""
    out = tmp_path / "fail"
    code = main(["run", "--out", str(out), "--quiet",
                 "--set", "plate.kind=rigid", "--set", "contact.points=1",
                 "--set", "roughness.kind=sinusoid", "--set", "roughness.amplitude=10e-6",
                 "--set", "roughness.wavelength=0.5e-3", "--set", "excitation.kind=prescribed",
                 "--set", "excitation.velocity=0.1", "--set", "excitation.amplitude=0.0",
                 "--set", "excitation.target_rms_velocity=none",
                 "--set", "solver.max_events=2", "--set", "solver.event_window=0.1",
                 "--set", "output.duration=0.03", "--set", "output.progress=false"])
    assert code == 1
    err = capsys.readouterr().err
    assert "event storm" in err and "Hint" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "event_storm"
    assert "more than 2 events" in summary["message"]
    assert not (out / "result.nc").exists()
    assert not any(p.name.startswith(".fail.tmp") for p in tmp_path.iterdir())
    # nothing lost: the time series up to the failure and the whole event log are kept
    part = load_result(out, partial=True)
    t_end = float(part.dataset["time"].values[-1])
    storm = part.events[part.events["kind"] == "event_storm"]
    assert len(storm) == 1 and t_end <= float(storm["time"].iloc[0]) + 1e-5
    assert np.all(np.isfinite(part.dataset["normal_force"].values))
    assert part.dataset.attrs["status"] == "event_storm"
    assert load_result(out).dataset.sizes.get("time", 0) == 0  # default: no series


def test_progress_on_stderr_into_a_log_file_is_whole_lines(tmp_path):
    """stderr is a file here (a batch job's log): a few complete lines, no bar redraws."""
    log = tmp_path / "run.log"
    with open(log, "w") as err:
        p = subprocess.run([sys.executable, "-m", "roughvib.cli", "run", "--out",
                            str(tmp_path / "p"), "--quiet", "--set", "output.duration=0.004",
                            "--set", "plate.max_frequency=3000"],
                           stdout=subprocess.PIPE, stderr=err, text=True, timeout=300)
    text = log.read_text()
    assert p.returncode == 0, text
    assert p.stdout == "" and "\r" not in text and text.endswith("\n")
    # the short run also draws validity warnings (one line each): the progress is the rest
    lines = [ln for ln in text.splitlines() if not ln.startswith("roughvib: warning: ")]
    assert 1 <= len(lines) <= 12 and all(" s sim (" in ln for ln in lines)
    assert lines[-1].startswith("roughvib paper: 0.0040/0.0040 s sim (100 %)")


def test_quickstart_example_runs(tmp_path):
    p = subprocess.run([sys.executable, str(ROOT / "examples" / "01_quickstart.py"),
                        str(tmp_path / "q")], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert "status: success" in p.stdout
    assert (tmp_path / "q" / "result.nc").exists()
