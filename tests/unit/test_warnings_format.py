"""What a user sees of warnings: on the command line one line each, ``roughvib: warning: ...``,
no source path, each once per command; in the library Python warnings, each once per call,
pointing at the caller's own line."""

import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
# a scene far shorter than its run-in and than one period: two validity warnings, cheap
SHORT = ["--set", "output.duration=0.01", "--set", "plate.max_frequency=2000"]
LINE = re.compile(r"roughvib: warning: \S[^\n]*")


def _cli(args, cwd):
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    p = subprocess.run([sys.executable, "-m", "roughvib", *args], cwd=cwd, env=env,
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    return p.stderr


def _warning_lines(stderr: str) -> list[str]:
    lines = [ln for ln in stderr.splitlines() if "warn" in ln.lower()]
    for ln in lines:
        assert LINE.fullmatch(ln), f"not one 'roughvib: warning:' line: {ln!r}"
        assert ".py:" not in ln and "Warning:" not in ln, ln  # no source path, no class name
    assert len(lines) == len(set(lines)), f"a warning shown twice:\n{stderr}"
    return lines


def _is_short_scene_pair(lines: list[str]) -> bool:
    return (len(lines) == 2
            and any("output.transient (0.142857 s) is not shorter than output.duration (0.01 s)"
                    in ln for ln in lines)
            and any("the analysis window (0.01 s) is shorter than one excitation period" in ln
                    for ln in lines))


def test_run_verify_shows_each_warning_once(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    err = _cli(["run", "paper", "--out", "r", "--verify", "--no-progress", "--quiet", *SHORT],
               tmp_path)
    assert _is_short_scene_pair(_warning_lines(err)), err


def test_compare_shows_the_scene_warnings_once(tmp_path, monkeypatch):
    # every run of the study (in a worker process) repeats the scene's warnings, and the
    # 20-step warm-up runs have warnings of their own: the user sees the scene's, once each
    monkeypatch.chdir(tmp_path)
    err = _cli(["compare", "paper", "--out", "wp", "--budget", "300", "--methods",
                "adaptive-modal,exact-modal", "--rtols", "1e-3", "--steps", "2e-5",
                "--no-presets", "--reference-rtol", "1e-4", "--no-progress", *SHORT], tmp_path)
    assert _is_short_scene_pair(_warning_lines(err)), err
    assert (tmp_path / "wp" / "work_precision.csv").exists()


def test_warning_line_is_one_line():
    from roughvib.cli import _warning_line
    from roughvib.scene import ModelValidityWarning

    assert _warning_line("a\n  b", ModelValidityWarning) == "roughvib: warning: a b"
    assert (_warning_line("overflow in exp", RuntimeWarning)
            == "roughvib: warning: RuntimeWarning: overflow in exp")


def test_library_warns_once_at_the_callers_line(tmp_path, monkeypatch):
    import roughvib
    from roughvib.scene import ModelValidityWarning

    monkeypatch.chdir(tmp_path)
    scene = roughvib.load_scene("paper", {"output.duration": 0.01, "plate.max_frequency": 2000.0,
                                          "output.progress": False})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # no help from Python's once-per-place memory
        result = roughvib.simulate(scene, verify=True)  # two assemblies, one set of warnings
    assert result.ok and result.summary["accuracy"]["verification"]["status"] == "success"
    ours = [w for w in caught if issubclass(w.category, ModelValidityWarning)]
    assert sorted(str(w.message) for w in ours) == sorted(result.summary["warnings"])
    assert len(ours) == 2
    assert all(Path(w.filename) == Path(__file__) for w in ours)  # this file, not roughvib's


@pytest.mark.parametrize("duration", [0.3, 2 / 7])
def test_readme_durations_do_not_warn(duration):
    # the analysis window is what follows the one-period run-in (output.transient = 1/7 s):
    # 0.2 s leaves 0.057 s, less than a period; 0.3 s and 2/7 s leave at least one
    import roughvib
    from roughvib.scene import validity_warnings

    assert validity_warnings(roughvib.load_scene("paper", **{"output.duration": 0.2}))
    assert validity_warnings(roughvib.load_scene("paper", **{"output.duration": duration})) == []
