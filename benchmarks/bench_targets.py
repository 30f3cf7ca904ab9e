"""Benchmark: the wall time of a default run, a sweep and an ensemble, each as a user runs it.

Run on demand, not by the tests (``nice`` on a shared machine; one at a time):

    python benchmarks/bench_targets.py                 # all three
    python benchmarks/bench_targets.py --quick         # 10-seed ensemble instead of 100
    python benchmarks/bench_targets.py --only run --repeat 5
    python benchmarks/bench_targets.py --only sweep --only ensemble --json out.json

The three targets (docs/performance.md, "The warm default run" and "Sweeps and ensembles"):

1. **default run, warm**: ``roughvib run`` (the ``paper`` scene, every default) with numba's
   and roughvib's caches filled by one unmeasured run first: at most 2 s wall for the whole
   command;
2. **paper-velocity sweep**: ``roughvib sweep paper-velocity`` (12 cases, local pool of one
   worker per core) into a new directory: at most 10 s wall on 2 cores;
3. **roughness ensemble**: ``roughvib run paper --seeds 100`` into a new directory: at most
   60 s wall (``--quick``: 10 seeds, no target; the time per seed is printed).

Each command runs in a fresh subprocess (``python -m roughvib``, this checkout's sources, or
``--src``), exactly as a user types it, with ``--no-progress``. For each the script prints the
wall time, the CPU seconds of the command and every process it started (user + system, from
``getrusage(RUSAGE_CHILDREN)``: much less sensitive to other jobs on the machine than wall time),
the solver's share (sum of the runs' own ``cpu_time``, from their summary.json) and the load
average before and after. ``solver CPU / cores`` is the floor the solver alone puts under the
wall time of a sweep on this machine; the rest is the fixed cost (start-up, Dask, imports, the
pilot solve, files, tables, report).

A target is met when every measured run is within it (the line says how many are). Each warm
default run is followed by a bare numba process (:data:`BARE_NUMBA`: Python, ``import numba``
and one call from numba's cache, nothing of roughvib's): its wall time shows how fast the
machine is at that moment (the same code's runs fall into faster and slower phases of the
shared host), and the run's wall time less it is what roughvib adds to numba's own start-up.

On a shared machine, read the CPU columns and repeat; the wall times are upper bounds.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

# this folder's module (the script's own directory is on sys.path)
from machine import describe, timed_python

HERE = Path(__file__).resolve().parent

TARGETS = {"run": 2.0, "sweep": 10.0, "ensemble": 60.0}  # [s] wall, the targets above


#: a process that does what every roughvib run must before its own work: start Python, import
#: numba (with numpy) and call one function from numba's cache (numba's set-up on first use,
#: which imports scipy.linalg for its BLAS check)
BARE_NUMBA = """import numba
import numpy as np


@numba.njit(cache=True)
def total(a):
    s = 0.0
    for x in a:
        s += x
    return s


total(np.ones(3))
"""


def _command(env: dict, args: list[str]) -> dict:
    """Run ``python -m roughvib ARGS`` (:func:`machine.timed_python`)."""
    return timed_python(["-m", "roughvib", *args], env)


def _solver_cpu(summary: Path) -> tuple[float, float]:
    """(solver cpu_time incl. the pilot, pilot wall) of one run's summary.json [s]."""
    s = json.loads(summary.read_text())["solver"]
    return float(s.get("cpu_time", 0.0)), float(s.get("pilot", {}).get("wall_time", 0.0))


def _cases(directory: Path) -> tuple[int, float, float, float]:
    """(cases, sum of solver CPU, sum of pilot wall, sum of case wall) of a sweep directory."""
    n, cpu, pilot, case_wall = 0, 0.0, 0.0, 0.0
    for d in sorted((directory / "cases").iterdir()):
        if not (d / "summary.json").is_file():
            continue
        c, p = _solver_cpu(d / "summary.json")
        n, cpu, pilot = n + 1, cpu + c, pilot + p
        try:
            case_wall += float(json.loads((d / "case.json").read_text())["wall_time"])
        except (OSError, KeyError, ValueError):
            pass
    return n, cpu, pilot, case_wall


def bench_run(env: dict, base: Path, repeat: int, extra: list[str]) -> dict:
    """The warm default run, each alternated with the bare numba process (:data:`BARE_NUMBA`)
    so that the machine's speed at the time shows next to the run's own share."""
    out = base / "run"
    args = ["run", "--out", str(out), "--no-progress", "--quiet", *extra]
    bare = base / "bare_numba.py"
    bare.write_text(BARE_NUMBA)
    _command(env, args)  # fills numba's and roughvib's caches: the measured runs are warm
    timed_python([str(bare)], env)
    runs, baseline = [], []
    for _ in range(repeat):
        r = _command(env, args)
        r["solver_cpu"], r["pilot_wall"] = _solver_cpu(out / "summary.json")
        runs.append(r)
        baseline.append(timed_python([str(bare)], env))
    return {"runs": runs, "baseline": baseline}


def _baseline_row(res: dict) -> str:
    """The bare numba process's walls and each run's wall less the one after it."""
    bare = [r["wall"] for r in res["baseline"]]
    own = [r["wall"] - b for r, b in zip(res["runs"], bare, strict=True)]
    walls = ", ".join(f"{w:.2f}" for w in bare)
    owns = ", ".join(f"{w:.2f}" for w in own)
    return (f"{'bare numba (import, cached call)':<34} wall {walls} s (median "
            f"{statistics.median(bare):.2f}), each after the run above\n"
            f"{'run less the bare numba after it':<34} {owns} s (median "
            f"{statistics.median(own):.2f})")


def bench_study(env: dict, base: Path, name: str, args: list[str], repeat: int,
                workers: int) -> dict:
    runs = []
    for i in range(repeat):
        out = base / f"{name}-{i}"
        r = _command(env, [*args, "--out", str(out), "--no-progress"])
        n, cpu, pilot, case_wall = _cases(out)
        r.update(cases=n, solver_cpu=cpu, pilot_wall=pilot, case_wall=case_wall,
                 solver_floor=cpu / workers)
        runs.append(r)
        shutil.rmtree(out, ignore_errors=True)
    return {"runs": runs}


def _row(label: str, res: dict, target: float | None) -> str:
    walls = [r["wall"] for r in res["runs"]]
    cpus = [r["cpu"] for r in res["runs"]]
    solver = [r["solver_cpu"] for r in res["runs"]]
    within = sum(w <= target for w in walls) if target is not None else 0
    verdict = "" if target is None else ("met" if within == len(walls) else "NOT met")
    loads = ", ".join(f"{r['load_before']:.1f}/{r['load_after']:.1f}" for r in res["runs"])
    line = (f"{label:<34} wall {', '.join(f'{w:.2f}' for w in walls)} s (median "
            f"{statistics.median(walls):.2f}); CPU {statistics.median(cpus):.2f} s, of it "
            f"solver {statistics.median(solver):.2f} s; load before/after {loads}")
    if "solver_floor" in res["runs"][0]:
        r0 = res["runs"][0]
        line += (f"\n{'':<34} {r0['cases']} cases; solver CPU / workers = "
                 f"{statistics.median(r['solver_floor'] for r in res['runs']):.2f} s; "
                 f"pilots {r0['pilot_wall']:.2f} s wall in all; per case "
                 f"{statistics.median(r['wall'] for r in res['runs']) / max(r0['cases'], 1):.2f}"
                 f" s wall")
    if target is not None:
        line += (f"\n{'':<34} target <= {target:g} s: {verdict} ({within} of {len(walls)} "
                 f"runs within it; slowest {max(walls):.2f} s)")
    return line


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", action="append", choices=["run", "sweep", "ensemble"],
                   help="measure only these targets (repeatable; default all three)")
    p.add_argument("--quick", action="store_true",
                   help="ensemble of 10 seeds instead of 100 (no target; minutes less)")
    p.add_argument("--seeds", type=int, default=None, help="ensemble size (default 100)")
    p.add_argument("--repeat", type=int, default=3, help="measured default runs (median)")
    p.add_argument("--repeat-studies", type=int, default=1,
                   help="measured sweeps and ensembles each (default 1: they take minutes)")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes of the sweep and ensemble (default: all cores, as "
                        "the commands' own default)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="passed to every command (e.g. solver.method=...); not for targets")
    p.add_argument("--src", default=str(HERE.parent / "src"),
                   help="the roughvib sources to measure (default: this checkout's src/)")
    p.add_argument("--json", default=None, help="also write the measurements to this file")
    a = p.parse_args()
    only = a.only or ["run", "sweep", "ensemble"]
    seeds = a.seeds or (10 if a.quick else 100)
    workers = a.workers or os.cpu_count() or 1
    # as a user runs it: these sources, byte-code cached (some sandboxes set
    # PYTHONDONTWRITEBYTECODE, which makes every import of roughvib compile its sources)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = str(Path(a.src).resolve())
    sets = [x for s in a.set for x in ("--set", s)]
    wk = ["--workers", str(a.workers)] if a.workers else []
    base = Path(tempfile.mkdtemp(prefix="bench_targets_"))
    report = {"src": env["PYTHONPATH"], "cpus": os.cpu_count(), "workers": workers,
              "python": sys.version.split()[0], "load_average_before": os.getloadavg(),
              "sets": a.set, "machine": describe()}
    print(report["machine"])
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()}, sources {env['PYTHONPATH']}")
    try:
        if "run" in only:
            report["run"] = bench_run(env, base, a.repeat, sets)
            print(_row("roughvib run (paper), warm", report["run"],
                       TARGETS["run"] if not a.set else None), flush=True)
            print(_baseline_row(report["run"]), flush=True)
        if "sweep" in only:
            report["sweep"] = bench_study(env, base, "sweep",
                                          ["sweep", "paper-velocity", *sets, *wk],
                                          a.repeat_studies, workers)
            print(_row(f"sweep paper-velocity ({workers} workers)", report["sweep"],
                       TARGETS["sweep"] if not a.set else None), flush=True)
        if "ensemble" in only:
            report["ensemble"] = bench_study(env, base, "ensemble",
                                             ["run", "paper", "--seeds", str(seeds), "--quiet",
                                              *sets, *wk], a.repeat_studies, workers)
            print(_row(f"run paper --seeds {seeds} ({workers} workers)", report["ensemble"],
                       TARGETS["ensemble"] if seeds == 100 and not a.set else None),
                  flush=True)
    finally:
        shutil.rmtree(base, ignore_errors=True)
    report["load_average_after"] = os.getloadavg()
    print(f"load average after: {report['load_average_after']}")
    if a.json:
        Path(a.json).write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
