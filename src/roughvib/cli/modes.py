"""``roughvib modes``: a scene's structure in the modes exchange format (docs/structures.md)."""

from __future__ import annotations

import argparse
from pathlib import Path

from roughvib.cli.args import EXIT_OK, InputError, parse_sets

__all__ = ["add_parsers", "cmd_modes_export"]

#: physics.structures.EXPORT_FACTOR, written out so that ``roughvib --help`` does not import
#: the structures (tests/physics/test_structures.py checks that the two agree)
EXPORT_FACTOR = 2.0


def cmd_modes_export(args: argparse.Namespace) -> int:
    from roughvib.physics.structures import export_modes
    from roughvib.physics.structures.exchange import SUFFIXES, write_modes
    from roughvib.rundir import claim_files, write_file
    from roughvib.scene import load_scene

    out = Path(args.file)
    if out.suffix.lower() not in SUFFIXES:
        raise InputError(f"FILE must end in one of {', '.join(SUFFIXES)}, got {str(out)!r}")
    if not out.parent.is_dir():
        raise InputError(f"FILE's folder must exist, got {str(out.parent)!r}")
    if args.max_frequency is not None and not args.max_frequency > 0:
        raise InputError(f"--max-frequency must be > 0 Hz, got {args.max_frequency}")
    claim_files([out], overwrite=args.overwrite)  # before the modes are computed
    scene = load_scene(args.scene, parse_sets(args.set))
    modes = export_modes(scene.plate, scene.base_dir, grid=args.grid,
                         max_frequency=args.max_frequency)
    write_file(out, lambda tmp: write_modes(tmp, modes))
    above = int((modes.frequency > scene.plate.max_frequency * (1.0 + 1e-12)).sum())
    print(f"{out}: {len(modes)} modes, {modes.frequency[0]:.6g} to {modes.frequency[-1]:.6g} "
          f"Hz, at {modes.nodes.shape[0]} nodes; {above} of them above plate.max_frequency = "
          f"{scene.plate.max_frequency:g} Hz (the residual compliance of a scene that imports "
          f"the file with that cut)")
    return EXIT_OK


def add_parsers(sub) -> None:
    """Add the ``modes`` command group to ``sub``, the subparsers of ``build_parser``."""
    fmt = argparse.RawDescriptionHelpFormatter
    mo = sub.add_parser(
        "modes", formatter_class=fmt, help="export a scene's structure (modes at nodes)",
        description="Work with the modes exchange format (docs/structures.md): mass-normalised "
                    "vertical mode shapes [1/sqrt(kg)] at nodes (x, y) [m] in the plate's "
                    "frame, frequencies [Hz], damping ratios.",
        epilog="example:\n  roughvib modes export paper plate.npz --grid 121 105\n")
    msub = mo.add_subparsers(dest="modes_command", metavar="COMMAND", required=True)
    ex = msub.add_parser(
        "export", formatter_class=fmt, help="write a scene's modes to .npz, .unv or .uff",
        description="Write the modes of a scene's structure (plate.kind) at the nodes of a "
                    "uniform grid over the plate (edges included) to FILE; the format follows "
                    "the suffix: .npz (NumPy: frequency, nodes, shapes, damping_ratio) or "
                    ".unv/.uff (universal file: datasets 2411 and 55).\n\n"
                    f"By default the modes go up to {EXPORT_FACTOR:g} x plate.max_frequency. "
                    "A scene with plate.kind = 'imported', FILE as plate.modes_file and the "
                    "same plate.max_frequency simulates the modes to the cut and sums the "
                    "file's modes above it, sum phi_r(a) phi_r(b) / omega_r^2, as its residual "
                    "compliance (the static compliance of the modes it leaves out; off with "
                    "plate.residual_compliance = false). Modes to N x the cut hold about "
                    "1 - 1/N of a thin plate's exact residual. The default export of 'paper' "
                    "(797 modes, 87 MB .npz) run imported meets the band, velocity and energy "
                    "items of the accuracy contract against the built-in plate; its event "
                    "times move by 3.6e-6 s over the default run (7.0e-6 s without the modes "
                    "above the cut, limit 1e-6 s): for event times export to a higher "
                    "--max-frequency or keep the built-in plate; docs/structures.md.",
        epilog="examples:\n"
               "  roughvib modes export paper plate.npz\n"
               "  roughvib modes export paper plate.unv --grid 121 105\n"
               "  roughvib modes export paper plate.npz --max-frequency 200e3   # 4 x the cut\n"
               "  roughvib modes export my_scene.toml modes.npz --max-frequency 50e3  "
               "# the simulated modes only\n"
               "  roughvib modes export paper plate.npz --overwrite   # replace plate.npz\n")
    ex.add_argument("scene", help="scene name or .toml file")
    ex.add_argument("file", help="output file (.npz, .unv or .uff); an existing file is "
                                 "refused unless --overwrite")
    ex.add_argument("--overwrite", action="store_true",
                    help="replace FILE if it exists")
    ex.add_argument("--grid", nargs=2, type=int, metavar=("NX", "NY"),
                    help="nodes along x and y (default: ten per shortest bending wavelength "
                         "of the simply supported plate's modes to plate.max_frequency; an "
                         "imported structure's own nodes)")
    ex.add_argument("--max-frequency", type=float, metavar="HZ",
                    help=f"export the modes up to this frequency (default: {EXPORT_FACTOR:g} "
                         f"x plate.max_frequency; those above the cut of the scene that "
                         f"imports them give its residual compliance; plate.max_frequency "
                         f"exports the simulated modes only, without residual)")
    ex.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene override")
    ex.set_defaults(func=cmd_modes_export)
