"""``roughvib sources``: where a run's band energy comes from (one source changed at a time)."""

from __future__ import annotations

import argparse

from roughvib.cli.args import EXIT_OK, out_path, parse_sets

__all__ = ["add_parsers", "cmd_sources"]

#: the files of a source study
SOURCE_FILES = ("sources.csv", "sources_runs.csv", "sources.png")


def cmd_sources(args: argparse.Namespace) -> int:
    from roughvib.rundir import claim_files, output_folder, write_file
    from roughvib.scene import load_scene
    from roughvib.studies.sources import source_study
    from roughvib.views.sources import sources_figure

    scene = load_scene(args.scene, parse_sets(args.set))
    out = out_path(args.out)
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
                    "overall levels, lift-offs, stick fraction) and sources.png into --out.",
        epilog="examples:\n  roughvib sources paper --out runs/sources-paper\n"
               "  roughvib sources paper-100mms --out runs/sources-100 --set "
               "roughness.seed=3\n")
    c.add_argument("scene", nargs="?", default="paper", help="scene name or .toml file")
    c.add_argument("--out", required=True, metavar="DIR",
                   help="output directory (its sources.* files are not replaced without "
                        "--overwrite)")
    c.add_argument("--overwrite", action="store_true",
                   help="replace the sources.* files of an earlier study in --out")
    c.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene value (repeatable)")
    c.add_argument("--no-progress", action="store_true", help="print nothing while running")
    c.set_defaults(func=cmd_sources)
