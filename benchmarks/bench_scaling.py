"""Benchmark: solver cost against the number of plate modes and contacts, and peak memory.

Run on demand, not by the tests:

    python benchmarks/bench_scaling.py [--duration 0.02] [--memory-duration 0.36]
        [--method ida|adaptive-modal]

Each case runs in its own subprocess (clean peak-memory numbers, no shared numba state) on the
``paper`` scene: plate.max_frequency chosen for about 100, 200, 400, 800 and 1600 modes (the
mode count is printed), and contact.points = 1, 10, 40 at the default modes. Prints wall time,
steps, time per step and peak RSS per case, the ratio t(800)/t(400) (target <= 2.2) and the
peak memory of a full ``paper`` run (target < 1 GB), then one JSON record.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys

CASE = r"""
import json, resource, sys, time
import roughvib
over = json.loads(sys.argv[1])
scene = roughvib.load_scene("paper-handset", {**over, "output.progress": False})
roughvib.simulate(scene.with_overrides({"output.duration": 0.002}))  # JIT warm-up
t0 = time.perf_counter()
r = roughvib.simulate(scene)
wall = time.perf_counter() - t0
s = r.summary["solver"]
print(json.dumps({"ok": r.ok, "modes": r.summary["model"]["modes"],
                  "contacts": r.summary["model"]["contacts"], "wall": wall,
                  "solver_wall": s["wall_time"], "steps": s.get("steps"),
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

# plate.max_frequency [Hz] for about 100 ... 1600 modes of the default plate (N ~ f)
MODE_FREQS = {100: 12.7e3, 200: 25.3e3, 400: 50.6e3, 800: 100.5e3, 1600: 199e3}


def _case(over: dict) -> dict:
    out = subprocess.run([sys.executable, "-c", CASE, json.dumps(over)], capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=0.02)
    p.add_argument("--memory-duration", type=float, default=0.36)
    p.add_argument("--method", default="ida", choices=("ida", "adaptive-modal"))
    a = p.parse_args()
    print(f"solver.method = {a.method}")
    rows = []
    print(f"{'case':>16} {'modes':>6} {'K':>3} {'wall [s]':>9} {'steps':>7} {'us/step':>8} "
          f"{'RSS MB':>7}")
    cases = [("modes~" + str(n), {"plate.max_frequency": f}) for n, f in MODE_FREQS.items()]
    cases += [(f"contacts={k}", {"contact.points": k}) for k in (1, 10, 40)]
    for name, over in cases:
        over = {**over, "output.duration": a.duration, "solver.method": a.method}
        if over.get("contact.points") == 40:
            over["contact.min_separation"] = 0.0
        r = _case(over)
        r["case"] = name
        rows.append(r)
        per = 1e6 * r["solver_wall"] / r["steps"] if r["steps"] else float("nan")
        print(f"{name:>16} {r['modes']:>6d} {r['contacts']:>3d} {r['solver_wall']:>9.2f} "
              f"{r['steps']:>7d} {per:>8.1f} {r['peak_rss_mb']:>7.0f}")
    by = {r["case"]: r for r in rows}
    ratio = by["modes~800"]["solver_wall"] / by["modes~400"]["solver_wall"]
    print(f"t(800 modes) / t(400 modes) = {ratio:.2f} (target <= 2.2)")
    mem = _case({"output.duration": a.memory_duration, "solver.method": a.method})
    print(f"paper {a.memory_duration} s: peak RSS {mem['peak_rss_mb']:.0f} MB (target < 1024), "
          f"wall {mem['wall']:.1f} s")
    print(json.dumps({"benchmark": "scaling", "method": a.method, "rows": rows,
                      "ratio_800_400": ratio, "paper_run": mem, "machine": platform.platform()}))


if __name__ == "__main__":
    main()
