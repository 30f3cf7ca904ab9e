"""The figure of a roughness ensemble: third-octave band spectra of block and plate over the
seeds (mean, one standard deviation either side, min and max).

It takes the plain band table made by :func:`roughvib.studies.sweep.ensemble.ensemble_tables`
and never imports the studies.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["ensemble_figure"]


def ensemble_figure(bands, path: Path) -> Path:
    """Draw the band spectra of an ensemble; write a PNG.

    Parameters
    ----------
    bands : pandas.DataFrame
        Columns ``group``, ``level`` ("block" / "plate"), ``centre`` [Hz], ``n``, ``mean``,
        ``std``, ``min``, ``max`` [dB re 1e-6 m/s^2].
    path : Path
        PNG file.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    roughvib.rundir.WriteError
        The file cannot be written (a full disk): one line naming it; nothing is left.
    """
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from roughvib.rundir import write_file

    fig = Figure(figsize=(10, 4), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2, sharey=True)
    groups = list(dict.fromkeys(bands["group"]))
    for ax, which in zip(axes, ("block", "plate"), strict=True):
        for gi, g in enumerate(groups):
            sub = bands[(bands["group"] == g) & (bands["level"] == which)].sort_values("centre")
            if not len(sub):
                continue
            f = sub["centre"].to_numpy()
            mean, std = sub["mean"].to_numpy(), np.nan_to_num(sub["std"].to_numpy())
            color = f"C{gi % 10}"
            n = int(sub["n"].max())
            ax.plot(f, mean, color=color, label=f"{g}: mean of {n}")
            ax.fill_between(f, mean - std, mean + std, color=color, alpha=0.25, linewidth=0)
            ax.plot(f, sub["min"], color=color, linestyle=":", linewidth=0.8)
            ax.plot(f, sub["max"], color=color, linestyle=":", linewidth=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("third-octave band centre [Hz]")
        ax.set_title(f"{which}: mean, ±1 std (shaded), min/max (dotted)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("band level [dB re 1e-6 m/s²]")
    fig.suptitle("roughness ensemble: band spectra over the seeds")
    write_file(path, lambda tmp: fig.savefig(tmp, dpi=110))  # complete or not at all
    return path
