"""``roughvib validate`` and ``roughvib export``: measured records in, exchange formats out."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from roughvib.cli.args import EXIT_OK, InputError, out_path

__all__ = ["add_parsers", "cmd_export", "cmd_validate"]


def _groups(paths: list[str]) -> list[tuple[str, list[str]]]:
    """``RUN FILE [FILE...] [RUN FILE...]``: a directory starts a group, files follow it."""
    groups: list[tuple[str, list[str]]] = []
    for p in paths:
        if Path(p).is_dir():
            if groups and not (Path(p) / "summary.json").is_file():  # meant as a record
                raise InputError(f"{p}: is a directory, not a measured record file (nor a run "
                                 f"directory: it holds no summary.json)")
            groups.append((p, []))
        elif not groups:
            raise InputError(f"{p}: the first argument must be a run directory (roughvib run)")
        else:
            groups[-1][1].append(p)
    for run, files in groups:
        if not files:
            raise InputError(f"{run}: no measured record given after this run directory")
    return groups


def cmd_validate(args: argparse.Namespace) -> int:
    """Compare measured records with runs; print one line per record (and the exponent)."""
    from roughvib.records import RecordError

    if args.noise is not None and args.noise_rms is not None:
        raise InputError("give --noise FILE or --noise-rms RMS, not both")
    if args.noise_rms is not None and not (args.noise_rms > 0 and math.isfinite(args.noise_rms)):
        raise InputError(f"--noise-rms must be > 0 m/s^2, got {args.noise_rms}")
    if not (args.margin > 0 and math.isfinite(args.margin)):
        raise InputError(f"--margin must be > 0 dB, got {args.margin}")
    if args.fmax is not None and not (args.fmax > 0 and math.isfinite(args.fmax)):
        raise InputError(f"--fmax must be > 0 Hz, got {args.fmax}")
    groups = _groups(args.paths)
    from roughvib.views.validation import VALIDATION_DIR, validate, velocity_exponent_of

    try:
        for run, files in groups:
            for v in validate(run, files, signal=args.signal, column=args.column,
                              units=args.units, scale=args.scale, noise=args.noise,
                              noise_rms=args.noise_rms, margin_db=args.margin,
                              start=args.start, fmax=args.fmax):
                print(f"{v.summary_line()} -> {Path(run) / VALIDATION_DIR}/")
        if len(groups) >= 2 and all(len(f) == 1 for _, f in groups):
            e = velocity_exponent_of([(r, f[0]) for r, f in groups])
            print(f"velocity exponent ({args.signal}, {len(groups)} runs): measured "
                  f"{e['measured']['db_per_doubling']:.2f} dB per doubling (n = "
                  f"{e['measured']['exponent']:.2f}), simulated "
                  f"{e['simulated']['db_per_doubling']:.2f} dB per doubling (n = "
                  f"{e['simulated']['exponent']:.2f}, power basis)")
    except (RecordError, FileNotFoundError, ValueError) as exc:
        raise InputError(str(exc)) from None
    return EXIT_OK


def cmd_export(args: argparse.Namespace) -> int:
    """Write a run's accelerations and normal force as UFF 58, WAV or CSV; print the files."""
    from roughvib.records import RecordError, export_run

    try:
        paths = export_run(args.dir, args.format, out=out_path(args.out), binary=args.binary,
                           overwrite=args.overwrite)
    except (RecordError, FileNotFoundError, ValueError) as exc:
        raise InputError(str(exc)) from None
    for p in paths:
        print(p)
    return EXIT_OK


def add_parsers(sub) -> None:
    """Add the ``validate`` and ``export`` commands to ``sub``, the subparsers of
    ``build_parser``."""
    fmt = argparse.RawDescriptionHelpFormatter
    v = sub.add_parser(
        "validate", formatter_class=fmt,
        help="compare measured acceleration records with a run (band levels, spectra)",
        description="Read measured acceleration records (CSV with a time column, WAV with "
                    "--scale, UFF dataset 58, NI TDMS) and compare each with the run's plate "
                    "or block acceleration: third-octave band levels over the same window "
                    "length with the run's band method, dB re 1e-6 m/s^2, difference = "
                    "measured - simulated. Writes RUN_DIR/validation/<file stem>/ (bands.csv, "
                    "validation.png, validation.json) and prints one line per record. Bands "
                    "above the lower of the two Nyquist frequencies are left out and named. "
                    "Several runs, each followed by its records, also give the velocity "
                    "exponent of measured and simulated levels. The run report (roughvib "
                    "report) lists every validation.",
        epilog="examples:\n"
               "  roughvib validate runs/paper lab/plate.wav --signal plate --scale 50\n"
               "  roughvib validate runs/paper lab/accel.csv --signal block --column block "
               "--noise lab/noise.csv\n"
               "  roughvib validate runs/paper lab/test.uff --signal plate --noise-rms 1e-3\n"
               "  roughvib validate runs/v5 lab/v5.wav runs/v10 lab/v10.wav runs/v20 lab/v20.wav "
               "--signal plate --scale 50\n\n"
               "units: taken from the file (CSV header 'acceleration [g]', UFF units label, "
               "TDMS unit_string);\n--units g|m/s^2|mm/s^2|cm/s^2|um/s^2|mg where the file "
               "has none.")
    v.add_argument("paths", nargs="+", metavar="RUN_DIR FILE",
                   help="a run directory followed by one or more records (repeatable)")
    v.add_argument("--signal", choices=("plate", "block"), required=True,
                   help="which of the run's vertical accelerations the records measured")
    v.add_argument("--column", help="value column, channel or dataset: a name or a number "
                                    "counting from 1 (where the file has several)")
    v.add_argument("--units", help="units of the samples where the file does not state them "
                                   "(for WAV: of --scale; default m/s^2)")
    v.add_argument("--scale", type=float,
                   help="WAV: acceleration per full-scale unit (m/s^2, or --units)")
    v.add_argument("--noise", metavar="FILE",
                   help="a measured noise record (same channel, no excitation): the floor")
    v.add_argument("--noise-rms", type=float, metavar="RMS",
                   help="or a white noise floor of this rms [m/s^2]")
    v.add_argument("--margin", type=float, default=6.0,
                   help="mark bands within this of the noise floor [dB] (default 6)")
    v.add_argument("--start", type=float, metavar="S",
                   help="start of each record's window from its first sample [s] "
                        "(default: the run's, i.e. its run-in skipped)")
    v.add_argument("--fmax", type=float, metavar="HZ",
                   help="highest band to compare [Hz] (default: the run's highest; the record "
                        "needs at least twice this sample rate)")
    v.set_defaults(func=cmd_validate)

    e = sub.add_parser(
        "export", formatter_class=fmt,
        help="write a run's accelerations and normal force as UFF 58, WAV or CSV",
        description="Write the block and plate vertical accelerations [m/s^2] and the total "
                    "normal contact force [N] of a run (vertical: positive down) as: UFF "
                    "dataset 58 records (ASCII; --binary for pyuff's binary form) with units "
                    "and node/direction labels (nodes 1 block, 2 plate, 3 contact; direction "
                    "-Z); float32 WAV files named with their scale "
                    "(plate_acceleration_10ms2_per_unit.wav: sample 1.0 = 10 m/s^2) and a "
                    "JSON sidecar (units, scale, sample rate, run id); or one CSV file with a "
                    "time column and units in the headers. Files of the same names in a "
                    "folder given with --out are not replaced without --overwrite (those in "
                    "DIR/export are).",
        epilog="examples:\n  roughvib export runs/paper --format uff\n"
               "  roughvib export runs/paper --format wav --out lab/sim\n"
               "  roughvib export runs/paper --format csv --out /tmp --overwrite\n")
    e.add_argument("dir", help="run directory (roughvib run)")
    e.add_argument("--format", required=True, choices=("uff", "wav", "csv"))
    e.add_argument("--out", metavar="DIR", help="output directory (default: DIR/export)")
    e.add_argument("--binary", action="store_true", help="UFF: binary dataset 58")
    e.add_argument("--overwrite", action="store_true",
                   help="replace files of the same names in --out DIR")
    e.set_defaults(func=cmd_export)
