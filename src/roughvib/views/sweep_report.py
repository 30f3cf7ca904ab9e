"""The sweep report's files: one figure per study (levels against the swept quantity with the
fitted slopes), ``report.md`` and ``report.html`` (built with :mod:`roughvib.views.html`).

Everything here takes plain tables, dicts and file names computed by
:mod:`roughvib.studies.sweep.report` and never imports the studies. A report is a title, an
introduction and a list of blocks ``(kind, payload)``: ``("h2", heading)``, ``("p", text)``,
``("img", PNG file name next to the report)`` and ``("table", (header, rows))`` with rows of
strings. The Markdown links the PNG files; the HTML page embeds them, so that it is one
self-contained file like the run report.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from roughvib.rundir import write_file
from roughvib.views.html import esc, figure, page, png_data_uri, slug, table

__all__ = ["render_html", "render_markdown", "study_figure"]


def study_figure(study: str, xlabel: str, groups: list[tuple[str, Any]], xcol: str,
                 seed_col: str | None, fits: dict, path: Path,
                 levels: Sequence[tuple[str, str]]) -> None:
    """Draw one study of a sweep report: levels against x with the fitted lines; write a PNG.

    Parameters
    ----------
    study : str
        Study name (figure title), e.g. ``"velocity"``.
    xlabel : str
        Label of the x axis, with its unit.
    groups : list of (str, pandas.DataFrame)
        Label and successful cases of each group (one fitted line each).
    xcol : str
        Column of the x values (> 0; drawn on a log axis).
    seed_col : str or None
        Column of the seeds (one marker per seed).
    fits : dict
        ``(which, group label) -> fit`` as made by ``roughvib.studies.sweep.tables``:
        ``db_per_doubling``, ``intercept``, ``ci_low``, ``ci_high``.
    path : Path
        PNG file.
    levels : sequence of (str, str)
        One panel each: name (``"block"``) and column of the level [dB re 1e-6 m/s^2].

    Raises
    ------
    roughvib.rundir.WriteError
        The file cannot be written (a full disk): one line naming it; nothing is left.
    """
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2, sharex=True)
    markers = "osD^v<>pP*"
    for ax, (which, col) in zip(axes, levels, strict=True):
        for gi, (label, df) in enumerate(groups):
            color = f"C{gi % 10}"
            seeds = df[seed_col].tolist() if seed_col else [None] * len(df)
            seed_order = list(dict.fromkeys(seeds))
            for si, seed in enumerate(seed_order):
                sel = [s == seed for s in seeds]
                ax.plot(df[xcol][sel], df[col][sel], linestyle="none",
                        marker=markers[si % len(markers)], color=color, alpha=0.8,
                        label=(f"seed {seed}" if seed is not None and gi == 0 else None))
            f = fits.get((which, label))
            if f is not None:
                xs = np.geomspace(df[xcol].min(), df[xcol].max(), 50)
                ci = "" if not math.isfinite(f["ci_low"]) else \
                    f" [{f['ci_low']:.1f}, {f['ci_high']:.1f}]"
                ax.plot(xs, f["intercept"] + f["db_per_doubling"] * np.log2(xs), color=color,
                        label=f"{label}: {f['db_per_doubling']:.1f}{ci} dB/doubling")
        ax.set_xscale("log")
        ticks: list[float] = []
        for v in sorted({float(f"{v:.2g}") for _, df in groups for v in df[xcol]}):
            if not ticks or v > 1.08 * ticks[-1]:  # values of several seeds differ slightly
                ticks.append(v)
        if len(ticks) <= 10:
            ax.set_xticks(ticks, [f"{t:.2g}" for t in ticks])
            ax.minorticks_off()
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"{which} acceleration level [dB re 1e-6 m/s²]")
        ax.set_title(f"{which} (total level)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{study} study")
    write_file(path, lambda tmp: fig.savefig(tmp, dpi=110))  # complete or not at all


def _md_table(header: list[str], rows: list[list[str]]) -> str:
    def esc(s: str) -> str:
        return str(s).replace("|", "\\|")

    lines = ["| " + " | ".join(esc(h) for h in header) + " |",
             "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(esc(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def render_markdown(title: str, intro: str, blocks: Sequence[tuple[str, Any]]) -> str:
    """The report as Markdown (see the module docstring for ``blocks``)."""
    md = [f"# {title}", "", intro, ""]
    for kind, payload in blocks:
        if kind == "h2":
            md += [f"## {payload}", ""]
        elif kind == "p":
            md += [payload, ""]
        elif kind == "img":
            md += [f"![{payload}]({payload})", ""]
        else:
            md += [_md_table(*payload), ""]
    return "\n".join(md)


def render_html(title: str, intro: str, blocks: Sequence[tuple[str, Any]], *,
                directory: str | Path) -> str:
    """The report as one HTML page of :func:`roughvib.views.html.page` (see the module
    docstring for ``blocks``): each ``h2`` block opens a section, each ``img`` block's PNG
    (read from ``directory``) is embedded as a data URI."""
    header = [f"<p>{esc(intro)}</p>"]
    sections: list[tuple[str, str, list[str]]] = []
    for kind, payload in blocks:
        if kind == "h2":
            ident = slug(payload)
            while ident in {i for i, _, _ in sections}:
                ident += "-"
            sections.append((ident, payload, []))
            continue
        if kind == "p":
            part = f"<p>{esc(payload)}</p>"
        elif kind == "img":
            png = (Path(directory) / payload).read_bytes()
            part = figure(png_data_uri(png), alt=payload)
        else:
            part = table(*payload)
        (sections[-1][2] if sections else header).append(part)
    return page(title, [(i, h, "".join(c)) for i, h, c in sections],
                header_html="".join(header))
