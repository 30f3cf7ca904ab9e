"""Running a scene: ``simulate(scene) -> Result`` and ``resume(directory) -> Result``.

Orchestrates the pipeline scene -> preprocessing/assembly -> solver -> Result and adds what every
run reports: the energy audit, rms values over whole excitation periods, the stick fraction and
the solver statistics. The studies (compare, sweep) call :func:`simulate`; users reach it as
``roughvib.simulate`` or through :mod:`roughvib.api`.
"""

from __future__ import annotations

import math
import os
import time
import tomllib
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from roughvib.analysis.levels import rms, stick_fraction, whole_period_window
from roughvib.model import kernels as kn
from roughvib.model.layout import ENERGY_TERMS
from roughvib.model.system import System, assemble, estimate_travel
from roughvib.results import FORMAT_VERSION, VARIABLES, Result, RunData, events_frame
from roughvib.scene import (
    Scene,
    SceneError,
    replace_section,
    scene_from_dict,
    scene_to_toml,
)
from roughvib.solvers.checkpoint import CHECKPOINT_NAME, Checkpoint, check_inputs, read_checkpoint

if TYPE_CHECKING:
    from roughvib.solvers.ida import RawSolution

__all__ = ["energy_audit", "resume", "simulate"]


def energy_audit(system: System, raw: RawSolution) -> dict:
    """Energy balance of a run: inputs - dissipation - change of stored energy.

    The work of the excitation and of the roughness (kinematic input at the contacts) must
    equal friction, damper and plate dissipation plus the change of kinetic, elastic and
    gravitational energy. The running integrals are IDA states, so the residual is of the
    order of the integration tolerance.

    Returns
    -------
    dict
        Terms [J], ``residual`` [J] and ``relative_residual`` (residual / sum of ``|terms|``).
    """
    terms = {n: float(raw.y_final[system.layout.index(f"energy.{n}")]) for n in ENERGY_TERMS}
    e0 = system.stored_energy(raw.y_initial)
    e1 = system.stored_energy(raw.y_final)
    inputs = terms["excitation_work"] + terms["roughness_work"]
    losses = (terms["friction_dissipation"] + terms["tangential_damping"]
              + terms["vertical_damping"] + terms["plate_damping"])
    delta = e1 - e0
    residual = inputs - losses - delta
    scale = sum(abs(v) for v in terms.values()) + abs(delta)
    return {
        **terms,
        "stored_energy_change": delta,
        "residual": residual,
        "relative_residual": (residual / scale if scale > 0 else 0.0)
        if np.isfinite(residual) else float("nan"),
        "t_end": raw.t_final,
    }


def _build_dataset(system: System, raw: RawSolution) -> RunData:
    """The time series of a run with their units (``Result.dataset`` is built from it)."""
    K = system.n_contacts
    n = raw.extra.get("rows_filled", raw.time.size)
    t = raw.time[:n]
    out = raw.outputs[:n]
    ds = RunData()
    n0 = kn.N_OUT_FIXED
    columns = [(name, "time", out[:, j]) for j, name in enumerate(kn.OUT_NAMES)]
    columns += [("contact_force", ("time", "contact"), out[:, n0:n0 + K]),
                ("roughness_input", ("time", "contact"), out[:, n0 + K:n0 + 2 * K])]
    no_friction = {"comment": "prescribed tangential motion: no friction model"}
    for name, dims, values in columns:
        units, long = VARIABLES[name]
        extra = no_friction if not system.tangential and name in (
            "friction_force", "friction_coefficient") else {}
        ds.add(name, dims, values, {"units": units, "long_name": long, **extra})
    ds.add("time", "time", t, {"units": "s", "long_name": "time"}, coord=True)
    ds.add("contact", "contact", np.arange(K), {"long_name": "contact index"}, coord=True)
    ds.add("contact_x", "contact", system.contact_xy[:, 0],
           {"units": "m", "long_name": "contact x position on the plate"}, coord=True)
    ds.add("contact_y", "contact", system.contact_xy[:, 1],
           {"units": "m", "long_name": "contact y position on the plate"}, coord=True)
    ds.add("contact_profile_position", "contact", system.contact_s,
           {"units": "m", "long_name": "profile coordinate at x=0"}, coord=True)
    ds.attrs.update(
        title="roughvib simulation result",
        convention="vertical quantities are positive downward (direction of gravity); "
                   "roughness_input = -z(s_k + x), z the profile height (positive up)",
        scene_name=system.scene.name,
        roughvib_format_version=FORMAT_VERSION,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
        force_amplitude=system.force_amplitude,
        reference="J. Feldmann, J. Vib. Acoust. 134 (2012) 041002",
    )
    return ds


def _events_by_kind(records: list) -> dict[str, int]:
    """Number of events of each kind, most frequent first (ties in order of appearance), as
    ``events_frame(records)["kind"].value_counts().to_dict()`` gives them."""
    counts: dict[str, int] = {}
    for r in records:
        counts[r.kind] = counts.get(r.kind, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: -kv[1]))  # sorted() is stable


def _add_regimes(ds: RunData, system: System, events) -> None:
    """``contact_closed(time, contact)`` and ``stick(time)`` from the event log, on the grid."""
    from roughvib.analysis.events import regime_series
    from roughvib.model.regimes import initial_regime

    _, closed0 = system.static_equilibrium()  # the start of every solver
    start = initial_regime(closed0, system.fp, system.tangential, system.coulomb)
    closed, stick = regime_series(events, ds["time"], closed0,
                                  start.stick and system.tangential)
    for name, dims, values, meanings in (("contact_closed", ("time", "contact"), closed,
                                          "open closed"),
                                         ("stick", "time", stick, "slip stick")):
        units, long = VARIABLES[name]
        attrs = {"units": units, "long_name": long, "flag_values": np.array([0, 1], np.int8),
                 "flag_meanings": meanings}
        if name == "stick" and not system.tangential:
            attrs["comment"] = "prescribed tangential motion: the block never sticks"
        ds.add(name, dims, values, attrs)


def _attr(value):
    """A scene value as a netCDF attribute (numbers and strings as they are)."""
    if isinstance(value, bool) or value is None:
        return str(value).lower() if value is not None else "none"
    if isinstance(value, int | float | str):
        return value
    return repr(value)


def _provenance(scene: Scene, scene_toml: str) -> dict:
    """What a reader of result.nc needs to know how the run was made (dataset attributes)."""
    import dataclasses
    from importlib import metadata

    from roughvib._version import __version__

    def version(dist: str) -> str:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return "not installed"

    attrs = {"roughvib_version": __version__,
             "software": ", ".join(f"{d} {version(d)}" for d in
                                   ("numpy", "scipy", "numba", "scikit-sundae", "xarray"))}
    for f in dataclasses.fields(scene.solver):  # every field, also ones added later
        attrs[f"solver_{f.name}"] = _attr(getattr(scene.solver, f.name))
    attrs["scene_toml"] = scene_toml
    return attrs


def _metrics(system: System, ds: RunData) -> dict:
    scene = system.scene
    t = ds["time"]
    if t.size < 2:
        return {}
    transient = scene.output.transient
    if transient >= t[-1]:
        transient = 0.0  # a run shorter than its run-in: report over the whole record
    win = whole_period_window(t, scene.period if math.isfinite(scene.period) else 0.0,
                              transient)
    tw = t[win]
    metrics = {"window_start": float(tw[0]), "window_end": float(tw[-1])}
    for name in ("block_vertical_acceleration", "plate_vertical_acceleration",
                 "block_tangential_velocity", "block_tangential_displacement", "normal_force",
                 "friction_force"):
        v = ds[name][win]
        if np.all(np.isnan(v)):
            continue
        metrics[f"{name}_rms"] = float(rms(v - np.mean(v)) if name.endswith("displacement")
                                       else rms(v))
    metrics["normal_force_mean"] = float(np.mean(ds["normal_force"][win]))
    metrics["normal_force_min"] = float(np.min(ds["normal_force"][win]))
    v = ds["block_tangential_velocity"][win]
    metrics["stick_fraction"] = float(stick_fraction(v, scene.friction.stick_velocity))
    for name in ("block_vertical_acceleration", "plate_vertical_acceleration"):
        r = metrics.get(f"{name}_rms")
        if r:
            metrics[f"{name}_level_db_re_1e-6"] = 20 * math.log10(r / 1e-6)
    cf = ds["contact_force"][win]
    metrics["active_contacts_mean"] = float(np.mean(np.sum(cf > 0, axis=1)))
    return metrics


def _resolve_contact(scene: Scene, system: System, comments: dict) -> Scene:
    """The scene with the contact module's results written in as numbers (count, stiffness
    with the velocity factor applied, r1), so that the saved scene.toml repeats the run even
    after the velocity target was replaced by the calibrated force amplitude."""
    c, b = scene.contact, scene.block
    if not any(isinstance(v, str) for v in (c.points, c.stiffness, b.vertical_damping)):
        return scene
    info = system.contact
    stat = system.calibration.get("contact_stiffness", {})
    if isinstance(c.points, str):
        comments["contact.points"] = (f"contact module: {info['micro_contacts']:.4g} "
                                      f"micro-contacts ({stat.get('model')})")
    if isinstance(c.stiffness, str):
        comments["contact.stiffness"] = (
            f"contact module ({stat.get('model')}), velocity factor "
            f"{stat.get('velocity_factor', 1.0):.4g} applied")
    if isinstance(b.vertical_damping, str):
        comments["block.vertical_damping"] = (f"{b.vertical_damping_ratio} of critical at the "
                                              f"contact resonance")
    scene = replace_section(scene, "contact", points=int(info["points"]),
                            stiffness=float(info["stiffness_total"]), velocity_factor=False)
    return replace_section(scene, "block", vertical_damping=float(info["vertical_damping"]))


def simulate(scene: Scene, *, progress: bool | None = None,
             force_amplitude: float | None = None,
             checkpoint_dir: str | os.PathLike | None = None,
             _resume_from: Checkpoint | None = None) -> Result:
    """Run a scene and return its :class:`~roughvib.results.Result`.

    Parameters
    ----------
    scene : Scene
        From :func:`roughvib.load_scene <roughvib.scene.load_scene>`.
    progress : bool, optional
        Progress bar on stderr (default: ``scene.output.progress``).
    force_amplitude : float, optional
        Override T0 [N] (skips the calibration).
    checkpoint_dir : path, optional
        With ``output.checkpoint_interval > 0``: write ``checkpoint.pkl`` there (replaced
        atomically at each checkpoint); continue a stopped run with :func:`resume`.

    Returns
    -------
    Result
        ``result.status`` is ``"success"`` or names the failure; a failed run carries the
        message and the statistics but no time series.

    Examples
    --------
    >>> import roughvib
    >>> scene = roughvib.load_scene("paper", **{"output.duration": 0.02})
    >>> result = roughvib.simulate(scene, progress=False)   # doctest: +SKIP
    >>> result.to_dataset()["block_vertical_acceleration"]   # doctest: +SKIP
    """
    t0 = time.perf_counter()
    system = assemble(scene, force_amplitude=force_amplitude, travel=estimate_travel(scene))
    t_pre = time.perf_counter() - t0
    # each solver is imported when it runs: IDA brings scikit-sundae and scipy.sparse
    if scene.solver.method == "ida":
        from roughvib.solvers.ida import solve_ida

        raw = solve_ida(system, progress=progress, checkpoint_dir=checkpoint_dir,
                        resume=_resume_from)
    elif scene.solver.method == "adaptive-modal":
        from roughvib.solvers.adaptive_modal import solve_adaptive_modal

        raw = solve_adaptive_modal(system, progress=progress, checkpoint_dir=checkpoint_dir,
                                   resume=_resume_from)
    elif scene.solver.method == "paper":
        from roughvib.solvers.paper_scheme import solve_paper_scheme

        raw = solve_paper_scheme(system, progress=progress)
    else:
        from roughvib.solvers.fixed_step import solve_fixed_step

        raw = solve_fixed_step(system, progress=progress)
    ds = _build_dataset(system, raw)
    events = list(raw.events)  # Result.events makes the table when it is first read
    audit = energy_audit(system, raw)

    resolved = scene
    comments = {}
    if system.tangential:
        exc = scene.excitation
        resolved = replace_section(scene, "excitation", force_amplitude=system.force_amplitude,
                                   target_rms_velocity=None)
        if exc.target_rms_velocity is not None:
            comments["excitation.force_amplitude"] = (
                f"calibrated for target_rms_velocity = {exc.target_rms_velocity} m/s")
    resolved = _resolve_contact(resolved, system, comments)
    scene_toml = scene_to_toml(resolved, comments=comments)
    _add_regimes(ds, system, events)
    ds.attrs.update(_provenance(resolved, scene_toml))

    by_kind = _events_by_kind(events)
    summary = {
        "format_version": FORMAT_VERSION,
        "status": raw.status,
        "message": raw.message,
        "scene": scene.name,
        "solver": {"method": scene.solver.method, "rtol": scene.solver.rtol,
                   "atol": scene.solver.atol, **raw.stats,
                   "preprocessing_time": t_pre},
        "force_amplitude": system.force_amplitude,
        "calibration": system.calibration,
        "model": {"modes": system.n_modes, "contacts": system.n_contacts,
                  "states": system.layout.size,
                  "contact_stiffness_total": float(np.sum(system.stiff)),
                  "contact": system.contact,
                  "initially_closed_contacts": int(np.sum(raw.y_initial[
                      system.layout.slice("contact.force")] > 0)),
                  "profile": system.profile.stats},
        "events_by_kind": by_kind,
        "metrics": _metrics(system, ds) if raw.status == "success" else {},
        "energy_audit": audit,
        "warnings": list(system.warnings),
    }
    if raw.status != "success":
        summary["last_events"] = events_frame(events[-20:]).to_dict(orient="records")
        summary["partial_result"] = {
            "file": "partial.nc", "t_end": float(ds["time"][-1]) if ds.sizes["time"]
            else None, "note": "time series up to the failure; load_result(dir, partial=True)"}
    if system.tangential and scene.excitation.target_rms_velocity is not None and \
            raw.status == "success":
        target = scene.excitation.target_rms_velocity
        got = summary["metrics"].get("block_tangential_velocity_rms", float("nan"))
        summary["calibration"]["achieved_rms_velocity"] = got
        summary["calibration"]["relative_deviation"] = (got - target) / target
    return Result(ds, events, summary, scene_toml,
                  extra={"system": system, "checkpoint_dir": checkpoint_dir})


def resume(directory: str | os.PathLike, *, progress: bool | None = None) -> Result:
    """Continue a run from ``directory/checkpoint.pkl`` (written with
    ``output.checkpoint_interval > 0``) to its end.

    The scene is the one stored in the checkpoint; the result (time series, events, energy
    audit, metrics) is identical to an uninterrupted run of that scene. Checkpoints keep being
    written to ``directory``.

    Parameters
    ----------
    directory : path
        The run's output directory.
    progress : bool, optional
        Progress bar on stderr (default: the scene's ``output.progress``).

    Returns
    -------
    Result

    Raises
    ------
    SceneError
        No checkpoint, a checkpoint of another format version, one that does not fit the
        scene it carries, or an input of the run (a roughness file) that changed since the
        checkpoint was written.
    """
    cp = read_checkpoint(directory)
    try:
        data = tomllib.loads(cp.scene_toml)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{directory}: the checkpoint's scene is not valid TOML ({exc})") from None
    scene = scene_from_dict(data, base_dir=cp.base_dir)
    check_inputs(cp, scene, Path(directory) / CHECKPOINT_NAME)
    return simulate(scene, progress=progress, checkpoint_dir=directory, _resume_from=cp)
