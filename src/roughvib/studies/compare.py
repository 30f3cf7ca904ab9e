"""Work-precision study: the tolerance-driven solvers (IDA, adaptive-modal) over a ladder of
tolerances and the fixed-step schemes over a ladder of steps, measured against a reference run
on the same scene.

For each run: wall and CPU time, steps and residual evaluations, and errors against the
reference over the same whole-period window: (a) third-octave band level error of block and
plate acceleration, largest ``|dB|`` over 100 Hz–20 kHz and over 20–50 kHz; (b) relative rms error
of the tangential velocity; (c) event-time error (stick, slip, lift-off, touch-down matched one
to one; unmatched counted); (d) the run's own energy-audit residual. Runs are started from
cheap to expensive, round-robin over the methods, while the time budget lasts; a run that
fails is a row with its status. Writes ``work_precision.csv``, ``work_precision.md`` and
``work_precision.png`` and reports where each method's error/time line crosses IDA's.

The plate-mode tolerance of the tolerance-driven solvers follows their rtol on the ladder
(``atol_acceleration`` = rtol x 1e-2 m/s^2), so that one knob traces the whole trade.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from roughvib.analysis.compare import (
    band_level_errors,
    common_grid,
    match_events,
    max_abs_db,
    relative_rms_error,
)
from roughvib.analysis.levels import whole_period_window
from roughvib.results import Result, load_result
from roughvib.scene import Scene
from roughvib.simulation import simulate

__all__ = ["DEFAULT_RTOLS", "DEFAULT_STEPS", "FIXED_METHODS", "TOLERANCE_METHODS", "crossings",
           "errors_against", "run_study"]

DEFAULT_RTOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)
DEFAULT_STEPS = (1e-4, 5e-5, 2e-5, 1e-5, 5e-6, 2.5e-6, 1e-6, 5e-7, 2e-7, 1e-7)
TOLERANCE_METHODS = ("ida", "adaptive-modal")  # driven by rtol, the others by their step
FIXED_METHODS = ("exact-modal", "newmark", "paper")  # moreau: coulomb scenes only
METRICS = ("block_band_db_100_20k", "block_band_db_20k_50k", "plate_band_db_100_20k",
           "plate_band_db_20k_50k", "velocity_rel_rms", "event_dt_max", "events_unmatched",
           "energy_rel_residual")


@dataclass
class _Run:
    method: str
    setting: float
    overrides: dict


def _overrides(method: str, value: float, out_step: float) -> dict:
    if method in TOLERANCE_METHODS:
        return {"solver.method": method, "solver.rtol": value,
                "solver.atol_acceleration": value * 1e-2}
    step_out = out_step if value <= out_step else value
    return {"solver.method": method, "solver.step": value, "output.step": step_out}


def errors_against(result: Result, reference: Result, period: float, transient: float
                   ) -> dict:
    """Error metrics of a run against a reference (see the module docstring)."""
    ds, dr = result.dataset, reference.dataset
    sa, sr, dt = common_grid(ds["time"].values, dr["time"].values)
    t = ds["time"].values[sa]
    win = whole_period_window(t, period, transient if transient < t[-1] else 0.0)
    out: dict = {}
    fs = 1.0 / dt
    for body, var in (("block", "block_vertical_acceleration"),
                      ("plate", "plate_vertical_acceleration")):
        x = ds[var].values[sa][win]
        xr = dr[var].values[sr][win]
        fc, d = band_level_errors(x, xr, fs)
        out[f"{body}_band_db_100_20k"] = max_abs_db(fc, d, 100.0, 20e3)
        out[f"{body}_band_db_20k_50k"] = max_abs_db(fc, d, 20e3, 50e3)
    v = ds["block_tangential_velocity"].values[sa][win]
    vr = dr["block_tangential_velocity"].values[sr][win]
    out["velocity_rel_rms"] = relative_rms_error(v, vr)
    dts, unmatched = match_events(result.events, reference.events)
    out["event_dt_max"] = float(np.max(np.abs(dts))) if dts.size else float("nan")
    out["events_unmatched"] = int(unmatched)
    out["energy_rel_residual"] = abs(result.summary["energy_audit"]["relative_residual"])
    return out


def crossings(table: pd.DataFrame, metric: str, against: str = "ida") -> list[dict]:
    """Where each method's log-log error/wall-time line crosses the line of ``against``.

    Returns
    -------
    list of dict
        ``method``, ``wall_time`` [s] and ``error`` at each crossing (linear interpolation in
        log-log between measured points); empty when the lines do not cross in their common
        wall-time range.
    """
    ok = table[(table["status"] == "success") & np.isfinite(table[metric])
               & (table[metric] > 0)]
    ref = ok[ok["method"] == against].sort_values("wall_time")
    out = []
    if len(ref) < 2:
        return out
    lx_r = np.log(ref["wall_time"].to_numpy())
    ly_r = np.log(ref[metric].to_numpy())
    for method in sorted(set(ok["method"]) - {against}):
        m = ok[ok["method"] == method].sort_values("wall_time")
        if len(m) < 2:
            continue
        lx = np.log(m["wall_time"].to_numpy())
        ly = np.log(m[metric].to_numpy())
        grid = np.linspace(max(lx.min(), lx_r.min()), min(lx.max(), lx_r.max()), 400)
        if grid[0] >= grid[-1]:
            continue
        diff = np.interp(grid, lx, ly) - np.interp(grid, lx_r, ly_r)
        for i in np.flatnonzero(np.sign(diff[:-1]) * np.sign(diff[1:]) < 0):
            f = diff[i] / (diff[i] - diff[i + 1])
            gx = grid[i] + f * (grid[i + 1] - grid[i])
            out.append({"method": method, "metric": metric, "wall_time": float(np.exp(gx)),
                        "error": float(np.exp(np.interp(gx, lx_r, ly_r)))})
    return out


def _plot(table: pd.DataFrame, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    panels = [("plate_band_db_100_20k", "plate band error 100 Hz-20 kHz [dB]"),
              ("block_band_db_100_20k", "block band error 100 Hz-20 kHz [dB]"),
              ("plate_band_db_20k_50k", "plate band error 20-50 kHz [dB]"),
              ("velocity_rel_rms", "tangential velocity rel. rms error [-]"),
              ("event_dt_max", "largest event-time error [s]"),
              ("energy_rel_residual", "energy-audit relative residual [-]")]
    fig, axes = plt.subplots(2, 3, figsize=(13, 7))
    ok = table[table["status"] == "success"]
    for ax, (metric, label) in zip(axes.ravel(), panels, strict=True):
        for i, method in enumerate(sorted(ok["method"].unique())):
            m = ok[(ok["method"] == method) & np.isfinite(ok[metric]) & (ok[metric] > 0)]
            m = m.sort_values("setting", ascending=False)  # along the ladder, coarse to fine
            if len(m):
                ax.loglog(m["wall_time"], m[metric], "o-", color=f"C{i}", label=method, ms=4)
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel(label, fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run_study(scene: Scene, out_dir: str | Path, *, budget: float = 900.0,
              reference: str | Path | None = None,
              methods=TOLERANCE_METHODS + FIXED_METHODS,
              rtols=DEFAULT_RTOLS, steps=DEFAULT_STEPS, reference_rtol: float = 1e-10,
              progress: bool = True) -> pd.DataFrame:
    """Run the work-precision study and write its table, markdown and figure.

    Parameters
    ----------
    scene : Scene
        The scene to study (its solver section is overridden per run).
    out_dir : str or Path
        Output directory.
    budget : float
        Wall-time budget for the ladder runs [s] (the reference is not counted). A run whose
        predicted cost exceeds the remaining budget is not started.
    reference : path, optional
        A result directory to use as reference instead of computing one.
    methods, rtols, steps
        What to run.
    reference_rtol : float
        rtol (and 1e-2 x rtol m/s^2 modal atol) of the IDA reference.

    Returns
    -------
    DataFrame
        One row per run (including failed and skipped runs).
    """
    from roughvib._progress import progress_bar

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    base = scene.with_overrides({"output.progress": False})
    if reference is not None:
        ref = load_result(reference)
    else:
        ref = simulate(base.with_overrides(_overrides("ida", reference_rtol, 0.0)))
        ref.save(out / "reference")
    if not ref.ok:
        raise RuntimeError(f"reference run failed: {ref.summary.get('message')}")
    # loose tolerances and long steps first: cheap first
    ladders = {m: sorted(rtols if m in TOLERANCE_METHODS else steps, reverse=True)
               for m in methods}
    queue: list[_Run] = []
    while any(ladders.values()):
        for m in methods:
            if ladders[m]:
                v = ladders[m].pop(0)
                queue.append(_Run(m, v, _overrides(m, v, base.output.step)))
    # warm-up: compile (or load) every method's numba kernels before anything is timed
    for m in methods:
        tiny = {**_overrides(m, rtols[0] if m in TOLERANCE_METHODS else base.output.step,
                             base.output.step),
                "output.duration": 20 * base.output.step}
        try:
            simulate(base.with_overrides(tiny))
        except Exception:  # noqa: BLE001 - the timed run will report the problem
            pass
    rows = []
    last_cost: dict[str, float] = {}
    spent = 0.0
    period = base.period if math.isfinite(base.period) else 0.0
    bar = progress_bar(len(queue), desc="work-precision runs", disable=not progress, unit="run")
    for run in queue:
        row = {"method": run.method, "setting": run.setting,
               "setting_name": "rtol" if run.method in TOLERANCE_METHODS else "step [s]"}
        predicted = last_cost.get(run.method, 0.0) * (
            3.0 if run.method in TOLERANCE_METHODS else 2.5)
        if spent + predicted > budget:
            row.update(status="skipped", message=f"predicted {predicted:.0f} s exceeds the "
                                                 f"remaining budget")
            rows.append(row)
            bar.update(1)
            continue
        t0 = time.perf_counter()
        c0 = time.process_time()
        try:
            res = simulate(base.with_overrides(run.overrides))
            row.update(status=res.status, message=res.summary.get("message", ""))
            s = res.summary["solver"]
            row.update(steps=s.get("steps"), residual_evaluations=s.get("residual_evaluations"))
            if res.ok:
                row.update(errors_against(res, ref, period, base.output.transient))
        except Exception as exc:  # noqa: BLE001 - a failed run is a row, not the end
            row.update(status="error", message=f"{type(exc).__name__}: {exc}")
        wall = time.perf_counter() - t0
        row.update(wall_time=wall, cpu_time=time.process_time() - c0)
        last_cost[run.method] = wall
        spent += wall
        rows.append(row)
        bar.update(1)
    bar.close()
    table = pd.DataFrame(rows)
    for col in METRICS + ("wall_time", "cpu_time", "steps", "residual_evaluations"):
        if col not in table:
            table[col] = np.nan
    table.to_csv(out / "work_precision.csv", index=False, float_format="%.6g")
    cols = ["method", "setting", "status", "wall_time", "steps", *METRICS]
    md = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for _, r in table.iterrows():
        md.append("| " + " | ".join(_fmt(r.get(c)) for c in cols) + " |")
    cross = []
    for metric in ("plate_band_db_100_20k", "block_band_db_100_20k", "velocity_rel_rms"):
        cross += crossings(table, metric)
    (out / "work_precision.md").write_text(
        f"# Work-precision: scene {scene.name}\n\nReference: "
        f"{'given ' + str(reference) if reference else f'IDA rtol {reference_rtol:g}'}.\n\n"
        + "\n".join(md) + "\n\n## Crossings with IDA\n\n"
        + ("\n".join(f"- {c['method']} ({c['metric']}): {c['wall_time']:.3g} s at error "
                     f"{c['error']:.3g}" for c in cross) or "none in the measured range")
        + "\n")
    _plot(table, out / "work_precision.png", f"work-precision, scene {scene.name}")
    return table


def _fmt(v) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    if isinstance(v, float):
        return f"{v:.3g}"
    return str(v)
