"""An on-disk cache of small preprocessing results (a few floats each), keyed by their inputs.

Some preprocessing steps cost a run far more than their result's size: the force calibration
(T0) integrates the tangential model ten times to reach its target, and the statistical
contact needs scipy's special functions and root finder, which take longer to import than the
rest of the run's set-up. Each such result is stored once per distinct input in the user's cache
directory and read back by every later run, sweep case or process with the same input.

Correctness:

* **exact**: the values are stored as ``float.hex`` strings, so a hit returns the very floats the
  computation returned, and the run is bit-identical to one without the cache;
* **keyed by everything the result depends on**: the inputs (a JSON object, floats written
  exactly), the source files of the code that computes it (SHA-256 of their bytes, so any edit
  invalidates), and the versions of Python, numpy, scipy, numba and llvmlite and the machine
  architecture. The key is the SHA-256 of all of these; the file also repeats them and a
  lookup checks them, so that a hash collision cannot return a wrong value;
* **safe under concurrency**: a file is written under a temporary name in the same directory
  and renamed into place (atomic on POSIX and Windows), so concurrent sweep workers see either
  no file or a complete one; two writers of the same key write the same content;
* **never fatal**: an unreadable, corrupt or foreign file counts as a miss (the value is
  recomputed and the file rewritten), and a directory that cannot be created or written only
  costs the saving.

Location: ``$ROUGHVIB_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/roughvib`` (default
``~/.cache/roughvib``; ``~/Library/Caches/roughvib`` on macOS, ``%LOCALAPPDATA%\\roughvib`` on
Windows). ``ROUGHVIB_CACHE=off`` (or ``0``, ``no``, ``false``) disables it: every value is
computed and nothing is read or written. Deleting the directory is always safe.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import sys
import tempfile
from collections.abc import Callable, Iterable
from importlib import import_module
from pathlib import Path

__all__ = ["CACHE_ENV", "CACHE_DIR_ENV", "cache_dir", "cached_values", "code_fingerprint"]

#: environment variable that switches the cache off (``off``, ``0``, ``no``, ``false``)
CACHE_ENV = "ROUGHVIB_CACHE"
#: environment variable naming the cache directory
CACHE_DIR_ENV = "ROUGHVIB_CACHE_DIR"
#: layout of the cache files; a change makes every older file a miss
FORMAT = 1


def cache_dir() -> Path | None:
    """The cache directory, or None when the cache is switched off (:data:`CACHE_ENV`).

    Returns
    -------
    Path or None
        ``$ROUGHVIB_CACHE_DIR``, else the platform's user cache directory + ``roughvib``. It
        need not exist yet.
    """
    if os.environ.get(CACHE_ENV, "").strip().lower() in ("off", "0", "no", "false"):
        return None
    given = os.environ.get(CACHE_DIR_ENV)
    if given:
        return Path(given).expanduser()
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "roughvib"


def code_fingerprint(files: Iterable[str | os.PathLike]) -> dict:
    """What, besides its inputs, decides a cached value: the code and the libraries.

    Parameters
    ----------
    files : iterable of path
        Source files of the code that computes the value (their SHA-256 enters the key).

    Returns
    -------
    dict
        JSON-ready: ``sources`` (name -> SHA-256), ``python``, ``machine`` and the versions of
        numpy, scipy, numba and llvmlite.
    """
    sources = {}
    for f in files:
        p = Path(f)
        sources[p.name] = hashlib.sha256(p.read_bytes()).hexdigest()
    # the top-level packages only (numba has imported them all; scipy's alone costs ~30 ms)
    libs = {name: import_module(name).__version__
            for name in ("numpy", "scipy", "numba", "llvmlite")}
    return {"sources": sources, "python": platform.python_version(),
            "machine": f"{sys.platform}-{platform.machine()}", **libs}


def _canonical(record: dict) -> str:
    return json.dumps(record, sort_keys=True)  # floats as repr: exact


def _path(directory: Path, kind: str, record: dict) -> Path:
    digest = hashlib.sha256(_canonical(record).encode()).hexdigest()
    return directory / kind / f"{digest}.json"


def _read(path: Path, record: dict) -> dict[str, float] | None:
    """The values of a cache file if it is complete and belongs to ``record``, else None."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if _canonical(data["key"]) != _canonical(record):
            return None  # another input under the same name (a hash collision)
        values = {str(n): float.fromhex(v) for n, v in data["values"].items()}
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None  # missing, unreadable, not JSON, truncated, or not a cache file
    if not values or not all(math.isfinite(v) for v in values.values()):
        return None
    return values


def _write(path: Path, record: dict, values: dict[str, float]) -> bool:
    """Write a cache file atomically; False if it could not be written (never raises)."""
    text = json.dumps({"key": record, "values": {n: float(v).hex() for n, v in values.items()},
                       "readable": {n: repr(float(v)) for n, v in values.items()}},
                      sort_keys=True, indent=1)
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".json")
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
        return True
    except OSError:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        return False


def cached_values(kind: str, inputs: dict, compute: Callable[[], dict[str, float]], *,
                  code: dict) -> tuple[dict[str, float], str]:
    """Values of ``compute()`` for these inputs: from the cache, or computed and stored.

    Parameters
    ----------
    kind : str
        Name of the computation (a subdirectory of the cache).
    inputs : dict
        Every input of the computation, JSON-ready (str, int, float, bool, None, lists).
    compute : callable
        ``compute() -> dict[str, float]``, called on a miss.
    code : dict
        :func:`code_fingerprint` of the computation.

    Returns
    -------
    values : dict of str to float
        Exactly what ``compute()`` returns (or returned when the entry was stored).
    status : {"hit", "miss", "off"}
        Read from the cache; computed (and stored if the directory is writable); computed
        with the cache switched off.
    """
    directory = cache_dir()
    if directory is None:
        return {n: float(v) for n, v in compute().items()}, "off"
    record = {"format": FORMAT, "kind": kind, "inputs": inputs, "code": code}
    path = _path(directory, kind, record)
    got = _read(path, record)
    if got is not None:
        return got, "hit"
    values = {n: float(v) for n, v in compute().items()}
    _write(path, record, values)
    return values, "miss"
