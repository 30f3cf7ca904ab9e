"""Work-precision study: every solver over a ladder of settings and at its accuracy presets,
measured against a reference run of the same scene by the accuracy contract's metrics.

The methods are those of the solver registry (:mod:`roughvib.solvers.registry`) that run the
scene, or those named; each runs the ladder of its kind: the tolerance-driven solvers (IDA,
adaptive-modal) a ladder of rtol (with ``atol_acceleration`` = rtol x 1e-2 m/s^2, so that one
knob traces the whole trade), the fixed-step schemes a ladder of steps; and each method also
runs its three accuracy presets
(``solver.accuracy``; ``roughvib.scene.ACCURACY_PRESETS``). Every run is measured against
the reference with :func:`roughvib.analysis.accuracy.measure_accuracy`, the code that
``roughvib run --verify`` uses: the largest band deviation of block and plate (the contract's
bands), the tangential velocity's relative rms error, the largest event-time error after
one-to-one matching (unmatched counted), the run's own energy-audit residual, the largest
ratio of an error to its contract limit and the verdict. Runs go from cheap to expensive,
round-robin over the methods.

The time budget bounds the whole study, the reference included: the reference and every
run execute in a worker process that is stopped when the budget is spent (a stopped run is a
row with status ``over_budget``; a stopped reference ends the study with
:class:`BudgetExceeded`). Writes ``work_precision.csv``, ``work_precision.md`` and
``work_precision.png`` and reports where each method's error/time line crosses IDA's.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import sys
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from roughvib.analysis.accuracy import CONTRACT, contract_ratio, measure_accuracy
from roughvib.results import Result, load_result
from roughvib.rundir import output_folder, writing
from roughvib.scene import ACCURACY_LEVELS, Scene, SceneError, user_stacklevel
from roughvib.simulation import simulate
from roughvib.solvers import registry

__all__ = ["DEFAULT_RTOLS", "DEFAULT_STEPS", "FIXED_METHODS", "TOLERANCE_METHODS",
           "BudgetExceeded", "crossings", "errors_against", "outcome_line", "run_study",
           "study_methods"]

DEFAULT_RTOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)
DEFAULT_STEPS = (1e-4, 5e-5, 2e-5, 1e-5, 5e-6, 2.5e-6, 1e-6, 5e-7, 2e-7, 1e-7)
#: the registered solvers driven by rtol (their ladder: ``rtols``)
TOLERANCE_METHODS = registry.names(registry.TOLERANCE)
#: the registered solvers driven by a fixed step (their ladder: ``steps``); a study runs those
#: of them that run its scene (:func:`study_methods`)
FIXED_METHODS = registry.names(registry.STEP)
METRICS = ("block_band_db", "plate_band_db", "velocity_rel_rms", "event_dt_max",
           "events_unmatched", "energy_rel_residual", "contract_ratio")


class BudgetExceeded(RuntimeError):
    """The reference run did not finish within the study's time budget."""


@dataclass
class _Run:
    method: str
    setting: float
    overrides: dict
    preset: str = ""


def _fixed(method: str) -> bool:
    """Whether ``method`` runs a ladder of steps (else one of rtol)."""
    return registry.get(method).kind == registry.STEP


def study_methods(scene: Scene, methods=None) -> tuple[str, ...]:
    """The methods a study of ``scene`` runs.

    Parameters
    ----------
    scene : Scene
        The scene (its solver section is not looked at; checkpoints off, as the study runs).
    methods : sequence of str, optional
        The methods to run; default: every registered solver that runs the scene, in the
        registry's order.

    Returns
    -------
    tuple of str

    Raises
    ------
    SceneError
        A named method that cannot run the scene: one line naming it, the rule and what
        would run the scene (the refusal of scene validation).
    ValueError
        A name that is no registered solver.
    """
    if methods is None:
        return registry.supporting(scene)
    for m in methods:
        reason = registry.get(m).supports(scene)
        if reason is not None:
            raise SceneError(f"solver.method = {m!r} cannot run this scene: {reason}")
    return tuple(methods)


def _overrides(method: str, value: float, out_step: float) -> dict:
    if not _fixed(method):
        return {"solver.method": method, "solver.rtol": value,
                "solver.atol_acceleration": value * 1e-2}
    step_out = out_step if value <= out_step else value
    return {"solver.method": method, "solver.step": value, "output.step": step_out}


def _preset_run(scene: Scene, method: str, level: str) -> _Run:
    over = {"solver.method": method, "solver.accuracy": level, "solver.rtol": None,
            "solver.atol": None, "solver.atol_acceleration": None, "solver.step": None}
    s = scene.with_overrides(over).resolved_solver()
    if _fixed(method):
        if s.step > scene.output.step:
            over["output.step"] = s.step
        return _Run(method, s.step, over, level)
    return _Run(method, s.rtol, over, level)


def _key(scene: Scene, run: _Run) -> tuple:
    """What a run computes: its resolved solver settings and output step."""
    sc = scene.with_overrides(run.overrides)
    s = sc.resolved_solver()
    if _fixed(s.method):
        return (s.method, s.step, sc.output.step)
    return (s.method, s.rtol, s.atol, s.atol_acceleration)


def errors_against(result: Result, reference: Result, period: float, transient: float
                   ) -> dict:
    """Error metrics of a run against a reference (the accuracy contract's measurement).

    Returns
    -------
    dict
        ``block_band_db`` and ``plate_band_db`` (largest absolute deviation over the contract's
        bands, inf for a lost band) with ``block_band_hz`` / ``plate_band_hz``,
        ``velocity_rel_rms``, ``event_dt_max`` [s], ``events_unmatched``,
        ``energy_rel_residual``, ``contract_ratio`` (largest error / its limit) and
        ``verdict``.
    """
    acc = measure_accuracy(result, reference, period=period, transient=transient)
    out: dict = {}
    for name, b in acc["bands"].items():
        d = b["deviation_db"]
        out[f"{name}_band_db"] = (math.inf if isinstance(d, str) else
                                  abs(d) if d is not None else math.nan)
        out[f"{name}_band_hz"] = b["worst_band_hz"]
    v = acc["velocity_rel_rms"]
    out.update(velocity_rel_rms=v if v is not None else math.nan,
               event_dt_max=acc["events"]["max_dt"],
               events_unmatched=acc["events"]["unmatched"],
               energy_rel_residual=acc["energy_rel_residual"],
               contract_ratio=contract_ratio(acc), verdict=acc["verdict"])
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
    ok = table[(table["status"] == "success") & np.isfinite(table[metric].astype(float))
               & (table[metric].astype(float) > 0)]
    ref = ok[ok["method"] == against].sort_values("wall_time")
    out = []
    if len(ref) < 2:
        return out
    lx_r = np.log(ref["wall_time"].to_numpy(float))
    ly_r = np.log(ref[metric].to_numpy(float))
    for method in sorted(set(ok["method"]) - {against}):
        m = ok[ok["method"] == method].sort_values("wall_time")
        if len(m) < 2:
            continue
        lx = np.log(m["wall_time"].to_numpy(float))
        ly = np.log(m[metric].to_numpy(float))
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


# --------------------------------------------------------------------------------------------
# bounded runs: in a worker process, stopped when the budget is spent
# --------------------------------------------------------------------------------------------


def _serve(conn) -> None:  # pragma: no cover - runs in the worker process
    """The worker's loop: do each job it is sent (:func:`_job`) and report what it gives and
    the warnings it issued (as ``(category, message)`` pairs: the study shows them, once)."""
    references: dict[str, Result] = {}
    while True:
        job = conn.recv()
        if job is None:
            return
        with warnings.catch_warnings(record=True) as caught:  # under the default filters
            try:
                info = _job(job, references)
            except Exception as exc:  # noqa: BLE001 - reported as the run's row
                info = {"status": "error", "message": f"{type(exc).__name__}: {exc}"}
        info["warnings"] = list(dict.fromkeys((w.category, str(w.message)) for w in caught))
        conn.send(info)


def _job(job: tuple, references: dict) -> dict:
    """One job of the worker: ``("run", scene, save_to, progress, measure)`` simulates the
    scene, saves it into ``save_to`` (if given) and, with ``measure = (reference_dir, period,
    transient)``, measures it against the reference there (loaded once per worker), so that
    the measurement is bounded by the budget like the run; ``("plot", table, path, title,
    contract)`` draws the study's figure."""
    if job[0] == "plot":
        from roughvib.views.work_precision import plot_work_precision

        _, table, path, title, contract = job
        plot_work_precision(table, path, title, contract=contract)
        return {"status": "success"}
    _, scene, save_to, progress, measure = job
    t0 = time.perf_counter()
    c0 = time.process_time()
    res = simulate(scene, progress=progress)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    s = res.summary.get("solver", {})
    info = {"wall_time": wall, "cpu_time": cpu, "status": res.status,
            "message": res.summary.get("message", ""), "steps": s.get("steps"),
            "residual_evaluations": s.get("residual_evaluations")}
    if save_to:
        res.save(save_to)
    if measure is not None and res.ok:
        ref_dir, period, transient = measure
        if ref_dir not in references:
            references[ref_dir] = load_result(ref_dir)
        info.update(errors_against(res, references[ref_dir], period, transient))
    return info


class _Worker:
    """A child process that does the study's jobs one after another, so that a job can be
    stopped when the budget is spent. It is started with ``spawn`` (a fresh interpreter:
    forking a process with threads can copy a held lock into the child and hang it) and
    restarted after a stop."""

    def __init__(self) -> None:
        self.proc = None
        self.conn = None

    def run(self, job: tuple, timeout: float) -> dict:
        """Do ``job`` (see :func:`_job`) for at most ``timeout`` seconds.

        Returns what the job gives (``status``, ``message``, ``wall_time``, ...), or status
        ``over_budget`` when it was stopped, or not started (``timeout`` <= 0)."""
        if not timeout > 0:
            return {"status": "over_budget", "wall_time": 0.0,
                    "message": "not started: the budget was spent"}
        t0 = time.perf_counter()
        if self.proc is None or not self.proc.is_alive():
            ctx = mp.get_context("spawn")
            self.conn, child = ctx.Pipe()
            self.proc = ctx.Process(target=_serve, args=(child,), daemon=True)
            self.proc.start()
            child.close()
        self.conn.send(job)
        if self.conn.poll(max(timeout - (time.perf_counter() - t0), 0.0)):
            try:
                return self.conn.recv()
            except (EOFError, OSError):  # the worker died (killed, out of memory)
                self.close()
                return {"status": "error", "wall_time": time.perf_counter() - t0,
                        "message": "the worker process ended unexpectedly"}
        self.close(busy=True)
        spent = time.perf_counter() - t0
        return {"status": "over_budget", "wall_time": spent,
                "message": f"stopped after {spent:.0f} s: the budget was spent"}

    def close(self, busy: bool = False) -> None:
        """End the worker: ask an idle one to return, stop a busy one (``busy``) at once."""
        if self.proc is not None:
            if self.proc.is_alive() and not busy:
                try:
                    self.conn.send(None)
                except (BrokenPipeError, OSError):
                    pass
                self.proc.join(timeout=0.5)
            if self.proc.is_alive():
                self.proc.terminate()
                self.proc.join()
            self.conn.close()
        self.proc = self.conn = None


class _Warnings:
    """Issues the warnings of the study's runs in this process, each distinct one once (every
    run of the study repeats the scene's validity warnings)."""

    def __init__(self) -> None:
        self.seen: set[tuple[type[Warning], str]] = set()

    def issue(self, info: dict) -> None:
        for category, message in info.get("warnings", ()):
            if (category, message) not in self.seen:
                self.seen.add((category, message))
                warnings.warn(message, category, stacklevel=user_stacklevel())


def _reference_scene(base: Scene, method: str, rtol: float) -> Scene:
    if method == "auto":
        method = base.with_overrides({"solver.method": "auto",
                                      "output.checkpoint_interval": 0.0}
                                     ).resolved_solver().method
    return base.with_overrides({**_overrides(method, rtol, base.output.step),
                                "solver.atol": min(1e-12, 1e-2 * rtol),
                                "output.checkpoint_interval": 0.0})


def run_study(scene: Scene, out_dir: str | Path, *, budget: float = 900.0,
              reference: str | Path | None = None,
              methods=None,
              rtols=DEFAULT_RTOLS, steps=DEFAULT_STEPS, reference_rtol: float = 1e-10,
              reference_method: str = "auto", presets: bool = True,
              progress: bool = True, started: float | None = None) -> pd.DataFrame:
    """Run the work-precision study and write its table, markdown and figure.

    Parameters
    ----------
    scene : Scene
        The scene to study (its solver section is overridden per run).
    out_dir : str or Path
        Output directory.
    budget : float
        Wall-time budget of the whole study, the reference included [s]. A run whose
        predicted cost exceeds the remaining budget is not started, a running one is stopped
        when the budget is spent.
    reference : path, optional
        A result directory to use as reference instead of computing one.
    methods : sequence of str, optional
        The solvers to run; default: every registered solver that runs the scene
        (:func:`study_methods`). A named one that cannot run it is refused before any run.
    rtols, steps
        The ladders of the tolerance-driven and of the fixed-step solvers.
    reference_rtol : float
        rtol of the reference (``atol_acceleration`` = 1e-2 x rtol m/s^2, ``atol`` =
        min(1e-12, 1e-2 x rtol) m).
    reference_method : {"auto", "ida", "adaptive-modal"}
        Solver of the reference; ``auto``: adaptive-modal where it can run, else IDA.
    presets : bool
        Also run each method at its accuracy presets.
    progress : bool
        Progress bars (the reference's solver, then the runs) on stderr.
    started : float, optional
        The ``time.perf_counter()`` value the budget counts from (the CLI passes its process's
        start, so that its imports count); default: the call of this function.

    Returns
    -------
    DataFrame
        One row per run (including failed, stopped and skipped runs).

    Raises
    ------
    SceneError
        A named method that cannot run the scene (one line, before any run).
    BudgetExceeded
        If the reference does not finish within the budget.
    RuntimeError
        If the reference run fails.
    roughvib.rundir.OutputError
        ``out_dir`` cannot be made or written to (a file in its way): one line, before any
        run.
    roughvib.rundir.WriteError
        A table cannot be written (a full disk): one line naming it; each file appears
        complete or not at all.
    """
    t_start = time.perf_counter() if started is None else float(started)
    base = scene.with_overrides({"output.progress": False, "output.checkpoint_interval": 0.0})
    methods = study_methods(base, methods)
    out = output_folder(out_dir)
    clock = _Deadlines(t_start, budget)
    worker = _Worker()
    try:
        return _study(scene, base, out, worker, budget, clock, reference, methods, rtols,
                      steps, reference_rtol, reference_method, presets, progress)
    finally:
        worker.close()


#: seconds of the budget kept for the process's exit after the study (the CLI's last lines,
#: the interpreter's teardown: 0.3-0.6 s measured on a quiet 2-core machine, 1.1 s at a load
#: of 11) and for writing the table and the markdown
EXIT_MARGIN = 2.0
#: seconds of the budget kept after the last run for drawing the figure in the worker
#: (matplotlib's import and the drawing: 1.7-2.6 s measured on the project's 2-core machine)
FIGURE_RESERVE = 5.0


class _Deadlines:
    """The study's budget as deadlines: the reference and the figure may use it up to
    :data:`EXIT_MARGIN` before its end, the runs up to :data:`FIGURE_RESERVE` before that."""

    def __init__(self, t_start: float, budget: float) -> None:
        self.t_start = t_start
        self.end = t_start + budget - EXIT_MARGIN

    def left(self) -> float:
        """Seconds left for the reference or the figure."""
        return self.end - time.perf_counter()

    def left_for_runs(self) -> float:
        """Seconds left for the runs (and their warm-up)."""
        return self.left() - FIGURE_RESERVE

    def spent(self) -> float:
        return time.perf_counter() - self.t_start


def _reference(base, out, worker, budget, clock, reference, reference_rtol, reference_method,
               progress, issued) -> tuple[str, str]:
    """The reference of the study: its directory and label (computed within the budget, or
    the given one, checked)."""
    if reference is not None:
        ref = load_result(reference)
        if not ref.ok:
            raise RuntimeError(f"reference run failed: {ref.summary.get('message')}")
        return str(reference), f"given {reference}"
    rscene = _reference_scene(base, reference_method, reference_rtol)
    rs = rscene.resolved_solver()
    label = (f"{rs.method} rtol {rs.rtol:g}, atol {rs.atol:g} m, atol_acceleration "
             f"{rs.atol_acceleration:g} m/s^2")
    print(f"reference: {label} (within the budget of {budget:g} s)", file=sys.stderr,
          flush=True)
    info = worker.run(("run", rscene, str(out / "reference"), progress, None), clock.left())
    issued.issue(info)
    if info["status"] == "over_budget":
        raise BudgetExceeded(
            f"the reference run ({label}) did not finish within --budget {budget:g} s; "
            f"give a larger --budget, a looser --reference-rtol or --reference DIR")
    if info["status"] != "success":
        raise RuntimeError(f"reference run failed ({info['status']}): {info['message']}")
    return str(out / "reference"), label


def _study(scene, base, out, worker, budget, clock, reference, methods, rtols, steps,
           reference_rtol, reference_method, presets, progress) -> pd.DataFrame:
    from roughvib._progress import progress_bar

    issued = _Warnings()
    ref_dir, ref_label = _reference(base, out, worker, budget, clock, reference,
                                    reference_rtol, reference_method, progress, issued)
    queue = _queue(base, methods, rtols, steps, presets)
    # warm-up: compile (or load) every method's numba kernels before anything is timed
    for m in methods:
        tiny = {**_overrides(m, base.output.step if _fixed(m) else rtols[0],
                             base.output.step),
                "output.duration": 20 * base.output.step}
        # a failure shows later; the warnings are those of its 20 steps, not of the study
        worker.run(("run", base.with_overrides(tiny), "", False, None), clock.left_for_runs())
    rows = []
    last_cost: dict[str, float] = {}
    measure = (ref_dir, base.period, base.output.transient)
    bar = progress_bar(len(queue), desc="work-precision runs", disable=not progress, unit="run")
    for run in queue:
        row = {"method": run.method, "setting": run.setting, "preset": run.preset,
               "setting_name": "step [s]" if _fixed(run.method) else "rtol"}
        predicted = last_cost.get(run.method, 0.0) * (2.5 if _fixed(run.method) else 3.0)
        left = clock.left_for_runs()
        if predicted > left or left <= 0:
            row.update(status="skipped",
                       message=f"predicted {predicted:.0f} s exceeds the remaining budget"
                       if left > 0 else "not started: the budget was spent")
        else:
            info = worker.run(("run", base.with_overrides(run.overrides), "", False, measure),
                              left)
            issued.issue(info)
            row.update({k: v for k, v in info.items() if k != "warnings"})
            last_cost[run.method] = float(info.get("wall_time") or 0.0)
        rows.append(row)
        bar.update(1)
    bar.close()
    table = pd.DataFrame(rows)
    for col in METRICS + ("wall_time", "cpu_time", "steps", "residual_evaluations",
                          "block_band_hz", "plate_band_hz", "verdict", "message"):
        if col not in table:
            table[col] = np.nan
    with writing(out / "work_precision.csv") as fh:
        table.to_csv(fh, index=False, float_format="%.6g")
    drawn = worker.run(("plot", table, str(out / "work_precision.png"),
                        f"work-precision, scene {scene.name}", asdict(CONTRACT)), clock.left())
    issued.issue(drawn)
    _write_markdown(table, out / "work_precision.md", scene.name, ref_label, clock.spent(),
                    budget, figure=drawn)
    return table


def outcome_line(table: pd.DataFrame) -> str:
    """One line on how the study's runs ended: succeeded, skipped or stopped for the budget,
    failed (with their statuses).

    Parameters
    ----------
    table : DataFrame
        :func:`run_study`'s table (column ``status``).

    Returns
    -------
    str
        e.g. ``"10 of 49 runs succeeded; 37 skipped and 1 stopped for the budget; 1 failed
        (newton_failure)"``.
    """
    status = table["status"].astype(str) if len(table) else pd.Series([], dtype=str)
    n_ok = int((status == "success").sum())
    skipped = int((status == "skipped").sum())
    stopped = int((status == "over_budget").sum())
    failed = status[~status.isin(["success", "skipped", "over_budget"])]
    parts = [f"{n_ok} of {len(status)} runs succeeded"]
    budget = [f"{skipped} skipped" if skipped else "", f"{stopped} stopped" if stopped else ""]
    if skipped or stopped:
        parts.append(" and ".join(b for b in budget if b) + " for the budget")
    if len(failed):
        counts = failed.value_counts()
        parts.append(f"{len(failed)} failed (" + ", ".join(
            f"{k}" if v == 1 else f"{v} {k}" for k, v in counts.items()) + ")")
    return "; ".join(parts)


def _queue(base: Scene, methods, rtols, steps, presets: bool) -> list[_Run]:
    """The runs, cheap first: per method its ladder and presets ordered from coarse to fine
    (a preset that equals a ladder rung replaces it), then round-robin over the methods."""
    per: dict[str, list[_Run]] = {}
    for m in methods:
        ladder = [_Run(m, v, _overrides(m, v, base.output.step))
                  for v in (steps if _fixed(m) else rtols)]
        runs: dict[tuple, _Run] = {}
        for r in ladder:
            runs[_key(base, r)] = r
        if presets:
            for level in ACCURACY_LEVELS:
                p = _preset_run(base, m, level)
                k = _key(base, p)
                if k in runs and runs[k].preset:
                    runs[k].preset += f"/{level}"  # two presets with one setting
                else:
                    runs[k] = p
        per[m] = sorted(runs.values(), key=lambda r: -r.setting)
    queue: list[_Run] = []
    while any(per.values()):
        for m in methods:
            if per[m]:
                queue.append(per[m].pop(0))
    return queue


def _write_markdown(table: pd.DataFrame, path: Path, name: str, ref_label: str, spent: float,
                    budget: float, figure: dict | None = None) -> None:
    cols = ["method", "setting", "preset", "status", "wall_time", "cpu_time", "steps",
            "block_band_db", "block_band_hz", "plate_band_db", "plate_band_hz",
            "velocity_rel_rms", "event_dt_max", "events_unmatched", "energy_rel_residual",
            "contract_ratio", "verdict"]
    md = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for _, r in table.iterrows():
        md.append("| " + " | ".join(_fmt(r.get(c)) for c in cols) + " |")
    cross = []
    for metric in ("plate_band_db", "block_band_db", "velocity_rel_rms"):
        cross += crossings(table, metric)
    fig = ""
    if figure is not None and figure.get("status") != "success":
        fig = (" The figure was not drawn: " + ("the budget was spent"
               if figure.get("status") == "over_budget" else str(figure.get("message"))) + ".")
    text = (
        f"# Work-precision: scene {name}\n\nReference: {ref_label}. Whole study: {spent:.0f} s "
        f"of a {budget:g} s budget; {outcome_line(table)}.{fig}\n\n" + "\n".join(md)
        + "\n\n## Crossings with IDA\n\n"
        + ("\n".join(f"- {c['method']} ({c['metric']}): {c['wall_time']:.3g} s at error "
                     f"{c['error']:.3g}" for c in cross) or "none in the measured range")
        + "\n")
    with writing(path) as fh:
        fh.write(text)


def _fmt(v) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    if isinstance(v, float):
        return f"{v:.3g}"
    return str(v)
