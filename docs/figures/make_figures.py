"""Make the figures of docs/paper-comparison.md from the ensembles listed there.

Usage (from the repository root, after ``python docs/figures/paper_ensembles.py run``)::

    python docs/figures/make_figures.py            # reads runs/ens/, writes docs/figures/*.png
    python docs/figures/make_figures.py --runs DIR --out DIR

The single-run figures show the draw with roughness.seed = 1 of each ensemble (the same as
`roughvib plot runs/ens/ENSEMBLE/cases/<seed=1 case> --figure NAME --out FILE`), drawn by the
library's own plot functions (roughvib.views.figures) at 100 dpi; the velocity sweep shows
every seed; the trend figures show the ensembles' band spectra (mean, ±1 std, min/max over
the seeds, roughvib.views.ensemble). A run that is missing is reported and its figures are
skipped.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

import roughvib
from roughvib.views import figures as plots

# single-run figures: file -> (ensemble, figure name)
SINGLE = {
    "velocity-10mms.png": ("paper-10", "velocity"),
    "velocity-100mms.png": ("paper-100", "velocity"),
    "friction-velocity-10mms.png": ("paper-10", "friction-velocity"),
    "friction-displacement-10mms.png": ("paper-10", "friction-displacement"),
    "acceleration-10mms.png": ("paper-10", "acceleration"),
    "acceleration-100mms.png": ("paper-100", "acceleration"),
}
NOISE_RMS = 1e-3  # simulated accelerometer floor on the block [m/s^2 rms], docs/theory.md
VELOCITY_TICKS = (10, 20, 40, 100)  # nominal rms velocities of the velocity sweep [mm/s]


def _cases(root: Path, ensemble: str) -> list[Path]:
    """Case directories of an ensemble's successful draws, by seed."""
    d = root / ensemble
    try:
        t = pd.read_csv(d / "sweep.csv")
    except OSError:
        return []
    t = t[t["status"] == "success"].sort_values("roughness.seed")
    return [d / "cases" / c for c in t["case"]]


def main(argv: list[str] | None = None) -> int:
    from roughvib.studies.sweep.ensemble import ensemble_tables
    from roughvib.views.ensemble import ensemble_figure

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default="runs/ens", help="directory holding the ensembles")
    ap.add_argument("--out", default=str(Path(__file__).parent), help="output directory")
    a = ap.parse_args(argv)
    runs, out = Path(a.runs), Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cache: dict[Path, roughvib.Result | None] = {}

    def load(path: Path):
        if path not in cache:
            try:
                cache[path] = roughvib.load_result(path)
            except (FileNotFoundError, ValueError) as exc:
                print(f"skip: {path}: {exc}", file=sys.stderr)
                cache[path] = None
        return cache[path]

    def get(ensemble: str):
        cases = _cases(runs, ensemble)
        if not cases:
            print(f"skip: {ensemble}: no successful draw in {runs / ensemble}", file=sys.stderr)
            return None
        return load(cases[0])

    def save(fig, fname: str) -> None:
        plots.save_figure(fig, out / fname, dpi=100)
        print(out / fname)

    plt = plots._plt()
    for fname, (run, fig_name) in SINGLE.items():
        r = get(run)
        if r is not None:
            save(plots.FIGURES[fig_name](r), fname)

    for run, tag in (("paper-10", "10mms"), ("paper-100", "100mms")):
        r = get(run)
        if r is not None:
            save(plots.plot_spectra(r, noise_rms=NOISE_RMS)[0].figure, f"spectra-{tag}.png")

    pair = [get("paper-10"), get("paper-100")]
    if all(pair):
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for ax, r, tag in zip(axes, pair, ("(a) 10 mm/s", "(b) 100 mm/s"), strict=True):
            plots.plot_wavenumber(r, ax=ax)
            ax.set_title(f"{tag}: wavenumber spectra of the input (dotted: 2π / stroke)",
                         fontsize=9)
        save(fig, "wavenumber.png")

    sweeps = {tag: [load(c) for e in (f"{prefix}-10", f"{prefix}-20", f"{prefix}-40",
                                      f"{prefix}-100") for c in _cases(runs, e)]
              for tag, prefix in (("(a) physical input (the scenes)", "paper"),
                                  ("(b) the paper's procedure (50 µm band, linear)",
                                   "procedure"))}
    sweeps = {k: v for k, v in sweeps.items() if v and all(v)}
    if sweeps:
        # stacked: the page shows figures about 600 px wide
        fig, axes = plt.subplots(len(sweeps), 1, figsize=(6, 3.6 * len(sweeps)), sharey=True,
                                 squeeze=False)
        for ax, (tag, results) in zip(axes[:, 0], sweeps.items(), strict=True):
            plots.plot_velocity_sweep(results, ax=ax)
            # one tick per nominal speed (each run's own v_rms would crowd the axis)
            ax.set_xticks(VELOCITY_TICKS)
            ax.set_xticklabels([f"{v:g}" for v in VELOCITY_TICKS])
            ax.set_title(f"{tag}; paper: 9-12 dB per doubling", fontsize=9)
            ax.set_ylabel("overall level [dB re 1e-6 m/s²]")
        fig.tight_layout()
        save(fig, "velocity-sweep.png")

    for tag, names in (("10mms", ("paper-10", "heavy-10", "rough-10")),
                       ("100mms", ("paper-100", "heavy-100", "rough-100"))):
        parts = []
        for name in names:
            ens = ensemble_tables(runs / name) if (runs / name / "sweep.csv").exists() else None
            if ens is not None and len(ens.bands):
                parts.append(ens.bands.assign(group=name))
        if len(parts) >= 2:
            print(ensemble_figure(pd.concat(parts), out / f"trends-{tag}.png"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
