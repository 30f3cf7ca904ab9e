"""Shared by every test.

- The on-disk cache of preprocessing results (roughvib._cache) lives in a fresh directory of the
  test session, so that no test reads or writes the user's cache and each session starts from an
  empty one (subprocesses inherit the setting).
- Every test runs in its own temporary directory (:func:`_own_directory`), so that no test
  depends on, or writes into, the directory pytest was started from: a ``runs/`` left there by
  ``roughvib run`` (README's first command) changes nothing.
- The session checks that claim: it lists the files below the start directory before the first
  test and after the last, and fails the run, naming the files, if a test added, changed or
  removed one (caches of Python and numba excepted).
"""

import os
import shutil
import tempfile
from pathlib import Path

import pytest

_saved = {}

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
    _saved["dir"] = os.environ.get("ROUGHVIB_CACHE_DIR")
    _saved["tmp"] = tempfile.mkdtemp(prefix="roughvib-test-cache-")
    os.environ["ROUGHVIB_CACHE_DIR"] = _saved["tmp"]
    _saved["start"] = Path.cwd()
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


def pytest_sessionfinish(session, exitstatus):
    before, after = _saved.get("before"), _snapshot(_saved["start"])
    if before is None:
        return
    touched = sorted(set(before) ^ set(after)
                     | {p for p in set(before) & set(after) if before[p] != after[p]})
    if touched:
        shown = ", ".join(touched[:10]) + (f" and {len(touched) - 10} more"
                                            if len(touched) > 10 else "")
        print(f"\nERROR: tests changed files in the directory pytest was started from "
              f"({_saved['start']}): {shown}")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


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
