"""Running a sweep: each case one task that writes its directory under a temporary name and
renames it into place when complete; resuming skips the complete cases, and so does a task whose
case is complete on disk (Dask re-runs the tasks of a killed worker). The tasks run on a local
pool of worker processes (:mod:`.pool`), or as Dask tasks on a cluster given by its scheduler's
address or client. One sweep at a time per directory (a lock file); temporary directories of
killed workers are removed."""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import re
import secrets
import shutil
import socket
import sys
import threading
import time
import traceback
import warnings
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from roughvib.rundir import DirectoryLock, OutputError, swap_into_place
from roughvib.scene import ModelValidityWarning, Scene, SceneError
from roughvib.studies.sweep.spec import (
    CASES_DIR,
    SUCCESS,
    Case,
    Sweep,
    _replace_file,
    adopt_old_case_names,
    load_sweep,
)
from roughvib.studies.sweep.tables import _write_tables

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

__all__ = ["THREAD_ENV", "SweepRun", "run_sweep"]

#: Environment of every local worker process: one thread for numba, OpenMP and BLAS, so that
#: N single-threaded workers use N cores and not N x cores.
THREAD_ENV: dict[str, str] = {
    "NUMBA_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
}

_TOKEN_FILE = ".sweep-token"
_LOCK_FILE = ".sweep.lock"
_STALE = re.compile(r"^\..*\.(tmp|old)-")
#: seconds to wait for a scheduler given by address (Dask's default is 30 s)
CONNECT_TIMEOUT = 10.0


def _write_json(path: Path, obj: Any) -> None:
    from roughvib.results import _jsonable

    path.write_text(json.dumps(_jsonable(obj), indent=2))


def _host_tag() -> str:
    return hashlib.sha256(socket.gethostname().encode()).hexdigest()[:8]


def _new_tmp(root: Path, name: str) -> Path:
    """A fresh temporary case directory (created with the umask's permissions, unlike
    ``mkdtemp``'s 0700, so that a shared sweep directory stays readable), named after its
    host and process so that a task can tell the directories of dead workers."""
    while True:
        tmp = root / f".{name}.tmp-{_host_tag()}-{os.getpid()}-{secrets.token_hex(6)}"
        try:
            tmp.mkdir()
            return tmp
        except FileExistsError:  # pragma: no cover - 48 random bits
            continue


def _remove_dead_tmp(root: Path, name: str) -> None:
    """Temporary directories of this case left by killed workers on this host."""
    pattern = re.compile(rf"^\.{re.escape(name)}\.tmp-{_host_tag()}-(\d+)-[0-9a-f]+$")
    for entry in root.iterdir():
        m = pattern.match(entry.name)
        if not m or int(m.group(1)) == os.getpid():
            continue
        try:
            os.kill(int(m.group(1)), 0)
        except ProcessLookupError:  # its process is gone
            shutil.rmtree(entry, ignore_errors=True)
        except OSError:  # alive (another user's process)
            pass


def _complete_case(final: Path, name: str) -> dict[str, Any] | None:
    """The task's return value for a case complete on disk (None if it is not)."""
    if not _is_complete(final):
        return None
    try:
        wall = float(json.loads((final / "case.json").read_text())["wall_time"])
    except (OSError, ValueError, KeyError, TypeError):
        wall = float("nan")
    return {"name": name, "status": SUCCESS, "message": "complete on disk, not recomputed",
            "wall_time": wall}


def _failure_summary(name: str, status: str, message: str) -> dict[str, Any]:
    """The summary.json of a case that failed before its run could write one (sealed with its
    digest, as a run's own summary)."""
    from roughvib.results import FORMAT_VERSION, seal_summary

    return seal_summary({"format_version": FORMAT_VERSION, "status": status,
                         "message": message, "scene": name, "solver": {}, "metrics": {}})


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if not isinstance(exc, SceneError) else text


def _run_case(base: Scene, name: str, values: dict[str, Any], cases_dir: str,
              token: str, row: bool = False) -> dict[str, Any]:
    """Run one case and publish its directory; the Dask task of a sweep.

    Parameters
    ----------
    base : Scene
        Base scene with the fixed overrides.
    name : str
        Case name (directory under ``cases_dir``).
    values : dict
        The case's varied values (dotted keys).
    cases_dir : str
        Absolute path of ``DIR/cases``; must be visible to the worker.
    token : str
        Content of ``DIR/.sweep-token``: proves the worker sees the client's directory.
    row : bool
        Also return the ensemble's numbers of a successful case (``"row"``:
        :func:`roughvib.studies.sweep.ensemble.case_row` of the result in memory), so that
        the client need not load the case again.

    Returns
    -------
    dict
        ``{"name", "status", "message", "wall_time"}`` (and ``"row"``). Errors of the case
        itself are recorded, not raised.
    """
    for k, v in THREAD_ENV.items():
        os.environ.setdefault(k, v)  # effective if numba/BLAS are not imported yet
    t0 = time.perf_counter()
    started = datetime.now(UTC).isoformat(timespec="seconds")
    root = Path(cases_dir)
    token_file = root.parent / _TOKEN_FILE
    try:
        seen = token_file.read_text().strip()
    except OSError:
        seen = ""
    if seen != token:
        raise RuntimeError(f"worker {socket.gethostname()} does not see the sweep directory "
                           f"{root.parent} of the client (the workers need it on a shared "
                           f"filesystem under the same path)")
    # Dask re-runs the tasks of a killed worker, finished ones included: never recompute
    done = _complete_case(root / name, name)
    if done is not None:
        return done
    _remove_dead_tmp(root, name)
    tmp = _new_tmp(root, name)
    extra: dict[str, Any] = {}
    try:
        try:
            from roughvib.simulation import simulate

            scene = base.with_overrides({**values, "name": name})
            with warnings.catch_warnings():  # kept in the case's summary.json
                warnings.simplefilter("ignore", ModelValidityWarning)
                result = simulate(scene, progress=False)
            with _local_dask():
                result.write_files(tmp)
            status, message = result.status, str(result.summary.get("message", ""))
        except SceneError as exc:
            status, message = "input_error", _one_line(exc)
            _write_json(tmp / "summary.json", _failure_summary(name, status, message))
        except Exception as exc:
            status, message = "error", _one_line(exc)
            _write_json(tmp / "summary.json", _failure_summary(name, status, message))
            (tmp / "error.txt").write_text(traceback.format_exc())
        wall = time.perf_counter() - t0
        _write_json(tmp / "case.json", {
            "name": name, "values": values, "status": status, "wall_time": wall,
            "host": socket.gethostname(), "pid": os.getpid(), "started": started,
            "finished": datetime.now(UTC).isoformat(timespec="seconds")})
        swap_into_place(tmp, root / name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if row and status == SUCCESS:  # after the case's wall_time: not part of the case
        from roughvib.studies.sweep.ensemble import case_row

        try:
            extra["row"] = case_row(result)
        except Exception:  # noqa: BLE001 - the client then reads this case from its files
            pass
    return {"name": name, "status": status, "message": message, "wall_time": wall, **extra}


def _local_dask():
    """Inside a Dask task, make xarray lock its netCDF writes locally: each case writes its
    own files, and a cluster-wide lock would tie every write to the scheduler connection. A
    worker of the local pool has not imported dask: nothing to do there."""
    if "dask" not in sys.modules:
        return contextlib.nullcontext()
    import dask

    return dask.config.set(scheduler="synchronous")


def _is_complete(case_dir: Path) -> bool:
    from roughvib.results import check_run_files, read_summary

    try:  # an edited or foreign summary.json (RunDirectoryError) is run again
        summary = read_summary(case_dir)
        check_run_files(case_dir, summary, hashes=False)  # sizes: cheap
    except (OSError, ValueError):  # MixedRunError and RunDirectoryError are ValueErrors
        return False
    return summary.get("status") == SUCCESS and (case_dir / "result.nc").is_file()


def _remove_stale(cases_dir: Path) -> None:
    """Temporary and replaced case directories left by a killed sweep."""
    for entry in cases_dir.iterdir():
        if _STALE.match(entry.name):
            if entry.is_dir():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)


# --------------------------------------------------------------------------------------------
# running a sweep (client side)
# --------------------------------------------------------------------------------------------


@dataclasses.dataclass
class SweepRun:
    """Outcome of :func:`run_sweep`.

    Attributes
    ----------
    directory : Path
        The sweep directory.
    table : pandas.DataFrame
        The sweep table (as in sweep.csv).
    skipped : int
        Cases complete before this run (not re-run).
    ran : int
        Cases run now.
    failed : int
        Cases in the table whose status is not success.
    rows : dict
        With ``case_rows=True``: the ensemble's numbers of each successful case run now
        (:func:`roughvib.studies.sweep.ensemble.case_row`), by case name.
    """

    directory: Path
    table: pd.DataFrame
    skipped: int
    ran: int
    failed: int
    rows: dict[str, Any] = dataclasses.field(default_factory=dict)


def _probe(address: str) -> None:
    """Fail at once, with one line, when nothing listens at a TCP scheduler address (Dask
    itself keeps retrying a refused connection until its timeout)."""
    from urllib.parse import urlsplit

    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    if parts.scheme not in ("tcp", "tls"):
        return  # other transports: Dask's own timeout
    try:
        host, port = parts.hostname, parts.port or 8786
    except ValueError:
        host = None
    if not host:
        raise SceneError(f"--scheduler must be an address like tcp://host:8786, got "
                         f"{address!r}")
    try:
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT).close()
    except OSError as exc:
        raise SceneError(f"--scheduler {address}: cannot connect ({exc.strerror or exc}); start "
                         f"a scheduler with 'dask scheduler' or check the address") from None


def _connect(scheduler: str):
    """A Dask client of the scheduler at ``scheduler``."""
    try:
        from dask.distributed import Client
    except ImportError:  # pragma: no cover - depends on the installation
        raise SceneError("--scheduler needs dask.distributed: "
                         "pip install 'dask[distributed]>=2024.1'") from None
    try:
        return Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        raise SceneError(f"--scheduler {scheduler}: no Dask scheduler answered within "
                         f"{CONNECT_TIMEOUT:g} s ({_one_line(exc)}); start one with 'dask "
                         f"scheduler' or check the address") from None


def run_sweep(sweep: str | os.PathLike | Sweep | dict, out: str | os.PathLike, *,
              scheduler: str | None = None, workers: int | None = None, client: Any = None,
              overrides: dict[str, Any] | None = None, progress: bool = True,
              log: Callable[[str], None] | None = None, case_rows: bool = False) -> SweepRun:
    """Run (or resume) a sweep: each case one task writing ``out/cases/<case>/``.

    Parameters
    ----------
    sweep : str, path, Sweep or dict
        See :func:`.load_sweep`.
    out : path
        Sweep directory; created if needed. With a remote scheduler it must be on a filesystem
        the workers share, under the same path.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://head:8786``): each case one Dask task
        on its cluster. Default: a local pool of worker processes for this call
        (:class:`~roughvib.studies.sweep.pool.LocalPool`; no Dask).
    workers : int, optional
        Worker processes of the local pool (default: all cores, at most one per case), one
        thread each. Ignored with ``scheduler`` or ``client``.
    client : dask.distributed.Client, optional
        Use this client (and its cluster) instead; it is not closed.
    overrides : dict, optional
        Extra fixed values for every case (dotted keys).
    progress : bool
        A progress bar over the cases on stderr.
    log : callable, optional
        Receives one-line notes (dashboard address, skipped cases); default: ignored.
    case_rows : bool
        Each worker also computes the ensemble's numbers of its successful cases from the
        result in memory (the ``rows`` of the returned ``SweepRun``; for
        :func:`.ensemble_tables`, which otherwise loads every case again in the client).

    Returns
    -------
    SweepRun
        The table (also in ``out/sweep.csv`` and ``out/sweep.nc``) and the counts.

    Raises
    ------
    SceneError
        Bad sweep file, ``workers < 1``, or no scheduler at ``scheduler``. A failing case does
        not raise: its status and message are in its directory and in the table.
    roughvib.rundir.OutputError
        ``out`` cannot be created, or another sweep is running into it (``out/.sweep.lock``).
    """
    spec = load_sweep(sweep, overrides)
    if workers is not None and workers < 1:
        raise SceneError(f"workers must be >= 1, got {workers}")
    note = log or (lambda _msg: None)
    if scheduler and client is None:
        _probe(scheduler)  # before anything is written
    out = Path(out).resolve()
    cases_dir = out / CASES_DIR
    try:
        cases_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{out} cannot be a sweep directory: {exc.strerror}") from None
    # one sweep at a time per directory (a second one would take over the first one's token)
    lock = DirectoryLock(out / _LOCK_FILE, str(out), "sweep").acquire()
    try:
        return _run_locked(spec, out, cases_dir, scheduler=scheduler, workers=workers,
                           client=client, progress=progress, note=note, case_rows=case_rows)
    finally:
        lock.release()


def _run_locked(spec: Sweep, out: Path, cases_dir: Path, *, scheduler: str | None,
                workers: int | None, client: Any, progress: bool,
                note: Callable[[str], None], case_rows: bool = False) -> SweepRun:
    """The body of :func:`run_sweep`, holding the sweep directory's lock."""
    from roughvib._progress import progress_bar

    token = secrets.token_hex(8)
    _replace_file(out / _TOKEN_FILE, token)
    _replace_file(out / "sweep.json", json.dumps(spec.to_json(), indent=2))
    _remove_stale(cases_dir)
    renamed = adopt_old_case_names(spec, cases_dir)
    if renamed:
        note(f"renamed {len(renamed)} case directories of an older roughvib to the new names "
             f"(e.g. {renamed[0][0]} -> {renamed[0][1]}); nothing recomputed")

    cases = spec.cases()
    todo = [c for c in cases if not _is_complete(cases_dir / c.name)]
    skipped = len(cases) - len(todo)
    if skipped:
        note(f"{skipped} of {len(cases)} cases complete in {out}; running the other "
             f"{len(todo)}")
    errors: dict[str, tuple[str, str]] = {}
    rows: dict[str, Any] = {}
    interrupted = False
    closing = None  # the local workers shutting down while the tables are written
    if todo:
        rank = _longest_first(spec.base, todo)
        # submitted in that order too: the first tasks reach idle workers at once
        order = sorted(todo, key=lambda c: -rank[c.name])
        args = {c.name: (spec.base, c.name, c.values, str(cases_dir), token, case_rows)
                for c in order}
        if client is None and not scheduler:
            stop, outcomes = _pool_outcomes(order, args, workers)
        else:
            stop, outcomes = _dask_outcomes(order, args, rank, client, scheduler, token, note)
        bar = None
        try:
            bar = progress_bar(len(cases), initial=skipped, desc=f"sweep {spec.name}",
                               unit="case", disable=not progress, file=sys.stderr)
            failed_now = 0
            for case, ok, done in outcomes:
                if ok:
                    status = done["status"]
                    if "row" in done:
                        rows[case.name] = done["row"]
                else:  # the task itself died (worker lost, no directory)
                    lost = type(done).__name__ in ("KilledWorker", "WorkerLost")
                    status = "worker_lost" if lost else "error"
                    errors[case.name] = (status, _one_line(done))
                    _record_failure(cases_dir, case.name, status, _one_line(done))
                failed_now += status != SUCCESS
                bar.set_postfix(failed=failed_now, refresh=False)
                bar.update()
        except BaseException:
            # interrupted: queued cases are dropped; the tables are written below, once the
            # local workers have stopped
            interrupted = True
            raise
        finally:
            if bar is not None:
                bar.close()
            closing = stop(interrupted)
            if interrupted:
                with contextlib.suppress(Exception):
                    _write_tables(spec, out, errors)
    try:
        table = _write_tables(spec, out, errors)
    finally:
        if closing is not None:
            closing.join()
    _remove_stale(cases_dir)  # every worker has stopped: what is left was a killed worker's
    return SweepRun(out, table, skipped, len(todo), int((table["status"] != SUCCESS).sum()),
                    rows)


def _init_worker() -> None:
    """Start of a local pool's worker: the solver's imports before the first case arrives, and
    a thread lock for tqdm (whose default lock is a multiprocessing semaphore, left behind, with
    a warning of Python's resource tracker, by a worker stopped in the middle of a case; the
    workers draw no bars)."""
    import threading

    from tqdm import tqdm

    tqdm.set_lock(threading.RLock())
    import roughvib.simulation  # noqa: F401


def _pool_outcomes(order: list[Case], args: dict[str, tuple], workers: int | None):
    """Run the cases on a :class:`LocalPool` of this machine.

    Returns ``(stop, outcomes)``: ``outcomes`` yields ``(case, ok, value or exception)`` as
    the cases end; ``stop(interrupted)`` stops the workers (at once when interrupted, else in a
    thread that it returns, so that the tables are written meanwhile).
    """
    from roughvib.studies.sweep.pool import LocalPool

    n = min(workers or os.cpu_count() or 1, len(order))
    pool = LocalPool(n, env=dict(THREAD_ENV), initializer=_init_worker)
    by_name = {c.name: c for c in order}
    for c in order:
        pool.submit(c.name, _run_case, *args[c.name])

    def outcomes():
        for name, ok, value in pool.results():
            yield by_name[name], ok, value

    def stop(interrupted: bool):
        if interrupted:
            pool.terminate()
            return None
        closing = threading.Thread(target=pool.close, name="roughvib-sweep-close")
        closing.start()
        return closing

    return stop, outcomes()


def _dask_outcomes(order: list[Case], args: dict[str, tuple], rank: dict[str, int], client,
                   scheduler: str | None, token: str, note: Callable[[str], None]):
    """Run the cases as Dask tasks: on ``client``, or on a new client of ``scheduler``.

    Returns ``(stop, outcomes)`` as :func:`_pool_outcomes`; ``stop`` cancels the tasks not
    ended when interrupted and closes a client made here.
    """
    from dask.distributed import as_completed

    own = client is None
    if own:
        client = _connect(scheduler)
    if getattr(client, "dashboard_link", None):
        note(f"dask dashboard: {client.dashboard_link}")
    futures: dict[Any, Case] = {}
    try:
        for c in order:
            fut = client.submit(_run_case, *args[c.name], pure=False,
                                key=f"case-{c.name}-{token}", priority=rank[c.name])
            futures[fut] = c
    except BaseException:
        if own:
            client.close()
        raise

    def outcomes():
        for fut in as_completed(list(futures)):
            # forget the future once read: Dask then has no result to recompute when the
            # worker that holds it dies (the task would find its case complete anyway)
            case = futures.pop(fut)
            try:
                value = fut.result()
            except Exception as exc:  # the task itself died (worker lost, no directory)
                yield case, False, exc
            else:
                yield case, True, value

    def stop(interrupted: bool):
        if interrupted:
            with contextlib.suppress(Exception):  # never hide the interrupt itself
                client.cancel([f for f in futures if not f.done()])
        if own:
            client.close()
        return None

    return stop, outcomes()


#: the scene keys by which one case costs more than another of the same sweep, in order: the
#: simulated time, then the speed of sliding (the default solver's steps grow with it: the
#: roughness passes the contacts faster)
_COST_KEYS = (("output", "duration"), ("excitation", "target_rms_velocity"),
              ("excitation", "velocity"))


def _longest_first(base: Scene, cases: list[Case]) -> dict[str, int]:
    """Priorities that start the cases expected to take longest first.

    The cases are submitted in the order of their priority, and a Dask cluster also gets
    them as task priorities (equal priorities in the order submitted); the local pool runs
    them in the order submitted. A long case started last would run alone at the end: on 2 workers
    the 12 cases of ``paper-velocity`` (solver CPU 1.9-5.4 s each) take 24.0 s of
    solver time in the order of the grid and 22.5 s longest first (22.4 s is the even split).
    The estimate only orders the cases, by the values of :data:`_COST_KEYS` (the case's own,
    else the base scene's); it changes no result.
    """
    def key(case: Case) -> tuple[float, ...]:
        out = []
        for section, field in _COST_KEYS:
            v = case.values.get(f"{section}.{field}", getattr(getattr(base, section), field,
                                                               None))
            try:
                out.append(abs(float(v)) if v is not None else 0.0)
            except (TypeError, ValueError):
                out.append(0.0)
        return tuple(out)

    keys = sorted({key(c) for c in cases})
    return {c.name: keys.index(key(c)) for c in cases}


def _record_failure(cases_dir: Path, name: str, status: str, message: str) -> None:
    """Write a failed case's directory from the client (when the task could not)."""
    try:
        tmp = _new_tmp(cases_dir, name)
        try:
            _write_json(tmp / "summary.json", _failure_summary(name, status, message))
            _write_json(tmp / "case.json", {"name": name, "status": status})
            swap_into_place(tmp, cases_dir / name)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    except OSError:
        pass  # the table still carries the error (collect_table's ``errors``)
