"""Command-line interface: thin argument parsing around the public API (no physics here).

Exit status: 0 success, 1 solver failure (status and message in summary.json and on
stderr), 2 bad input (one line naming the field, rule, unit and value; no traceback).
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path
from typing import Any

EXIT_OK = 0
EXIT_SOLVER = 1
EXIT_INPUT = 2


class InputError(Exception):
    """Bad command-line input (exit status 2)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that runs stop the way Ctrl-C stops them."""


def _on_sigterm(signum, frame):  # pragma: no cover - exercised through a subprocess
    raise Terminated()


def _parse_value(text: str) -> Any:
    """A --set value: TOML syntax (numbers, true/false, [a, b], "str"); bare words are strings."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _parse_sets(items: list[str] | None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for item in items or []:
        if "=" not in item:
            raise InputError(f"--set expects section.key=value, got {item!r}")
        key, value = item.split("=", 1)
        out[key.strip()] = _parse_value(value.strip())
    return out


def _fmt_db(x: float | None) -> str:
    return "n/a" if x is None else f"{x:6.1f} dB"


def _print_summary(summary: dict, out_dir: Path) -> None:
    m = summary.get("metrics", {})
    s = summary.get("solver", {})
    a = summary.get("energy_audit", {})
    cal = summary.get("calibration", {})
    lines = [
        f"scene            {summary.get('scene')}  ->  {out_dir}",
        f"status           {summary.get('status')}: {summary.get('message')}",
        f"force amplitude  T0 = {summary.get('force_amplitude', float('nan')):.6g} N"
        + (f"  (target {cal['target_rms_velocity']} m/s, achieved "
           f"{cal.get('achieved_rms_velocity', float('nan')):.6g} m/s)"
           if "target_rms_velocity" in cal else ""),
    ]
    if m:
        lines += [
            f"window           {m['window_start']:.4f} .. {m['window_end']:.4f} s",
            f"velocity rms     {m.get('block_tangential_velocity_rms', float('nan')) * 1e3:.3f}"
            f" mm/s, stick fraction {m.get('stick_fraction', float('nan')):.3f}",
            f"block accel      {m.get('block_vertical_acceleration_rms', float('nan')):.4g} "
            f"m/s^2 rms ({_fmt_db(m.get('block_vertical_acceleration_level_db_re_1e-6'))} "
            f"re 1e-6 m/s^2)",
            f"plate accel      {m.get('plate_vertical_acceleration_rms', float('nan')):.4g} "
            f"m/s^2 rms ({_fmt_db(m.get('plate_vertical_acceleration_level_db_re_1e-6'))} "
            f"re 1e-6 m/s^2)",
            f"normal force     mean {m.get('normal_force_mean', float('nan')):.5g} N, "
            f"min {m.get('normal_force_min', float('nan')):.4g} N",
        ]
    ev = summary.get("events_by_kind", {})
    lines.append("events           " + (", ".join(f"{k} {v}" for k, v in sorted(ev.items()))
                                        or "none"))
    # each solver reports the counters it has (fixed-step schemes have no residual counts)
    counters = [("steps", "steps"), ("rejected_steps", "rejected"),
                ("residual_evaluations", "residuals"), ("jacobian_evaluations", "Jacobians"),
                ("root_evaluations", "root-search steps"), ("restarts", "restarts")]
    parts = [f"{s[key]} {label}" for key, label in counters if s.get(key) is not None]
    lines.append(f"solver           {s.get('method', '')}: " + ", ".join(parts)
                 + f", {s.get('wall_time', 0):.1f} s wall")
    if a:
        lines.append(f"energy audit     residual {a.get('residual', 0):.3e} J "
                     f"(relative {a.get('relative_residual', 0):.2e})")
    print("\n".join(lines))


def cmd_run(args: argparse.Namespace) -> int:
    from roughvib.api import resume, simulate
    from roughvib.scene import load_scene
    from roughvib.solvers.checkpoint import CHECKPOINT_NAME

    if args.resume:
        if args.scene is not None or args.set or args.out:
            raise InputError("--resume DIR continues the run stored in DIR; give no scene, "
                             "--set or --out with it")
        out_dir = Path(args.resume)
        runner = lambda: resume(out_dir, progress=False if args.no_progress else None)  # noqa: E731
    else:
        scene = load_scene(args.scene or "paper", _parse_sets(args.set))
        if args.no_progress:
            scene = scene.with_overrides({"output.progress": False})
        out_dir = Path(args.out) if args.out else Path("runs") / scene.name
        cp_dir = out_dir if scene.output.checkpoint_interval > 0 else None
        if cp_dir is not None and (out_dir / CHECKPOINT_NAME).exists():
            raise InputError(f"{out_dir / CHECKPOINT_NAME} exists: continue it with 'roughvib "
                             f"run --resume {out_dir}', or remove it to start again")
        runner = lambda: simulate(scene, checkpoint_dir=cp_dir)  # noqa: E731
    try:
        result = runner()
    except KeyboardInterrupt as exc:
        cp = out_dir / CHECKPOINT_NAME
        what = "terminated" if isinstance(exc, Terminated) else "interrupted"
        if cp.exists():
            print(f"roughvib: {what}; the last checkpoint is kept in {cp}: continue with "
                  f"'roughvib run --resume {out_dir}'", file=sys.stderr)
        else:
            print(f"roughvib: {what}; nothing was written", file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    result.save(out_dir)
    if result.ok:
        (out_dir / CHECKPOINT_NAME).unlink(missing_ok=True)
    if not args.quiet:
        _print_summary(result.summary, out_dir)
    if not result.ok:
        print(f"roughvib: run failed ({result.status}): {result.summary.get('message')}",
              file=sys.stderr)
        t_end = (result.summary.get("partial_result") or {}).get("t_end")
        if t_end is not None:
            print(f"roughvib: the time series up to t = {t_end:.6g} s and the event log are in "
                  f"{out_dir}/partial.nc and events.csv", file=sys.stderr)
        return EXIT_SOLVER
    return EXIT_OK


def cmd_scenes(args: argparse.Namespace) -> int:
    from roughvib.scene import builtin_scenes

    scenes = builtin_scenes()
    width = max(len(n) for n in scenes)
    for name in sorted(scenes, key=lambda n: (n != "paper", n)):
        print(f"{name:<{width}}  {scenes[name]}")
    return EXIT_OK


def _load(dir_: str):
    from roughvib.results import load_result

    try:
        r = load_result(dir_)
    except (FileNotFoundError, ValueError) as exc:
        raise InputError(str(exc)) from None
    if not r.ok:
        raise InputError(f"{dir_} holds a failed run ({r.status}): {r.summary.get('message')}")
    return r


def _scene_of(result):
    from roughvib.scene import scene_from_dict

    return scene_from_dict(tomllib.loads(result.scene_toml))


def cmd_events(args: argparse.Namespace) -> int:
    import json

    import pandas as pd

    from roughvib.analysis.events import phase_table

    r = _load(args.dir)
    scene = _scene_of(r)
    t_end = float(r.dataset["time"].values[-1])
    ev = r.events
    if args.kind:
        kinds = set(args.kind)
        unknown = kinds - set(ev["kind"].unique())
        if unknown and len(ev):
            print(f"note: no events of kind {', '.join(sorted(unknown))} (present: "
                  f"{', '.join(sorted(ev['kind'].unique()))})", file=sys.stderr)
        ev = ev[ev["kind"].isin(kinds)]
    table = phase_table(r.events, t_end, scene.period, int(r.dataset.sizes["contact"]))
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
        with pd.option_context("display.width", 200, "display.max_rows", args.max_rows,
                               "display.max_columns", 20):
            print(ev.drop(columns=["regime_before", "regime_after"]).to_string(index=False)
                  if len(ev) <= args.max_rows else ev.head(args.max_rows).to_string(index=False))
        return EXIT_OK
    K = int(r.dataset.sizes["contact"])
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
    from roughvib.views.figures import FIGURES, save_figure

    if args.figure not in FIGURES:
        raise InputError(f"--figure must be one of {', '.join(sorted(FIGURES))}, got "
                         f"{args.figure!r}")
    r = _load(args.dir)
    out = Path(args.out) if args.out else Path(args.dir) / "figures" / f"{args.figure}.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(FIGURES[args.figure](r), out)
    print(out)
    return EXIT_OK


def cmd_compare(args: argparse.Namespace) -> int:
    from roughvib.compare import DEFAULT_RTOLS, DEFAULT_STEPS, crossings, run_study
    from roughvib.scene import SOLVER_METHODS, load_scene

    scene = load_scene(args.scene, _parse_sets(args.set))
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


def cmd_surface(args: argparse.Namespace) -> int:
    import json

    from roughvib.scene import load_scene
    from roughvib.views.surface_report import write_surface_report

    scene = load_scene(args.scene, _parse_sets(args.set))
    out = Path(args.out) if args.out else Path("runs") / f"{scene.name}-surface"
    paths = write_surface_report(scene, out)
    info = json.loads(paths["contacts_json"].read_text())
    stat = info.get("statistical_contact", {})
    prof = info.get("profile", {}).get("stats", {})
    print(f"profile: {prof.get('kind')}, rms {prof.get('rms', float('nan')) * 1e6:.3g} um, "
          f"rms slope {prof.get('rms_slope', float('nan')):.3g}")
    print(f"contact stiffness used: {info['stiffness_used_N_per_m']:.4g} N/m "
          f"({info['stiffness_source']})")
    if "s_total" in stat:
        print(f"statistical contact ({stat['model']}): s_total {stat['s_total']:.4g} N/m, "
              f"{stat['micro_contacts']:.3g} micro-contacts, plasticity index "
              f"{stat['plasticity_index']:.3g}, rigid-plate resonance "
              f"{stat['resonance_hz']:.4g} Hz")
    elif "error" in stat:
        print(f"statistical contact: not available ({stat['error']})")
    for name in sorted(paths):
        print(f"  {paths[name]}")
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    fmt = argparse.RawDescriptionHelpFormatter
    p = argparse.ArgumentParser(
        prog="roughvib", formatter_class=fmt,
        description="Roughness-induced vibration of a tangentially oscillating block on a "
                    "plate (Feldmann 2012), solved event-driven with SUNDIALS IDA.",
        epilog="examples:\n  roughvib run\n  roughvib run paper-100mms --out runs/fast\n"
               "  roughvib scenes\n  roughvib events runs/paper\n"
               "  roughvib plot runs/paper --figure events\n"
               "  roughvib compare paper --out runs/wp --budget 900\n"
               "  roughvib surface paper --out runs/paper-surface\n"
               "  roughvib report runs/paper\n"
               "  roughvib sweep paper-velocity --out runs/velocity\n\n"
               "exit status: 0 success, 1 solver failure, 2 bad input, 130 interrupted "
               "(Ctrl-C), 143 terminated (SIGTERM)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    r = sub.add_parser(
        "run", formatter_class=fmt, help="run a scene and write its results",
        description="Run a scene (built-in name or TOML file) and write result.nc, "
                    "events.csv, summary.json and scene.toml into the output directory.",
        epilog="examples:\n"
               "  roughvib run                         # built-in 'paper' scene\n"
               "  roughvib run paper-100mms --out runs/fast\n"
               "  roughvib run my_scene.toml --set block.mass=0.543 "
               "--set output.duration=0.2\n"
               "  roughvib run paper-100mms --out runs/long --set output.checkpoint_interval=0.05\n"
               "  roughvib run --resume runs/long      # after Ctrl-C, SIGTERM or a crash\n")
    r.add_argument("scene", nargs="?", default=None,
                   help="built-in scene name (see 'roughvib scenes') or a .toml file "
                        "(default: paper)")
    r.add_argument("--resume", metavar="DIR",
                   help="continue the run whose checkpoint is in DIR (written when "
                        "output.checkpoint_interval > 0) and write its results there")
    r.add_argument("--out", metavar="DIR", help="output directory (default: runs/<scene name>)")
    r.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override a scene value, e.g. --set block.mass=0.543 (repeatable)")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.add_argument("--quiet", action="store_true", help="do not print the summary")
    r.set_defaults(func=cmd_run)

    s = sub.add_parser("scenes", formatter_class=fmt, help="list the built-in scenes",
                       description="List the built-in scenes with one line each.",
                       epilog="example:\n  roughvib scenes\n")
    s.set_defaults(func=cmd_scenes)

    e = sub.add_parser(
        "events", formatter_class=fmt, help="phase table and event log of a run",
        description="Per excitation cycle: stick fraction, number and mean duration of stick "
                    "phases, lift-offs and open time per contact, guard activations. "
                    "--kind lists the events of the given kinds instead.",
        epilog="examples:\n  roughvib events runs/paper\n"
               "  roughvib events runs/paper --kind lift_off --kind touch_down --cycle 1\n"
               "  roughvib events runs/paper --json > phases.json\n")
    e.add_argument("dir", help="result directory written by 'roughvib run'")
    e.add_argument("--kind", action="append",
                   help="list events of this kind (repeatable), e.g. stick, slip, lift_off")
    e.add_argument("--cycle", type=int, help="only this excitation cycle (0-based)")
    e.add_argument("--json", action="store_true", help="machine-readable output")
    e.add_argument("--max-rows", type=int, default=200, help="rows listed with --kind")
    e.set_defaults(func=cmd_events)

    pl = sub.add_parser(
        "plot", formatter_class=fmt, help="draw a figure of a run (PNG)",
        description="Draw one figure of a saved run. Figures: velocity (Figs. 6/7), "
                    "friction-velocity (3/8), friction-displacement (9), acceleration (10/11), "
                    "spectra (14), wavenumber (5), events (regime timeline over velocity and "
                    "normal force). 'roughvib report DIR' draws them all into one HTML file.",
        epilog="examples:\n  roughvib plot runs/paper --figure events\n"
               "  roughvib plot runs/paper --figure spectra --out spectra.png\n")
    pl.add_argument("dir", help="result directory written by 'roughvib run'")
    pl.add_argument("--figure", default="events", help="figure name (default: events)")
    pl.add_argument("--out", help="PNG path (default: DIR/figures/NAME.png)")
    pl.set_defaults(func=cmd_plot)

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

    su = sub.add_parser(
        "surface", formatter_class=fmt,
        help="inspect a scene's roughness profile, spectra and contact stiffness",
        description="Build the scene's roughness profile and contact points without running "
                    "it, and write profile.csv, spectrum_bands.csv (third-octave wavelength "
                    "bands re 1 um: whole profile and the stretch one contact scans, the "
                    "paper's Fig. 5), spectrum_psd.csv, contacts.csv/.json (contact points; "
                    "Greenwood-Williamson/Tripp stiffness, micro-contacts, real area, "
                    "plasticity index, contact resonance) and profile.png, spectrum.png.",
        epilog="examples:\n  roughvib surface paper --out runs/paper-surface\n"
               "  roughvib surface paper --set contact.stiffness=auto --set contact.model=gt\n"
               "  roughvib surface my_scene.toml --set roughness.reduce_3d=true\n")
    su.add_argument("scene", nargs="?", default="paper", help="scene name or .toml file")
    su.add_argument("--out", metavar="DIR", help="output directory (default: "
                    "runs/<scene name>-surface)")
    su.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene override")
    su.set_defaults(func=cmd_surface)

    from roughvib import sweep
    from roughvib.views import report

    report.add_parsers(sub)
    sweep.add_parsers(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Console entry point ``roughvib``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_INPUT
    import signal

    from roughvib.scene import SceneError

    previous = signal.getsignal(signal.SIGTERM)
    try:
        signal.signal(signal.SIGTERM, _on_sigterm)
    except ValueError:  # not the main thread (e.g. called from a worker): leave it alone
        previous = None
    try:
        return args.func(args)
    except (SceneError, InputError) as exc:
        print(f"roughvib: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt as exc:
        print(f"roughvib: {'terminated' if isinstance(exc, Terminated) else 'interrupted'}",
              file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
