"""``roughvib sweep`` (run or resume a parameter study) and ``roughvib sweep-report``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from roughvib.cli.args import EXIT_INTERRUPT, EXIT_TERM, Terminated, out_path, parse_sets
from roughvib.scene import SceneError

# the sweep machinery (the studies, the views of the report, logging, hashing) is imported by
# the sweep commands when they run: every other command, `roughvib run` first, does without

__all__ = ["add_parsers", "cmd_sweep", "cmd_sweep_report"]


def cmd_sweep(args: argparse.Namespace) -> int:
    """``roughvib sweep``: run or resume a sweep; 0 all cases succeeded, 1 some failed.

    Parameters
    ----------
    args : argparse.Namespace
        ``sweep`` (file or built-in name), ``out`` (directory or None: ``runs/<name>``),
        ``scheduler`` (address or None), ``workers`` (int or None); optional ``set`` (list of
        KEY=VALUE), ``no_progress``, ``report``, ``list``.
    """
    from roughvib.studies.sweep.ensemble import ensemble_tables
    from roughvib.studies.sweep.report import sweep_report
    from roughvib.studies.sweep.run import run_sweep
    from roughvib.studies.sweep.spec import SUCCESS, builtin_sweeps, load_sweep

    if getattr(args, "list", False):
        sweeps = builtin_sweeps()
        width = max((len(n) for n in sweeps), default=0)
        for name, descr in sweeps.items():
            print(f"{name:<{width}}  {descr}")
        return 0
    if not getattr(args, "sweep", None):
        raise SceneError(f"sweep: name a sweep file or a built-in sweep "
                         f"({', '.join(builtin_sweeps()) or 'none installed'})")
    spec = load_sweep(args.sweep, parse_sets(getattr(args, "set", None)))
    out = out_path(getattr(args, "out", None)) or Path("runs") / spec.name
    scheduler = getattr(args, "scheduler", None)
    workers = getattr(args, "workers", None)
    if scheduler and workers is not None:
        print("roughvib: note: --workers is ignored with --scheduler (the cluster has its own "
              "workers)", file=sys.stderr)
        workers = None
    quiet_log = getattr(args, "no_progress", False)
    # a report of a sweep over seeds has an ensemble section: its numbers come from the
    # workers, which hold each result, instead of loading every case again at the end
    report = getattr(args, "report", False)
    rows = report and bool(spec.to_json()["seed_keys"])
    try:
        run = run_sweep(spec, out, scheduler=scheduler, workers=workers,
                        progress=not getattr(args, "no_progress", False),
                        log=None if quiet_log else (lambda m: print(m, file=sys.stderr)),
                        case_rows=rows)
    except KeyboardInterrupt as exc:
        term = isinstance(exc, Terminated)
        print(f"roughvib: sweep {'terminated' if term else 'interrupted'}; completed cases are "
              f"kept in {out}/cases, run the same command again to resume", file=sys.stderr)
        return EXIT_TERM if term else EXIT_INTERRUPT
    n = len(run.table)
    print(f"{n} cases: {run.skipped} complete before, {run.ran} run now, {n - run.failed} "
          f"succeeded, {run.failed} failed -> {run.directory}/sweep.csv, sweep.nc")
    for _, row in run.table[run.table["status"] != SUCCESS].iterrows():
        print(f"  {row['case']}: {row['status']}: {row['message']}")
    if report:
        print(sweep_report(run.directory, ensemble=ensemble_tables(run.directory, rows=run.rows)
                           if rows else None))
    return 0 if run.failed == 0 else 1


def cmd_sweep_report(args: argparse.Namespace) -> int:
    """``roughvib sweep-report DIR``: plots and report of a sweep directory; 0 on success.

    Parameters
    ----------
    args : argparse.Namespace
        ``dir``: the sweep directory.
    """
    from roughvib.studies.sweep.report import sweep_report

    try:
        path = sweep_report(args.dir)
    except FileNotFoundError as exc:
        raise SceneError(str(exc)) from None
    print(path)
    return 0


def add_parsers(subparsers) -> None:
    """Add the ``sweep`` and ``sweep-report`` subcommands to a ``roughvib`` subparser set.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        From ``parser.add_subparsers()``.
    """
    fmt = argparse.RawDescriptionHelpFormatter
    s = subparsers.add_parser(
        "sweep", formatter_class=fmt,
        help="run a parameter study on local worker processes or a Dask cluster (resumable)",
        description="Run every case of a sweep (a base scene and the values to vary, as a grid "
                    "and/or a list of cases) as one task: on a local pool of single-threaded "
                    "worker processes by default, or as Dask tasks on the cluster of "
                    "--scheduler. Each case writes DIR/cases/<case>/ atomically; re-running "
                    "the same command skips completed cases and re-runs failed or missing "
                    "ones. At the end DIR/sweep.csv and DIR/sweep.nc hold one row per case. "
                    "See docs/sweeps.md for the file format.",
        epilog="examples:\n"
               "  roughvib sweep --list                                # built-in sweeps\n"
               "  roughvib sweep paper-velocity --out runs/velocity    # all local cores\n"
               "  roughvib sweep velocity.toml --out runs/v --workers 4\n"
               "  roughvib sweep velocity.toml --out runs/v --scheduler tcp://head:8786\n"
               "  roughvib sweep paper-velocity --set output.duration=0.2 --report\n\n"
               "exit status: 0 all cases succeeded, 1 some failed (see sweep.csv), "
               "2 bad sweep file")
    s.add_argument("sweep", nargs="?",
                   help="built-in sweep name (see --list) or a sweep .toml file")
    s.add_argument("--out", metavar="DIR", help="sweep directory (default: runs/<sweep name>)")
    s.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of a running Dask scheduler, e.g. tcp://head:8786 (default: "
                        "a local pool of worker processes); DIR must be on a filesystem the "
                        "workers share")
    s.add_argument("--workers", type=int, metavar="N",
                   help="worker processes of the local pool (default: all cores; one "
                        "thread each)")
    s.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="fixed value for every case, e.g. --set output.duration=0.2 "
                        "(repeatable; changes the case names)")
    s.add_argument("--report", action="store_true", help="write the sweep report at the end")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    s.add_argument("--list", action="store_true", help="list the built-in sweeps and exit")
    s.set_defaults(func=cmd_sweep)

    r = subparsers.add_parser(
        "sweep-report", formatter_class=fmt,
        help="plots and report of a sweep (levels vs velocity, load, roughness)",
        description="Draw total block and plate levels against friction velocity (and load, "
                    "roughness) with the fitted slope in dB per doubling and its 95 % "
                    "interval across seeds; write DIR/report/report.md, report.html, "
                    "fits.csv and the PNGs.",
        epilog="example:\n  roughvib sweep-report runs/velocity\n")
    r.add_argument("dir", help="sweep directory written by 'roughvib sweep'")
    r.set_defaults(func=cmd_sweep_report)
