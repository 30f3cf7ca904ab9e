"""The tables of docs/surfaces.md, "How the input moves the bands".

Usage (from the repository root)::

    python docs/figures/input_tail.py            # prints the tables (a few minutes)

For ``paper`` (10 mm/s) and ``paper-100mms``, each with one roughness draw (seed 1), the
contact count, spot radius and stiffness and the third-octave levels of block and plate
(Hann-tapered FFT band sums over the analysis window, dB re 1e-6 m/s^2) of:

* the default input, its tail carried to 50, 10, 2, 1 um, "auto" and half of "auto";
* the same without the contact filter (``contact.filter = "none"``) at the auto tail;
* the paper's procedure: the band to 50 um on the 10 um grid, linear interpolation, no
  contact filter; and that band with a quintic spline instead (what roughvib ran before the
  tail and the filter).
"""

from __future__ import annotations

import numpy as np

import roughvib
from roughvib.analysis.bands import band_levels
from roughvib.physics.surface.field import input_band

BANDS = (160.0, 630.0, 1000.0, 4000.0, 16000.0, 40000.0)
PAPER_PROCEDURE = {"roughness.shortest_wavelength": 50e-6, "roughness.spacing": 10e-6,
                   "roughness.interpolation": "linear", "contact.filter": "none"}


def cases(name: str):
    auto = input_band(roughvib.load_scene(name)).shortest_wavelength
    for lam in (50e-6, 10e-6, 2e-6, 1e-6):
        if lam > auto:
            yield f"tail to {lam * 1e6:g} um", {"roughness.shortest_wavelength": lam}
    yield f"tail to {auto * 1e6:.2g} um (auto)", {}
    yield f"tail to {auto * 0.5e6:.2g} um", {"roughness.shortest_wavelength": auto / 2}
    yield "auto tail, no contact filter", {"contact.filter": "none"}
    yield "the paper's procedure", PAPER_PROCEDURE
    yield "50 um band, quintic, no filter", {**PAPER_PROCEDURE,
                                              "roughness.interpolation": "quintic"}


def levels(result):
    ds = result.dataset
    t = ds["time"].values
    sel = t >= 1.0 / 7.0
    out = {}
    for sig in ("block", "plate"):
        bl = band_levels(ds[f"{sig}_vertical_acceleration"].values[sel], 1e5, method="fft")
        out[sig] = dict(zip(np.round(bl.center_hz), bl.level_db, strict=True))
        m = result.summary["metrics"][f"{sig}_vertical_acceleration_level_db_re_1e-6"]
        out[sig]["overall"] = m
        finite = np.isfinite(bl.level_db)
        out[sig]["peak"] = float(bl.center_hz[finite][np.argmax(bl.level_db[finite])])
    return out


def main() -> None:
    for name in ("paper", "paper-100mms"):
        print(f"\n{name}\n")
        head = " | ".join(f"{f / 1e3:g} kHz" if f >= 1e3 else f"{f:g} Hz" for f in BANDS)
        print(f"| input | points (n_c) | a [um] | s_total [N/m] | overall | peak band | {head} |")
        print("|" + "---|" * (6 + len(BANDS)))
        for label, over in cases(name):
            r = roughvib.simulate(roughvib.load_scene(name, {"output.progress": False,
                                                             **over}))
            c = r.summary["model"]["contact"]
            spot = r.summary["model"]["profile"].get("spot_radius")
            lv = levels(r)
            cells = " | ".join(f"{lv['block'].get(f, np.nan):.0f} / "
                               f"{lv['plate'].get(f, np.nan):.0f}" for f in BANDS)
            print(f"| {label} | {c['points']} ({c['micro_contacts']:.2f}) | "
                  f"{spot * 1e6 if spot else float('nan'):.2f} | {c['stiffness_total']:.3g} | "
                  f"{lv['block']['overall']:.1f} / {lv['plate']['overall']:.1f} | "
                  f"{lv['block']['peak']:g} / {lv['plate']['peak']:g} | {cells} |")


if __name__ == "__main__":
    main()
