"""``roughvib compare``: the work-precision study."""

from __future__ import annotations

import argparse
import sys

from roughvib.cli.args import EXIT_OK, EXIT_SOLVER, InputError, out_path, parse_sets
from roughvib.solvers import registry

__all__ = ["add_parsers", "cmd_compare"]


def cmd_compare(args: argparse.Namespace) -> int:
    from roughvib.rundir import claim_files, output_folder
    from roughvib.scene import load_scene
    from roughvib.studies.compare import (
        DEFAULT_RTOLS,
        DEFAULT_STEPS,
        BudgetExceeded,
        crossings,
        outcome_line,
        run_study,
    )

    scene = load_scene(args.scene, parse_sets(args.set))
    methods = None  # every solver that runs the scene (the registry's)
    if args.methods is not None:
        methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
        known = registry.names()
        for m in methods:
            if m not in known:
                raise InputError(f"--methods must be a comma list of {', '.join(known)}, "
                                 f"got {m!r}")
    if not args.budget > 0:
        raise InputError(f"--budget must be > 0 s, got {args.budget}")
    out = out_path(args.out)  # an empty --out is refused
    # before the study: a folder that cannot be used, or the tables of an earlier study that
    # it would replace (without --overwrite)
    claim_files([out / f"work_precision.{ext}" for ext in ("csv", "md", "png")],
                overwrite=args.overwrite)
    output_folder(out, "--out")
    rtols = tuple(float(v) for v in args.rtols.split(",")) if args.rtols else DEFAULT_RTOLS
    steps = tuple(float(v) for v in args.steps.split(",")) if args.steps else DEFAULT_STEPS
    try:
        table = run_study(scene, args.out, budget=args.budget, reference=args.reference,
                          methods=methods, rtols=rtols, steps=steps,
                          reference_rtol=args.reference_rtol,
                          reference_method=args.reference_method,
                          presets=not args.no_presets, progress=not args.no_progress,
                          started=getattr(args, "started", None))
    except BudgetExceeded as exc:
        print(f"roughvib: {exc}", file=sys.stderr)
        return EXIT_SOLVER
    print(f"{outcome_line(table)}; results in {args.out}/work_precision.*")
    for metric in ("plate_band_db", "block_band_db", "velocity_rel_rms"):
        for c in crossings(table, metric):
            print(f"  {c['method']} crosses ida ({metric}) at {c['wall_time']:.3g} s wall, "
                  f"error {c['error']:.3g}")
    return EXIT_OK


def add_parsers(sub) -> None:
    """Add the ``compare`` command to ``sub``, the subparsers of ``build_parser``."""
    fmt = argparse.RawDescriptionHelpFormatter
    c = sub.add_parser(
        "compare", formatter_class=fmt,
        help="work-precision study: every solver's cost and error, and its accuracy presets",
        description="Run a reference (adaptive-modal or IDA at rtol 1e-10), then every "
                    "solver that runs the scene: IDA and adaptive-modal over a ladder of "
                    "rtol, each fixed-step scheme over a ladder of steps, and every method at "
                    "its accuracy presets (reference, "
                    "standard, draft), cheap runs first; measure each run against the "
                    "reference with the accuracy contract's metrics (the code of 'roughvib "
                    "run --verify'); write work_precision.csv/.md/.png into --out. The "
                    "budget bounds the whole command, the reference included: a run still "
                    "going when it is spent is stopped.",
        epilog="examples:\n  roughvib compare paper --out runs/wp --budget 900\n"
               "  roughvib compare paper --out runs/wp --budget 900 --overwrite   # again\n"
               "  roughvib compare paper --out runs/wp --reference runs/ref "
               "--methods ida,exact-modal\n")
    c.add_argument("scene", nargs="?", default="paper", help="scene name or .toml file")
    c.add_argument("--out", required=True, metavar="DIR",
                   help="output directory (its work_precision.* files are not replaced "
                        "without --overwrite; a reference run there is, as by 'roughvib run')")
    c.add_argument("--overwrite", action="store_true",
                   help="replace the work_precision.* files of an earlier study in --out")
    c.add_argument("--budget", type=float, default=900.0,
                   help="wall-time budget of the whole command in seconds, reference "
                        "included (default 900)")
    c.add_argument("--reference", metavar="DIR", help="use this result directory as reference")
    c.add_argument("--reference-method", choices=("auto", *registry.names(registry.TOLERANCE)),
                   default="auto",
                   help="solver of the reference (default auto: adaptive-modal where it can "
                        "run, else ida)")
    c.add_argument("--reference-rtol", type=float, default=1e-10,
                   help="rtol of the reference (atol_acceleration = 1e-2 x rtol m/s^2; "
                        "default 1e-10)")
    c.add_argument("--methods",
                   help="comma list of solvers (default: every solver that runs the scene, "
                        "in the order " + ",".join(registry.names()) + "; the paper scene: "
                        "all but moreau, a set-valued friction law: ida,adaptive-modal,moreau)")
    c.add_argument("--rtols", help="comma list of rtols of the tolerance-driven solvers "
                                   "(default 1e-3 ... 1e-9)")
    c.add_argument("--steps", help="comma list of fixed steps in s (default 1e-4 ... 1e-7)")
    c.add_argument("--no-presets", action="store_true",
                   help="do not run the accuracy presets, only the ladders")
    c.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene override")
    c.add_argument("--no-progress", action="store_true", help="no progress bars")
    c.set_defaults(func=cmd_compare)
