"""The local pool of a sweep on one machine: worker processes, one task at a time each.

A sweep without a scheduler address runs its cases here instead of on a Dask
``LocalCluster``: the workers are plain ``spawn`` processes that import roughvib's solver stack
once and take one case after the other over a pipe. Neither the client nor the workers import
dask.distributed, and no scheduler runs (docs/performance.md, "Sweeps and ensembles": with a
Dask ``LocalCluster`` in its place, the 12-case ``paper-velocity`` sweep took about 8
CPU-seconds more).

What a Dask cluster gave a sweep, the pool keeps:

* the tasks start in the order submitted (the sweep submits the longest cases first);
* each worker has one thread for numba, OpenMP and BLAS (the ``env`` given), and ignores
  SIGINT: Ctrl-C reaches the whole process group, and the client stops the workers itself;
* a task's exception is handed back as the task's outcome, the worker goes on;
* a worker that dies (killed, out of memory, a crash in compiled code) is replaced; the task
  it was running is started again on the new worker, at most ``attempts`` times in all, then
  reported as lost (:class:`WorkerLost`), as Dask reports ``KilledWorker`` after its allowed
  failures. The client knows exactly which task each worker runs: it hands out one task at a
  time.
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import os
import signal
import traceback
from collections import deque
from collections.abc import Callable, Iterator
from multiprocessing.connection import wait
from typing import Any, NamedTuple

__all__ = ["LocalPool", "WorkerLost"]

#: seconds a worker gets to exit after it was told to (then it is killed)
_JOIN_TIMEOUT = 5.0


class WorkerLost(RuntimeError):
    """The worker process running a task died ``attempts`` times in a row."""


class _Task(NamedTuple):
    """A task as sent to a worker."""

    key: Any
    fn: Callable
    args: tuple


class _Answer(NamedTuple):
    """A worker's answer: the task's value (``ok``) or its exception."""

    key: Any
    ok: bool
    value: Any


@dataclasses.dataclass
class _Worker:
    """A worker process, the client's end of its pipe and the task it runs (None: idle)."""

    proc: Any
    conn: Any
    task: _Task | None = None


def _worker_main(conn, env: dict[str, str], initializer: Callable[[], Any] | None) -> None:
    """A worker process: set its environment, call ``initializer``, run tasks until told to
    stop.

    Each message from the client is ``(key, function, args)`` or None (stop); each answer is
    ``(key, True, value)`` or ``(key, False, exception)``.
    """
    os.environ.update(env)
    with contextlib.suppress(ValueError):
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # the client stops the workers itself
    if initializer is not None:  # e.g. the solver's imports, before the first task arrives
        initializer()
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):  # the client is gone
            return
        if msg is None:
            return
        task = _Task(*msg)
        try:
            answer = _Answer(task.key, True, task.fn(*task.args))
        except Exception as exc:  # noqa: BLE001 - handed to the client as the outcome
            answer = _Answer(task.key, False, exc)
        try:
            conn.send(tuple(answer))
        except Exception:  # noqa: BLE001 - an outcome that does not pickle
            text = ("".join(traceback.format_exception_only(type(answer.value), answer.value))
                    if not answer.ok else "the task's value could not be sent to the client")
            conn.send((task.key, False, RuntimeError(text.strip())))


class LocalPool:
    """Worker processes on this machine running tasks in the order submitted.

    Parameters
    ----------
    workers : int
        Worker processes (>= 1), started at once.
    env : dict, optional
        Environment variables set in every worker before anything is imported there.
    initializer : callable, optional
        Called once in every worker when it starts (importable by name, no arguments).
    attempts : int
        How often a task is started in all when its worker dies under it (default 3).

    Notes
    -----
    Use as a context manager; leaving it stops the workers (and kills those that do not exit
    within a few seconds). :meth:`terminate` stops them at once, tasks in flight included.
    """

    def __init__(self, workers: int, *, env: dict[str, str] | None = None,
                 initializer: Callable[[], Any] | None = None, attempts: int = 3) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self._ctx = multiprocessing.get_context("spawn")
        self._env = dict(env or {})
        self._initializer = initializer
        self._attempts = attempts
        self._queue: deque[_Task] = deque()
        self._tries: dict[Any, int] = {}
        self._done: deque[_Answer] = deque()  # outcomes known without a worker
        self._procs: list[_Worker] = []
        for _ in range(workers):
            self._start_worker()

    # ---- workers --------------------------------------------------------------------------

    def _start_worker(self) -> None:
        parent, child = self._ctx.Pipe(duplex=True)
        proc = self._ctx.Process(target=_worker_main, args=(child, self._env, self._initializer),
                                 daemon=True, name="roughvib-sweep-worker")
        # a worker ignores SIGINT from its birth (a disposition "ignore" survives exec, and
        # Python then installs no KeyboardInterrupt handler): Ctrl-C reaches the whole process
        # group, and the client stops its workers itself
        try:
            previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        except ValueError:  # not the main thread: the worker sets it itself when it starts
            previous = None
        try:
            proc.start()
        finally:
            if previous is not None:
                signal.signal(signal.SIGINT, previous)
        child.close()
        self._procs.append(_Worker(proc, parent))

    @property
    def pids(self) -> list[int]:
        """Process ids of the current workers."""
        return [w.proc.pid for w in self._procs]

    # ---- tasks ----------------------------------------------------------------------------

    def submit(self, key: Any, fn: Callable, *args: Any) -> None:
        """Queue ``fn(*args)`` under ``key`` (unique); ``fn`` must be importable by name."""
        self._queue.append(_Task(key, fn, args))
        self._tries[key] = 0

    def cancel_queued(self) -> int:
        """Drop the tasks not started yet; how many were dropped."""
        n = len(self._queue)
        self._queue.clear()
        return n

    def _feed(self, worker: _Worker) -> None:
        """Hand the next queued task to ``worker`` if it is idle."""
        while worker.task is None and self._queue:
            task = self._queue.popleft()
            self._tries[task.key] += 1
            try:
                worker.conn.send(tuple(task))
            except (OSError, EOFError):  # the worker is gone: its death is handled later
                self._queue.appendleft(task)
                self._tries[task.key] -= 1
                return
            except Exception as exc:  # noqa: BLE001 - a task that does not pickle
                self._done.append(_Answer(task.key, False, exc))
                continue
            worker.task = task

    def results(self) -> Iterator[tuple[Any, bool, Any]]:
        """The outcome of every task, as each one ends: ``(key, ok, value or exception)``.

        A task whose worker died ``attempts`` times ends with ``ok`` False and a
        :class:`WorkerLost`.
        """
        for worker in self._procs:
            self._feed(worker)
        while self._done or any(w.task is not None for w in self._procs):
            while self._done:
                yield tuple(self._done.popleft())
            if not any(w.task is not None for w in self._procs):
                break
            ready = wait([w.conn for w in self._procs] + [w.proc.sentinel for w in self._procs])
            for worker in list(self._procs):
                proc, conn, task = worker.proc, worker.conn, worker.task
                if conn in ready or (proc.sentinel in ready and conn.poll()):
                    try:
                        answer = _Answer(*conn.recv())
                    except (EOFError, OSError):
                        pass  # died while answering: handled as a death below
                    else:
                        worker.task = None
                        self._feed(worker)
                        yield tuple(answer)
                        continue
                if proc.sentinel in ready or not proc.is_alive():
                    self._procs.remove(worker)
                    conn.close()
                    proc.join()
                    self._start_worker()
                    if task is not None:
                        if self._tries[task.key] < self._attempts:
                            self._queue.appendleft(task)  # again, before the others
                        else:
                            yield (task.key, False, WorkerLost(
                                f"the worker process running it died {self._tries[task.key]} "
                                f"times (exit code {proc.exitcode})"))
                    self._feed(self._procs[-1])

    # ---- stopping -------------------------------------------------------------------------

    def terminate(self) -> None:
        """Stop every worker now (SIGTERM, then SIGKILL after a few seconds); drop the queue."""
        self._queue.clear()
        for w in self._procs:
            with contextlib.suppress(Exception):
                w.proc.terminate()
            w.conn.close()
        self._reap()

    def close(self) -> None:
        """Tell the idle workers to exit and wait for them (killed after a few seconds)."""
        self._queue.clear()
        for w in self._procs:
            with contextlib.suppress(Exception):
                if w.task is None:
                    w.conn.send(None)
                else:
                    w.proc.terminate()
            w.conn.close()
        self._reap()

    def _reap(self) -> None:
        for w in self._procs:
            w.proc.join(_JOIN_TIMEOUT)
            if w.proc.is_alive():
                w.proc.kill()
                w.proc.join()
        self._procs.clear()

    def __enter__(self) -> LocalPool:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.terminate()
