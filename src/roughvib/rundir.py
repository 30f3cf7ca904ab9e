"""Run directories: where a run's files go, what a run may touch, and how they appear at once.

The rules (docs/robustness.md, "What a run may touch"):

* The output directory is checked before any work starts: a path that is a file, cannot be
  created or is not writable, a directory that another run is writing to (lock file), a
  directory holding the checkpoint of an unfinished run (unless resuming), and a non-empty
  directory that does not hold a roughvib run (unless ``overwrite``) are refused with one line
  (:class:`OutputError`).
* A run writes its files into a staging directory next to the output directory
  (``.<name>.tmp-<id>``) and renames it to the output directory when complete; an earlier
  roughvib run there is first renamed aside (``.<name>.old-<id>``) and deleted after. A
  directory rename is atomic on POSIX, so the output directory always holds one complete run
  (the earlier or the new one). A process killed between the two renames leaves no output
  directory and the earlier run aside; the next run into the directory (or
  :func:`remove_stale`) renames it back. Staging directories of killed runs are deleted.
* Where a directory swap would delete files roughvib did not write (``overwrite``), or cannot
  be done (the output directory contains the working directory, its parent is not writable),
  the run's files are renamed into the directory one by one, ``summary.json`` last; files of
  the earlier roughvib run that the new run does not write are removed first, everything else
  is kept. ``load_result`` checks every file against the list in ``summary.json``, so a
  directory that a kill left half-replaced is refused, never read as a mix.
* What is published is on disk first: every file and the staging directory are flushed
  (``fsync``) before the rename that publishes them, and the parent directory after it, so a
  power cut or a system crash cannot leave the output directory naming files whose contents
  were never written (:func:`sync_tree`).
* One run at a time per directory: an exclusive ``flock`` on ``.<name>.lock`` next to the
  output directory, released when the process ends however it ends.

The files the other commands write (``report``, ``plot``, ``export``, ``modes export``,
``surface``, ``compare``, ``sweep-report``, a sweep's tables) follow the same rules, through
:func:`output_folder`, :func:`claim_files` and :func:`write_file`: a folder that cannot be
made is one line (:class:`OutputError`); a file the user named that exists is not replaced
without ``--overwrite``; a file appears complete or not at all (written under a temporary name
next to it and renamed); a write that fails (a full disk, a read-only file system) is one line
naming the path and, for a full disk, the space needed and free (:class:`WriteError`), and
leaves no temporary file behind.
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import re
import secrets
import shutil
import socket
from datetime import UTC, datetime
from pathlib import Path

from roughvib._errors import WriteError, format_bytes, free_space, write_failed
from roughvib.scene import SceneError
from roughvib.solvers.checkpoint import CHECKPOINT_NAME

__all__ = ["OWNED_NAMES", "RUN_FILES", "DirectoryLock", "OutputError", "OutputWarning",
           "RunDirectory", "WriteError",
           "check_room", "claim_files", "free_space", "holds_run", "output_folder",
           "remove_stale", "swap_into_place", "sync_tree", "write_failed", "write_file",
           "writing"]

#: the files of a saved run (``summary.json`` lists which of them the run wrote)
#: the optional tables of a run with ``output.radiation`` (and ``output.microphones``)
RADIATION_FILE, MICROPHONES_FILE = "radiation.csv", "microphones.csv"
RUN_FILES = ("summary.json", "scene.toml", "result.nc", "partial.nc", "events.csv",
             RADIATION_FILE, MICROPHONES_FILE)
#: every name roughvib writes into a run directory (the run, its checkpoint, the report and the
#: figures of ``roughvib report`` and ``roughvib plot``, the folders of ``roughvib validate``
#: and ``roughvib export``); a directory holding a roughvib run and nothing else is replaced as
#: a whole by the next run into it
OWNED_NAMES = frozenset(RUN_FILES + (CHECKPOINT_NAME, "report.html", "figures", "validation",
                                     "export"))
_CHECKPOINT_TMP = f".{CHECKPOINT_NAME}."  # write_checkpoint's temporary files
_INSIDE = ".roughvib"  # lock and staging directory inside the output directory (read-only parent)


class OutputError(SceneError):
    """The output directory cannot be used; the message is one line (exit status 2)."""


class OutputWarning(UserWarning):
    """Something about the output directory the user should know; one line."""


def check_room(path: str | os.PathLike, need: int, what: str, *,
               shown: str | None = None) -> None:
    """Refuse, before anything is written, a write that cannot fit on its file system.

    Parameters
    ----------
    path : path
        Where the files go (a directory, or a file's folder).
    need : int
        Bytes the files will take at least.
    what : str
        What needs them, for the message (``"the run's files"``).
    shown : str, optional
        The path as the user knows it, for the message (default ``path``).

    Raises
    ------
    WriteError
        ``need`` exceeds the free space: one line naming ``path``, the space needed and free.
    """
    free = free_space(path)
    if free is not None and need > free:
        raise WriteError(f"{shown or path}: no room for {what} ({format_bytes(need)} "
                         f"needed, {format_bytes(free)} free); free some space or write "
                         f"elsewhere", errno.ENOSPC)


def output_folder(path: str | os.PathLike, option: str = "") -> Path:
    """Make the folder a command writes its files into, or refuse it in one line.

    Parameters
    ----------
    path : path
        The folder (created with its parents if missing).
    option : str
        The option that named it, for the message (``"--out"``; empty for a default folder).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OutputError
        ``path`` is a file, cannot be created (a parent is a file, a read-only file system, no
        permission) or is not writable: one line naming it and why (exit status 2, as for
        ``roughvib run --out``).
    """
    p = Path(path)
    name = f"{option} {path}" if option else str(path)
    if p.exists() and not p.is_dir():
        raise OutputError(f"{name} exists and is not a directory; give a directory for the "
                          f"files")
    if not p.is_dir():
        a = p.parent
        while not os.path.lexists(a) and a != a.parent:
            a = a.parent
        if os.path.lexists(a) and not a.is_dir():
            raise OutputError(f"{name} cannot be created: {a} is not a directory")
        try:
            p.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"{name} cannot be created: {exc.strerror or exc} "
                              f"({exc.filename or p})") from None
    if not _writable(p):
        why = ("a read-only file system" if _read_only(p) else "no permission")
        raise OutputError(f"{name} is not writable ({why})")
    return p


def _read_only(path: Path) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):  # pragma: no cover - not POSIX
        return False


def claim_files(paths, *, overwrite: bool, option: str = "--overwrite") -> None:
    """Refuse to replace files that exist, unless the user allowed it.

    A command writes only new files, or files the user allowed it to replace: a file the user
    named (``report --out notes.html``), or a file of the names a command writes into a folder
    the user named (``export --out DIR``), that already exists is refused without
    ``overwrite``. A path that is a directory is refused always.

    Parameters
    ----------
    paths : iterable of path
        The files about to be written.
    overwrite : bool
        Replace files that exist.
    option : str
        The option that allows it, for the message.

    Raises
    ------
    OutputError
        One line naming the first such path (and how many more).
    """
    paths = [Path(p) for p in paths]
    for p in paths:
        if p.is_dir():
            raise OutputError(f"{p} is a directory; give the name of a file to write")
    there = [p for p in paths if os.path.lexists(p)]
    if there and not overwrite:
        more = f" (and {len(there) - 1} more of the files to write)" if len(there) > 1 else ""
        raise OutputError(f"{there[0]} exists{more}: choose another path, or give {option} "
                          f"to replace it")


def _tmp_name(path: Path) -> Path:
    """A new name next to ``path`` for writing it: ``.<stem>.tmp-<id><suffix>``."""
    return path.with_name(f".{path.stem}.tmp-{secrets.token_hex(4)}{path.suffix}")


@contextlib.contextmanager
def writing(path: str | os.PathLike, mode: str = "w", *, encoding: str = "utf-8",
            newline: str | None = None):
    """A file object whose contents appear at ``path`` complete or not at all.

    The ``with`` block writes into memory; when it ends without an error, the bytes go to
    ``path`` through :func:`write_file` (so their size is known for the message of a full
    disk). For files of a few megabytes (reports, tables).

    Parameters
    ----------
    path : path
        The file.
    mode : {"w", "wb"}
        Text or bytes.
    encoding : str
        Of the text (mode ``"w"``).
    newline : str, optional
        As for ``open()``: None writes ``"\\n"`` as ``os.linesep``, ``""`` as it is.

    Yields
    ------
    io.StringIO or io.BytesIO

    Raises
    ------
    WriteError
        The file cannot be written: one line naming ``path``.
    """
    binary = "b" in mode
    buf = io.BytesIO() if binary else io.StringIO(newline="")
    yield buf
    if binary:
        data = buf.getvalue()
    else:
        text = buf.getvalue()
        data = (text if newline is not None else text.replace("\n", os.linesep)).encode(encoding)
    write_file(path, lambda tmp: tmp.write_bytes(data), need=len(data))


def write_file(path: str | os.PathLike, write, *, need: int | None = None) -> Path:
    """Write one file completely or not at all.

    ``write(tmp)`` writes the file's contents to ``tmp``, a new name in the same folder
    (``.<stem>.tmp-<id><suffix>``, the suffix kept for writers that go by it), which is then
    renamed to ``path``, replacing a file of that name (check with :func:`claim_files` first).

    Parameters
    ----------
    path : path
        The file.
    write : callable
        ``write(tmp: Path) -> None``.
    need : int, optional
        Bytes the file needs, for the message of a full disk.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    WriteError
        The write or the rename failed (an :class:`OSError`): one line naming ``path``; the
        temporary file is removed.
    """
    path = Path(path)
    tmp = _tmp_name(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        _unlink(tmp)  # first: the message names the space free without it
        raise write_failed(path, exc, need) from None
    finally:
        _unlink(tmp)
    return path


def _unlink(path: Path) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _writable(d: Path) -> bool:
    return os.access(d, os.W_OK | os.X_OK)


class DirectoryLock:
    """An exclusive lock file, held by one process at a time (``fcntl.flock``).

    The kernel releases the lock when the holder ends, however it ends, so a lock file left
    by a killed process does not block anybody. The file holds the holder's pid, host and
    start time, which a refused run names.

    On a file system without ``flock`` (some network file systems) the lock falls back to a
    claim file ``<lock>.held`` created exclusively (``O_EXCL``), and says so
    (:class:`OutputWarning`). A claim left by a killed process on this host (its pid is gone)
    is taken over; one from another host must be removed by hand, as the refusal says.

    Parameters
    ----------
    path : Path
        The lock file (created if needed, removed on :meth:`release`).
    target : str
        What is locked, for the message (the directory as the user gave it).
    what : str
        Who holds such locks, for the message (``"roughvib run"``, ``"sweep"``).
    """

    def __init__(self, path: Path, target: str, what: str):
        self.path = Path(path)
        self.target = target
        self.what = what
        self._fd: int | None = None
        self._claim: Path | None = None

    def acquire(self) -> DirectoryLock:
        """Take the lock or raise :class:`OutputError` naming the holder.

        Returns
        -------
        DirectoryLock
            ``self``.
        """
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX: the file's existence is the lock
            fcntl = None
        while True:
            flags = os.O_RDWR | os.O_CREAT | (os.O_EXCL if fcntl is None else 0)
            try:
                fd = os.open(self.path, flags, 0o644)
            except FileExistsError:  # pragma: no cover - not POSIX
                raise OutputError(f"{self._busy(self.path.read_text().strip())} (if no run is "
                                  f"going on, remove {self.path})") from None
            except OSError as exc:
                raise OutputError(f"{self.target} cannot be used: {exc.strerror} "
                                  f"({self.path})") from None
            if fcntl is not None:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    holder = os.read(fd, 500).decode(errors="replace").strip()
                    os.close(fd)
                    raise OutputError(self._busy(holder)) from None
                except OSError as exc:  # a file system without flock: claim file instead
                    self._fd = fd
                    try:
                        self._take_claim(exc)
                    except BaseException:
                        self._fd = None
                        os.close(fd)
                        raise
                    return self
                # the previous holder may have removed the file between our open and flock
                try:
                    same = os.path.samestat(os.fstat(fd), os.stat(self.path))
                except FileNotFoundError:
                    same = False
                if not same:
                    os.close(fd)
                    continue
            os.ftruncate(fd, 0)
            os.write(fd, self._holder_line())
            self._fd = fd
            return self

    def _holder_line(self) -> bytes:
        return f"pid {os.getpid()} on {socket.gethostname()} since {_now()}\n".encode()

    def _take_claim(self, why: OSError) -> None:
        """Hold the lock through an exclusively created claim file (no flock here)."""
        import warnings

        claim = self.path.with_name(self.path.name + ".held")
        for _ in range(3):
            try:
                fd = os.open(claim, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                try:
                    holder = claim.read_text(errors="replace").strip()
                except FileNotFoundError:  # released in between: try again
                    continue
                if not _holder_gone(holder):
                    raise OutputError(f"{self._busy(holder)} (no file locks on this file "
                                      f"system; if no run is going on, remove {claim})"
                                      ) from None
                claim.unlink(missing_ok=True)  # its holder on this host has ended
                continue
            except OSError as exc:
                raise OutputError(f"{self.target} cannot be used: {exc.strerror} ({claim})"
                                  ) from None
            try:
                os.write(fd, self._holder_line())
            finally:
                os.close(fd)
            self._claim = claim
            warnings.warn(f"{self.path.parent} has no file locks ({why.strerror or why}): "
                          f"{self.target} is locked by the claim file {claim} instead; a run "
                          f"killed on another host leaves it behind", OutputWarning,
                          stacklevel=3)
            return
        raise OutputError(f"{self.target} cannot be used: the claim file {claim} keeps "
                          f"changing hands")

    def _busy(self, holder: str) -> str:
        return (f"{self.target} is in use by another {self.what} ({holder or 'holder unknown'}); "
                f"wait for it to end or choose another directory")

    def release(self) -> None:
        """Remove the lock file and release the lock (idempotent)."""
        if self._fd is None:
            return
        try:
            if self._claim is not None:
                self._claim.unlink(missing_ok=True)
                self._claim = None
            self.path.unlink(missing_ok=True)
        finally:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> DirectoryLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _holder_gone(holder: str) -> bool:
    """Whether the process a holder line names (``pid N on HOST since ...``) has ended.

    Only a holder on this host can be checked; any other (or an unreadable line) counts as
    alive.
    """
    m = re.match(r"pid (\d+) on (\S+) ", holder + " ")
    if not m or m.group(2) != socket.gethostname():
        return False
    pid = int(m.group(1))
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # exists, owned by someone else
        return False
    return False


def _stale_pattern(prefix: str) -> re.Pattern:
    return re.compile(rf"^{re.escape(prefix)}\.(tmp|old)-[0-9a-f]{{12}}$")


def remove_stale(directory: Path, final: Path, prefix: str | None = None) -> None:
    """Clean up after killed runs: delete staging directories, restore or delete set-aside runs.

    Call it only while holding the lock of ``final``: the staging directories then belong to
    runs that ended.

    Parameters
    ----------
    directory : Path
        Where the staging directories are (the parent of ``final``).
    final : Path
        The output directory.
    prefix : str, optional
        Name prefix of the staging directories (default ``.<final name>``).
    """
    pattern = _stale_pattern(f".{final.name}" if prefix is None else prefix)
    try:
        entries = sorted(directory.iterdir())
    except OSError:
        return
    for entry in entries:
        m = pattern.match(entry.name)
        if not m:
            continue
        if m.group(1) == "old" and not final.exists():
            os.rename(entry, final)  # killed between the renames of a swap: the earlier run
        else:
            shutil.rmtree(entry, ignore_errors=True)


def _fsync(path: Path) -> None:
    """Flush one file or directory to disk (a file system that cannot is skipped silently)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:  # e.g. a directory on a file system without directory fsync
        pass
    finally:
        os.close(fd)


def sync_tree(directory: Path) -> None:
    """Flush every file under ``directory``, then its subdirectories and itself, to disk.

    A rename is atomic in the name space, not on disk: without this a system crash after the
    rename can leave the published names pointing at files whose data was never written.
    """
    for root, _dirs, files in os.walk(directory, topdown=False):
        for name in files:
            _fsync(Path(root, name))
        _fsync(Path(root))


def swap_into_place(stage: Path, final: Path) -> None:
    """Rename the complete directory ``stage`` to ``final``, replacing an earlier ``final``.

    One atomic rename when ``final`` is missing or empty; otherwise ``final`` is renamed to
    ``.<name>.old-<id>`` first and deleted after (:func:`remove_stale` restores it if the
    process dies between the two renames). ``stage`` is flushed to disk before the rename and
    the parent directory after it (:func:`sync_tree`).
    """
    sync_tree(stage)
    try:
        os.rename(stage, final)
        _fsync(final.parent)
        return
    except OSError as exc:
        if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST):
            raise
    old = final.with_name(f".{final.name}.old-{secrets.token_hex(6)}")
    os.rename(final, old)
    os.rename(stage, final)
    _fsync(final.parent)
    shutil.rmtree(old, ignore_errors=True)


def _entries(directory: Path) -> list[str]:
    """The names in a directory that count: not write_checkpoint's or our own temporaries."""
    return sorted(e for e in os.listdir(directory)
                  if not e.startswith((_CHECKPOINT_TMP, _INSIDE)))


def _summary(directory: Path) -> dict | None:
    """The roughvib summary in ``directory``, None if there is none."""
    try:
        summary = json.loads((directory / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if isinstance(summary, dict) and "format_version" in summary and "status" in summary:
        return summary
    return None


def _is_checkpoint(path: Path) -> bool:
    try:
        with path.open("rb") as fh:
            return b"roughvib-checkpoint" in fh.read(256)  # the pickle's first key, unpickled
    except OSError:
        return False


def _earlier_run(directory: Path) -> list[str]:
    """The files of the roughvib run in ``directory``: its summary, the files the summary lists
    (all standard names for a summary without a list) and a roughvib checkpoint."""
    summary = _summary(directory)
    names = []
    if summary is not None:
        files = summary.get("files")
        listed = [n for n in files if n in RUN_FILES] if isinstance(files, dict) else RUN_FILES
        names = ["summary.json", *listed]
    if _is_checkpoint(directory / CHECKPOINT_NAME):
        names.append(CHECKPOINT_NAME)
    return names


def holds_run(directory: Path) -> bool:
    """Whether ``directory`` holds a roughvib run: a roughvib ``summary.json`` or checkpoint."""
    return bool(_earlier_run(directory))


def _contains_cwd(path: Path) -> bool:
    try:
        cwd = Path.cwd()
    except OSError:
        return False
    return cwd == path or path in cwd.parents


class RunDirectory:
    """The output directory of one run: checked and locked before the run, published after.

    Use it as a context manager, or call :meth:`open` and :meth:`close`; in between, write the
    run's files into ``stage`` and call :meth:`publish`. ``Result.save`` does all of this.

    Parameters
    ----------
    path : str or path
        The output directory.
    overwrite : bool
        Accept a directory holding files roughvib did not write: they are kept, the run's files
        replace files of the same names.
    resume : bool
        The run continues the checkpoint in ``path`` (otherwise a checkpoint there refuses the
        run, so that an unfinished run is never lost).

    Attributes
    ----------
    path : Path
        The output directory (absolute, symbolic links resolved).
    stage : Path or None
        The staging directory while open and not yet published.
    replaces : bool
        The directory holds an earlier roughvib run, which the new one replaces as a whole.
    """

    def __init__(self, path: str | os.PathLike, *, overwrite: bool = False,
                 resume: bool = False):
        self.given = str(path)
        self.path = Path(os.path.realpath(path))
        self.overwrite = overwrite
        self.resume = resume
        self.stage: Path | None = None
        self.replaces = False
        self.published = False
        self._inside = False
        self._lock: DirectoryLock | None = None
        self._made: list[Path] = []

    # ---- before the run --------------------------------------------------------------
    def open(self) -> RunDirectory:
        """Check the directory, take its lock, clean up after killed runs, make the stage.

        Returns
        -------
        RunDirectory
            ``self``.

        Raises
        ------
        OutputError
            One line naming the directory and the problem.
        """
        try:
            self._check_path()
        except OSError as exc:  # anything the checks did not foresee: still one line
            raise OutputError(f"{self.given} cannot be used: {exc.strerror or exc}") from None
        p = self.path
        lock = p / f"{_INSIDE}.lock" if self._inside else p.parent / f".{p.name}.lock"
        self._lock = DirectoryLock(lock, self.given, "roughvib run").acquire()
        try:
            if self._inside:
                remove_stale(p, p, _INSIDE)
            else:
                remove_stale(p.parent, p)
            self._check_contents()
            self.stage = self._new_stage()
        except BaseException:
            self.close()
            raise
        return self

    def _check_path(self) -> None:
        p = self.path
        try:
            name_max = os.pathconf(p.anchor or "/", "PC_NAME_MAX")
        except (OSError, ValueError):  # pragma: no cover - not POSIX
            name_max = 255
        for part in p.parts[1:]:
            if len(os.fsencode(part)) > name_max:
                raise OutputError(f"{self.given} cannot be created: a name in it has "
                                  f"{len(os.fsencode(part))} bytes, the filesystem allows "
                                  f"{name_max}")
        room = name_max - len(".tmp-") - 13  # the staging directory's longer name
        if len(os.fsencode(p.name)) > room:
            raise OutputError(f"{self.given}: the directory name must have at most {room} bytes "
                              f"(the run is staged next to it under a longer name), got "
                              f"{len(os.fsencode(p.name))}")
        if p.exists() and not p.is_dir():
            raise OutputError(f"{self.given} exists and is not a directory; give a directory "
                              f"for the run's files")
        if not p.exists():
            self._make_parents()
        elif not _writable(p):
            raise OutputError(f"{self.given} is not writable")
        self._inside = p.is_dir() and not _writable(p.parent)

    def _make_parents(self) -> None:
        missing = []
        a = self.path
        while not a.exists():
            if os.path.lexists(a):
                raise OutputError(f"{self.given} cannot be created: {a} is a broken symbolic "
                                  f"link")
            missing.append(a)
            a = a.parent
        if not a.is_dir():
            raise OutputError(f"{self.given} cannot be created: {a} is a file, not a directory")
        if not _writable(a):
            raise OutputError(f"{self.given} cannot be created: {a} is not writable")
        for d in reversed(missing[1:]):  # the parents; the directory itself comes last
            try:
                d.mkdir()
            except FileExistsError:
                continue
            except OSError as exc:
                raise OutputError(f"{self.given} cannot be created: {exc.strerror} ({d})"
                                  ) from None
            self._made.append(d)

    def _check_contents(self) -> None:
        p = self.path
        if not p.is_dir():
            return
        entries = _entries(p)
        if not entries:
            return
        cp = p / CHECKPOINT_NAME
        if CHECKPOINT_NAME in entries and not self.resume:
            raise OutputError(f"{self.given} holds the checkpoint of an unfinished run: "
                              f"continue it with 'roughvib run --resume {self.given}', or "
                              f"remove {cp} to start again")
        ours = holds_run(p)
        foreign = [e for e in entries if e not in OWNED_NAMES] if ours else entries
        if foreign and not self.overwrite:
            what = ("holds files roughvib did not write" if ours else
                    "is not empty and holds no roughvib run")
            shown = ", ".join(repr(e) for e in foreign[:3]) + (", ..." if len(foreign) > 3
                                                                else "")
            raise OutputError(f"{self.given} {what} ({shown}): choose a new or empty "
                              f"directory, or give --overwrite (Python: overwrite=True) to "
                              f"write the run's files among them (files of the same names are "
                              f"replaced, the others kept)")
        self.replaces = ours

    def _new_stage(self) -> Path:
        parent, prefix = (self.path, _INSIDE) if self._inside else \
            (self.path.parent, f".{self.path.name}")
        while True:
            stage = parent / f"{prefix}.tmp-{secrets.token_hex(6)}"
            try:
                stage.mkdir()  # the umask's permissions (mkdtemp would make it 0700)
                return stage
            except FileExistsError:  # pragma: no cover - 48 random bits
                continue
            except OSError as exc:
                raise OutputError(f"{self.given} cannot be written: {exc.strerror} ({stage})"
                                  ) from None

    def require(self, need: int, what: str = "the run's files") -> None:
        """Refuse a run whose files cannot fit: :func:`check_room` on the output directory's
        file system, naming the directory as given.

        Parameters
        ----------
        need : int
            Bytes, at least (:func:`roughvib.results.expected_result_bytes`).
        what : str
            What needs them, for the message.

        Raises
        ------
        WriteError
            One line naming the directory, the space needed and the space free.
        """
        check_room(self.stage or self.path, need, what, shown=self.given)

    # ---- after the run ---------------------------------------------------------------
    def publish(self, keep: tuple[str, ...] = ()) -> list[str]:
        """Move the files written into ``stage`` into the output directory.

        Parameters
        ----------
        keep : tuple of str
            Files of the output directory to carry over into the new run (a failed run keeps
            its checkpoint).

        Returns
        -------
        list of str
            The names now in place.
        """
        if self.stage is None:
            raise RuntimeError("RunDirectory.publish needs an open, unpublished directory")
        stage, p = self.stage, self.path
        for name in keep:
            if (p / name).is_file() and not (stage / name).exists():
                try:
                    os.link(p / name, stage / name)
                except OSError:  # a filesystem without hard links
                    shutil.copy2(p / name, stage / name)
        names = sorted(os.listdir(stage))
        if self._inside or _contains_cwd(p) or (
                p.is_dir() and any(e not in OWNED_NAMES for e in _entries(p))):
            self._publish_files(names)
        else:
            swap_into_place(stage, p)
        self.stage = None
        self.published = True
        return names

    def _publish_files(self, names: list[str]) -> None:
        """One file at a time (see the module docstring): nothing but the run's files moves."""
        stage, p = self.stage, self.path
        p.mkdir(exist_ok=True)
        earlier = _earlier_run(p)
        if "summary.json" in earlier:  # the directory no longer claims to hold a complete run
            (p / "summary.json").unlink()
        for name in earlier:
            if name not in names:
                (p / name).unlink(missing_ok=True)
        sync_tree(stage)
        for name in sorted(names, key=lambda n: n == "summary.json"):
            os.replace(stage / name, p / name)
        _fsync(p)
        os.rmdir(stage)

    def close(self) -> None:
        """Delete an unpublished stage, release the lock, remove parents made for nothing."""
        if self.stage is not None:
            shutil.rmtree(self.stage, ignore_errors=True)
            self.stage = None
        if self._lock is not None:
            self._lock.release()
            self._lock = None
        if not self.published:
            for d in reversed(self._made):
                try:
                    d.rmdir()
                except OSError:
                    break
            self._made = []

    def __enter__(self) -> RunDirectory:
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()
