"""``roughvib sources``: where a run's band energy comes from (one source changed at a time)."""

from __future__ import annotations

import argparse

from roughvib.cli.args import EXIT_OK, out_path, parse_sets

__all__ = ["add_parsers", "cmd_sources"]

#: the files of a source study
SOURCE_FILES = ("sources.csv", "sources_runs.csv", "sources.png")


def cmd_sources(args: argparse.Namespace) -> int:
    from pathlib import Path

    from roughvib.cli.args import InputError
    from roughvib.rundir import claim_files, output_folder, write_file
    from roughvib.scene import load_scene
    from roughvib.studies.sources import source_study
    from roughvib.views.sources import sources_figure

    source, out = args.scene, out_path(args.out)
    if Path(source).is_dir():  # a run's directory: its resolved scene, the study beside it
        if not (Path(source) / "scene.toml").is_file():
            raise InputError(f"{source}: a directory without scene.toml is not a run "
                             f"directory (give a scene name, a .toml file or a run directory)")
        source, out = str(Path(source) / "scene.toml"), out or Path(source)
    elif out is None:
        raise InputError(f"--out is required for a scene ({args.scene}); it defaults to the "
                         f"run directory only when SCENE is one")
    scene = load_scene(source, parse_sets(args.set))
    claim_files([out / n for n in SOURCE_FILES], overwrite=args.overwrite)
    output_folder(out, "--out")
    bands, runs = source_study(scene, progress=None if args.no_progress else print)
    write_file(out / "sources.csv", lambda tmp: bands.to_csv(tmp, index=False))
    write_file(out / "sources_runs.csv", lambda tmp: runs.to_csv(tmp, index=False))
    sources_figure(bands, out / "sources.png", title=f"{scene.name}: band levels with one "
                   f"source changed, against the run as it is")
    for row in runs.itertuples():
        moved = bands[(bands["variant"] == row.variant) & (bands["band_hz"] >= 1000.0)]
        span = (f"1-40 kHz bands {moved['change_db'].min():+.1f} .. "
                f"{moved['change_db'].max():+.1f} dB" if len(moved) else "")
        print(f"{row.variant:16s} {row.status}, block {row.block_db:.1f} dB, plate "
              f"{row.plate_db:.1f} dB, {row.lift_offs} lift-offs"
              + (f"; {span}" if row.variant != "as is" and span else ""))
    print(f"results in {out}/sources.*")
    return EXIT_OK


def add_parsers(sub) -> None:
    """Add the ``sources`` command to ``sub``, the subparsers of ``build_parser``."""
    c = sub.add_parser(
        "sources", formatter_class=argparse.RawDescriptionHelpFormatter,
        help="where the band energy comes from: the scene rerun with one source changed",
        description="Run the scene, then again with one source of its vertical vibration "
                    "changed at a time: the surface's tail below 50 um removed, the contact "
                    "filter off, the stick-slip sliding replaced by a sinusoidal sliding of "
                    "the same rms velocity, the friction moment toggled (each where it "
                    "applies; every other value as the scene ran). Writes sources.csv (the "
                    "band levels of each run and their change), sources_runs.csv (the runs: "
                    "overall levels, lift-offs, stick fraction) and sources.png into --out. "
                    "SCENE may be a run's directory: the study then reruns its scene.toml "
                    "and writes beside the run (--out defaults to it), and 'roughvib report "
                    "DIR' shows the study.",
        epilog="examples:\n  roughvib sources paper --out runs/sources-paper\n"
               "  roughvib run paper --out runs/paper && roughvib sources runs/paper && "
               "roughvib report runs/paper\n"
               "  roughvib sources paper-100mms --out runs/sources-100 --set "
               "roughness.seed=3\n")
    c.add_argument("scene", nargs="?", default="paper",
                   help="scene name, .toml file or a run directory")
    c.add_argument("--out", metavar="DIR",
                   help="output directory (its sources.* files are not replaced without "
                        "--overwrite); required unless SCENE is a run directory, which is "
                        "the default then")
    c.add_argument("--overwrite", action="store_true",
                   help="replace the sources.* files of an earlier study in --out")
    c.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene value (repeatable)")
    c.add_argument("--no-progress", action="store_true", help="print nothing while running")
    c.set_defaults(func=cmd_sources)
