"""``roughvib surface``: the surface inspection report of a scene."""

from __future__ import annotations

import argparse
from pathlib import Path

from roughvib.cli.args import EXIT_OK, out_path, parse_sets

__all__ = ["add_parsers", "cmd_surface"]


def cmd_surface(args: argparse.Namespace) -> int:
    import json

    from roughvib.scene import load_scene
    from roughvib.views.surface_report import write_surface_report

    scene = load_scene(args.scene, parse_sets(args.set))
    given = out_path(args.out)
    out = given or Path("runs") / f"{scene.name}-surface"
    paths = write_surface_report(scene, out, overwrite=args.overwrite or given is None)
    info = json.loads(paths["contacts_json"].read_text())
    stat = info.get("statistical_contact", {})
    prof = info.get("profile", {}).get("stats", {})
    print(f"profile: {prof.get('kind')}, rms {prof.get('rms', float('nan')) * 1e6:.3g} um, "
          f"rms slope {prof.get('rms_slope', float('nan')):.3g}")
    print(f"contact stiffness used: {info['stiffness_used_N_per_m']:.4g} N/m "
          f"({info['stiffness_source']})")
    cp = info["contact"]
    print(f"contact points used: {cp['points']} ({cp['points_source']}), selection "
          f"{cp['selection']}")
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


def add_parsers(sub) -> None:
    """Add the ``surface`` command to ``sub``, the subparsers of ``build_parser``."""
    fmt = argparse.RawDescriptionHelpFormatter
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
               "  roughvib surface paper --out runs/paper-surface --overwrite   # again\n"
               "  roughvib surface paper --set contact.model=gt --set block.mass=0.543\n"
               "  roughvib surface my_scene.toml --set roughness.reduce_3d=true\n")
    su.add_argument("scene", nargs="?", default="paper", help="scene name or .toml file")
    su.add_argument("--out", metavar="DIR", help="output directory (default: "
                    "runs/<scene name>-surface, whose files each new report replaces)")
    su.add_argument("--overwrite", action="store_true",
                    help="replace files of the report's names in --out DIR (without it, they "
                         "are refused)")
    su.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene override")
    su.set_defaults(func=cmd_surface)
