"""The work-precision figure of ``roughvib compare``: error against cost, one panel per metric.

Takes the plain table :func:`roughvib.studies.compare.run_study` writes
(``work_precision.csv``) and never imports the study. Each method's points are joined in order
of cost and labelled with their setting (rtol, or step in s); the accuracy presets are drawn
as stars labelled with their name; the contract's limit is a dashed line in every panel. Labels
that would cover one another (runs of about equal cost and error) are moved up or down by a
line until they are free.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["PANELS", "label_boxes", "log_ticks", "plot_work_precision"]

#: (column, axis label, contract limit key) of each panel
PANELS = (
    ("plate_band_db", "plate: largest band deviation [dB]", "band_db"),
    ("block_band_db", "block: largest band deviation [dB]", "band_db"),
    ("velocity_rel_rms", "tangential velocity rel. rms error [-]", "velocity_rel_rms"),
    ("event_dt_max", "largest event-time error [s]", "event_dt"),
    ("energy_rel_residual", "energy-audit relative residual [-]", "energy_rel_residual"),
    ("contract_ratio", "largest error / contract limit [-]", None),
)


def log_ticks(lo: float, hi: float, max_ticks: int = 6) -> list[float]:
    """Tick positions for a log axis over [lo, hi] that leave room for their labels.

    The candidates are 1, 2, 5 x 10^k, then 1 x 10^k, then every n-th decade, whichever is the
    densest set with at most ``max_ticks`` ticks in the range; at least the two ends' decades
    when the range is narrower than one candidate step.
    """
    if not (lo > 0 and hi > 0 and math.isfinite(lo) and math.isfinite(hi)):
        return []
    lo, hi = min(lo, hi), max(lo, hi)
    k0, k1 = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
    for subs in ((1, 2, 5), (1,)):
        ticks = [m * 10.0**k for k in range(k0, k1 + 1) for m in subs
                 if lo * (1 - 1e-9) <= m * 10.0**k <= hi * (1 + 1e-9)]
        if 2 <= len(ticks) <= max_ticks:
            return ticks
    decades = [10.0**k for k in range(k0, k1 + 1)]
    step = max(1, math.ceil(len(decades) / max_ticks))
    return decades[::step] if len(decades) >= 2 else [10.0**k0, 10.0**k1]


def _fmt_tick(v: float) -> str:
    return f"{v:g}"


def _set_ticks(ax, axis: str) -> None:
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter, NullLocator

    lo, hi = (ax.get_xlim() if axis == "x" else ax.get_ylim())
    ticks = log_ticks(lo, hi, max_ticks=5 if axis == "x" else 6)
    a = ax.xaxis if axis == "x" else ax.yaxis
    a.set_major_locator(FixedLocator(ticks))
    a.set_major_formatter(FuncFormatter(lambda v, _pos: _fmt_tick(v)))
    a.set_minor_locator(NullLocator())
    a.set_minor_formatter(NullFormatter())


def _spread_labels(fig, axes, step: float = 7.0, tries: int = 8) -> None:
    """Place each point label near its point where it covers no other text.

    Labels are visited in drawing order; each takes the best place among: right of its point
    at offsets 0, -step, +step, -2 step, ... [points] up, then the same left of it (``tries``
    heights per side, nearest first). A place costs 10 for each label placed before it, tick
    label, axis label or title it covers and for leaving its panel, and 1 for each point
    marker of the panel it covers; the first place of the least cost wins.
    """
    from matplotlib.transforms import Bbox

    fig.draw_without_rendering()  # lays the figure out: boxes in display units
    renderer = fig.canvas.get_renderer()
    pad = fig.dpi / 72.0  # one point in pixels
    for ax in axes:
        inside = ax.get_window_extent(renderer)
        texts = [t.get_window_extent(renderer)
                 for t in (*ax.get_xticklabels(), *ax.get_yticklabels(), ax.xaxis.label,
                           ax.yaxis.label, ax.title) if t.get_visible() and t.get_text()]
        markers = []
        for line in ax.lines:
            if line.get_marker() in (None, "", "None", " "):
                continue
            r = 0.5 * line.get_markersize() * pad
            markers += [Bbox.from_extents(x - r, y - r, x + r, y + r)
                        for x, y in line.get_transform().transform(line.get_xydata())
                        if np.isfinite(x) and np.isfinite(y)]
        for ann in ax.texts:
            x0, y0 = ann.xyann
            best = None
            for side in (1, -1):
                for k in range(tries):
                    xy = (side * abs(x0), y0 + ((k + 1) // 2) * step * (-1) ** k)
                    ha = "left" if side > 0 else "right"
                    ann.xyann = xy
                    ann.set_horizontalalignment(ha)
                    box = ann.get_window_extent(renderer)
                    out = not (inside.contains(box.x0, box.y0)
                               and inside.contains(box.x1, box.y1))
                    cost = (10 * (sum(box.overlaps(o) for o in texts) + out)
                            + sum(box.overlaps(m) for m in markers))
                    if best is None or cost < best[0]:
                        best = (cost, xy, ha)
                    if cost == 0:
                        break
                if best[0] == 0:
                    break
            ann.xyann = best[1]
            ann.set_horizontalalignment(best[2])
            texts.append(ann.get_window_extent(renderer))


def label_boxes(fig) -> list[list]:
    """The display-unit boxes of the point labels of each panel of a drawn figure (for tests).

    Returns
    -------
    list of list of matplotlib.transforms.Bbox
        One list per panel, in the panels' order.
    """
    renderer = fig.canvas.get_renderer()
    return [[t.get_window_extent(renderer) for t in ax.texts] for ax in fig.axes]


def _setting_label(row) -> str:
    if isinstance(row.get("preset"), str) and row["preset"]:
        return str(row["preset"])
    v = row["setting"]
    return f"{v:g}" if row.get("setting_name") == "rtol" else f"{v:g} s"


def plot_work_precision(table: pd.DataFrame, path: str | Path, title: str,
                        contract: dict | None = None, *, dpi: int = 110):
    """Draw the work-precision figure and write it as PNG.

    Parameters
    ----------
    table : DataFrame
        One row per run: ``method``, ``setting``, ``setting_name`` (``"rtol"`` or
        ``"step [s]"``), ``preset`` (name or empty), ``status``, ``wall_time`` [s] and the
        metric columns of :data:`PANELS`.
    path : str or Path
        PNG file.
    title : str
        Figure title.
    contract : dict, optional
        The contract's limits (``band_db``, ``event_dt``, ...), drawn as dashed lines.
    dpi : int
        Resolution [dots per inch].

    Returns
    -------
    matplotlib.figure.Figure
        The figure as written.

    Raises
    ------
    roughvib.rundir.WriteError
        The file cannot be written (a full disk): one line naming it; nothing is left.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from roughvib.rundir import write_file

    contract = contract or {}
    fig = Figure(figsize=(15, 9), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3)
    ok = table[table["status"] == "success"]
    methods = sorted(ok["method"].unique())
    for ax, (metric, label, limit_key) in zip(axes.ravel(), PANELS, strict=True):
        drawn = False
        for i, method in enumerate(methods):
            m = ok[(ok["method"] == method) & np.isfinite(ok[metric].astype(float))
                   & (ok[metric].astype(float) > 0)]
            m = m.sort_values("wall_time")  # in order of cost
            if not len(m):
                continue
            drawn = True
            color = f"C{i % 10}"
            ax.loglog(m["wall_time"], m[metric], "-", color=color, lw=1, label=method)
            is_preset = m["preset"].fillna("").astype(str) != ""
            ax.plot(m["wall_time"][~is_preset], m[metric][~is_preset], "o", color=color, ms=4)
            ax.plot(m["wall_time"][is_preset], m[metric][is_preset], "*", color=color, ms=11,
                    mec="k", mew=0.5)
            for _, row in m.iterrows():
                ax.annotate(_setting_label(row), (row["wall_time"], row[metric]),
                            textcoords="offset points", xytext=(4, 3), fontsize=6,
                            color=color, in_layout=False)
        limit = 1.0 if limit_key is None else contract.get(limit_key)
        if limit:
            ax.axhline(limit, color="k", ls="--", lw=0.8)
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel(label, fontsize=8)
        ax.grid(True, which="major", alpha=0.3)
        if drawn:
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.margins(x=0.15, y=0.15)
            _set_ticks(ax, "x")
            _set_ticks(ax, "y")
        ax.tick_params(labelsize=7)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8)
    fig.suptitle(f"{title}  (points: rtol or step; stars: accuracy presets; dashed: contract "
                 f"limit)", fontsize=10)
    _spread_labels(fig, axes.ravel())
    write_file(path, lambda tmp: fig.savefig(tmp, dpi=dpi))  # complete or not at all
    return fig
