"""Progress on stderr: a live tqdm bar on a terminal, a few whole lines anywhere else.

A tqdm bar redraws itself with carriage returns many times a second; written into a log file
(a batch job, ``2> run.log``, a CI log) that is one endless line. When the stream is not a
terminal, :func:`progress_bar` returns a :class:`LineProgress` instead, which writes one
complete line at every tenth of the work (at most one every 5 s) and at least one every 30 s
while the work advances, and the final state at the end. With ``disable`` it returns a
:class:`NoProgress`, which keeps count and shows nothing. :func:`kernel_clock` times the
loading and compiling of numba's kernels and says once when they are being compiled. A leaf
module (tqdm is imported only for a terminal or a notebook, numba only when a run asks for the
kernel clock), so that every stage may show progress.
"""

from __future__ import annotations

import math
import sys
import time
from typing import IO, Any

__all__ = ["KernelClock", "LineProgress", "NoProgress", "kernel_clock", "progress_bar"]


def _interactive(file: IO) -> bool:
    try:
        return bool(file.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


def progress_bar(total: float, *, desc: str, unit: str, initial: float = 0.0,
                 disable: bool = False, file: IO | None = None, value_format: str = "g",
                 **tqdm_options: Any):
    """A progress indicator for ``total`` units of work.

    Parameters
    ----------
    total : float
        The amount of work (simulated seconds, runs, cases).
    desc, unit : str
        What is progressing and its unit, e.g. ``"roughvib paper"`` and ``"s sim"``.
    initial : float
        Work already done (a resumed run or sweep).
    disable : bool
        Show nothing (a :class:`NoProgress`: neither tqdm nor its lock is created).
    file : file object, optional
        Default: ``sys.stderr``.
    value_format : str
        Format of the amounts in the lines of :class:`LineProgress` (e.g. ``".4f"``).
    **tqdm_options
        Passed to :class:`tqdm.tqdm` on a terminal (e.g. ``bar_format``).

    Returns
    -------
    tqdm.tqdm or LineProgress or NoProgress
        Each has ``n``, ``total``, ``update``, ``refresh``, ``set_postfix`` and ``close``.
    """
    if disable:  # a silent run (--no-progress, sweep cases) pays no tqdm import, no lock
        return NoProgress(total, initial=initial)
    file = sys.stderr if file is None else file
    if _interactive(file):
        from tqdm import tqdm

        return tqdm(total=total, desc=desc, unit=unit, initial=initial, disable=disable,
                    file=file, **tqdm_options)
    if "ipykernel" in sys.modules and file is sys.stderr:  # a notebook: its own widget
        from tqdm.auto import tqdm

        return tqdm(total=total, desc=desc, unit=unit, initial=initial, file=file)
    return LineProgress(total, desc=desc, unit=unit, initial=initial, file=file,
                        value_format=value_format)


def _clock(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "?"
    m, s = divmod(int(round(seconds)), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class NoProgress:
    """A progress indicator that shows nothing: ``progress_bar(..., disable=True)``.

    It counts like the others (``n``, ``total``, ``update``) and writes nothing anywhere.

    Parameters
    ----------
    total : float
    initial : float
    """

    def __init__(self, total: float, *, initial: float = 0.0) -> None:
        self.total = total
        self.n = initial

    def update(self, n: float = 1) -> None:
        """Add ``n`` units of work."""
        self.n += n

    def refresh(self) -> None:
        """Nothing to show."""

    def set_postfix(self, refresh: bool = True, **values: Any) -> None:
        """Nothing to show."""

    def close(self) -> None:
        """Nothing to close."""

    def __enter__(self) -> NoProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class LineProgress:
    """Progress as whole lines, for a stream that is not a terminal.

    A line is written when the work crosses the next tenth of ``total`` and ``min_gap``
    seconds have passed since the last line, or when ``interval`` seconds have passed and the
    work has advanced; :meth:`close` writes the last state if it has not been written yet
    (so a short run writes a single line). Each line reads
    ``desc: n/total unit (p %), elapsed m:ss, about m:ss left``.

    Parameters
    ----------
    total : float
    desc, unit : str
    initial : float
    file : file object
    value_format : str
        Format of ``n`` and ``total``.
    interval : float
        Longest silence while the work advances [s].
    min_gap : float
        Shortest time between two lines [s].
    """

    def __init__(self, total: float, *, desc: str, unit: str, initial: float = 0.0,
                 file: IO | None = None, value_format: str = "g", interval: float = 30.0,
                 min_gap: float = 5.0):
        self.total = total
        self.n = initial
        self.desc, self.unit, self.fmt = desc, unit, value_format
        self.file = sys.stderr if file is None else file
        self.interval, self.min_gap = interval, min_gap
        self.postfix = ""
        self._t0 = self._last_t = time.monotonic()
        self._n0 = initial
        self._last_n = initial
        self._next = self._tenth_after(initial)
        self._closed = False

    def _tenth_after(self, n: float) -> float:
        if not self.total or self.total <= 0:
            return math.inf
        return (math.floor(10 * n / self.total + 1e-9) + 1) * self.total / 10

    def line(self) -> str:
        """The current state as one line (without the newline)."""
        elapsed = time.monotonic() - self._t0
        done = self.n - self._n0
        left = (self.total - self.n) * elapsed / done if done > 0 else math.inf
        pct = 100.0 * self.n / self.total if self.total else 100.0
        post = f", {self.postfix}" if self.postfix else ""
        return (f"{self.desc}: {self.n:{self.fmt}}/{self.total:{self.fmt}} {self.unit} "
                f"({pct:.0f} %){post}, elapsed {_clock(elapsed)}, about {_clock(left)} left")

    def _write(self) -> None:
        self.file.write(self.line() + "\n")
        self.file.flush()
        self._last_t, self._last_n = time.monotonic(), self.n
        self._next = self._tenth_after(self.n)

    def refresh(self) -> None:
        """Write a line if the work crossed a tenth or the interval has passed (see above)."""
        if self._closed or self.n == self._last_n:
            return
        quiet = time.monotonic() - self._last_t
        if quiet >= self.interval or (quiet >= self.min_gap and
                                      self.n >= self._next - 1e-12 * abs(self.total)):
            self._write()

    def update(self, n: float = 1) -> None:
        """Add ``n`` units of work."""
        self.n += n
        self.refresh()

    def set_postfix(self, refresh: bool = True, **values: Any) -> None:
        """Extra ``key=value`` items at the end of the next lines."""
        self.postfix = ", ".join(f"{k}={v}" for k, v in values.items())
        if refresh:
            self.refresh()

    def close(self) -> None:
        """Write the last state (if not written yet); nothing after this."""
        if not self._closed and self.n != self._last_n:
            self._write()
        self._closed = True

    def __enter__(self) -> LineProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class KernelClock:
    """Time spent loading or compiling numba kernels in this process, and a notice, once per
    process, when a kernel has to be compiled (a cold cache: the first run after installing or
    changing roughvib, about a minute).

    It listens to numba's event API (``numba.core.event``): ``"numba:compiler_lock"`` brackets
    every load of a kernel from numba's cache and every compilation, ``"numba:compile"`` fires
    only when a kernel was not in the cache and is compiled. A warm run compiles nothing and
    shows no notice. Get the one clock of the process with :func:`kernel_clock`; read
    :attr:`seconds` before and after a phase to get the phase's share.

    Attributes
    ----------
    seconds : float
        Wall time spent holding numba's compiler lock so far [s] (outermost holds only).
    compiled : int
        Kernels (signatures) compiled so far, i.e. not found in numba's cache.
    notify : bool
        Print the notice at the next compilation (if not printed yet); see :meth:`notifying`.
    """

    def __init__(self, file: IO | None = None) -> None:
        self.seconds = 0.0
        self.compiled = 0
        self.notify = False
        self.noticed = False
        self.file = file
        self._depth = 0
        self._since = 0.0

    def lock_taken(self) -> None:
        """numba took its compiler lock (a load or a compilation starts)."""
        if self._depth == 0:
            self._since = time.perf_counter()
        self._depth += 1

    def lock_released(self) -> None:
        """numba released its compiler lock."""
        self._depth = max(self._depth - 1, 0)
        if self._depth == 0:
            self.seconds += time.perf_counter() - self._since

    def compiling(self) -> None:
        """numba starts compiling a kernel that was not in its cache."""
        self.compiled += 1
        if self.notify and not self.noticed:
            self.noticed = True
            file = sys.stderr if self.file is None else self.file
            print("roughvib: compiling the numba kernels (not in numba's cache yet: the first "
                  "run after installing or changing roughvib); this takes a minute or more, once; "
                  "later runs load them from the cache", file=file, flush=True)

    def notifying(self, on: bool):
        """Context manager: :attr:`notify` set to ``on`` inside, restored after."""
        import contextlib

        @contextlib.contextmanager
        def scope():
            before, self.notify = self.notify, bool(on)
            try:
                yield self
            finally:
                self.notify = before

        return scope()


_KERNEL_CLOCK: KernelClock | None = None


def kernel_clock() -> KernelClock:
    """The process's :class:`KernelClock`, listening to numba's events from the first call on
    (numba is imported here, when a run first asks).

    Returns
    -------
    KernelClock
    """
    global _KERNEL_CLOCK
    if _KERNEL_CLOCK is None:
        from numba.core import event

        clock = KernelClock()

        class _Lock(event.Listener):
            def on_start(self, ev):
                clock.lock_taken()

            def on_end(self, ev):
                clock.lock_released()

        class _Compile(event.Listener):
            def on_start(self, ev):
                clock.compiling()

            def on_end(self, ev):
                pass

        event.register("numba:compiler_lock", _Lock())
        event.register("numba:compile", _Compile())
        _KERNEL_CLOCK = clock
    return _KERNEL_CLOCK
