"""Shared by every test.

- The on-disk cache of preprocessing results (roughvib._cache) lives in a fresh directory of the
  test session, so that no test reads or writes the user's cache and each session starts from an
  empty one (subprocesses inherit the setting).
- Every test runs in its own temporary directory (:func:`_own_directory`), so that no test
  depends on, or writes into, the directory pytest was started from: a ``runs/`` left there by
  ``roughvib run`` (README's first command) changes nothing.
- The session checks that claim: it lists the files below the start directory before the first
  test and after the last, and fails the run if a file was added, changed or removed meanwhile
  (caches of Python and numba excepted). It names each file with when it was written, against
  the session's start and end: the writer may be another process (a ``roughvib`` command run in
  that directory in a second terminal during the session), which the check cannot tell from a
  test.
- The marker ``short_run``: a test that runs scenes shorter than the run-in plus one excitation
  period on purpose (to be fast, or to look at the start of a run) expects the two
  ``ModelValidityWarning``s that say so, and they are not shown for it. Every other warning
  still shows, and these two do for any test without the marker.
"""

import os
import shutil
import tempfile
import time
from pathlib import Path

import pytest

_saved = {}

#: the warnings a run shorter than the paper's analysis issues (``filterwarnings`` syntax: the
#: message is a regular expression matched at its start)
SHORT_RUN_WARNINGS = (
    r"ignore:the analysis window \(.*\) is shorter than one excitation period"
    r":roughvib.scene.ModelValidityWarning",
    r"ignore:output\.transient \(.*\) is not shorter than output\.duration"
    r":roughvib.scene.ModelValidityWarning",
)

#: folders below the start directory that tests may legitimately change: interpreter and
#: numba caches next to the sources, pytest's own cache, build output of the docs
_VOLATILE_DIRS = frozenset({"__pycache__", ".pytest_cache", ".git", "_build", ".ruff_cache"})


def _snapshot(root: Path) -> dict[str, tuple[int, int]]:
    """Every file below ``root`` outside the volatile folders: relative path -> (size, mtime)."""
    files = {}
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames
                       if d not in _VOLATILE_DIRS and not d.endswith(".egg-info")]
        for name in filenames:
            path = Path(dirpath, name)
            try:
                st = path.stat()
            except OSError:
                continue
            files[str(path.relative_to(root))] = (st.st_size, st.st_mtime_ns)
    return files


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "short_run: the test runs scenes shorter than the run-in plus one excitation "
        "period on purpose; the two ModelValidityWarnings that say so are expected (not shown)")
    _saved["dir"] = os.environ.get("ROUGHVIB_CACHE_DIR")
    _saved["tmp"] = tempfile.mkdtemp(prefix="roughvib-test-cache-")
    os.environ["ROUGHVIB_CACHE_DIR"] = _saved["tmp"]
    _saved["start"] = Path.cwd()
    _saved["t_start"] = time.time()
    _saved["before"] = _snapshot(_saved["start"])
    # hypothesis keeps its caches (constants, unicode data) and example database in
    # ./.hypothesis unless told: its storage goes to the session's temporary directory
    _saved["hypothesis"] = os.environ.get("HYPOTHESIS_STORAGE_DIRECTORY")
    os.environ["HYPOTHESIS_STORAGE_DIRECTORY"] = str(Path(_saved["tmp"], "hypothesis"))
    try:  # and keeps no example database at all
        from hypothesis import settings

        settings.register_profile("roughvib", database=None)
        settings.load_profile("roughvib")
    except ImportError:
        pass


def _clock(t: float) -> str:
    return time.strftime("%H:%M:%S", time.localtime(t))


def _when(mtime_ns: int, start: float, end: float) -> str:
    """When a file was written, against the session's start and end."""
    t = mtime_ns / 1e9
    if t < start:
        return f"modified {_clock(t)}, before the session (its time kept from elsewhere)"
    if t > end:
        return f"modified {_clock(t)}, after the session"
    return f"modified {_clock(t)}, {t - start:.0f} s into the session"


def _changes(before: dict, after: dict, start: float, end: float) -> list[str]:
    """One line per file added, changed or removed between the snapshots ``before`` and
    ``after`` (:func:`_snapshot`), in path order."""
    lines = []
    for path in sorted(set(before) | set(after)):
        if path not in after:
            lines.append(f"{path}: removed")
        elif path not in before:
            lines.append(f"{path}: added, {_when(after[path][1], start, end)}")
        elif before[path] != after[path]:
            lines.append(f"{path}: changed, {_when(after[path][1], start, end)}")
    return lines


def pytest_sessionfinish(session, exitstatus):
    before, after = _saved.get("before"), _snapshot(_saved["start"])
    if before is None:
        return
    start, end = _saved["t_start"], time.time()
    lines = _changes(before, after, start, end)
    if lines:
        shown = lines[:10] + ([f"and {len(lines) - 10} more"] if len(lines) > 10 else [])
        print(f"\nERROR: changed files in the directory pytest was started from "
              f"({_saved['start']}) during the test session ({_clock(start)} to {_clock(end)}):"
              + "".join(f"\n  {line}" for line in shown)
              + "\nEach test runs in its own temporary directory, so either a test escaped it, or "
                "another process wrote these files: if you ran roughvib (or anything else) in "
                "this directory during the session, that was the writer; run the tests again "
                "without it to tell.")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.get_closest_marker("short_run") is not None:
            for spec in SHORT_RUN_WARNINGS:
                item.add_marker(pytest.mark.filterwarnings(spec))


def pytest_unconfigure(config):
    for var, key in (("ROUGHVIB_CACHE_DIR", "dir"), ("HYPOTHESIS_STORAGE_DIRECTORY", "hypothesis")):
        if _saved.get(key) is None:
            os.environ.pop(var, None)
        else:
            os.environ[var] = _saved[key]
    if _saved.get("tmp"):
        shutil.rmtree(_saved["tmp"], ignore_errors=True)


@pytest.fixture(autouse=True)
def _own_directory(tmp_path, monkeypatch):
    """Run the test in its own empty temporary directory (``tmp_path``)."""
    monkeypatch.chdir(tmp_path)
