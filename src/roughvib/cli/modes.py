"""``roughvib modes``: a scene's structure in the modes exchange format (docs/structures.md)."""

from __future__ import annotations

import argparse
from pathlib import Path

from roughvib.cli.args import EXIT_OK, InputError, parse_sets

__all__ = ["add_parsers", "cmd_modes_export"]


def cmd_modes_export(args: argparse.Namespace) -> int:
    from roughvib.physics.structures import export_modes
    from roughvib.physics.structures.exchange import SUFFIXES, write_modes
    from roughvib.scene import load_scene

    out = Path(args.file)
    if out.suffix.lower() not in SUFFIXES:
        raise InputError(f"FILE must end in one of {', '.join(SUFFIXES)}, got {str(out)!r}")
    if not out.parent.is_dir():
        raise InputError(f"FILE's folder must exist, got {str(out.parent)!r}")
    if args.max_frequency is not None and not args.max_frequency > 0:
        raise InputError(f"--max-frequency must be > 0 Hz, got {args.max_frequency}")
    scene = load_scene(args.scene, parse_sets(args.set))
    modes = export_modes(scene.plate, scene.base_dir, grid=args.grid,
                         max_frequency=args.max_frequency)
    write_modes(out, modes)
    print(f"{out}: {len(modes)} modes, {modes.frequency[0]:.6g} to {modes.frequency[-1]:.6g} "
          f"Hz, at {modes.nodes.shape[0]} nodes")
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
                    ".unv/.uff (universal file: datasets 2411 and 55). A scene with "
                    "plate.kind = 'imported' and FILE as plate.modes_file runs like the "
                    "scene exported, within the interpolation error of the grid.",
        epilog="examples:\n"
               "  roughvib modes export paper plate.npz\n"
               "  roughvib modes export paper plate.unv --grid 121 105\n"
               "  roughvib modes export my_scene.toml modes.npz --max-frequency 100e3\n")
    ex.add_argument("scene", help="scene name or .toml file")
    ex.add_argument("file", help="output file (.npz, .unv or .uff)")
    ex.add_argument("--grid", nargs=2, type=int, metavar=("NX", "NY"),
                    help="nodes along x and y (default: ten per shortest bending wavelength "
                         "of the simply supported plate; an imported structure's own nodes)")
    ex.add_argument("--max-frequency", type=float, metavar="HZ",
                    help="export the modes up to this frequency instead of "
                         "plate.max_frequency (those above the cut of the scene that imports "
                         "them give its residual compliance)")
    ex.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene override")
    ex.set_defaults(func=cmd_modes_export)
