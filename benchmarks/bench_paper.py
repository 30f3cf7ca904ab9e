"""Benchmark: wall time of the `paper` scene over 0.36 s (2.5 periods) with IDA at rtol 1e-6.

Run on demand, not by the tests:

    python benchmarks/bench_paper.py [--duration 0.36] [--rtol 1e-6] [--scene paper]

Prints one line per run (wall time, steps, residual and Jacobian evaluations, events, restarts,
energy-audit residual) and a JSON record for docs/performance.md. The first run in a fresh
environment includes numba compilation; the script runs a short warm-up first.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import time

import roughvib


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="paper-handset")
    p.add_argument("--duration", type=float, default=0.36)
    p.add_argument("--rtol", type=float, default=1e-6)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    a = p.parse_args()
    over = {"output.progress": False, "solver.rtol": a.rtol}
    for item in a.set:
        k, v = item.split("=", 1)
        over[k] = float(v)
    # warm-up: compiles/loads the numba kernels
    roughvib.simulate(roughvib.load_scene(a.scene, {**over, "output.duration": 0.002}))
    scene = roughvib.load_scene(a.scene, {**over, "output.duration": a.duration})
    t0 = time.perf_counter()
    r = roughvib.simulate(scene)
    wall = time.perf_counter() - t0
    s = r.summary["solver"]
    rec = {
        "scene": a.scene, "duration_s": a.duration, "rtol": a.rtol, "status": r.status,
        "wall_s": round(wall, 2), "solver_wall_s": round(s["wall_time"], 2),
        "preprocessing_s": round(s["preprocessing_time"], 2),
        "steps": s.get("steps"), "residual_evaluations": s.get("residual_evaluations"),
        "jacobian_evaluations": s.get("jacobian_evaluations"), "restarts": s.get("restarts"),
        "events": r.summary["events_by_kind"],
        "energy_relative_residual": r.summary["energy_audit"]["relative_residual"],
        "modes": r.summary["model"]["modes"],
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
        "python": platform.python_version(),
    }
    print(json.dumps(rec, indent=1))


if __name__ == "__main__":
    main()
