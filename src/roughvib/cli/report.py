"""``roughvib report DIR``: the self-contained HTML report of a run."""

from __future__ import annotations

import argparse
import math
import sys

from roughvib.cli.args import failed_run_note, out_path

__all__ = ["add_parsers", "cmd_report"]


def cmd_report(args: argparse.Namespace) -> int:
    """``roughvib report DIR``: write DIR/report.html and print its path.

    Returns
    -------
    int
        0 on success (also for the report of a failed run, which shows what the run recorded
        up to the failure under a banner, with a note on stderr), 2 if DIR
        is not a readable result directory, an option is out of range or the --out file
        exists (without --overwrite); a file that cannot be written (a full disk) is
        :class:`~roughvib.rundir.WriteError` (exit status 1).
    """
    noise = getattr(args, "noise_floor", None)
    dpi = getattr(args, "dpi", 90)
    if noise is not None and not (noise >= 0 and math.isfinite(noise)):
        print(f"roughvib: error: --noise-floor must be >= 0 m/s^2, got {noise}", file=sys.stderr)
        return 2
    if not 20 <= dpi <= 600:
        print(f"roughvib: error: --dpi must be in [20, 600], got {dpi}", file=sys.stderr)
        return 2
    from roughvib.views.report import write_report

    try:
        path = write_report(args.dir, out=out_path(getattr(args, "out", None)), dpi=dpi,
                            noise_rms=noise, overwrite=getattr(args, "overwrite", False))
    except (FileNotFoundError, ValueError) as exc:
        print(f"roughvib: error: {exc}", file=sys.stderr)
        return 2
    summary = _summary_of(args.dir)
    if summary.get("status") != "success":
        print(failed_run_note(args.dir, summary), file=sys.stderr)
    print(path)
    return 0


def _summary_of(result_dir) -> dict:
    from roughvib.results import read_summary

    try:  # write_report has read and checked it
        return read_summary(result_dir)
    except (OSError, ValueError):
        return {}


def add_parsers(subparsers) -> argparse.ArgumentParser:
    """Add the ``report`` subcommand to the CLI's subparsers.

    Parameters
    ----------
    subparsers
        The object returned by ``ArgumentParser.add_subparsers``.

    Returns
    -------
    argparse.ArgumentParser
        The ``report`` parser (its handler, :func:`cmd_report`, set as ``func``).
    """
    p = subparsers.add_parser(
        "report", formatter_class=argparse.RawDescriptionHelpFormatter,
        help="write a self-contained HTML report of a run",
        description="Write DIR/report.html: the scene, summary tables (levels, contact "
                    "resonance, third-octave band levels in dB re 1e-6 m/s^2), solver "
                    "statistics, energy audit, the per-cycle event phase table and every "
                    "figure (velocity, friction-velocity, friction-displacement, acceleration, "
                    "spectra, wavenumber, events) as embedded PNGs. The file opens in a browser "
                    "without a server. The report of a failed run opens with a banner and shows "
                    "what the run recorded up to the failure (partial.nc, events.csv).",
        epilog="examples:\n"
               "  roughvib run --out runs/paper && roughvib report runs/paper\n"
               "  roughvib report runs/paper --noise-floor 1e-3   # block accelerometer floor\n"
               "  roughvib report runs/paper --out /tmp/paper.html --dpi 120 --overwrite\n")
    p.add_argument("dir", help="result directory written by 'roughvib run'")
    p.add_argument("--out", metavar="HTML", help="output file (default: DIR/report.html, "
                                                 "replaced by each new report)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the --out file if it exists (without it, it is refused)")
    p.add_argument("--noise-floor", type=float, metavar="RMS",
                   help="add white noise of this rms [m/s^2] to the block acceleration in the "
                        "spectra figure (the paper's simulated measuring-chain floor; "
                        "1e-3 is an estimate of it)")
    p.add_argument("--dpi", type=int, default=90, help="resolution of the figures (default 90)")
    p.set_defaults(func=cmd_report)
    return p
