"""The marker ``short_run`` (tests/conftest.py) hides the two warnings of a short run for the
tests that carry it, and nothing else: any other warning of those tests shows, and the two show
for a test without the marker."""

import subprocess
import sys
import textwrap
from pathlib import Path


def _summary_blocks(stdout: str) -> list[tuple[set[str], str]]:
    """pytest's warnings summary as (the tests that issued it, the warning) per entry."""
    text = stdout.split("warnings summary", 1)[1].split("-- Docs:", 1)[0]
    blocks = []
    for block in text.strip("= \n").split("\n\n"):
        lines = block.strip().splitlines()
        tests = {ln.split("::", 1)[1] for ln in lines if ln.startswith("tests/")}
        blocks.append((tests, "\n".join(ln for ln in lines if not ln.startswith("tests/"))))
    return blocks


def test_short_run_hides_only_the_two_short_run_warnings(tmp_path):
    start = tmp_path / "clone"
    (start / "tests").mkdir(parents=True)
    conftest = Path(__file__).resolve().parents[1] / "conftest.py"
    (start / "tests" / "conftest.py").write_text(conftest.read_text())
    (start / "tests" / "test_warns.py").write_text(textwrap.dedent("""
        import warnings

        import pytest

        import roughvib
        from roughvib.scene import ModelValidityWarning, validity_warnings

        def _short_run_and_another_warning(name):
            # the notes of a scene as short as the tests run, issued as a run issues them
            notes = validity_warnings(roughvib.load_scene("paper", {"output.duration": 0.05}))
            assert len(notes) == 2, notes
            for note in notes:
                warnings.warn(note, ModelValidityWarning)
            warnings.warn(f"a warning nobody expects ({name})", ModelValidityWarning)

        @pytest.mark.short_run
        def test_marked():
            _short_run_and_another_warning("marked")

        def test_unmarked():
            _short_run_and_another_warning("unmarked")
        """))
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "-n", "0", "tests"], cwd=start, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    shown = {}
    for tests, warning in _summary_blocks(done.stdout):
        for key in ("the analysis window", "output.transient", "nobody expects (marked)",
                    "nobody expects (unmarked)"):
            if key in warning:
                shown[key] = tests
    assert shown == {"the analysis window": {"test_unmarked"},
                     "output.transient": {"test_unmarked"},
                     "nobody expects (marked)": {"test_marked"},
                     "nobody expects (unmarked)": {"test_unmarked"}}, done.stdout
