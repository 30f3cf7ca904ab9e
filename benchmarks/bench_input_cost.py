"""Benchmark: what the physical input costs the default solve, at equal contact count.

Run on demand, not by the tests:

    python benchmarks/bench_input_cost.py                   # paper and paper-100mms
    python benchmarks/bench_input_cost.py paper --repeat 3
    python benchmarks/bench_input_cost.py --processes 5     # the ratio in 5 fresh processes

For each scene, in one process, the default run's solve (adaptive-modal at ``reference``, its
plate tolerance set by the pilot as in ``roughvib run``) on the default input (the surface's
self-affine tail to the automatic limit, through the contact filter, on the automatic grid with
the quintic interpolant) and on the paper's band input (the surface stopped at 50 um, no
contact filter, a 10 um grid, a cubic spline: the input of roughvib before the tail) are timed
warm, the best CPU time of ``--repeat`` solves each, alternating. Both have the contact points,
stiffness and spot radius of the default run (resolved once, then fixed), so the ratio is the
input's cost at equal contact count. Printed with the machine: CPU times, kept steps, step
evaluations, events and restarts of each, and their ratio. ``--processes N`` repeats each
scene in N fresh processes and prints the median and range of the ratio.

OpenBLAS is held to one thread, as in ``bench_floor_ratio.py``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy is imported

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
import tomllib  # noqa: E402
import warnings  # noqa: E402
from dataclasses import replace  # noqa: E402

from machine import describe, measurements, ratio_line  # noqa: E402  (this folder's; the script's directory is on sys.path)

from roughvib import simulation  # noqa: E402
from roughvib.model.system import assemble  # noqa: E402
from roughvib.scene import ModelValidityWarning, load_scene  # noqa: E402

#: the paper's band input (what the default input replaced), at the default run's contacts
PAPER_BAND = {"roughness.shortest_wavelength": 50e-6, "roughness.spacing": 1e-5,
              "roughness.interpolation": "cubic", "contact.filter": "none"}
#: the target of the issue that brought the physical input
TARGET_RATIO = 1.5


def _system(scene):
    scene = replace(scene, solver=scene.resolved_solver())
    system, _ = simulation._scale_atol_acceleration(assemble(scene))
    return system


def _best_cpu(systems, repeat: int):
    """Best CPU time [s] of ``repeat`` solves of each system after one warm-up each, the
    systems' solves alternating. Returns ``[(best, raw), ...]``."""
    raws = [simulation._solve(s, progress=False) for s in systems]
    best = [float("inf")] * len(systems)
    for _ in range(repeat):
        for i, system in enumerate(systems):
            t0 = time.process_time()
            raws[i] = simulation._solve(system, progress=False)
            best[i] = min(best[i], time.process_time() - t0)
    return list(zip(best, raws, strict=True))


def _row(t: float, raw) -> dict:
    st = raw.stats
    return {"cpu": t, "steps": st.get("steps"), "evaluations": st.get("step_evaluations"),
            "events": len(raw.events), "restarts": st.get("restarts"), "status": raw.status}


def measure(name: str, repeat: int) -> dict:
    """The default solve on the physical and on the paper's band input of scene ``name``."""
    scene = load_scene(name, {"output.progress": False})
    # the contacts as the default run resolves them (the saved scene.toml of a short run)
    with warnings.catch_warnings():  # 0.02 s: shorter than a period, which is known here
        warnings.simplefilter("ignore", ModelValidityWarning)
        short = simulation.simulate(scene.with_overrides({"output.duration": 0.02,
                                                          "output.transient": 0.0}),
                                    progress=False)
    resolved = tomllib.loads(short.scene_toml)["contact"]
    fixed = {f"contact.{k}": resolved[k] for k in ("points", "stiffness", "spot_radius")}
    fixed["excitation.force_amplitude"] = tomllib.loads(
        short.scene_toml)["excitation"]["force_amplitude"]
    fixed["excitation.target_rms_velocity"] = "none"
    physical = scene.with_overrides(fixed)
    band = physical.with_overrides(PAPER_BAND)
    (t_p, raw_p), (t_b, raw_b) = _best_cpu([_system(physical), _system(band)], repeat)
    return {"scene": name, "points": fixed["contact.points"],
            "physical": _row(t_p, raw_p), "band": _row(t_b, raw_b), "ratio": t_p / t_b}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=["paper", "paper-100mms"])
    ap.add_argument("--repeat", type=int, default=2, help="timed solves per input (best)")
    ap.add_argument("--processes", type=int, default=0,
                    help="measure each scene in this many fresh processes and summarise")
    ap.add_argument("--json-line", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.json_line:
        print(json.dumps(measure(args.scenes[0], args.repeat)))
        return
    print(describe())
    print("| scene | points | input | CPU [s] | steps | evaluations | events | restarts | "
          "ratio |")
    print("|---|---|---|---|---|---|---|---|---|")
    ratios: dict[str, list[float]] = {}
    for name, r in measurements(__file__, args.scenes, args.repeat, args.processes, measure):
        ratios.setdefault(name, []).append(r["ratio"])
        for key, label in (("physical", "physical"), ("band", "paper's band")):
            x = r[key]
            print(f"| `{name}` | {r['points']} | {label} | {x['cpu']:.3f} | "
                  f"{x['steps']:,} | {x['evaluations']:,} | {x['events']} | "
                  f"{x['restarts']} | {r['ratio']:.2f} |", flush=True)
    for name, rs in ratios.items():
        print(ratio_line(name, rs, TARGET_RATIO, "ratio physical / paper's band"))

if __name__ == "__main__":
    main()
