"""Figures of a run. Pure functions: they take a Result (and ``ax``/``axes`` = None) and return
the Axes they drew on; matplotlib is imported lazily and nothing is shown.

``FIGURES`` maps the names accepted by ``roughvib plot DIR --figure NAME`` to functions that
draw a whole figure and return it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from roughvib.analysis.events import lift_off_intervals, stick_intervals

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from roughvib.results import Result

__all__ = ["FIGURES", "plot_events", "plot_regime_timeline", "plot_velocity", "save_figure"]


def _plt():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "module://matplotlib_inline.backend_inline"):
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _ax(ax):
    if ax is None:
        _, ax = _plt().subplots(figsize=(8, 3))
    return ax


def plot_velocity(result: Result, *, ax: Axes | None = None) -> Axes:
    """Tangential block velocity against time (the paper's Figs. 6/7), stick phases shaded."""
    ax = _ax(ax)
    ds = result.dataset
    t = ds["time"].values
    ax.plot(t, ds["block_tangential_velocity"].values * 1e3, lw=0.8, color="C0")
    for s, e in stick_intervals(result.events, float(t[-1])):
        ax.axvspan(s, e, color="0.85", lw=0, zorder=0)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tangential velocity [mm/s]")
    ax.set_title("friction velocity (grey: stick)")
    return ax


def plot_regime_timeline(result: Result, *, ax: Axes | None = None) -> Axes:
    """Regimes over time: one row per contact (bar = lift-off) and one for the block (stick)."""
    ax = _ax(ax)
    ds = result.dataset
    t_end = float(ds["time"].values[-1])
    K = ds.sizes["contact"]
    for k in range(K):
        iv = lift_off_intervals(result.events, k, t_end)
        if iv:
            ax.broken_barh([(s, e - s) for s, e in iv], (k - 0.4, 0.8), color="C3")
    iv = stick_intervals(result.events, t_end)
    if iv:
        ax.broken_barh([(s, e - s) for s, e in iv], (K - 0.4 + 0.5, 0.8), color="C0")
    guards = result.events[result.events["kind"].isin(["hysteresis_hold", "dwell_hold"])]
    if len(guards):
        ax.plot(guards["time"], np.full(len(guards), K + 0.5), "k|", ms=8, label="guard")
        ax.legend(loc="upper right", fontsize=7)
    ax.set_yticks(list(range(K)) + [K + 0.5])
    ax.set_yticklabels([f"contact {k}" for k in range(K)] + ["block stick"], fontsize=7)
    ax.set_ylim(-0.7, K + 1.2)
    ax.set_xlim(0, t_end)
    ax.set_xlabel("time [s]")
    ax.set_title("regimes (red: contact open, blue: stick)")
    return ax


def plot_events(result: Result, *, axes=None):
    """Timeline of regimes per contact under the tangential velocity and normal force.

    Returns the three Axes (velocity, normal force, regimes).
    """
    if axes is None:
        fig, axes = _plt().subplots(3, 1, figsize=(9, 7), sharex=True,
                                    gridspec_kw={"height_ratios": [1, 1, 1.4]})
    ds = result.dataset
    t = ds["time"].values
    plot_velocity(result, ax=axes[0])
    axes[0].set_xlabel("")
    axes[1].plot(t, ds["normal_force"].values, lw=0.6, color="C2")
    axes[1].set_ylabel("normal force [N]")
    axes[1].set_title("total normal contact force")
    plot_regime_timeline(result, ax=axes[2])
    return axes


def save_figure(fig: Figure, path) -> None:
    """Write a figure as PNG and close it."""
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    _plt().close(fig)


def _whole(fn: Callable, **kw) -> Callable[[Result], Figure]:
    def draw(result: Result) -> Figure:
        out = fn(result, **kw)
        ax = out[0] if isinstance(out, list | tuple | np.ndarray) else out
        return ax.figure

    return draw


FIGURES: dict[str, Callable[[Result], Figure]] = {
    "events": _whole(plot_events),
    "velocity": _whole(plot_velocity),
}

