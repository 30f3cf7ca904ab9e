"""Make the figures of docs/paper-comparison.md from the runs listed there.

Usage (from the repository root, after the ``roughvib run`` commands of that page)::

    python docs/figures/make_figures.py            # reads runs/, writes docs/figures/*.png
    python docs/figures/make_figures.py --runs DIR --out DIR

Every figure is drawn by the library's own plot functions (roughvib.views.figures) at 100 dpi. A run
that is missing is reported and its figures are skipped.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import roughvib
from roughvib.views import figures as plots

# single-run figures: file -> (run, figure name); the same as
# `roughvib plot runs/RUN --figure NAME --out docs/figures/FILE`
SINGLE = {
    "velocity-10mms.png": ("paper", "velocity"),
    "velocity-100mms.png": ("paper-100mms", "velocity"),
    "friction-velocity-10mms.png": ("paper", "friction-velocity"),
    "friction-displacement-10mms.png": ("paper", "friction-displacement"),
    "acceleration-10mms.png": ("paper", "acceleration"),
    "acceleration-100mms.png": ("paper-100mms", "acceleration"),
}
NOISE_RMS = 1e-3  # simulated accelerometer floor on the block [m/s^2 rms], docs/theory.md


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default="runs", help="directory holding the runs")
    ap.add_argument("--out", default=str(Path(__file__).parent), help="output directory")
    a = ap.parse_args(argv)
    runs, out = Path(a.runs), Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cache: dict[str, roughvib.Result | None] = {}

    def get(name: str):
        if name not in cache:
            try:
                cache[name] = roughvib.load_result(runs / name)
            except (FileNotFoundError, ValueError) as exc:
                print(f"skip: {name}: {exc}", file=sys.stderr)
                cache[name] = None
        return cache[name]

    def save(fig, fname: str) -> None:
        plots.save_figure(fig, out / fname, dpi=100)
        print(out / fname)

    plt = plots._plt()
    for fname, (run, fig_name) in SINGLE.items():
        r = get(run)
        if r is not None:
            save(plots.FIGURES[fig_name](r), fname)

    for run, tag in (("paper", "10mms"), ("paper-100mms", "100mms")):
        r = get(run)
        if r is not None:
            save(plots.plot_spectra(r, noise_rms=NOISE_RMS)[0].figure, f"spectra-{tag}.png")

    pair = [get("paper"), get("paper-100mms")]
    if all(pair):
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for ax, r, tag in zip(axes, pair, ("(a) 10 mm/s", "(b) 100 mm/s"), strict=True):
            plots.plot_wavenumber(r, ax=ax)
            ax.set_title(f"{tag}: wavenumber spectra of the input (dotted: 2π / stroke)",
                         fontsize=9)
        save(fig, "wavenumber.png")

    sweep = [get(n) for n in ("v10", "v20", "v40", "paper-100mms")]
    if all(sweep):
        save(plots.plot_velocity_sweep(sweep).figure, "velocity-sweep.png")

    for tag, names, labels in (
            ("10mms", ("paper", "paper-heavy", "paper-rough", "paper-rms2"),
             ("paper", "heavy (0.543 kg, 7.4e6 N/m)", "rough (2x rms, s/2)", "2x rms only")),
            ("100mms", ("paper-100mms", "paper-heavy-100mms", "paper-rough-100mms",
                        "paper-100mms-soft"),
             ("paper-100mms", "heavy", "rough (2x rms, s/2)", "soft contact (0.33 s)"))):
        rs = [(get(n), lab) for n, lab in zip(names, labels, strict=True)]
        rs = [(r, lab) for r, lab in rs if r is not None]
        if len(rs) >= 2:
            fig, axes = plt.subplots(1, 2, figsize=(11, 4))
            for ax, q in zip(axes, ("block", "plate"), strict=True):
                plots.plot_band_comparison([r for r, _ in rs], [lab for _, lab in rs], ax=ax,
                                           quantity=q)
            save(fig, f"trends-{tag}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
