"""The local pool of a sweep (:mod:`roughvib.studies.sweep.pool`): order, outcomes, the
workers' environment, a dying worker, stopping. The tasks are standard-library functions (a
spawned worker imports a task's function by name)."""

from __future__ import annotations

import operator
import os
import time

import pytest

from roughvib.studies.sweep.pool import LocalPool, WorkerLost


def test_tasks_run_in_the_order_submitted_and_errors_are_outcomes():
    with LocalPool(1, env={"ROUGHVIB_POOL_TEST": "x1"}) as pool:
        pool.submit("a", os.getenv, "ROUGHVIB_POOL_TEST")
        pool.submit("b", operator.truediv, 1.0, 0.0)
        pool.submit("c", operator.add, 2, 3)
        pool.submit("d", os.getpid)
        pool.submit("e", lambda: 1)  # does not pickle: an outcome, not a crash
        got = list(pool.results())
        pids = pool.pids
    assert [k for k, _, _ in got] == ["a", "b", "c", "d", "e"]  # one worker: in order
    assert got[4][1] is False and "pickle" in str(got[4][2])
    assert got[0][1:] == (True, "x1")  # the env reaches the worker
    assert got[1][1] is False and isinstance(got[1][2], ZeroDivisionError)
    assert got[2][1:] == (True, 5)  # the worker went on after the error
    assert got[3][2] == pids[0] != os.getpid()


def test_a_dying_worker_is_replaced_and_its_task_ends_as_lost_after_the_attempts():
    with LocalPool(2, attempts=2) as pool:
        first = set(pool.pids)
        pool.submit("dies", os._exit, 7)
        pool.submit("fine", operator.mul, 6, 7)
        got = {k: (ok, v) for k, ok, v in pool.results()}
        assert len(pool.pids) == 2 and set(pool.pids) != first  # a new worker
    assert got["fine"] == (True, 42)
    ok, exc = got["dies"]
    assert not ok and isinstance(exc, WorkerLost)
    assert str(exc) == "the worker process running it died 2 times (exit code 7)"


def test_terminate_stops_a_running_task_at_once():
    pool = LocalPool(1)
    pool.submit("long", time.sleep, 60.0)
    results = pool.results()
    t0 = time.monotonic()
    pool._feed(pool._procs[0])  # hand the task out without waiting for it
    [proc] = [w.proc for w in pool._procs]
    pool.terminate()
    assert time.monotonic() - t0 < 10.0
    assert not proc.is_alive()
    del results
    with pytest.raises(ValueError, match="workers must be >= 1, got 0"):
        LocalPool(0)
