"""Benchmark: cost and accuracy of the accuracy presets (docs/accuracy.md's tables).

Run on demand, not by the tests:

    python benchmarks/bench_presets.py paper --out runs/presets
    python benchmarks/bench_presets.py paper-100mms --out runs/presets \
        --methods ida,adaptive-modal
    python benchmarks/bench_presets.py paper --out runs/presets --methods adaptive-modal \
        --trapezoidal --extra "rtol 1e-6, no pilot;solver.rtol=1e-6,solver.atol_acceleration=1e-8"

For one built-in scene at its default length it

1. solves the converged pair: ``adaptive-modal`` and ``ida`` at rtol 1e-9, atol 1e-14 m and
   ``atol_acceleration`` 1e-11 m/s^2 (``--no-pair`` reuses them from ``--out``), and measures
   one against the other by the accuracy contract;
2. solves every ``--methods`` x ``--levels`` preset, each in its own process (so every run pays
   its own fixed cost, as a user's run does), saving the result to ``OUT/SCENE/METHOD-LEVEL``;
   with ``--trapezoidal`` also ``adaptive-modal`` at each level with its second-order
   trapezoidal step (the step of the scenes the Hermite step does not cover), and each
   ``--extra "LABEL;KEY=VALUE,..."`` as one more row (``adaptive-modal`` unless it sets
   ``solver.method``; a key ``trapezoidal=1`` selects that step);
3. prints a Markdown table (one row per run, the scene first): wall and CPU time of the
   ``simulate`` call (pilot, calibration and assembly included) and the CPU time of the
   solve alone (``summary["solver"]["cpu_time"]``), the largest band deviation
   per signal with its band, the event-time and velocity deviations, the run's energy audit
   and the verdict against the tight ``adaptive-modal`` run
   (:func:`roughvib.analysis.accuracy.measure_accuracy`).

Runs that exist in ``OUT`` (a ``timing.json`` next to the result) are not solved again.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

from roughvib.solvers import registry

TIGHT = {"solver.rtol": 1e-9, "solver.atol": 1e-14, "solver.atol_acceleration": 1e-11}
FIXED = registry.names(registry.STEP)  # the fixed-step solvers (the others: tolerances)


def solve_one(scene_name: str, out: Path, overrides: dict) -> None:
    """Solve a scene with ``overrides``; save the result and timing.json to ``out``.

    ``overrides["trapezoidal"]`` (not a scene key) makes ``adaptive-modal`` take its
    trapezoidal step where the Hermite step would apply."""
    import roughvib

    overrides = dict(overrides)
    if overrides.pop("trapezoidal", False):
        from roughvib.solvers import adaptive_modal

        adaptive_modal.hermite_applies = lambda system: False
    over = {"output.progress": False, **overrides}
    scene = roughvib.load_scene(scene_name, over)
    t0, c0 = time.perf_counter(), time.process_time()
    result = roughvib.simulate(scene)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    result.save(out, overwrite=True)
    info = {"scene": scene_name, "overrides": over, "wall": wall, "cpu": cpu,
            "status": result.status, "solver": result.summary["solver"]}
    (out / "timing.json").write_text(json.dumps(info, indent=1, default=str))


def _run(scene_name: str, out: Path, overrides: dict) -> dict:
    if not (out / "timing.json").exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, __file__, "--child", scene_name, str(out),
                        json.dumps(overrides)], check=True)
    return json.loads((out / "timing.json").read_text())


def _fmt_band(b: dict) -> str:
    d = b["deviation_db"]
    if d is None:
        return "–"
    if isinstance(d, str):
        return d
    f = b["worst_band_hz"]
    return f"{d:+.2g} dB @ " + (f"{f / 1e3:.3g} kHz" if f >= 1e3 else f"{f:.0f} Hz")


def _g(x) -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.2g}"


def _s(seconds: float) -> str:
    """A time [s] to two digits, whole seconds from 10 s."""
    return f"{seconds:.0f}" if seconds >= 10 else f"{seconds:.2g}"


def _number(text: str):
    """A value of ``--extra``: an int, a float, true/false, or the text itself."""
    low = text.strip().lower()
    if low in ("true", "false"):
        return low == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text.strip()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene", nargs="?", default="paper", help="built-in scene (default: paper)")
    p.add_argument("--out", default="runs/presets", help="directory of the runs")
    p.add_argument("--methods", default="adaptive-modal,ida,exact-modal,newmark,paper")
    p.add_argument("--levels", default="reference,standard,draft")
    p.add_argument("--no-pair", action="store_true", help="do not solve the converged pair")
    p.add_argument("--trapezoidal", action="store_true",
                   help="also adaptive-modal at each level with its trapezoidal step")
    p.add_argument("--extra", action="append", default=[], metavar="LABEL;KEY=VALUE,...",
                   help="one more run (adaptive-modal unless solver.method is given)")
    p.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        solve_one(args.child[0], Path(args.child[1]), json.loads(args.child[2]))
        return 0

    import roughvib
    from roughvib.analysis.accuracy import measure_accuracy
    from roughvib.results import load_result

    scene = roughvib.load_scene(args.scene)
    base = Path(args.out) / args.scene
    window = {"period": scene.period, "transient": scene.output.transient}
    ref_dir, ida_dir = base / "tight-adaptive-modal", base / "tight-ida"
    if not args.no_pair:
        _run(args.scene, ref_dir, {"solver.method": "adaptive-modal", **TIGHT})
        _run(args.scene, ida_dir, {"solver.method": "ida", **TIGHT})
    ref = load_result(ref_dir)
    rows = []
    if ida_dir.exists():
        rows.append(("ida", "tight (rtol 1e-9)", ida_dir))
    for method in args.methods.split(","):
        for level in args.levels.split(","):
            d = base / f"{method}-{level}"
            _run(args.scene, d, {"solver.method": method, "solver.accuracy": level})
            rows.append((method, f"`{level}`", d))
    if args.trapezoidal:
        for level in args.levels.split(","):
            d = base / f"adaptive-modal-{level}-trapezoidal"
            _run(args.scene, d, {"solver.method": "adaptive-modal", "solver.accuracy": level,
                                 "trapezoidal": 1})
            rows.append(("adaptive-modal", f"`{level}`, trapezoidal step", d))
    for extra in args.extra:
        label, _, spec = extra.partition(";")
        over = {"solver.method": "adaptive-modal"}
        for item in filter(None, spec.split(",")):
            key, _, value = item.partition("=")
            over[key.strip()] = (json.loads(value) if value[:1] and value[:1] in "[{\"" else
                                _number(value))
        d = base / ("extra-" + "".join(c if c.isalnum() or c in "-." else "_" for c in label))
        _run(args.scene, d, over)
        rows.append((over["solver.method"], label, d))
    print(f"\n{args.scene}: against {ref_dir}\n")
    print("| scene | method | preset | as run | wall [s] | CPU [s] | solve CPU [s] | block | "
          "plate | event dt [s] | v rel. rms | energy audit | verdict |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for method, level, d in rows:
        t = json.loads((d / "timing.json").read_text())
        s = t["solver"]
        acc = measure_accuracy(load_result(d), ref, **window)
        as_run = (f"step {s['step']:g} s" if method in FIXED
                  else f"rtol {s['rtol']:g}, aa {s['atol_acceleration']:.2g}")
        e = acc["events"]
        ev = _g(e["max_dt"]) + (f" ({e['unmatched']} unmatched)" if e["unmatched"] else "")
        solve_cpu = s.get("cpu_time")
        print(f"| `{args.scene}` | `{method}` | {level} | {as_run} | {_s(t['wall'])} | "
              f"{_s(t['cpu'])} | {'–' if solve_cpu is None else _s(solve_cpu)} | "
              f"{_fmt_band(acc['bands']['block'])} | {_fmt_band(acc['bands']['plate'])} | "
              f"{ev} | {_g(acc['velocity_rel_rms'])} | {_g(acc['energy_rel_residual'])} | "
              f"**{acc['verdict']}** |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
