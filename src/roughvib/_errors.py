"""The error of a failed write, for every stage that writes files.

A leaf (stage 0), so that the solvers (a checkpoint) can raise the same one-line
:class:`WriteError` as the run directory and the commands. Its public home is
:mod:`roughvib.rundir`, which imports and documents these names.
"""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

__all__ = ["WriteError", "format_bytes", "free_space", "write_failed"]


class WriteError(OSError):
    """A file could not be written: a full disk, a read-only file system, an I/O error.

    The message is one line naming the path and why, for a full disk also the space needed and
    free (exit status 1, as for a run that fails). A subclass of :class:`OSError`, so that code
    catching the error of the write itself still does; ``errno`` is the failed write's.
    """

    def __init__(self, message: str, errno_: int | None = None):
        super().__init__(message)
        self.errno = errno_


#: errno values that mean "no room": a full file system or a full quota
_NO_ROOM = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})


def format_bytes(n: float) -> str:
    """A size in bytes as a short text with a decimal unit (``4.23 MB``)."""
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{int(n)} bytes"


def free_space(path: str | os.PathLike) -> int | None:
    """Bytes this process may still write on the file system of ``path``.

    Parameters
    ----------
    path : path
        A file or directory; where it does not exist yet, its nearest existing parent.

    Returns
    -------
    int or None
        ``shutil.disk_usage(...).free`` [bytes]; None where the file system does not say.
    """
    p = Path(os.path.abspath(path))
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return shutil.disk_usage(p).free
    except OSError:
        return None


def write_failed(path: str | os.PathLike, exc: OSError, need: int | None = None,
                 what: str | None = None, *, approx: bool = False) -> WriteError:
    """The one-line :class:`WriteError` for a failed write of ``path``.

    Parameters
    ----------
    path : path
        The file or directory as the user knows it (named in the message).
    exc : OSError
        The error of the write; its reason (``strerror``) is named, not its traceback.
    need : int, optional
        Bytes the write needed: named with the free space when the file system is full.
    what : str, optional
        What was written, if not the path itself (``"the run's files"``).
    approx : bool
        ``need`` is an estimate ("about ... needed").

    Returns
    -------
    WriteError
    """
    if isinstance(exc, WriteError):
        return exc
    why = exc.strerror or " ".join(str(exc).split())[:160] or type(exc).__name__
    text = f"cannot write {what + ' into ' if what else ''}{path}: {why}"
    if exc.errno in _NO_ROOM:
        free = free_space(path)
        room = [f"{'about ' if approx else ''}{format_bytes(need)} needed"
                if need is not None else "",
                f"{format_bytes(free)} free" if free is not None else ""]
        room = [r for r in room if r]
        text += f" ({', '.join(room)})" if room else ""
        text += "; free some space or write elsewhere"
    return WriteError(text, exc.errno)


# documented, and imported by users, as roughvib.rundir.<name>
for _public in (WriteError, format_bytes, free_space, write_failed):
    _public.__module__ = "roughvib.rundir"
del _public
