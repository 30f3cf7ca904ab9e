"""Benchmark: what limits the step of the default solver (adaptive-modal at ``reference``).

Run on demand, not by the tests:

    python benchmarks/bench_step_limits.py paper
    python benchmarks/bench_step_limits.py paper-100mms --duration 0.2

The step count of an error-controlled solver is set by whatever part of the solution is
hardest to follow at the requested tolerance. Its causes are separated here by ablation: the
scene is solved once as it is and then with one ingredient changed at a time (fewer or more
plate modes, no roughness, more contact points, a looser or tighter tolerance, a coarser output
grid, the prescribed tangential motion instead of the friction-coupled block). Step counts,
rejections, root-search steps and restarts are deterministic (CPU-time independent), so the
table can be read on a loaded machine; the CPU time of the solve is printed too, for the
proportion of cost per step.

Each variant runs in its own process (``--jobs`` at a time), so that one variant's caches do
not serve another and a slow one does not hold up the table.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

from roughvib.scene import ACCURACY_PRESETS

#: the default run's plate-mode tolerance, relative to the signal level (the ``reference``
#: preset): the tolerance rows scale it, whatever the preset is
_AA_REL = ACCURACY_PRESETS["adaptive-modal"]["reference"]["atol_acceleration_relative"]
_RTOL = ACCURACY_PRESETS["adaptive-modal"]["reference"]["rtol"]
_ATOL = ACCURACY_PRESETS["adaptive-modal"]["reference"]["atol"]

#: (label, overrides): one ingredient changed per row
VARIANTS = (
    ("as is", {}),
    ("modes to 10 kHz", {"plate.max_frequency": 10e3}),
    ("modes to 25 kHz", {"plate.max_frequency": 25e3}),
    ("modes to 100 kHz", {"plate.max_frequency": 100e3}),
    ("no plate modes (max_frequency 10 Hz)", {"plate.max_frequency": 10.0}),
    ("no roughness", {"roughness.kind": "none"}),
    ("3 contact points", {"contact.points": 3}),
    ("10 contact points", {"contact.points": 10}),
    ("30 contact points", {"contact.points": 30}),
    ("rtol x 10", {"solver.rtol": 10 * _RTOL}),
    ("rtol / 10", {"solver.rtol": _RTOL / 10}),
    ("atol x 10 (displacements)", {"solver.atol": 10 * _ATOL}),
    ("atol_acceleration_relative x 10", {"solver.atol_acceleration_relative": 10 * _AA_REL}),
    ("atol_acceleration_relative / 10", {"solver.atol_acceleration_relative": _AA_REL / 10}),
    ("output step 2e-5 s", {"output.step": 2e-5}),
    ("prescribed tangential motion", {"excitation.kind": "prescribed",
                                      "excitation.velocity": 0.0}),
)

_CHILD = """
import json, sys, time
import roughvib
over = json.loads(sys.argv[2])
scene = roughvib.load_scene(sys.argv[1], over)
c0 = time.process_time()
result = roughvib.simulate(scene)
stats = result.summary["solver"]
print(json.dumps({"status": result.status, "cpu": time.process_time() - c0,
                  "n_modes": result.summary["model"]["modes"],
                  "n_contacts": result.summary["model"]["contacts"],
                  **{k: stats.get(k) for k in ("steps", "rejected_steps", "root_evaluations",
                                                 "restarts", "step_evaluations",
                                                 "nonlinear_iterations", "cpu_time",
                                                 "events_total")}}))
"""


def run_variant(scene: str, overrides: dict) -> dict:
    """Solve ``scene`` with ``overrides`` in a fresh process; the statistics as a dict."""
    done = subprocess.run([sys.executable, "-c", _CHILD, scene, json.dumps(overrides)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        return {"status": "error: " + (done.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    """Solve the variants and print the Markdown table (see module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="paper")
    ap.add_argument("--duration", type=float, default=None,
                    help="simulated time [s] (default: the scene's)")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--only", default=None,
                    help="comma-separated substrings: solve only the variants whose label has one "
                         "(the first row, 'as is', is always solved)")
    args = ap.parse_args(argv)
    base = {"output.progress": False}
    if args.duration:
        base["output.duration"] = args.duration
    chosen = [v for i, v in enumerate(VARIANTS)
              if i == 0 or args.only is None or any(s in v[0] for s in args.only.split(","))]
    with ThreadPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(lambda v: (v[0], run_variant(args.scene, {**base, **v[1]})),
                             chosen))
    ref = rows[0][1].get("steps") or 1
    print(f"scene {args.scene}" + (f", first {args.duration} s" if args.duration else ""))
    print()
    print("| variant | modes | contacts | steps | / as is | implicit steps | rejected | "
          "root-search steps | restarts | solver CPU [s] | CPU per step [µs] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for label, r in rows:
        if "steps" not in r:
            print(f"| {label} | {r['status']} ||||||||||")
            continue
        per = 1e6 * (r["cpu_time"] or 0) / max(r["steps"], 1)
        print(f"| {label} | {r['n_modes']} | {r['n_contacts']} | {r['steps']} | "
              f"{r['steps'] / ref:.2f} | {r['step_evaluations']} | {r['rejected_steps']} | "
              f"{r['root_evaluations']} | "
              f"{r['restarts']} | {r['cpu_time']:.2f} | {per:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
