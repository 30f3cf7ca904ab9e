"""Running a scene: ``simulate(scene) -> Result`` and ``resume(directory) -> Result``.

Orchestrates the pipeline scene -> preprocessing/assembly -> solver -> Result and adds what every
run reports: the energy audit, rms values over whole excitation periods, the stick fraction and
the solver statistics. The studies (compare, sweep) call :func:`simulate`; users reach it as
``roughvib.simulate`` or through :mod:`roughvib.api`.
"""

from __future__ import annotations

import functools
import math
import os
import time
import tomllib
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from roughvib._progress import kernel_clock
from roughvib.analysis.levels import rms, stick_fraction, whole_period_window
from roughvib.model import kernels as kn
from roughvib.model.layout import ENERGY_TERMS
from roughvib.model.system import System, assemble, check_stroke, estimate_travel
from roughvib.results import FORMAT_VERSION, VARIABLES, Result, RunData, events_frame
from roughvib.scene import (
    Scene,
    SceneError,
    Solver,
    replace_section,
    scene_from_dict,
    scene_to_toml,
)
from roughvib.solvers import registry
from roughvib.solvers.checkpoint import CHECKPOINT_NAME, Checkpoint, check_inputs, read_checkpoint

if TYPE_CHECKING:
    from roughvib.solvers.base import RawSolution

__all__ = ["check_verifiable", "checkpoint_scene", "energy_audit", "energy_audit_note", "resume",
           "simulate", "verification_scene", "verify_result"]


def energy_audit(system: System, raw: RawSolution) -> dict:
    """Energy balance of a run: inputs - dissipation - change of stored energy.

    The work of the excitation and of the roughness (kinematic input at the contacts) must
    equal friction, damper and plate dissipation plus the change of kinetic, elastic and
    gravitational energy. The running integrals are IDA states, so the residual is of the
    order of the integration tolerance.

    The relative residual is the residual over the energies involved: the sum of ``|terms|``
    and ``|change of stored energy|``, but at least ``energy_scale_floor``, the larger
    magnitude of the stored energy at the start and at the end (kinetic, elastic and
    gravitational with its zero at z = 0). The residual is a difference of those
    stored energies, so it is known only to their round-off: a run in which nothing moves
    (pure stick) has terms of round-off size too, and its residual of 7e-21 J read as a
    relative residual of 1 without the floor.

    Returns
    -------
    dict
        Terms [J], ``stored_energy_change`` [J], ``residual`` [J], ``energy_scale`` [J] (the
        denominator), ``energy_scale_floor`` [J], ``relative_residual`` and ``t_end`` [s].
        Where the audit cannot be computed (a solver that keeps no energy integrals, the
        paper's convolution scheme; a state that is not finite) every value but ``t_end`` is
        None; :func:`energy_audit_note` says why.
    """
    terms = {n: float(raw.y_final[system.layout.index(f"energy.{n}")]) for n in ENERGY_TERMS}
    e0 = system.stored_energy(raw.y_initial)
    e1 = system.stored_energy(raw.y_final)
    if not all(math.isfinite(v) for v in (*terms.values(), e0, e1)):
        return {**dict.fromkeys(terms), "stored_energy_change": None, "residual": None,
                "energy_scale": None, "energy_scale_floor": None, "relative_residual": None,
                "t_end": raw.t_final}
    inputs = terms["excitation_work"] + terms["roughness_work"]
    losses = (terms["friction_dissipation"] + terms["tangential_damping"]
              + terms["vertical_damping"] + terms["plate_damping"])
    delta = e1 - e0
    residual = inputs - losses - delta
    floor = max(abs(e0), abs(e1))
    scale = max(sum(abs(v) for v in terms.values()) + abs(delta), floor)
    return {
        **terms,
        "stored_energy_change": delta,
        "residual": residual,
        "energy_scale": scale,
        "energy_scale_floor": floor,
        "relative_residual": residual / scale if scale > 0 else 0.0,
        "t_end": raw.t_final,
    }


def energy_audit_note(system: System, audit: dict) -> str | None:
    """Why a run's energy audit (:func:`energy_audit`) was not computed, or None if it was.

    Parameters
    ----------
    system : System
        The run's system.
    audit : dict
        Its energy audit.

    Returns
    -------
    str or None
        One sentence for the summary (``energy_audit_note`` of summary.json).
    """
    if audit.get("residual") is not None:
        return None
    if system.scene.solver.method == "paper":
        return ("not computed: solver.method = 'paper' keeps no energy integrals (the "
                "convolution scheme has no modal states)")
    return "not computed: the run's state at its end is not finite"


def _build_dataset(system: System, raw: RawSolution) -> RunData:
    """The time series of a run with their units (``Result.dataset`` is built from it)."""
    K = system.n_contacts
    n = raw.extra.get("rows_filled", raw.time.size)
    t = raw.time[:n]
    out = raw.outputs[:n]
    ds = RunData()
    columns = [(name, "time" if isinstance(col, int) else ("time", "contact"), out[:, col])
               for name, col in kn.output_columns(K).items()]
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
    start = initial_regime(closed0, system.fp, system.tangential, system.scene.friction.law)
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


@functools.cache
def _software() -> str:
    """The versions of the libraries a run used, as installed when this process first asked
    (read once per process: 5 metadata look-ups cost 10-30 ms, paid by every case of a sweep
    worker; a package upgraded under a running worker is not the one it has loaded anyway)."""
    from importlib import metadata

    def version(dist: str) -> str:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return "not installed"

    return ", ".join(f"{d} {version(d)}" for d in
                     ("numpy", "scipy", "numba", "scikit-sundae", "xarray"))


def _provenance(scene: Scene, scene_toml: str) -> dict:
    """What a reader of result.nc needs to know how the run was made (dataset attributes)."""
    import dataclasses

    from roughvib._version import __version__

    attrs = {"roughvib_version": __version__, "software": _software()}
    for f in dataclasses.fields(scene.solver):  # every field, also ones added later
        attrs[f"solver_{f.name}"] = _attr(getattr(scene.solver, f.name))
    attrs["scene_toml"] = scene_toml
    return attrs


def _residual_summary(system: System) -> dict:
    """The summary's ``model.residual_compliance``: where it came from (one line, with its
    truncation error for imported modes) and its largest value at the contacts [m/N]."""
    plate = system.scene.plate
    if not plate.residual_compliance:
        return {"source": "off (plate.residual_compliance = false)", "largest": 0.0}
    return {"source": system.structure.residual,
            "largest": float(np.max(np.diag(system.cres))) if system.cres.size else 0.0}


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
        vf = stat.get("velocity_factor", 1.0)
        comments["contact.stiffness"] = (
            f"contact module ({stat.get('model')})" + (
                f", velocity factor {vf:.4g} applied" if c.velocity_factor
                and not stat.get("velocity_factor_note") else ""))
        if c.velocity_factor:
            # the number above holds the factor: off here, so that it is not applied twice
            comments["contact.velocity_factor"] = (
                f"the scene's velocity factor ({vf:.4g}) is already in contact.stiffness"
                if not stat.get("velocity_factor_note") else stat["velocity_factor_note"])
    if isinstance(b.vertical_damping, str):
        comments["block.vertical_damping"] = (f"{b.vertical_damping_ratio} of critical at the "
                                              f"contact resonance")
    scene = replace_section(scene, "contact", points=int(info["points"]),
                            stiffness=float(info["stiffness_total"]), velocity_factor=False)
    return replace_section(scene, "block", vertical_damping=float(info["vertical_damping"]))


def _resolve_input(scene: Scene, system: System, comments: dict) -> Scene:
    """The scene with the input's ``"auto"`` keys written in as numbers (tail limit, grid,
    spot radius), so that the saved scene.toml repeats the run: its ``"auto"`` tail follows
    the velocity target, which the saved scene replaces by the calibrated force."""
    r, c = scene.roughness, scene.contact
    band = system.contact.get("input", {})
    if isinstance(r.shortest_wavelength, str) and band:
        comments["roughness.shortest_wavelength"] = (
            f"auto: {band['speed']:.4g} m/s rms over {band['top_frequency']:.6g} Hz")
        scene = replace_section(scene, "roughness",
                                shortest_wavelength=float(band["shortest_wavelength"]))
    if isinstance(r.spacing, str) and band:
        comments["roughness.spacing"] = "auto"
        scene = replace_section(scene, "roughness", spacing=float(band["spacing"]))
    spot = system.profile.stats.get("spot_radius")
    if isinstance(c.spot_radius, str) and spot is not None:
        comments["contact.spot_radius"] = "contact module: mean micro-contact radius"
        scene = replace_section(scene, "contact", spot_radius=float(spot))
    return scene


def _input_summary(system: System, ds) -> dict:
    """What the run's input resolves: the tail limit, the grid, the contact filter, and the
    frequency up to which the input holds the surface at the run's rms and peak speed."""
    band = dict(system.contact.get("input", {}))
    st = system.profile.stats
    lam = st.get("shortest_wavelength", band.get("shortest_wavelength"))
    out = {**band, "grid_spacing": system.profile.dx, "contact_filter":
           st.get("contact_filter", "none"), "spot_radius": st.get("spot_radius")}
    if system.tangential and "block_tangential_velocity" in ds and lam:
        v = np.abs(np.asarray(ds["block_tangential_velocity"]))
        if v.size:
            out["peak_speed"] = float(v.max())
            out["resolved_frequency_peak"] = float(v.max() / lam)
            out["resolved_frequency_rms"] = float(np.sqrt(np.mean(v**2)) / lam)
    return out


def simulate(scene: Scene, *, progress: bool | None = None,
             force_amplitude: float | None = None,
             checkpoint_dir: str | os.PathLike | None = None, verify: bool = False) -> Result:
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
    verify : bool
        After a successful run, solve the scene a second, independent way
        (:func:`verification_scene`) and write the deviations and a verdict against the
        accuracy contract into ``summary["accuracy"]`` (:func:`verify_result`). Costs a second
        run, usually the slower solver's.

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
    return _simulate(scene, progress=progress, force_amplitude=force_amplitude,
                     checkpoint_dir=checkpoint_dir, verify=verify, resume_from=None)


def _simulate(scene: Scene, *, progress: bool | None, force_amplitude: float | None,
              checkpoint_dir: str | os.PathLike | None, verify: bool,
              resume_from: Checkpoint | None, warn: bool = True) -> Result:
    """:func:`simulate`, or with ``resume_from`` the continuation of a checkpoint
    (:func:`resume`); ``warn=False`` keeps the scene's validity warnings quiet (a second solve
    of a scene whose warnings the first one issued)."""
    if verify:
        check_verifiable(scene)
    clock = kernel_clock()
    k_start, n_start = clock.seconds, clock.compiled
    with clock.notifying(scene.output.progress if progress is None else progress):
        t0 = time.perf_counter()
        system = assemble(scene, force_amplitude=force_amplitude,
                          travel=estimate_travel(scene), warn=warn)
        k_pre = clock.seconds - k_start
        t_pre = time.perf_counter() - t0 - k_pre  # numba's loading has its own line
        pilot = None
        if (scene.solver.atol_acceleration is None and resume_from is None
                and system.scene.solver.atol_acceleration_relative is not None):
            system, pilot = _scale_atol_acceleration(system)
            _check_scaled_atol(system, scene.solver, pilot)
        solver = system.scene.solver  # resolved: concrete method, tolerances from the preset
        resolved, scene_toml = _resolved_scene(scene, system)
        k_solve = clock.seconds
        raw = _solve(system, progress=progress, checkpoint_dir=checkpoint_dir,
                     resume=resume_from)
    kernels = {"time": clock.seconds - k_start, "compiled": clock.compiled - n_start,
               "preprocessing": k_pre, "pilot": (pilot or {}).get("kernel_time", 0.0),
               "solve": clock.seconds - k_solve}
    ds = _build_dataset(system, raw)
    if system.tangential and ds["block_tangential_displacement"].size:
        check_stroke(system, np.asarray(ds["block_tangential_displacement"]))
    events = list(raw.events)  # Result.events makes the table when it is first read
    audit = energy_audit(system, raw)
    _add_regimes(ds, system, events)
    ds.attrs.update(_provenance(resolved, scene_toml))

    by_kind = _events_by_kind(events)
    summary = {
        "format_version": FORMAT_VERSION,
        "status": raw.status,
        "message": raw.message,
        "scene": scene.name,
        "solver": {"method": solver.method, "accuracy": solver.accuracy,
                   "rtol": solver.rtol, "atol": solver.atol,
                   "atol_acceleration": solver.atol_acceleration, "step": solver.step,
                   "atol_acceleration_relative": solver.atol_acceleration_relative,
                   "from_preset": list(scene.solver.from_preset()),
                   **({"pilot": pilot} if pilot else {}), **raw.stats,
                   "preprocessing_time": t_pre, "kernels": kernels},
        "force_amplitude": system.force_amplitude,
        "calibration": system.calibration,
        "model": {"modes": system.n_modes, "structure": system.structure.name,
                  "residual_compliance": _residual_summary(system),
                  "contact_patch": system.scene.contact.patch,
                  "contacts": system.n_contacts,
                  "states": system.layout.size,
                  "contact_stiffness_total": float(np.sum(system.stiff)),
                  "contact": system.contact,
                  "initially_closed_contacts": int(np.sum(raw.y_initial[
                      system.layout.slice("contact.force")] > 0)),
                  "profile": system.profile.stats,
                  "input": _input_summary(system, ds)},
        "events_by_kind": by_kind,
        "metrics": _metrics(system, ds) if raw.status == "success" else {},
        "energy_audit": audit,
        **({"energy_audit_note": note} if (note := energy_audit_note(system, audit)) else {}),
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
    result = Result(ds, events, summary, scene_toml,
                    extra={"system": system, "checkpoint_dir": checkpoint_dir})
    if scene.output.radiation and result.ok:
        _add_radiation(result, system, raw, ds)
    if verify and result.ok:
        verify_result(result, scene, progress=progress)
    return result


def _resolved_scene(scene: Scene, system: System) -> tuple[Scene, str]:
    """The scene as it runs, and its TOML text (the run's ``scene.toml``).

    The saved scene repeats the run: the solver section as it ran (concrete method, the
    preset's tolerances and the pilot's atol_acceleration as numbers), so a resumed run (whose
    checkpoint holds that section) writes the same scene.toml as an uninterrupted one. Built
    before the solve: its derived values (calibrated force, contact module, pilot tolerance)
    are validated like any scene value, and a bad one stops the run before its expensive
    work, not after it.
    """
    comments: dict[str, str] = {}
    try:
        resolved = replace(scene, solver=system.scene.solver)
        if system.tangential:
            exc = scene.excitation
            resolved = replace_section(resolved, "excitation",
                                       force_amplitude=system.force_amplitude,
                                       target_rms_velocity=None)
            if exc.target_rms_velocity is not None:
                comments["excitation.force_amplitude"] = (
                    f"calibrated for target_rms_velocity = {exc.target_rms_velocity} m/s")
        resolved = _resolve_contact(resolved, system, comments)
        resolved = _resolve_input(resolved, system, comments)
    except SceneError as exc:
        raise SceneError(f"a value derived for this run (calibrated force amplitude, contact "
                         f"module or solver tolerance) is out of range: {exc}") from None
    return resolved, scene_to_toml(resolved, comments=comments)


def _add_radiation(result: Result, system: System, raw: RawSolution, ds: RunData) -> None:
    """Radiated sound of the plate (``output.radiation``): the band table goes to
    ``result.extra["radiation"]`` (written as ``radiation.csv``), totals to the summary."""
    import pandas as pd

    from roughvib.analysis.radiation import (
        RADIATION_COLUMNS,
        microphone_bands,
        radiation_bands,
    )

    scene = system.scene
    t = ds["time"]
    transient = scene.output.transient if scene.output.transient < t[-1] else 0.0
    win = whole_period_window(t, scene.period if math.isfinite(scene.period) else 0.0,
                              transient)
    lay = system.layout
    # the solver's modal states are mass-normalised (shapes in 1/sqrt(kg)); the radiation
    # module works with the plate's unit-amplitude shapes and its modal mass: q = q_n * scale
    q0 = raw.y_initial[lay.slice("plate.q")] * system.mode_scale
    dq0 = raw.y_initial[lay.slice("plate.dq")] * system.mode_scale
    t0 = time.perf_counter()
    try:
        bands = radiation_bands(ds["contact_force"], system.contact_xy, scene.output.step,
                                scene.plate, win, q0=q0, dq0=dq0,
                                sides=scene.output.radiating_sides,
                                air_density=scene.output.air_density,
                                sound_speed=scene.output.sound_speed)
    except ValueError as exc:  # e.g. an analysis window too short: the run itself stands
        result.summary["radiation"] = {"error": str(exc)}
        result.summary.setdefault("warnings", []).append(f"output.radiation: {exc}")
        return
    levels = bands.levels()
    result.extra["radiation"] = pd.DataFrame({c: levels[c] for c in RADIATION_COLUMNS})
    mics = scene.output.microphones
    if mics:
        band_hz, spl = microphone_bands(
            ds["contact_force"], system.contact_xy, scene.output.step, scene.plate, win, mics,
            q0=q0, dq0=dq0, air_density=scene.output.air_density,
            sound_speed=scene.output.sound_speed)
        result.extra["microphones"] = pd.DataFrame(
            {"band_hz": band_hz, **{f"mic{i + 1}_spl_db": spl[i] for i in range(len(mics))}})
    total = bands.total_sound_power()
    result.summary["radiation"] = {
        "sound_power_level_db_re_1pW": 10.0 * math.log10(total / 1e-12) if total > 0
        else float("-inf"),
        "bands_hz": [float(bands.band_hz[0]), float(bands.band_hz[-1])],
        "microphones": [list(m) for m in mics],
        "radiating_sides": bands.sides, "modes": bands.n_modes,
        "window_start": float(t[win][0]), "window_end": float(t[win][-1]),
        "method": "modal radiation efficiencies (Wallace 1972), cross-modal coupling "
                  "neglected; modal velocities from the contact forces",
        "time": time.perf_counter() - t0,
    }


#: longest pilot solve that measures the acceleration level for a scaled atol_acceleration [s]
PILOT_DURATION = 0.02
#: level floor of the scaled atol_acceleration [m/s^2] (0 dB re 1e-6 m/s^2)
PILOT_LEVEL_FLOOR = 1e-6


def _scale_atol_acceleration(system: System) -> tuple[System, dict]:
    """The system with ``atol_acceleration`` = relative x the level a pilot solve measures.

    The pilot solves the first ``PILOT_DURATION`` (at most a quarter of the run) with
    adaptive-modal (IDA where it cannot run) at the draft tolerances, and takes the smaller
    rms vertical acceleration of block and plate that is above ``PILOT_LEVEL_FLOOR`` (the
    contract judges each signal against its own strongest band, so the quieter one sets the
    tolerance: with a 0.1 g block the plate is 40 dB quieter than the block, and a tolerance
    on the block's level left IDA's plate 31 dB low in its 40 kHz band). A failed pilot leaves
    the preset's absolute ``atol_acceleration``. Returns the system and what the pilot did
    (for the summary).
    """
    scene = system.scene
    s = scene.solver
    out = scene.output
    n = max(10, int(round(min(PILOT_DURATION, out.duration / 4) / out.step)))
    pscene = replace(scene, output=replace(out, duration=n * out.step, progress=False,
                                           checkpoint_interval=0.0),
                     solver=replace(s, method="auto", accuracy="draft", rtol=None, atol=None,
                                    atol_acceleration=None, atol_acceleration_relative=None,
                                    step=None))
    pscene = replace(pscene, solver=pscene.resolved_solver())
    method = pscene.solver.method
    clock = kernel_clock()
    k0 = clock.seconds
    t0 = time.perf_counter()
    info = {"method": method, "duration": n * out.step}
    try:
        raw = _solve(replace(system, scene=pscene), progress=False)
    except Exception as exc:  # noqa: BLE001 - the run goes on with the absolute preset value
        raw = None
        info["message"] = f"{type(exc).__name__}: {exc}"
    # the pilot is usually the run's first solve: loading (or compiling) the solver's numba
    # kernels falls into it and is reported on its own line (summary solver.kernels)
    info["kernel_time"] = clock.seconds - k0
    info["wall_time"] = time.perf_counter() - t0 - info["kernel_time"]
    if raw is None or raw.status != "success":
        info.update(level=None, atol_acceleration=s.atol_acceleration,
                    note="pilot failed: the preset's absolute atol_acceleration is used")
        return system, info
    rows = raw.extra.get("rows_filled", raw.time.size)
    cols = [kn.OUT_AZ, kn.OUT_PLATE_ACC]
    acc = raw.outputs[:rows, cols]
    levels = np.sqrt(np.mean(acc * acc, axis=0))
    moving = levels[levels > PILOT_LEVEL_FLOOR]
    level = float(np.min(moving)) if moving.size else float(np.max(levels))
    atol = s.atol_acceleration_relative * max(level, PILOT_LEVEL_FLOOR)
    info.update(level=level, atol_acceleration=atol)
    return replace(system, scene=replace(scene, solver=replace(s, atol_acceleration=atol))), info


def _check_scaled_atol(system: System, given: Solver, pilot: dict) -> None:
    """Refuse, naming ``solver.atol_acceleration_relative``, a relative tolerance that the
    pilot's level turns into an ``atol_acceleration`` below the scene's round-off floor.

    The solvers refuse an absolute tolerance below its floor
    (:func:`roughvib.solvers.ida.check_tolerances`) by the key they are given, which here the
    user did not set: this check, at the same state (the solver's start), names the key the
    value came from, its lowest value for this scene and the derived tolerance.
    """
    if pilot.get("level") is None or not system.n_modes:
        return  # a failed pilot leaves the preset's absolute value: the solver checks it
    from roughvib.solvers.base import tolerance_floors
    from roughvib.solvers.checkpoint import start_state

    reg, rf = system.new_regime_arrays()
    _, _, y0 = start_state(system, reg, rf, None, 0, 0)
    floor, u = tolerance_floors(system, y0)["atol_acceleration"]
    atol = pilot["atol_acceleration"]
    if atol >= floor:
        return
    rel = system.scene.solver.atol_acceleration_relative
    level = max(pilot["level"], PILOT_LEVEL_FLOOR)
    origin = (f" (from solver.accuracy = {given.accuracy!r})"
              if "atol_acceleration_relative" in given.from_preset() else "")
    need = floor / level
    step = 10.0 ** (math.floor(math.log10(need)) - 2)
    need = math.ceil(need / step) * step  # rounded up to 3 digits: the value shown passes
    raise SceneError(
        f"solver.atol_acceleration_relative must be >= {need:.3g} for this scene: "
        f"times the pilot's acceleration level {level:.3g} m/s^2 it gives atol_acceleration "
        f"= {atol:.3g} m/s^2, below the round-off floor {floor:.3g} m/s^2 of the plate modes' "
        f"force balance (modal forces per modal mass reach {u:.3g} m/s^2), got {rel:g}{origin}")


def _solve(system: System, *, progress, checkpoint_dir=None, resume=None) -> RawSolution:
    """Run the system's solver (``system.scene.solver.method``) through the solver registry,
    which imports its module when it runs (IDA brings scikit-sundae and scipy.sparse)."""
    return registry.get(system.scene.solver.method).run(
        system, progress=progress, checkpoint_dir=checkpoint_dir, resume=resume)


def check_verifiable(scene: Scene) -> None:
    """Refuse to verify a run that cannot meet the accuracy contract whatever its accuracy.

    The paper's convolution scheme (``solver.method = "paper"``) keeps no energy audit, one
    item of the contract (docs/accuracy.md), so its verdict would be FAIL by construction.

    Raises
    ------
    SceneError
        One line naming the method.
    """
    method = scene.resolved_solver().method
    if not registry.get(method).energy_audit:
        raise SceneError(f"--verify (verify=True) judges a run by the accuracy contract, which "
                         f"includes the energy audit; solver.method = {method!r} keeps none, so "
                         f"it cannot pass: verify a run of another method, or compare the "
                         f"{method} scheme with 'roughvib compare'")


def verification_scene(scene: Scene) -> tuple[Scene, str]:
    """The second, independent solve that checks a run of ``scene`` (``verify=True``).

    The other event-driven solver at its ``reference`` preset: IDA checks adaptive-modal and
    adaptive-modal checks IDA. Where adaptive-modal cannot run (overdamped plate modes),
    IDA checks IDA at 100x tighter rtol, atol and
    atol_acceleration. The fixed-step schemes are checked by the ``auto`` method at
    ``reference``.

    Returns
    -------
    Scene
        The scene of the second solve (no checkpoints, explicit method and tolerances).
    str
        How it solves, for the report (e.g. ``"ida at accuracy 'reference'"``).
    """
    run = scene.resolved_solver()
    base = replace_section(scene, "output", checkpoint_interval=0.0)
    base = replace_section(base, "solver", method="auto", accuracy="reference", rtol=None,
                           atol=None, atol_acceleration=None, step=None)
    auto = base.resolved_solver().method  # adaptive-modal where it can run, else ida
    # the preset's tolerances, but atol_acceleration left open where the preset scales it to
    # the run's own level (a pilot solve, as the run itself does): a fixed 1e-10 m/s^2 is too
    # coarse for a scene 350 times quieter than the paper's (its plate's 40 kHz band then
    # read 2 dB off a much tighter solve, where the run itself was within 0.3 dB)
    if run.method == "adaptive-modal":
        other, how = _open_atol(replace(base.solver, method="ida")), "ida at accuracy 'reference'"
    elif run.method == "ida" and auto == "ida":  # the only event-driven solver of this scene
        other = replace(run, rtol=max(run.rtol / 100, 1e-14), atol=run.atol / 100,
                        atol_acceleration=run.atol_acceleration / 100)
        how = "ida at 100x tighter tolerances"
    else:
        other = _open_atol(replace(base.solver, method=auto))
        how = f"{other.method} at accuracy 'reference'"
    return replace(base, solver=other), how


def _open_atol(solver: Solver) -> Solver:
    """``solver`` resolved from its preset, with ``atol_acceleration`` left None where the
    preset gives a relative one (the run's pilot then scales it)."""
    res = solver.resolved()
    if res.atol_acceleration_relative is not None:
        return replace(res, atol_acceleration=None)
    return res


def _tol_text(s: Solver) -> str:
    if registry.get(s.method).kind == registry.STEP:
        return f"step {s.step:g} s"
    return f"rtol {s.rtol:g}, atol {s.atol:g} m, atol_acceleration {s.atol_acceleration:g} m/s^2"


def verify_result(result: Result, scene: Scene, *, progress: bool | None = None) -> dict:
    """Solve ``scene`` a second, independent way and judge ``result`` by the accuracy contract.

    The second solve is :func:`verification_scene`'s, with the run's force amplitude (no
    second calibration). Writes the measurement
    (:func:`~roughvib.analysis.accuracy.measure_accuracy`) into ``result.summary["accuracy"]``
    and returns it; the second solve's
    method, tolerances, wall time and status are in its ``verification`` entry. A failed
    second solve gives the verdict ``"unverified"``.

    Parameters
    ----------
    result : Result
        A successful run of ``scene``.
    scene : Scene
        The scene of that run.
    progress : bool, optional
        Progress bar for the second solve (default: the scene's ``output.progress``).

    Returns
    -------
    dict
        The ``accuracy`` section.
    """
    from roughvib.analysis.accuracy import measure_accuracy

    vscene, label = verification_scene(scene)
    system = result.extra.get("system")
    t0 = time.perf_counter()
    # the same scene but for its solver section: its validity warnings were the run's
    ref = _simulate(vscene, progress=progress,
                    force_amplitude=result.summary.get("force_amplitude")
                    if system is None or system.tangential else None, checkpoint_dir=None,
                    verify=False, resume_from=None, warn=False)
    info = {"method": ref.summary["solver"]["method"], "how": label,
            "settings": _tol_text(ref.extra["system"].scene.solver
                                  if "system" in ref.extra else vscene.resolved_solver()),
            "status": ref.status,
            "wall_time": time.perf_counter() - t0}
    if ref.ok:
        acc = measure_accuracy(result, ref, period=scene.period,
                               transient=scene.output.transient, reference_label=label)
    else:
        acc = {"reference": label, "verdict": "unverified",
               "failures": [f"the verification run failed ({ref.status}): "
                            f"{ref.summary.get('message')}"]}
    acc["verification"] = info
    if ref.ok and (rscene := representation_scene(scene, system)) is not None:
        rep = acc["representation"] = _check_representation(result, scene, rscene, progress)
        if rep["verdict"] != "pass":
            acc["failures"] = list(acc.get("failures", [])) + rep["failures"]
            acc["verdict"] = ("fail" if "fail" in (rep["verdict"], acc["verdict"])
                              else "unverified")
    result.summary["accuracy"] = acc
    result.extra["verification"] = ref
    return acc


def representation_scene(scene: Scene, system: System | None) -> Scene | None:
    """The scene on a refined input: half the grid spacing and half the tail limit of the
    run's synthetic surface (as resolved), half the tail limit of a measured one with a
    fitted tail (its grid follows), or None where the input has no such parameters (the
    other kinds, a file's own band, or no system to read the resolved values from)."""
    r = scene.roughness
    band = (system.contact.get("input") if system is not None else None) or {}
    if not band or r.reduce_3d:
        return None
    if r.kind == "synthetic":
        return replace_section(scene, "roughness", spacing=0.5 * float(system.profile.dx),
                               shortest_wavelength=0.5 * float(band["shortest_wavelength"]))
    if r.kind == "file" and system.profile.stats.get("tail") == "fitted":
        # the grid of a file's field follows its tail limit ("auto" spacing is the file's)
        return replace_section(scene, "roughness", shortest_wavelength=0.5 * float(
            system.profile.stats["shortest_wavelength"]))
    return None


def _check_representation(result: Result, scene: Scene, rscene: Scene,
                          progress: bool | None) -> dict:
    """Rerun ``rscene`` (the run's own solver, tolerances and force) and compare the bands."""
    from roughvib.analysis.accuracy import measure_representation

    t0 = time.perf_counter()
    solver = result.extra["system"].scene.solver
    rscene = replace(replace_section(rscene, "output", checkpoint_interval=0.0),
                     solver=solver)
    system = result.extra.get("system")
    ref = _simulate(rscene, progress=progress,
                    force_amplitude=result.summary.get("force_amplitude")
                    if system is None or system.tangential else None, checkpoint_dir=None,
                    verify=False, resume_from=None, warn=False)
    how = (f"grid {rscene.roughness.spacing:.3g} m, tail to "
           f"{rscene.roughness.shortest_wavelength:.3g} m (half the run's)")
    if not ref.ok:
        return {"refinement": how, "verdict": "unverified",
                "failures": [f"the refined-input run failed ({ref.status}): "
                             f"{ref.summary.get('message')}"]}
    out = measure_representation(result, ref, period=scene.period,
                                 transient=scene.output.transient, refinement=how)
    out["wall_time"] = time.perf_counter() - t0
    return out


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
    return _simulate(_scene_of_checkpoint(cp, directory), progress=progress,
                     force_amplitude=None, checkpoint_dir=directory, verify=False,
                     resume_from=cp)


def checkpoint_scene(directory: str | os.PathLike) -> Scene:
    """The scene of the checkpointed run in ``directory`` (what :func:`resume` continues).

    Raises
    ------
    SceneError
        No checkpoint, or one whose scene cannot be read.
    """
    return _scene_of_checkpoint(read_checkpoint(directory), directory)


def _scene_of_checkpoint(cp: Checkpoint, directory) -> Scene:
    try:
        data = tomllib.loads(cp.scene_toml)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{directory}: the checkpoint's scene is not valid TOML ({exc})") from None
    scene = scene_from_dict(data, base_dir=cp.base_dir)
    check_inputs(cp, scene, Path(directory) / CHECKPOINT_NAME)
    return scene
