"""Shared by every test: the on-disk cache of preprocessing results (roughvib._cache) lives in
a fresh directory of the test session, so that no test reads or writes the user's cache and
each session starts from an empty one (subprocesses inherit the setting)."""

import os
import shutil
import tempfile

_saved = {}


def pytest_configure(config):
    _saved["dir"] = os.environ.get("ROUGHVIB_CACHE_DIR")
    _saved["tmp"] = tempfile.mkdtemp(prefix="roughvib-test-cache-")
    os.environ["ROUGHVIB_CACHE_DIR"] = _saved["tmp"]


def pytest_unconfigure(config):
    if _saved.get("dir") is None:
        os.environ.pop("ROUGHVIB_CACHE_DIR", None)
    else:
        os.environ["ROUGHVIB_CACHE_DIR"] = _saved["dir"]
    if _saved.get("tmp"):
        shutil.rmtree(_saved["tmp"], ignore_errors=True)
