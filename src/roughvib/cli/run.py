"""``roughvib run`` (run a scene, resume a checkpointed run) and ``roughvib scenes``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from roughvib.cli.args import (
    EXIT_INTERRUPT,
    EXIT_OK,
    EXIT_SOLVER,
    EXIT_TERM,
    InputError,
    Terminated,
    out_path,
    parse_sets,
)

__all__ = ["add_parsers", "cmd_run", "cmd_scenes"]


def _fmt_db(x: float | None) -> str:
    return "n/a" if x is None else f"{x:6.1f} dB"


def _print_summary(summary: dict, out_dir: Path) -> None:
    from roughvib.analysis.levels import single_draw_note

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
            f"re 1e-6 m/s^2)" if summary.get("model", {}).get("modes") != 0 else
            f"plate accel      none: the {summary['model'].get('structure', 'structure')} "
            f"does not move",
            f"normal force     mean {m.get('normal_force_mean', float('nan')):.5g} N, "
            f"min {m.get('normal_force_min', float('nan')):.4g} N",
        ]
        if (note := single_draw_note(summary)) is not None:
            lines.insert(-1, f"levels           {note}")
    if (c := summary.get("model", {}).get("contact")):
        nc = c.get("micro_contacts")
        lines.append(f"contact          {c['points']} points ({c['points_source']}"
                     + (f", {nc:.3g} micro-contacts" if nc is not None else "")
                     + f"), s_total {c['stiffness_total']:.4g} N/m ({c['stiffness_source']}), "
                     f"r1 {c['vertical_damping']:.4g} N s/m")
    if (note := cal.get("contact_stiffness", {}).get("velocity_factor_note")):
        lines.append(f"                 {note}")
    if (inp := summary.get("model", {}).get("input")) and inp.get("shortest_wavelength"):
        spot = inp.get("spot_radius")
        filt = (f"contact filter a = {spot * 1e6:.3g} um" if spot else "no contact filter")
        res = inp.get("resolved_frequency_rms")
        prof = summary.get("model", {}).get("profile", {})
        how = inp.get("shortest_source")
        if prof.get("tail") == "fitted":
            how = f"fitted tail, H = {prof.get('hurst_fit'):.2f}"
        elif prof.get("tail") not in (None, "fitted"):
            how = f"the file's band; no tail: {prof.get('tail')}"
        lam = prof.get("shortest_wavelength", inp["shortest_wavelength"])
        lines.append(f"input            surface to {lam * 1e6:.3g} um "
                     f"({how}), {filt}, grid "
                     f"{inp.get('grid_spacing', float('nan')) * 1e6:.3g} um"
                     + (f"; resolved to {res / 1e3:.3g} kHz at the rms speed" if res else ""))
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
    if (k := _kernel_line(s.get("kernels"))):
        lines.append(f"kernels          {k}")
    if summary.get("energy_audit_note") or (a and a.get("residual") is None):
        lines.append(f"energy audit     {summary.get('energy_audit_note') or 'not computed'}")
    elif a:
        lines.append(f"energy audit     residual {a['residual']:.3e} J "
                     f"(relative {a.get('relative_residual') or 0.0:.2e} of "
                     f"{a.get('energy_scale') or float('nan'):.3g} J)")
    rad = summary.get("radiation")
    if rad:  # output.radiation
        lines.append("radiation        " + (
            f"sound power {_fmt_db(rad.get('sound_power_level_db_re_1pW'))} re 1 pW "
            f"({rad.get('radiating_sides')} side(s), {rad.get('bands_hz', ['?'])[0]:g}-"
            f"{rad.get('bands_hz', ['?', '?'])[-1]:g} Hz bands; radiation.csv)"
            if "error" not in rad else f"not computed: {rad['error']}"))
    acc = summary.get("accuracy")
    if acc:
        from roughvib.analysis.accuracy import verdict_line

        lines.append(f"accuracy         {verdict_line(acc)}")
    print("\n".join(lines))


def _kernel_line(k: dict | None) -> str | None:
    """The summary's line on numba's kernels: compiled (a cold cache) or loaded from its cache,
    and how long it took (not part of the pilot's or the preprocessing's time; part of the
    solver's wall time only where it fell into the solve). None below 0.05 s."""
    if not isinstance(k, dict) or not (k.get("time") or 0.0) >= 0.05:
        return None
    how = (f"compiled {k['compiled']} numba kernels (not in numba's cache yet)"
           if k.get("compiled") else "numba kernels loaded from numba's cache")
    solve = k.get("solve") or 0.0
    return (f"{how} in {k['time']:.1f} s" + (f", {solve:.1f} s of it in the solver's wall time"
                                              if solve >= 0.05 else ""))


def _run_command(args: argparse.Namespace, out_dir: Path) -> str:
    """The ``roughvib run`` command of this run's scene, for the hints of the summary: the
    scene as the user gave it (file path or built-in name) and its ``--set`` options but
    ``roughness.seed`` (which an ensemble varies); for a resumed run, whose command line is
    not known, the run directory's saved scene (which repeats the run)."""
    import shlex

    if args.resume:
        return "roughvib run " + shlex.quote(str(out_dir / "scene.toml"))
    # an ensemble sets roughness.seed itself (and refuses a --set of it)
    sets = [v for v in (args.set or []) if v.partition("=")[0].strip() != "roughness.seed"]
    words = ([args.scene] if args.scene is not None else []) + [
        w for value in sets for w in ("--set", value)]
    return " ".join(["roughvib run", shlex.join(words)]).rstrip()


def _failure_files(summary: dict, out_dir: Path) -> str:
    """The files a failed run wrote, each with what it holds (only files that exist)."""
    files = summary.get("files") or {}
    t_end = (summary.get("partial_result") or {}).get("t_end")
    parts = [f"{out_dir / 'summary.json'} (status, message, last events)"]
    if "partial.nc" in files:
        parts.append(f"{out_dir / 'partial.nc'} (time series up to t = {t_end:.6g} s)")
    if "events.csv" in files:
        parts.append(f"{out_dir / 'events.csv'} (event log)")
    return ", ".join(parts)


def _run_ensemble(args: argparse.Namespace) -> int:
    """``roughvib run SCENE --seeds N``: the scene over roughness seeds 1..N as a sweep, then
    its report with the ensemble's mean and spread."""
    from roughvib.studies.sweep.ensemble import ensemble_tables, seed_sweep
    from roughvib.studies.sweep.report import sweep_report
    from roughvib.studies.sweep.run import run_sweep

    if args.resume:
        raise InputError("--seeds runs an ensemble of new runs; give no --resume with it")
    spec = seed_sweep(args.scene or "paper", args.seeds, parse_sets(args.set))
    out = out_path(args.out) or Path("runs") / spec.name
    try:
        run = run_sweep(spec, out, workers=args.workers, progress=not args.no_progress,
                        log=None if args.quiet else (lambda m: print(m, file=sys.stderr)),
                        case_rows=True)
    except KeyboardInterrupt as exc:
        term = isinstance(exc, Terminated)
        print(f"roughvib: ensemble {'terminated' if term else 'interrupted'}; completed draws "
              f"are kept in {out}/cases, run the same command again to resume",
              file=sys.stderr)
        return EXIT_TERM if term else EXIT_INTERRUPT
    # the workers computed each new case's numbers from the result they held: only cases
    # complete before this run are read back, and only once (the report and the lines below)
    ens = ensemble_tables(run.directory, rows=run.rows)
    report = sweep_report(run.directory, ensemble=ens)
    if not args.quiet:
        print(f"{spec.name}: {len(run.table) - run.failed} of {len(run.table)} draws succeeded "
              f"-> {run.directory}")
        for _, r in (ens.levels.iterrows() if ens is not None else ()):
            print(f"  {r['level']:<5} level  mean {r['mean']:6.1f} dB, std {r['std']:4.2f} dB, "
                  f"range {r['min']:.1f} .. {r['max']:.1f} dB re 1e-6 m/s^2 ({r['n']} draws)")
        print(f"  report: {report} (and report.html)")
    return EXIT_OK if run.failed == 0 else EXIT_SOLVER


def _verify(result, scene, out_dir: Path, args: argparse.Namespace) -> None:
    """``--verify``: solve the scene a second way, judge the saved run by the accuracy contract
    and save it again with its ``accuracy`` section."""
    from roughvib.simulation import verification_scene, verify_result

    _, how = verification_scene(scene)
    print(f"verifying: solving the scene again with {how}", file=sys.stderr)
    try:
        verify_result(result, scene, progress=False if args.no_progress else None)
    except KeyboardInterrupt:
        print(f"roughvib: verification interrupted; the run itself is saved in {out_dir}",
              file=sys.stderr)
        raise
    result.save(out_dir, overwrite=args.overwrite)


def _check_resumable(directory: Path) -> None:
    """``--resume DIR``: refuse in one line, before the directory is touched, what cannot be
    resumed: no directory, no checkpoint (an ended run, or user files), a checkpoint file that
    is empty, foreign, truncated or of another format (the file is not unpickled here)."""
    from roughvib.results import read_summary
    from roughvib.solvers.checkpoint import CHECKPOINT_NAME, check_checkpoint_file

    if not directory.is_dir():
        raise InputError(f"--resume {directory}: no such directory (give the output directory "
                         f"of a run that wrote checkpoints)")
    cp = directory / CHECKPOINT_NAME
    if not cp.exists():
        try:
            status = read_summary(directory).get("status")
        except (OSError, ValueError):
            status = None
        if status is not None:
            raise InputError(f"--resume {directory}: the run there has ended ({status}; a run "
                             f"removes its checkpoint when it ends), there is nothing to "
                             f"resume; run it again with 'roughvib run "
                             f"{directory / 'scene.toml'}'")
        raise InputError(f"--resume {directory}: no {CHECKPOINT_NAME} there, nothing to resume "
                         f"(a run writes checkpoints into its output directory when "
                         f"output.checkpoint_interval > 0 s)")
    check_checkpoint_file(cp)


def cmd_run(args: argparse.Namespace) -> int:
    from roughvib.rundir import RunDirectory
    from roughvib.scene import load_scene
    from roughvib.solvers.checkpoint import CHECKPOINT_NAME

    out_path(args.out)  # an empty --out is refused, not taken for the default
    out_path(args.resume, "--resume")  # and an empty --resume is not a new run
    if args.workers is not None and args.seeds is None:
        raise InputError(f"--workers sets the worker processes of an ensemble (--seeds N); a "
                         f"single run uses one process, got --workers {args.workers} without "
                         f"--seeds")
    if args.seeds is not None:
        if args.verify:
            raise InputError("--verify checks one run; give no --seeds with it (verify a draw "
                             "of the ensemble with 'roughvib run SCENE --set "
                             "roughness.seed=N --verify')")
        return _run_ensemble(args)
    if args.resume:
        if args.scene is not None or args.set or args.out is not None:
            raise InputError("--resume DIR continues the run stored in DIR; give no scene, "
                             "--set or --out with it")
        out_dir = Path(args.resume)
        _check_resumable(out_dir)
    else:
        scene = load_scene(args.scene or "paper", parse_sets(args.set))
        if args.verify:  # before the run: a verdict that cannot pass is refused up front
            from roughvib.simulation import check_verifiable

            check_verifiable(scene)
        if args.no_progress:
            scene = scene.with_overrides({"output.progress": False})
        out_dir = out_path(args.out) or Path("runs") / scene.name
        cp_dir = out_dir if scene.output.checkpoint_interval > 0 else None
    # the output directory is checked and locked before anything expensive (imports included)
    rundir = RunDirectory(out_dir, overwrite=args.overwrite, resume=bool(args.resume)).open()
    try:
        # a run whose time series cannot fit is refused before it starts (a resumed run's
        # scene is the checkpoint's: read, and its inputs checked, under the lock)
        from roughvib.results import expected_result_bytes

        if args.resume:
            from roughvib.simulation import checkpoint_scene

            scene = checkpoint_scene(out_dir)
        rundir.require(expected_result_bytes(scene), "the run's time series alone")
        if rundir.replaces and not args.resume:
            print(f"roughvib: note: {out_dir} holds an earlier run; this run replaces it when it "
                  f"ends", file=sys.stderr)
        try:
            from roughvib.api import resume, simulate

            if args.resume:
                if args.verify:  # before the run: a verdict that cannot pass is refused
                    from roughvib.simulation import check_verifiable

                    check_verifiable(scene)
                result = resume(out_dir, progress=False if args.no_progress else None)
            else:
                result = simulate(scene, checkpoint_dir=cp_dir)
        except KeyboardInterrupt as exc:
            cp = out_dir / CHECKPOINT_NAME
            what = "terminated" if isinstance(exc, Terminated) else "interrupted"
            if cp.exists():
                print(f"roughvib: {what}; the last checkpoint is kept in {cp}: continue with "
                      f"'roughvib run --resume {out_dir}'", file=sys.stderr)
            else:
                print(f"roughvib: {what}; nothing was written", file=sys.stderr)
            return EXIT_TERM if isinstance(exc, Terminated) else EXIT_INTERRUPT
        result.summary["run_command"] = _run_command(args, out_dir)
        result.save(rundir)
    finally:
        rundir.close()
    if args.verify and result.ok:
        # the run is saved first: an interrupted or failed second solve loses nothing
        _verify(result, scene, out_dir, args)
    if not args.quiet:
        _print_summary(result.summary, out_dir)
    if not result.ok:
        print(f"roughvib: run failed ({result.status}): {result.summary.get('message')}",
              file=sys.stderr)
        print(f"roughvib: written: {_failure_files(result.summary, out_dir)}", file=sys.stderr)
        return EXIT_SOLVER
    return EXIT_OK


def cmd_scenes(args: argparse.Namespace) -> int:
    from roughvib.scene import builtin_scenes

    scenes = builtin_scenes()
    width = max(len(n) for n in scenes)
    for name in sorted(scenes, key=lambda n: (n != "paper", n)):
        print(f"{name:<{width}}  {scenes[name]}")
    return EXIT_OK


def add_parsers(sub) -> None:
    """Add the ``run`` and ``scenes`` commands to ``sub``, the subparsers of ``build_parser``."""
    fmt = argparse.RawDescriptionHelpFormatter
    r = sub.add_parser(
        "run", formatter_class=fmt, help="run a scene and write its results",
        description="Run a scene (built-in name or TOML file) and write result.nc, "
                    "events.csv, summary.json and scene.toml into the output directory. The "
                    "directory is checked before the run; the run appears in it as a whole "
                    "and never deletes or overwrites files it did not create (an earlier "
                    "roughvib run there is replaced; other files refuse the run unless "
                    "--overwrite).",
        epilog="examples:\n"
               "  roughvib run                         # built-in 'paper' scene\n"
               "  roughvib run paper-100mms --out runs/fast\n"
               "  roughvib run my_scene.toml --set block.mass=0.543 "
               "--set output.duration=0.2\n"
               "  roughvib run paper-100mms --out runs/long --set output.checkpoint_interval=0.05\n"
               "  roughvib run --resume runs/long      # after Ctrl-C, SIGTERM or a crash\n"
               "  roughvib run --verify                # and check it by a second solver\n"
               "  roughvib run my_scene.toml --out ~/notes --overwrite  # among other files\n"
               "  roughvib run paper --seeds 10        # ensemble: 10 roughness draws, mean "
               "and spread\n")
    r.add_argument("scene", nargs="?", default=None,
                   help="built-in scene name (see 'roughvib scenes') or a .toml file "
                        "(default: paper)")
    r.add_argument("--resume", metavar="DIR",
                   help="continue the run whose checkpoint is in DIR (written when "
                        "output.checkpoint_interval > 0) and write its results there")
    r.add_argument("--out", metavar="DIR", help="output directory (default: runs/<scene name>)")
    r.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override a scene value, e.g. --set block.mass=0.543 (repeatable)")
    r.add_argument("--verify", action="store_true",
                   help="after the run, solve the scene a second, independent way (the other "
                        "event-driven solver at accuracy 'reference') and write the deviations "
                        "and a verdict against the accuracy contract into summary.json "
                        "('accuracy') and the report; costs a second run")
    r.add_argument("--overwrite", action="store_true",
                   help="write into a directory that holds files roughvib did not write: the "
                        "run's files replace files of the same names, the others are kept "
                        "(without it such a directory is refused; an earlier roughvib run "
                        "alone is always replaced as a whole)")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.add_argument("--quiet", action="store_true", help="do not print the summary")
    r.add_argument("--seeds", type=int, metavar="N",
                   help="run the ensemble of roughness.seed = 1..N instead of one draw (a "
                        "sweep: DIR/cases/<case>/ per seed, resumable) and report the mean "
                        "and spread of the levels and band spectra in DIR/report/ (default "
                        "DIR: runs/<scene name>-seeds)")
    r.add_argument("--workers", type=int, metavar="N",
                   help="with --seeds: worker processes (default: all cores)")
    r.set_defaults(func=cmd_run)

    s = sub.add_parser("scenes", formatter_class=fmt, help="list the built-in scenes",
                       description="List the built-in scenes with one line each.",
                       epilog="example:\n  roughvib scenes\n")
    s.set_defaults(func=cmd_scenes)
