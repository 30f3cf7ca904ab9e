"""Tests never depend on, or write into, the directory pytest was started from."""

import re
import subprocess
import sys
import textwrap
from pathlib import Path


def test_each_test_starts_in_its_own_empty_directory(tmp_path):
    assert Path.cwd() == tmp_path
    assert list(tmp_path.iterdir()) == []


def test_a_test_that_writes_into_the_start_directory_fails_the_session(tmp_path):
    """The session's check of the start directory catches a test that escapes its own one."""
    start = tmp_path / "clone"
    (start / "tests").mkdir(parents=True)
    conftest = Path(__file__).resolve().parents[1] / "conftest.py"
    (start / "tests" / "conftest.py").write_text(conftest.read_text())
    (start / "tests" / "test_escape.py").write_text(textwrap.dedent(f"""
        from pathlib import Path

        def test_escapes():
            Path({str(start)!r}, "runs").mkdir()
            (Path({str(start)!r}) / "runs" / "left.txt").write_text("x")
        """))
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "tests"], cwd=start, capture_output=True, text=True, timeout=120)
    assert done.returncode != 0
    assert "changed files in the directory pytest was started from" in done.stdout
    # the file, when it was written against the session, and that the writer may be another
    # process than the tests (a roughvib command run in that directory meanwhile)
    assert re.search(r"\n  runs/left\.txt: added, modified \d\d:\d\d:\d\d, \d+ s into the "
                     r"session\n", done.stdout), done.stdout
    assert "another process wrote these files" in done.stdout
