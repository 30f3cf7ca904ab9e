"""Benchmark: the cost of one IDA restart (what every event costs on top of the smooth path).

Run on demand, not by the tests:

    python benchmarks/bench_restart.py [--scene paper] [--duration 0.05]

Forced restarts are made with checkpoints (``output.checkpoint_interval``: at each one IDA is
re-initialised from a consistent state at a grid time, exactly as after an event, but without
writing a file when no directory is given). The extra steps, residual evaluations and wall
time over the run without forced restarts, divided by the number of restarts, is the cost per
restart. Prints a table and a JSON record for docs/performance.md.
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import roughvib


def _run(scene):
    t0 = time.perf_counter()
    r = roughvib.simulate(scene, progress=False)
    wall = time.perf_counter() - t0
    s = r.summary["solver"]
    return {"wall": s["wall_time"], "total_wall": wall, "steps": s.get("steps"),
            "res": s["residual_evaluations"], "restarts": s.get("restarts", 0),
            "checkpoints": s.get("checkpoints", 0), "ok": r.ok}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="paper-handset")
    p.add_argument("--duration", type=float, default=0.05)
    p.add_argument("--intervals", default="0,1e-3,2e-4,1e-4",
                   help="comma list of forced-restart intervals [s] (0: none)")
    a = p.parse_args()
    base = roughvib.load_scene(a.scene, {"output.duration": a.duration,
                                         "output.progress": False})
    _run(base.with_overrides({"output.duration": 0.002}))  # JIT warm-up
    rows = []
    for iv in (float(v) for v in a.intervals.split(",")):
        rows.append({"interval": iv, **_run(base.with_overrides(
            {"output.checkpoint_interval": iv}))})
    ref = rows[0]
    print(f"{'interval [s]':>12} {'forced':>7} {'steps':>8} {'res':>8} {'wall [s]':>9} "
          f"{'+steps/restart':>15} {'+ms/restart':>12}")
    for r in rows:
        n = r["checkpoints"]
        ds = (r["steps"] - ref["steps"]) / n if n and r["steps"] else float("nan")
        dw = 1e3 * (r["wall"] - ref["wall"]) / n if n else float("nan")
        r.update(extra_steps_per_restart=ds, extra_ms_per_restart=dw)
        print(f"{r['interval']:>12g} {n:>7d} {r['steps']:>8d} {r['res']:>8d} {r['wall']:>9.2f} "
              f"{ds:>15.1f} {dw:>12.2f}")
    print(json.dumps({"benchmark": "restart_cost", "scene": a.scene, "duration": a.duration,
                      "rows": rows, "machine": platform.platform()}))


if __name__ == "__main__":
    main()
