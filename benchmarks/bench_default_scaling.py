"""Benchmark: how the default solver's cost grows with the plate modes and the contact points.

Run on demand, not by the tests:

    python benchmarks/bench_default_scaling.py --repeat 5 --figure docs/figures/default_scaling.png

The default run (``adaptive-modal`` at ``reference``) of ``paper`` and ``paper-100mms`` at
``plate.max_frequency`` = 10, 25, 50, 100 kHz (one contact point) and at ``contact.points`` =
1, 3, 10, 30 (modes to 50 kHz), each in its own process
(:func:`bench_step_limits.run_variant`). Prints a Markdown table of modes, contacts, steps and
solver CPU time, and the exponents p of cost ~ N^p fitted by least squares in log-log over
each series; draws both series in a log-log figure. CPU time of the solve (not wall time), so
that a busy machine distorts it less; with ``--repeat N``, the least of N processes per case,
in N rounds through all cases; the step counts are exact.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_step_limits import run_variant  # noqa: E402
from machine import describe  # noqa: E402

MAX_FREQUENCIES = (10e3, 25e3, 50e3, 100e3)
POINTS = (1, 3, 10, 30)


def exponent(n: list[float], cost: list[float]) -> float:
    """Least-squares slope of log(cost) against log(n)."""
    return float(np.polyfit(np.log(n), np.log(cost), 1)[0])


def plot(series: dict, scenes: list[str], path: str) -> None:
    """Log-log figure of both series: ``series[(scene, 'modes'|'contacts')] = (n, cpu)``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter, ScalarFormatter

    fig, axes = plt.subplots(1, 2, figsize=(8, 3.4), layout="constrained")
    for ax, name in zip(axes, ("modes", "contacts"), strict=True):
        for scene in scenes:
            n, cpu = series[(scene, name)]
            ax.loglog(n, cpu, "o-", label=f"{scene} (p = {exponent(n, cpu):.2f})")
        ax.set_xticks(n)
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        # labels at 1, 2, 5 x 10^k: a range within one decade still gets labelled ticks
        ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("plate modes" if name == "modes" else "contact points")
        ax.set_ylabel("solver CPU time [s]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title("modes (one contact point)", fontsize=9)
    axes[1].set_title("contact points (modes to 50 kHz)", fontsize=9)
    fig.savefig(path, dpi=110)


def _least_cpu(cases: list[tuple[str, dict]], repeat: int) -> list[dict]:
    """Each case's run with the least solver CPU over ``repeat`` rounds through all cases.

    Round by round, not case by case: the machine's slower phases last seconds to minutes,
    and a case's repeats spread over the whole measurement meet them less alike. The
    repeats of a case take the same steps (checked).
    """
    runs = [[] for _ in cases]
    for _ in range(max(repeat, 1)):
        for i, (scene, overrides) in enumerate(cases):
            r = run_variant(scene, overrides)
            if "steps" not in r:
                raise SystemExit(f"{scene} {overrides}: {r['status']}")
            runs[i].append(r)
    for (scene, overrides), rs in zip(cases, runs, strict=True):
        if len({r["steps"] for r in rs}) != 1:
            raise SystemExit(f"{scene} {overrides}: the repeated runs took different steps "
                             f"{[r['steps'] for r in rs]}")
    return [min(rs, key=lambda r: r["cpu_time"]) for rs in runs]


def main(argv: list[str] | None = None) -> int:
    """Solve the series, print the table and exponents, optionally save the figure."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="paper,paper-100mms")
    ap.add_argument("--figure", default=None, help="PNG file for the log-log figure")
    ap.add_argument("--repeat", type=int, default=1,
                    help="processes per case; the least solver CPU is kept (a single run "
                         "carries the machine's scatter)")
    args = ap.parse_args(argv)
    series = {}
    print(describe())
    print("| scene | series | modes | contacts | steps | solver CPU [s] |")
    print("|---|---|---|---|---|---|")
    plan = [(scene, name, key, v) for scene in args.scenes.split(",")
            for name, key, values in (("modes", "plate.max_frequency", MAX_FREQUENCIES),
                                      ("contacts", "contact.points", POINTS))
            for v in values]
    best = _least_cpu([(scene, {"output.progress": False, key: v})
                       for scene, _, key, v in plan], args.repeat)
    for scene in args.scenes.split(","):
        for name in ("modes", "contacts"):
            rows = [r for (sc, nm, _, _), r in zip(plan, best, strict=True)
                    if sc == scene and nm == name]
            n = [r["n_modes"] if name == "modes" else r["n_contacts"] for r in rows]
            cpu = [r["cpu_time"] for r in rows]
            series[(scene, name)] = (n, cpu)
            for r in rows:
                print(f"| {scene} | {name} | {r['n_modes']} | {r['n_contacts']} | "
                      f"{r['steps']} | {r['cpu_time']:.2f} |")
    print()
    for (scene, name), (n, cpu) in series.items():
        print(f"{scene}: cost ~ {name}^{exponent(n, cpu):.2f}")
    if args.figure:
        plot(series, args.scenes.split(","), args.figure)
        print(f"figure: {args.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
