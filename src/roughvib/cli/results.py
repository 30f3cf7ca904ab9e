"""``roughvib events`` (phase table and event log) and ``roughvib plot`` (one figure) of a
saved run."""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path

from roughvib._eventlog import EVENT_KINDS, REGIME_NOTATION
from roughvib.cli.args import EXIT_OK, InputError, failed_run_note, out_path

__all__ = ["add_parsers", "cmd_events", "cmd_plot"]


def _load(dir_: str, what: str):
    """The run in ``dir_``. A failed run comes with its partial time series and event log and
    is announced by one line on stderr; without either, ``what`` (the command's output) names
    what is missing in the one-line error."""
    from roughvib.results import load_result

    try:
        r = load_result(dir_, partial=True)
    except (FileNotFoundError, ValueError) as exc:
        raise InputError(str(exc)) from None
    if r.ok:
        return r
    if r.dataset.sizes.get("time", 0) == 0 and (what != "events" or not len(r.events)):
        raise InputError(f"{dir_} holds a failed run ({r.status}) that stopped before its "
                         f"first output sample: no {what} to show; summary.json has the "
                         f"message: {r.summary.get('message')}")
    print(failed_run_note(dir_, r.summary), file=sys.stderr)
    return r


def _scene_of(result, dir_: str):
    from roughvib.scene import SceneError, scene_from_dict

    try:  # load_result has checked that it is TOML
        return scene_from_dict(tomllib.loads(result.scene_toml))
    except (SceneError, ValueError, TypeError, KeyError) as exc:
        raise InputError(f"{Path(dir_) / 'scene.toml'}: not a scene this roughvib reads "
                         f"({' '.join(str(exc).split())})") from None


def cmd_events(args: argparse.Namespace) -> int:
    import json

    import pandas as pd

    from roughvib.analysis.events import phase_table

    unknown = sorted(set(args.kind or ()) - set(EVENT_KINDS))
    if unknown:
        raise InputError(f"--kind must be one of {', '.join(EVENT_KINDS)}, got "
                         f"{', '.join(map(repr, unknown))}")
    r = _load(args.dir, "events")
    scene = _scene_of(r, args.dir)
    ds = r.dataset
    K = int(ds.sizes["contact"]) if "contact" in ds.sizes else \
        int(r.summary.get("model", {}).get("contacts", 0))
    # a failed run may have logged events after its last output sample
    ends = [float(ds["time"].values[-1])] if ds.sizes.get("time", 0) else []
    t_end = max(ends + [float(t) for t in r.events["time"]])
    ev = r.events
    if args.kind:
        kinds = set(args.kind)
        missing = kinds - set(ev["kind"].unique())
        if missing:
            print(f"note: no events of kind {', '.join(sorted(missing))} (present: "
                  f"{', '.join(sorted(ev['kind'].unique())) or 'none'})", file=sys.stderr)
        ev = ev[ev["kind"].isin(kinds)]
    table = phase_table(r.events, t_end, scene.period, K)
    if args.cycle is not None:
        if args.cycle < 0 or args.cycle >= len(table):
            raise InputError(f"--cycle must be in [0, {len(table) - 1}], got {args.cycle}")
        lo, hi = table.loc[args.cycle, ["start", "end"]]
        table = table.iloc[[args.cycle]]
        ev = ev[(ev["time"] >= lo) & (ev["time"] < hi)]
    if args.json:
        out = {"phases": table.to_dict(orient="records")}
        if args.kind or args.cycle is not None:
            out["events"] = json.loads(ev.to_json(orient="records"))
        print(json.dumps(out, indent=1))
        return EXIT_OK
    if args.kind:
        if len(ev):
            with pd.option_context("display.width", 250, "display.max_columns", 20):
                print(ev.drop(columns=["regime_before"]).head(args.max_rows)
                      .to_string(index=False))
        if len(ev) > args.max_rows:
            print(f"note: {len(ev) - args.max_rows} more events not listed (--max-rows, or "
                  f"--json for all)", file=sys.stderr)
        return EXIT_OK
    print(f"{'cycle':>5} {'start s':>8} {'stick':>6} {'sticks':>6} {'mean ms':>8} "
          f"{'lift-offs':>9} {'open ms':>8} {'guards':>6}")
    for _, row in table.iterrows():
        lifts = sum(int(row[f"lift_offs_{k}"]) for k in range(K))
        open_ms = sum(row[f"lift_off_time_{k}"] for k in range(K)) * 1e3
        print(f"{int(row['cycle']):>5} {row['start']:8.4f} {row['stick_fraction']:6.3f} "
              f"{int(row['stick_phases']):>6} {row['mean_stick_duration'] * 1e3:8.2f} "
              f"{lifts:>9} {open_ms:8.2f} {int(row['guard_activations']):>6}")
    per = {k: (int(table[f"lift_offs_{k}"].sum()), table[f"lift_off_time_{k}"].sum() * 1e3)
           for k in range(K)}
    print("lift-offs per contact: " + ", ".join(f"{k}: {n} ({ms:.2f} ms open)"
                                                 for k, (n, ms) in per.items()))
    return EXIT_OK


def cmd_plot(args: argparse.Namespace) -> int:
    from roughvib.rundir import claim_files, output_folder
    from roughvib.views.figures import FIGURES, save_figure

    if args.figure not in FIGURES:
        raise InputError(f"--figure must be one of {', '.join(sorted(FIGURES))}, got "
                         f"{args.figure!r}")
    given = out_path(args.out)
    r = _load(args.dir, "figure")
    out = given or Path(args.dir) / "figures" / f"{args.figure}.png"
    claim_files([out], overwrite=args.overwrite or given is None)
    output_folder(out.parent)
    save_figure(FIGURES[args.figure](r), out)
    print(out)
    return EXIT_OK


def add_parsers(sub) -> None:
    """Add the ``events`` and ``plot`` commands to ``sub``, the subparsers of ``build_parser``."""
    fmt = argparse.RawDescriptionHelpFormatter
    e = sub.add_parser(
        "events", formatter_class=fmt, help="phase table and event log of a run",
        description="Per excitation cycle: stick fraction, number and mean duration of stick "
                    "phases, lift-offs and open time per contact, guard activations. "
                    "--kind lists the events of the given kinds instead. A failed run shows "
                    "what it recorded up to the failure, with a note on stderr.",
        epilog="examples:\n  roughvib events runs/paper\n"
               "  roughvib events runs/paper --kind lift_off --kind touch_down --cycle 1\n"
               "  roughvib events runs/paper --json > phases.json\n\n"
               "event kinds:\n" + "".join(f"  {k:<16} {v}\n" for k, v in EVENT_KINDS.items())
               + "\n" + REGIME_NOTATION + "\n")
    e.add_argument("dir", help="result directory written by 'roughvib run'")
    e.add_argument("--kind", action="append",
                   help="list events of this kind (repeatable; the kinds are listed below)")
    e.add_argument("--cycle", type=int, help="only this excitation cycle (0-based)")
    e.add_argument("--json", action="store_true", help="machine-readable output")
    e.add_argument("--max-rows", type=int, default=200, help="rows listed with --kind")
    e.set_defaults(func=cmd_events)

    pl = sub.add_parser(
        "plot", formatter_class=fmt, help="draw a figure of a run (PNG)",
        description="Draw one figure of a saved run. Figures: velocity (Figs. 6/7), "
                    "friction-velocity (3/8), friction-displacement (9), acceleration (10/11), "
                    "spectra (14), wavenumber (5), events (regime timeline over velocity and "
                    "normal force). 'roughvib report DIR' draws them all into one HTML file. "
                    "A failed run is drawn up to the failure, with a note on stderr.",
        epilog="examples:\n  roughvib plot runs/paper --figure events\n"
               "  roughvib plot runs/paper --figure spectra --out spectra.png\n"
               "  roughvib plot runs/paper --figure spectra --out spectra.png --overwrite\n")
    pl.add_argument("dir", help="result directory written by 'roughvib run'")
    pl.add_argument("--figure", default="events", help="figure name (default: events)")
    pl.add_argument("--out", help="PNG path (default: DIR/figures/NAME.png, replaced by each "
                                  "new plot)")
    pl.add_argument("--overwrite", action="store_true",
                    help="replace the --out file if it exists (without it, it is refused)")
    pl.set_defaults(func=cmd_plot)
