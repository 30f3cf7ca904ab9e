"""Benchmark: where a sweep's or an ensemble's wall time goes, stage by stage, in one process.

Run on demand, not by the tests (one at a time on a shared machine):

    python benchmarks/bench_study_breakdown.py --sweep paper-velocity
    python benchmarks/bench_study_breakdown.py --seeds 100
    python benchmarks/bench_study_breakdown.py --seeds 10 --pool dask     # the Dask LocalCluster

The study runs in this process as ``roughvib sweep`` / ``roughvib run --seeds`` run it
(``run_sweep``, then for an ensemble ``ensemble_tables`` and ``sweep_report``), with timers
around the client's stages. ``--pool dask`` starts a Dask ``LocalCluster`` (a cluster as
``roughvib sweep --scheduler`` is given one) and hands its client to ``run_sweep``; ``--pool
local`` (default) lets ``run_sweep`` start its own local pool, as the commands do. The workers'
side is read back from the case directories: each case's wall time in its task (``case.json``),
the solve's CPU time, the pilot and the preprocessing (``summary.json``), the worker process
(``pid``).

Printed: the client's stages (imports, pool start, the cases, pool shutdown, tables, report),
the sum of the cases' solver CPU and its share per worker (the floor the solver puts under the
wall time at the solver's speed on this machine), the cases' time around the solve (per case and
the first case of each worker, which loads the solver's imports and numba kernels) and the
workers' idle time (workers x span of the cases - the cases' own wall time: start-up, scheduling
and the last cases running alone).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path


def _cpu() -> float:
    """CPU seconds of this process and its waited-for children."""
    s = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--sweep", help="a built-in sweep or sweep file")
    g.add_argument("--seeds", type=int, help="an ensemble of the paper scene over N seeds")
    p.add_argument("--pool", choices=["local", "dask"], default="local")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--keep", default=None, help="write the study here and keep it")
    a = p.parse_args()

    stages: list[tuple[str, float, float]] = []
    wall0, cpu0 = time.perf_counter(), _cpu()
    last = [wall0, cpu0]

    def mark(name: str) -> None:
        w, c = time.perf_counter(), _cpu()
        stages.append((name, w - last[0], c - last[1]))
        last[:] = [w, c]

    from roughvib.cli.args import parse_sets
    from roughvib.studies.sweep.ensemble import ensemble_tables, seed_sweep
    from roughvib.studies.sweep.report import sweep_report
    from roughvib.studies.sweep.run import run_sweep
    from roughvib.studies.sweep.spec import load_sweep

    sets = parse_sets(a.set)
    spec = seed_sweep("paper", a.seeds, sets) if a.seeds else load_sweep(a.sweep, sets)
    mark("client imports (roughvib.studies), the sweep's spec")
    client = cluster = None
    if a.pool == "dask":
        import dask.distributed

        from roughvib.studies.sweep.run import THREAD_ENV

        mark("client: import dask.distributed")
        # a cluster of the local cores, as a sweep given --scheduler would use
        cluster = dask.distributed.LocalCluster(n_workers=a.workers, threads_per_worker=1,
                                                processes=True, env=dict(THREAD_ENV))
        client = dask.distributed.Client(cluster)
        mark("start the LocalCluster (workers import distributed)")
    base = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="breakdown_"))
    out = base / spec.name
    t_cases = time.perf_counter()
    run = run_sweep(spec, out, workers=a.workers, client=client, progress=False,
                    case_rows=bool(a.seeds))
    t_end = time.perf_counter()
    mark("run_sweep (pool start, the cases, tables" +
         (")" if a.pool == "dask" else ", pool shutdown)"))
    if cluster is not None:
        client.close()
        cluster.close()
        mark("close the Dask client and LocalCluster")
    if a.seeds:
        ens = ensemble_tables(run.directory, rows=run.rows)
        mark("ensemble tables")
        sweep_report(run.directory, ensemble=ens)
        mark("ensemble report (figure, CSV, HTML)")
    total_wall, total_cpu = time.perf_counter() - wall0, _cpu() - cpu0

    # the workers' side, from the case directories
    per_pid: dict[int, list[dict]] = defaultdict(list)
    n = 0
    solver_cpu = solver_wall = pilot = pre = case_wall = 0.0
    for d in sorted((out / "cases").iterdir()):
        if d.name.startswith(".") or not (d / "summary.json").is_file():
            continue
        s = json.loads((d / "summary.json").read_text())["solver"]
        c = json.loads((d / "case.json").read_text())
        rec = {"wall": float(c["wall_time"]), "solver_wall": float(s["wall_time"]),
               "solver_cpu": float(s["cpu_time"]),
               "pilot": float(s.get("pilot", {}).get("wall_time", 0.0)),
               "pre": float(s.get("preprocessing_time", 0.0)), "finished": c["finished"]}
        per_pid[c["pid"]].append(rec)
        n += 1
        solver_cpu += rec["solver_cpu"]
        solver_wall += rec["solver_wall"]
        pilot += rec["pilot"]
        pre += rec["pre"]
        case_wall += rec["wall"]
    around = case_wall - solver_wall - pilot - pre
    print(f"{spec.name}: {n} cases, pool {a.pool}, {a.workers} workers, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    print(f"{'stage':<58} {'wall [s]':>9} {'CPU [s]':>9}")
    for name, w, c in stages:
        print(f"{name:<58} {w:9.2f} {c:9.2f}")
    print(f"{'total':<58} {total_wall:9.2f} {total_cpu:9.2f}")
    span = t_end - t_cases
    print(f"cases: solver CPU {solver_cpu:.2f} s in all, / {a.workers} workers = "
          f"{solver_cpu / a.workers:.2f} s (the floor); solver wall {solver_wall:.2f} s, "
          f"pilots {pilot:.2f} s, preprocessing {pre:.2f} s, the rest of the cases' wall "
          f"(result, files, rows) {around:.2f} s = {around / max(n, 1):.3f} s per case")
    print(f"cases' own wall {case_wall:.2f} s; run_sweep's span {span:.2f} s x {a.workers} "
          f"workers = {span * a.workers:.2f} s: workers idle (start-up, scheduling, the "
          f"tables, the end) {span * a.workers - case_wall:.2f} worker-seconds")
    for pid, recs in per_pid.items():
        oh = sorted(r["wall"] - r["solver_wall"] - r["pilot"] - r["pre"] for r in recs)
        print(f"  worker {pid}: {len(recs)} cases, {sum(r['wall'] for r in recs):.2f} s; "
              f"besides solve, pilot and preprocessing: largest {oh[-1]:.2f} s (its first "
              f"case: imports, numba kernels), median {oh[len(oh) // 2]:.3f} s; "
              f"preprocessing largest {max(r['pre'] for r in recs):.2f} s, pilot largest "
              f"{max(r['pilot'] for r in recs):.2f} s")
    if not a.keep:
        shutil.rmtree(base, ignore_errors=True)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
