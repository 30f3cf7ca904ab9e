"""The figure of a source study: how far each band moves when one source is changed.

It takes the plain band table of :func:`roughvib.studies.sources.source_study` and never
imports the studies.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["sources_figure"]


def sources_figure(bands, path: Path, title: str = "") -> Path:
    """Draw the band-level change of each variant against the run as it is; write a PNG.

    Parameters
    ----------
    bands : pandas.DataFrame
        Columns ``variant``, ``label`` (the legend), ``signal`` ("block" / "plate"),
        ``band_hz`` [Hz], ``level_db`` and ``change_db`` [dB].
    path : Path
        PNG file.
    title : str
        Figure title (the scene).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    roughvib.rundir.WriteError
        The file cannot be written (a full disk): one line naming it; nothing is left.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from roughvib.rundir import write_file

    fig = Figure(figsize=(8.0, 7.0), layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = axes = fig.subplots(2, 1, sharex=True)
    variants = [v for v in dict.fromkeys(bands["variant"]) if v != "as is"]
    for ax, sig in zip(axes, ("block", "plate"), strict=True):
        sub = bands[bands["signal"] == sig]
        for i, v in enumerate(variants):
            b = sub[sub["variant"] == v]
            label = b["label"].iloc[0] if "label" in b and len(b) else v
            ax.semilogx(b["band_hz"], b["change_db"], marker="o", ms=3, lw=1.2,
                        color=f"C{i}", label=label)
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_ylabel(f"{sig}: level change [dB]")
        ax.grid(True, which="both", alpha=0.3)
    top.legend(loc="best", fontsize=8)
    top.set_title(title or "band levels with one source changed, against the run as it is")
    bottom.set_xlabel("third-octave band [Hz]")
    return write_file(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
