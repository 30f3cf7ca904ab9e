"""Benchmark: generating and reducing the default 2-D surface.

Run on demand, not by the tests:

    python benchmarks/bench_surface.py [--repeat 3] [--layout uniform|cbrt2]

Builds the default ``reduce_3d`` profile (isotropic 2-D surface, span average over the 40 mm
block width, functional filter) and prints the wall and CPU time of each repetition, the
reduction in dB and a JSON record for docs/performance.md.
"""

from __future__ import annotations

import argparse
import json
import platform
import time

from roughvib.physics.surface.roughness import build_profile
from roughvib.scene import Block, Roughness


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--layout", default="uniform", choices=("uniform", "cbrt2"))
    a = p.parse_args()
    rough, block = Roughness(reduce_3d=True, trace_layout=a.layout), Block()
    walls, cpus = [], []
    for i in range(a.repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        prof = build_profile(rough, block)
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
        print(f"run {i}: {walls[-1]:.2f} s wall, {cpus[-1]:.2f} s CPU, "
              f"reduction {prof.stats['reduction_db']:.2f} dB over {prof.stats['n_traces']} "
              f"traces, {prof.z.size} points")
    rec = {"benchmark": "surface_reduce_3d", "layout": a.layout, "wall_s_min": min(walls),
           "cpu_s_min": min(cpus), "goal_s": 10.0, "reduction_db": prof.stats["reduction_db"],
           "machine": platform.platform(), "python": platform.python_version()}
    print(json.dumps(rec))


if __name__ == "__main__":
    main()
