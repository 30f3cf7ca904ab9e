"""``roughvib compare``: the work-precision study."""

from __future__ import annotations

import argparse

from roughvib.cli.args import EXIT_OK, InputError, parse_sets

__all__ = ["add_parsers", "cmd_compare"]


def cmd_compare(args: argparse.Namespace) -> int:
    from roughvib.scene import SOLVER_METHODS, load_scene
    from roughvib.studies.compare import DEFAULT_RTOLS, DEFAULT_STEPS, crossings, run_study

    scene = load_scene(args.scene, parse_sets(args.set))
    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    for m in methods:
        if m not in SOLVER_METHODS:
            raise InputError(f"--methods must be a comma list of {', '.join(SOLVER_METHODS)}, "
                             f"got {m!r}")
    rtols = tuple(float(v) for v in args.rtols.split(",")) if args.rtols else DEFAULT_RTOLS
    steps = tuple(float(v) for v in args.steps.split(",")) if args.steps else DEFAULT_STEPS
    table = run_study(scene, args.out, budget=args.budget, reference=args.reference,
                      methods=methods, rtols=rtols, steps=steps,
                      reference_rtol=args.reference_rtol, progress=not args.no_progress)
    done = table[table["status"] == "success"]
    print(f"{len(done)} of {len(table)} runs succeeded; results in {args.out}/work_precision.*")
    for metric in ("plate_band_db_100_20k", "block_band_db_100_20k", "velocity_rel_rms"):
        for c in crossings(table, metric):
            print(f"  {c['method']} crosses ida ({metric}) at {c['wall_time']:.3g} s wall, "
                  f"error {c['error']:.3g}")
    return EXIT_OK


def add_parsers(sub) -> None:
    """Add the ``compare`` command to ``sub``, the subparsers of ``build_parser``."""
    fmt = argparse.RawDescriptionHelpFormatter
    c = sub.add_parser(
        "compare", formatter_class=fmt,
        help="work-precision study: IDA and adaptive-modal vs fixed-step schemes",
        description="Run a reference (IDA, rtol 1e-10) and then IDA and adaptive-modal over a "
                    "ladder of rtol and each fixed-step scheme over a ladder of steps while "
                    "the time budget "
                    "lasts; measure band-level, velocity, event-time and energy errors against "
                    "the reference; write work_precision.csv/.md/.png into --out.",
        epilog="examples:\n  roughvib compare paper --out runs/wp --budget 900\n"
               "  roughvib compare paper --out runs/wp --reference runs/ref "
               "--methods ida,exact-modal\n")
    c.add_argument("scene", nargs="?", default="paper", help="scene name or .toml file")
    c.add_argument("--out", required=True, metavar="DIR", help="output directory")
    c.add_argument("--budget", type=float, default=900.0,
                   help="wall-time budget of the ladder runs in seconds (default 900)")
    c.add_argument("--reference", metavar="DIR", help="use this result directory as reference")
    c.add_argument("--reference-rtol", type=float, default=1e-10,
                   help="rtol of the IDA reference (modal atol = 1e-2 x rtol m/s^2; "
                        "default 1e-10)")
    c.add_argument("--methods", default="ida,adaptive-modal,exact-modal,newmark,paper",
                   help="comma list (default: ida,adaptive-modal,exact-modal,newmark,paper)")
    c.add_argument("--rtols", help="comma list of rtols of the tolerance-driven solvers "
                                   "(default 1e-3 ... 1e-9)")
    c.add_argument("--steps", help="comma list of fixed steps in s (default 1e-4 ... 1e-7)")
    c.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene override")
    c.add_argument("--no-progress", action="store_true", help="no progress bar")
    c.set_defaults(func=cmd_compare)
