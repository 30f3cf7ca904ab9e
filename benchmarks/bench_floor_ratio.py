"""Benchmark: the default solver's time as a multiple of the fixed-step floor.

Run on demand, not by the tests:

    python benchmarks/bench_floor_ratio.py                  # paper and paper-100mms
    python benchmarks/bench_floor_ratio.py paper --repeat 3
    python benchmarks/bench_floor_ratio.py --processes 7    # the ratio in 7 fresh processes

For each scene, in one process (so that both see the same machine load), the default run's
solver (adaptive-modal at the ``reference`` preset, its plate tolerance set by the pilot solve
as in ``roughvib run``) and the exact-modal fixed-step scheme at the 1e-5 s output step (the
cheapest scheme that produces the same output grid: the floor) are timed warm, the best CPU
time of ``--repeat`` solves each (numba compilation and loading excluded by a first call),
the two solvers' solves alternating (so that a drift of the machine's speed within the
process reaches both alike).
Printed: solver CPU times, step counts and their ratio. ``--processes N`` measures each
scene in N fresh processes, one after the other, and prints each process's row and the
median, range and count at or below the target of the ratios: a process keeps its speed
through its repeats (measured: the best of five solves of one process read 0.22-0.32 s from
one process to the next on an idle machine), so one process's ratio is one draw, and the
target is judged on the median of several. Only the solve is timed: assembly,
force calibration and the pilot are the same for both and are measured by
``bench_fixed_cost.py``.

OpenBLAS is held to one thread (``OPENBLAS_NUM_THREADS=1`` unless set): the floor solves its
contact system with ``numpy.linalg.solve``, whose OpenBLAS worker threads otherwise spin
between calls, and their CPU time counts in the process's (measured: the floor's process
CPU time 2.1-3.5 s against 0.29-0.41 s held to one thread, on a loaded machine). The adaptive
solver calls no BLAS.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy is imported

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402

from machine import describe, measurements, ratio_line  # noqa: E402  (this folder's; the script's directory is on sys.path)

from roughvib import simulation  # noqa: E402
from roughvib.model.system import assemble  # noqa: E402
from roughvib.scene import load_scene  # noqa: E402

#: the floor: the exact-modal fixed-step scheme at the output step [s]
FLOOR_STEP = 1e-5
#: the target: the default solve at most this multiple of the floor's
TARGET_RATIO = 1.5


def _best_cpu(systems, repeat: int):
    """Best process CPU time [s] of ``repeat`` solves of each system, after one untimed
    warm-up solve each; the systems' solves alternate, so that a change of the machine's
    speed within the process reaches all of them alike. Returns ``[(best, raw), ...]``."""
    raws = [simulation._solve(system, progress=False) for system in systems]
    best = [float("inf")] * len(systems)
    for _ in range(repeat):
        for i, system in enumerate(systems):
            t0 = time.process_time()
            raws[i] = simulation._solve(system, progress=False)
            best[i] = min(best[i], time.process_time() - t0)
    return list(zip(best, raws, strict=True))


def measure(name: str, repeat: int) -> dict:
    """The default solver's and the floor's solve times on scene ``name``."""
    scene = load_scene(name, {"output.progress": False})
    scene = replace(scene, solver=scene.resolved_solver())
    system, pilot = simulation._scale_atol_acceleration(assemble(scene))
    floor_scene = replace(scene, solver=replace(scene.solver, method="exact-modal",
                                                step=FLOOR_STEP))
    floor = replace(system, scene=replace(floor_scene,
                                          solver=floor_scene.resolved_solver()))
    (t_def, raw_def), (t_floor, raw_floor) = _best_cpu([system, floor], repeat)
    return {"scene": name, "method": scene.solver.method,
            "atol_acceleration": pilot.get("atol_acceleration"),
            "default_cpu": t_def, "default_steps": raw_def.stats.get("steps"),
            "default_propagations": raw_def.stats.get("step_evaluations"),
            "floor_cpu": t_floor, "floor_steps": raw_floor.stats.get("steps"),
            "ratio": t_def / t_floor, "status": (raw_def.status, raw_floor.status)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=["paper", "paper-100mms"])
    ap.add_argument("--repeat", type=int, default=2, help="timed solves per solver (best)")
    ap.add_argument("--processes", type=int, default=0,
                    help="measure each scene in this many fresh processes and summarise")
    ap.add_argument("--json-line", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.json_line:  # one measurement for the parent of --processes
        print(json.dumps(measure(args.scenes[0], args.repeat)))
        return
    print(describe())
    print("| scene | default: steps | propagations | CPU [s] | floor: steps | CPU [s] | "
          "ratio |")
    print("|---|---|---|---|---|---|---|")
    ratios = {}
    for name, r in measurements(__file__, args.scenes, args.repeat, args.processes, measure):
        ratios.setdefault(name, []).append(r["ratio"])
        print(f"| `{name}` | {r['default_steps']:,} | {r['default_propagations']:,} | "
              f"{r['default_cpu']:.3f} | {r['floor_steps']:,} | {r['floor_cpu']:.3f} | "
              f"{r['ratio']:.2f} |", flush=True)
    if args.processes:
        for name, rs in ratios.items():
            print(ratio_line(name, rs, TARGET_RATIO))

if __name__ == "__main__":
    main()
