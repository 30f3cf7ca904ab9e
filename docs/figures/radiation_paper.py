"""The numbers and the figure of docs/radiation.md, from a paper run with output.radiation.

Usage (from the repository root)::

    roughvib run paper --set output.radiation=true --out runs/paper-radiation
    python docs/figures/radiation_paper.py runs/paper-radiation

prints (1) how well the modal states rebuilt from the stored contact forces reproduce the plate
acceleration the solver stored (third-octave levels, Hann window, over the analysis window),
(2) the radiated power with and without the coupling between modes in the bands that carry
the power, and writes docs/figures/radiation-paper.png.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import roughvib
from roughvib.analysis.figures_data import scene_of, tapered_band_levels
from roughvib.analysis.levels import whole_period_window
from roughvib.analysis.radiation import cross_modal_check, modal_response
from roughvib.physics.plate import mode_shapes, plate_modes
from roughvib.views.figures import plot_radiation, save_figure

BANDS = [100, 125, 160, 200, 250, 315, 400, 500, 630, 800, 1000, 1250, 1600, 2000, 2500, 4000]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "radiation-paper.png")
    args = ap.parse_args()
    result = roughvib.load_result(args.run)
    scene = scene_of(result)
    ds = result.dataset
    t = ds["time"].values
    win = whole_period_window(t, scene.period, scene.output.transient)
    F = ds["contact_force"].values
    xy = np.column_stack([ds["contact_x"].values, ds["contact_y"].values])
    dt = scene.output.step

    modes = plate_modes(scene.plate)
    q, dq = modal_response(F, xy, dt, modes)
    phi = mode_shapes(modes, xy[:, 0], xy[:, 1])
    obs = mode_shapes(modes, *([c] for c in scene.plate.observation_position))[:, 0]
    acc = ((F @ phi.T) / modes.modal_mass - 2 * modes.damping_ratio * modes.omega * dq
           - modes.omega**2 * q) @ obs
    ref = ds["plate_vertical_acceleration"].values
    fc, l_ref = tapered_band_levels(ref[win], 1 / dt, fmin=50, fmax=40e3)
    _, l_new = tapered_band_levels(acc[win], 1 / dt, fmin=50, fmax=40e3)
    _, l_err = tapered_band_levels((acc - ref)[win], 1 / dt, fmin=50, fmax=40e3)
    held = l_new - 40 * np.log10(np.sinc(fc * dt))  # the hold's sinc^2 undone at the centres
    print("band [Hz]  solver [dB re 1e-6 m/s^2]  rebuilt - solver [dB]  same, hold undone [dB]"
          "  error below signal [dB]")
    for row in zip(fc, l_ref, l_new - l_ref, held - l_ref, l_ref - l_err, strict=True):
        print("{:8.0f}  {:8.2f}  {:+8.3f}  {:+8.3f}  {:8.1f}".format(*row))
    for top in (20e3, 40e3):
        ok = np.isfinite(l_ref) & (fc <= top * 1.06)
        raw, undone = np.max(np.abs(l_new - l_ref)[ok]), np.max(np.abs(held - l_ref)[ok])
        print(f"to {top / 1e3:g} kHz: largest |rebuilt - solver| {raw:.3f} dB, with the hold "
              f"undone {undone:.3f} dB")

    check = cross_modal_check(F, xy, dt, scene.plate, win, BANDS,
                              sound_speed=scene.output.sound_speed)
    print("band [Hz]  modes  full/diagonal [dB]")
    for b, m, r in zip(check["band_hz"], check["modes"], check["ratio_db"], strict=True):
        print(f"{b:8.0f}  {m:5d}  {r:+.2f}")
    total = 10 * np.log10(check["full"].sum() / check["diagonal"].sum())
    print(f"sum over these bands: {total:+.3f} dB")
    print("radiation summary:", result.summary.get("radiation"))

    save_figure(plot_radiation(result)[0].figure, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
