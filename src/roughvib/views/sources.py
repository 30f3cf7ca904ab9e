"""The figure of a source study: how far each band moves when one source is changed.

It takes the plain band table of :func:`roughvib.studies.sources.source_study` and never
imports the studies.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["draw_sources", "sources_figure"]


def draw_sources(bands, title: str = ""):
    """The figure of a source study: each variant's band-level change, block above plate.

    Parameters
    ----------
    bands : pandas.DataFrame
        Columns ``variant``, ``label`` (the legend), ``signal`` ("block" / "plate"),
        ``band_hz`` [Hz], ``level_db`` and ``change_db`` [dB].
    title : str
        Figure title (the scene).

    Returns
    -------
    matplotlib.figure.Figure
        8 x 7 in, laid out (constrained), with an Agg canvas.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

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
    return fig


def sources_figure(bands, path: Path, title: str = "") -> Path:
    """Draw the band-level change of each variant against the run as it is; write a PNG.

    Parameters
    ----------
    bands : pandas.DataFrame
        The study's band table (:func:`draw_sources`).
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
    from roughvib.rundir import write_file

    fig = draw_sources(bands, title)
    return write_file(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))


def sources_section(run_dir, summary: dict, *, dpi: int = 90) -> str | None:
    """HTML of the run report's source section, or None if the run directory has no study.

    The study is ``sources.csv`` and ``sources_runs.csv`` beside the run (``roughvib sources
    DIR``): one row per run of the study (the change, status, lift-offs, overall levels and
    the range of its 1-40 kHz band changes) and the figure of :func:`draw_sources`. A study
    whose run as it is does not reproduce this run's overall levels (within 0.05 dB) was made
    for another scene; the section says so.

    Parameters
    ----------
    run_dir : str or os.PathLike
        The run's directory.
    summary : dict
        The run's summary (its overall levels).
    dpi : int
        Resolution of the embedded figure [dots per inch].

    Returns
    -------
    str or None
    """
    import math

    import pandas as pd

    from roughvib.views.html import esc, figure, figure_data_uri, num, table

    folder = Path(run_dir)
    if not ((folder / "sources.csv").is_file() and (folder / "sources_runs.csv").is_file()):
        return None
    bands = pd.read_csv(folder / "sources.csv")
    runs = pd.read_csv(folder / "sources_runs.csv")
    rows = []
    for r in runs.itertuples():
        span = []
        for sig in ("block", "plate"):
            c = bands[(bands["variant"] == r.variant) & (bands["signal"] == sig)
                      & (bands["band_hz"] >= 1000.0)]["change_db"].dropna()
            span.append(f"{c.min():+.1f} .. {c.max():+.1f}"
                        if r.variant != "as is" and len(c) else "")
        rows.append([r.variant, "" if pd.isna(r.change) else r.change, r.status,
                     int(r.lift_offs), num(r.block_db, ".1f"), num(r.plate_db, ".1f"), *span])
    head = ["run", "change", "status", "lift-offs", "block [dB re 1e-6 m/s²]",
            "plate [dB re 1e-6 m/s²]", "block 1–40 kHz bands [dB]",
            "plate 1–40 kHz bands [dB]"]
    metrics = summary.get("metrics", {})
    own = [metrics.get(f"{s}_vertical_acceleration_level_db_re_1e-6") for s in ("block", "plate")]
    base = runs[runs["variant"] == "as is"]
    note = ("<p class='note'>each run changes one source of the run as it is (roughvib "
            "sources; sources.csv has every band): a source matters in a band where changing "
            "it moves the level.</p>")
    offs = [abs(float(base[f"{sig}_db"].iloc[0]) - v)
            for sig, v in zip(("block", "plate"), own, strict=True)
            if len(base) and v is not None and math.isfinite(v)]  # a rigid base: no plate
    if offs:
        off = max(offs)
        if not off <= 0.05:
            note += (f"<p class='status-failed'>the study's run as it is differs from this "
                     f"run by up to {esc(f'{off:.2g}')} dB overall: it was made for another "
                     f"scene.</p>")
    fig = draw_sources(bands, "band levels with one source changed, against the run as it is")
    src = figure_data_uri(fig, dpi=dpi)
    return table(head, rows) + note + figure(
        src, alt="figure sources", id="fig-sources",
        caption_html="<b>sources</b>: change of each third-octave band (FFT band sums over "
                     "the analysis window) when one source is changed, block above plate.")
