"""Benchmark: which IDA tolerance sets the plate-acceleration error (rtol or atol_acceleration)?

Run on demand, not by the tests:

    python benchmarks/bench_ida_tolerances.py [--duration 0.02]

The first ``--duration`` seconds of the ``paper-handset`` scene (ten contact points) from rest
(the window of bench_peers_events.py) at every pair rtol x atol_acceleration of a grid; prints
wall time (roughvib's ``wall_time``), IDA steps and the relative rms error of the plate
acceleration against IDA at rtol 1e-10, ``atol_acceleration`` 1e-12. Result in
docs/performance.md ("IDA", "Tolerances"): the error and the steps follow ``atol_acceleration``
alone.
"""

from __future__ import annotations

import argparse
import itertools

import roughvib
from roughvib.analysis.compare import relative_rms_error

SIGNAL = "plate_vertical_acceleration"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=0.02)
    a = p.parse_args()
    scene = roughvib.load_scene("paper-handset", {"output.duration": a.duration,
                                                  "output.progress": False})

    def run(over: dict):
        r = roughvib.simulate(scene.with_overrides(over))
        st = r.summary["solver"]
        return r.dataset[SIGNAL].values, st["wall_time"], st["steps"]

    run({"output.duration": 2e-4})  # JIT warm-up
    ref, _, _ = run({"solver.rtol": 1e-10, "solver.atol_acceleration": 1e-12})
    print(f"{'rtol':>8} {'atol_acc [m/s^2]':>17} {'wall [s]':>9} {'steps':>8} {'error':>9}")
    for rtol, factor in itertools.product([1e-5, 1e-6, 1e-7, 1e-8], [1, 1e-1, 1e-2, 1e-3, 1e-4]):
        sig, wall, steps = run({"solver.rtol": rtol, "solver.atol_acceleration": rtol * factor})
        print(f"{rtol:>8.0e} {rtol * factor:>17.0e} {wall:>9.2f} {steps:>8d} "
              f"{relative_rms_error(sig, ref):>9.2e}", flush=True)


if __name__ == "__main__":
    main()
