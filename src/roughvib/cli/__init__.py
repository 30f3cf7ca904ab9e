"""Command-line interface: thin argument parsing around the public API (no physics here).

Exit status: 0 success, 1 solver failure (status and message in summary.json and on
stderr) or a file that could not be written (a full disk: one line naming the path and the
space needed), 2 bad input (one line naming the field, rule, unit and value; no traceback), 141
when the reader of the output went away (``roughvib events --json | head``), as for a command
stopped by SIGPIPE.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import gc
import os
import sys
import time

from roughvib._version import __version__
from roughvib.cli import compare, lab, modes, report, results, run, sources, surface, sweep
from roughvib.cli.args import (
    EXIT_INPUT,
    EXIT_INTERRUPT,
    EXIT_PIPE,
    EXIT_SOLVER,
    EXIT_TERM,
    InputError,
    Terminated,
    on_sigterm,
)

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The ``roughvib`` argument parser with every command (each command module adds its own).

    Returns
    -------
    argparse.ArgumentParser
    """
    fmt = argparse.RawDescriptionHelpFormatter
    p = argparse.ArgumentParser(
        prog="roughvib", formatter_class=fmt,
        description="Roughness-induced vibration of a tangentially oscillating block on a "
                    "plate (Feldmann 2012), solved event-driven: by default with the "
                    "adaptive exact-modal scheme at reference accuracy (SUNDIALS IDA where "
                    "that cannot run, or with --set solver.method=ida); 'run --verify' "
                    "checks one against the other.",
        epilog="examples:\n  roughvib run\n  roughvib run paper-100mms --out runs/fast\n"
               "  roughvib scenes\n  roughvib events runs/paper\n"
               "  roughvib plot runs/paper --figure events\n"
               "  roughvib compare paper --out runs/wp --budget 900\n"
               "  roughvib surface paper --out runs/paper-surface\n"
               "  roughvib modes export paper plate.npz\n"
               "  roughvib report runs/paper\n"
               "  roughvib sweep paper-velocity --out runs/velocity\n"
               "  roughvib validate runs/paper lab/plate.wav --signal plate --scale 50\n"
               "  roughvib export runs/paper --format uff\n\n"
               "exit status: 0 success, 1 solver failure or a failed write (full disk), 2 bad "
               "input, 130 interrupted "
               "(Ctrl-C), 141 output pipe closed, 143 terminated (SIGTERM)")
    p.add_argument("--version", action="version", version=f"roughvib {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    run.add_parsers(sub)
    results.add_parsers(sub)
    compare.add_parsers(sub)
    sources.add_parsers(sub)
    surface.add_parsers(sub)
    modes.add_parsers(sub)
    report.add_parsers(sub)
    sweep.add_parsers(sub)
    lab.add_parsers(sub)
    return p


def _no_collection_at_exit() -> None:
    """Let the interpreter skip its last garbage collection when the process exits.

    At exit Python collects every object that is still alive; after a run (numba, scipy,
    xarray, pandas loaded) those are hundreds of thousands, for memory the operating system
    frees at once anyway (docs/performance.md, "Fixed cost of a run": the last sweep at exit is
    skipped). ``gc.freeze()`` as the last exit handler moves those objects out of the collector's
    sight. The exit handlers registered after it (those of the libraries imported during the
    run) run before it, and reference counting still frees and finalises every object that is
    not part of a reference cycle while the modules are torn down; Python does not promise to
    finalise cycles at exit in any case.
    """
    global _EXIT_REGISTERED
    if not _EXIT_REGISTERED:
        import atexit
        import gc

        atexit.register(gc.freeze)
        _EXIT_REGISTERED = True


_EXIT_REGISTERED = False

#: the garbage collector's first threshold while a command runs (Python's default is 700)
GC_YOUNG_THRESHOLD = 50_000


@contextlib.contextmanager
def _fewer_collections():
    """Run the garbage collector less often while a command runs.

    A command imports numpy, numba, scipy and h5py and sets up numba's typing and target
    contexts: hundreds of thousands of objects that live as long as the process. With
    Python's default thresholds the collector runs about 275 times in a warm ``roughvib
    run``, twice over every object alive, 0.16-0.19 s of CPU; with a first threshold of
    :data:`GC_YOUNG_THRESHOLD` about 40 times, never over all objects, 0.08-0.09 s
    (docs/performance.md, "Fixed cost of a run").
    Cycles are still collected, after 50 000 new container objects instead of 700. The
    previous thresholds are restored when the command ends; a collector switched off by a
    threshold of 0 stays off.
    """
    old = gc.get_threshold()
    if old[0]:
        gc.set_threshold(max(old[0], GC_YOUNG_THRESHOLD), *old[1:])
    try:
        yield
    finally:
        gc.set_threshold(*old)


def main(argv: list[str] | None = None) -> int:
    """Console entry point ``roughvib``; returns the exit status."""
    _no_collection_at_exit()
    # a command line of its own (the console script, python -m roughvib): the budget of a
    # command counts from the process's start; called with arguments from Python, from here
    started = time.perf_counter() - (_process_age() if argv is None else 0.0)
    parser = build_parser()
    args = parser.parse_args(argv)
    args.started = started  # what a command's time budget counts from (compare --budget)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_INPUT
    import signal
    import warnings

    from roughvib.rundir import OutputWarning, WriteError
    from roughvib.scene import ModelValidityWarning, SceneError

    show = _warning_printer()
    previous = signal.getsignal(signal.SIGTERM)
    try:
        signal.signal(signal.SIGTERM, on_sigterm)
    except ValueError:  # not the main thread (e.g. called from a worker): leave it alone
        previous = None
    try:
        with warnings.catch_warnings(), _fewer_collections():
            warnings.showwarning = show
            # roughvib's own warnings reach the printer every time (Python's once-per-place
            # memory is reset whenever a library touches the filters); it prints each once
            warnings.simplefilter("always", ModelValidityWarning)
            warnings.simplefilter("always", OutputWarning)
            status = args.func(args)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
        return status
    except BrokenPipeError:
        _discard_stdout()
        return EXIT_PIPE
    except (SceneError, InputError) as exc:
        print(f"roughvib: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except WriteError as exc:  # a full disk, a read-only file system: one line, exit 1
        print(f"roughvib: error: {exc}", file=sys.stderr)
        return EXIT_SOLVER
    except OSError as exc:  # the same met by a write that does not say which file it was
        line = _write_failure(exc)
        if line is None:
            raise
        print(f"roughvib: error: {line}", file=sys.stderr)
        return EXIT_SOLVER
    except KeyboardInterrupt as exc:
        print(f"roughvib: {'terminated' if isinstance(exc, Terminated) else 'interrupted'}",
              file=sys.stderr)
        return EXIT_TERM if isinstance(exc, Terminated) else EXIT_INTERRUPT
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


#: /proc/self/stat's field 22 (starttime: clock ticks after boot), counted from the field
#: after the process name (field 3 is index 0)
_STAT_STARTTIME = 22 - 3


def _process_age() -> float:
    """Seconds since this process started (its interpreter's start-up and imports), from
    Linux's /proc; 0 where that cannot be read (then a budget counts from ``main``)."""
    try:
        with open("/proc/self/stat", "rb") as fh:
            _, after_name = fh.read().rsplit(b")", 1)
        with open("/proc/uptime", "rb") as fh:
            uptime = float(fh.read().split()[0])
        ticks = int(after_name.split()[_STAT_STARTTIME])
        age = uptime - ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return 0.0
    return age if 0.0 <= age < 3600.0 else 0.0


#: errno values of a write that cannot succeed where it is: a full file system or quota, a file
#: too large for it, a read-only file system
_WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS})


def _write_failure(exc: OSError) -> str | None:
    """The one line for an :class:`OSError` of a write that reached the command line as it is
    (not as a ``WriteError``: a write the code that wrote did not turn into one); None for
    any other error.

    The file is named where the error names it (an ``open``); a failed ``write`` does not.
    """
    from roughvib.rundir import write_failed

    if exc.errno not in _WRITE_ERRNOS:
        return None
    if exc.filename:
        return str(write_failed(exc.filename, exc))
    return (f"a write failed: {exc.strerror or exc} (the error does not name the file); free "
            f"some space or write elsewhere")


def _warning_line(message: Warning | str, category: type[Warning]) -> str:
    """The one line a warning is shown as on the command line: ``roughvib: warning:
    <message>``, the message on one line, no source file or line. A warning that is not a
    :class:`UserWarning` (roughvib's own are) names its category, e.g. ``roughvib: warning:
    RuntimeWarning: overflow encountered in exp``."""
    text = " ".join(str(message).split())
    if not issubclass(category, UserWarning):
        text = f"{category.__name__}: {text}"
    return f"roughvib: warning: {text}"


def _warning_printer():
    """A ``warnings.showwarning`` for one command: each warning as ``_warning_line`` on
    stderr, each distinct line once (a command that builds a scene twice, as ``run --verify``
    does, or runs it many times, as ``compare`` does, repeats its warnings)."""
    seen: set[str] = set()

    def show(message, category, filename, lineno, file=None, line=None):
        text = _warning_line(message, category)
        if text not in seen:
            seen.add(text)
            print(text, file=sys.stderr, flush=True)

    return show


def _discard_stdout() -> None:
    """After a closed pipe: point stdout at /dev/null, so that Python's final flush at exit
    does not report the same broken pipe again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # stdout without a descriptor (captured)
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
