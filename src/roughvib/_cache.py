"""An on-disk cache of preprocessing results, keyed by everything they depend on.

Some preprocessing steps cost a run far more than their result's size: the force calibration
(T0) integrates the tangential model about ten times, and the statistical contact, the plate's
residual compliance and the profile's spline interpolant need scipy's special functions, root
finder and splines, whose imports alone take longer than the rest of a short run's set-up
(docs/performance.md, "Fixed cost of a run"). Each such result is stored once per distinct
input in the user's cache directory and read back by every later run, sweep case or process.

Correctness:

* **exact**: values are stored as float64 arrays in an ``.npz`` file (no text conversion), so a
  hit returns the very numbers the computation returned and the run is bit-identical to one
  without the cache;
* **keyed by everything the result depends on**: the inputs (a JSON object, floats written
  exactly; large arrays by their SHA-256), the source files of the code that computes it
  (SHA-256 of their bytes, so any edit invalidates), and the versions of Python, numpy,
  scipy, numba and llvmlite and the platform. The file name is the SHA-256 of all of these;
  the file repeats them and a lookup compares them, so a hash collision cannot return a wrong
  value;
* **safe under concurrency**: a file is written under a temporary name in the same directory
  and renamed into place (atomic on POSIX and Windows), so concurrent sweep workers see either
  no file or a complete one; two writers of the same key write the same content;
* **never fatal**: a missing, unreadable, truncated, corrupt or foreign file, or values that
  are not finite, count as a miss (the value is recomputed and the file rewritten); a
  directory that cannot be created or written only costs the saving;
* **bounded**: each kind keeps at most :data:`MAX_BYTES` of files; the least recently used go
  first.

Location: ``$ROUGHVIB_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/roughvib`` (default
``~/.cache/roughvib``; ``~/Library/Caches/roughvib`` on macOS, ``%LOCALAPPDATA%\\roughvib`` on
Windows). ``ROUGHVIB_CACHE=off`` (or ``0``, ``no``, ``false``) switches it off: every value is
computed and nothing is read or written. Deleting the directory is always safe.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import platform
import sys
import tempfile
from collections.abc import Callable, Iterable
from importlib import import_module
from pathlib import Path

import numpy as np

__all__ = ["CACHE_DIR_ENV", "CACHE_ENV", "MAX_BYTES", "array_digest", "cache_dir",
           "cached_arrays", "cached_values", "code_fingerprint", "library_versions"]

#: environment variable that switches the cache off (``off``, ``0``, ``no``, ``false``)
CACHE_ENV = "ROUGHVIB_CACHE"
#: environment variable naming the cache directory
CACHE_DIR_ENV = "ROUGHVIB_CACHE_DIR"
#: layout of the cache files; a change makes every older file a miss
FORMAT = 1
#: most bytes kept per kind of result (least recently used files are deleted beyond it)
MAX_BYTES = 256 * 2**20
_KEY = "__key__"


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
    try:
        if given:
            return Path(given).expanduser()
        if sys.platform == "win32":
            base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
        elif sys.platform == "darwin":
            base = Path.home() / "Library" / "Caches"
        else:
            base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    except RuntimeError:  # no home directory (e.g. a batch job without HOME): no cache
        return None
    return base / "roughvib"


def code_fingerprint(files: Iterable[str | os.PathLike]) -> dict | None:
    """What, besides its inputs, decides a cached value: the code and the libraries.

    Parameters
    ----------
    files : iterable of path
        Source files of the code that computes the value (their SHA-256 enters the key).

    Returns
    -------
    dict or None
        JSON-ready: ``sources`` (file name -> SHA-256), ``python``, ``platform`` and the
        versions of numpy, scipy, numba and llvmlite. None if a source file cannot be read
        (e.g. a package inside a zip file): then the cache is not used, since a change of
        the code could not be detected.
    """
    sources = {}
    try:
        for f in files:
            p = Path(f)
            sources[p.name] = hashlib.sha256(p.read_bytes()).hexdigest()
    except OSError:
        return None
    return {"sources": sources, "python": platform.python_version(),
            "platform": f"{sys.platform}-{platform.machine()}", **library_versions()}


@functools.cache
def library_versions() -> dict[str, str]:
    """Versions of the numerical libraries whose change can change a computed number.

    Returns
    -------
    dict of str to str
        ``numpy``, ``scipy``, ``numba`` and ``llvmlite`` -> ``__version__`` (the top-level
        packages only: numba has imported them all; scipy's submodules alone cost ~30 ms).
    """
    return {name: import_module(name).__version__
            for name in ("numpy", "scipy", "numba", "llvmlite")}


def array_digest(a: np.ndarray) -> str:
    """Stand-in for a large input array in a cache key: dtype, shape and SHA-256 of its bytes."""
    a = np.ascontiguousarray(a)
    return f"{a.dtype.str}{list(a.shape)}:{hashlib.sha256(a.tobytes()).hexdigest()}"


def _canonical(record: dict) -> str:
    return json.dumps(record, sort_keys=True)  # floats as repr: exact


def _read(path: Path, record: dict) -> dict[str, np.ndarray] | None:
    """The arrays of a cache file if it is complete, finite and belongs to ``record``."""
    try:
        with np.load(path, allow_pickle=False) as f:
            if str(f[_KEY][()]) != _canonical(record):
                return None  # another input under the same name (a hash collision)
            arrays = {name: f[name] for name in f.files if name != _KEY}
    except Exception:  # noqa: BLE001 - missing, truncated, not a zip, not ours: a miss
        return None
    if not arrays or not all(a.dtype.kind in "fiub" and np.all(np.isfinite(a))
                             for a in arrays.values()):
        return None
    try:
        os.utime(path)  # recently used: kept longest when the kind outgrows MAX_BYTES
    except OSError:
        pass
    return arrays


def _prune(directory: Path, keep: Path) -> None:
    """Delete the least recently used files of a kind beyond :data:`MAX_BYTES`."""
    try:
        files = [(p.stat().st_mtime, p.stat().st_size, p) for p in directory.glob("*.npz")]
    except OSError:
        return
    total = sum(size for _, size, _ in files)
    for _, size, p in sorted(files):
        if total <= MAX_BYTES:
            break
        if p != keep:
            try:
                p.unlink()
                total -= size
            except OSError:
                pass


def _write(path: Path, record: dict, arrays: dict[str, np.ndarray]) -> bool:
    """Write a cache file atomically; False if it could not be written (never raises)."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".npz")
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **{_KEY: np.array(_canonical(record))}, **arrays)
        os.replace(tmp, path)
    except Exception:  # noqa: BLE001 - full disk, permissions, anything: only the saving is lost
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        return False
    _prune(path.parent, keep=path)
    return True


def cached_arrays(kind: str, inputs: dict, compute: Callable[[], dict[str, np.ndarray]], *,
                  code: dict | None) -> tuple[dict[str, np.ndarray], str]:
    """Arrays of ``compute()`` for these inputs: from the cache, or computed and stored.

    Parameters
    ----------
    kind : str
        Name of the computation (a subdirectory of the cache).
    inputs : dict
        Every input of the computation, JSON-ready (str, int, float, bool, None, lists; an
        array through :func:`array_digest`).
    compute : callable
        ``compute() -> dict[str, ndarray]`` (numeric arrays), called on a miss.
    code : dict or None
        :func:`code_fingerprint` of the computation (None: the cache is not used).

    Returns
    -------
    arrays : dict of str to ndarray
        Exactly what ``compute()`` returns (or returned when the entry was stored).
    status : {"hit", "miss", "off"}
        Read from the cache; computed (and stored if the directory is writable); computed
        with the cache switched off (or without a home directory or readable sources).
    """
    directory = cache_dir()
    if directory is None or code is None:
        return compute(), "off"
    record = {"format": FORMAT, "kind": kind, "inputs": inputs, "code": code}
    digest = hashlib.sha256(_canonical(record).encode()).hexdigest()
    path = directory / kind / f"{digest}.npz"
    got = _read(path, record)
    if got is not None:
        return got, "hit"
    arrays = {name: np.asarray(a) for name, a in compute().items()}
    _write(path, record, arrays)
    return arrays, "miss"


def cached_values(kind: str, inputs: dict, compute: Callable[[], dict[str, float]], *,
                  code: dict | None) -> tuple[dict[str, float], str]:
    """:func:`cached_arrays` for a few floats: ``compute() -> dict[str, float]``.

    Returns
    -------
    values : dict of str to float
        Exactly the floats ``compute()`` returns.
    status : {"hit", "miss", "off"}
    """
    def as_arrays() -> dict[str, np.ndarray]:
        return {name: np.float64(v) for name, v in compute().items()}

    arrays, status = cached_arrays(kind, inputs, as_arrays, code=code)
    return {name: float(a) for name, a in arrays.items()}, status
