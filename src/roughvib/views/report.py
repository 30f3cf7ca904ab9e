"""Run report: one self-contained HTML page per result directory.

``write_report(DIR)`` reads a result directory written by ``roughvib run`` and writes
``DIR/report.html``: the scene, the summary tables (levels, calibration, model, contact
resonance, third-octave band levels), the solver statistics, the energy audit, the accuracy
section of a verified run (``roughvib run --verify``), the per-cycle event phase table, every
figure of :data:`roughvib.views.figures.FIGURES`, embedded as base64 PNG data URIs, and the
validations and source study written into the run directory (``roughvib validate``,
``roughvib sources DIR``). The report of a failed run opens with a banner and shows what the
run recorded up to the failure (``partial.nc`` and the event log). The page needs no server,
no network and no script; it opens from disk in any browser.

``roughvib report DIR`` (:mod:`roughvib.cli.report`) calls :func:`write_report`.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd

from roughvib.analysis.levels import single_draw_note
from roughvib.views.html import esc, figure, figure_data_uri, frame_table, kv_table, num, page

__all__ = ["build_report", "write_report"]

#: figure name -> caption
_CAPTIONS = {
    "velocity": "Tangential (friction) velocity of the block; grey: logged stick phases "
                "(paper Figs. 6/7).",
    "friction-velocity": "Friction coefficient T/F_N and friction force T against friction "
                         "velocity over one excitation period after the run-in "
                         "(paper Figs. 3 and 8).",
    "friction-displacement": "(a) Friction force against tangential displacement and (b) the "
                             "global tangential stiffness dT/dx, not evaluated where the "
                             "velocity is near zero, over up to 2.5 periods (paper Fig. 9).",
    "acceleration": "Vertical acceleration (positive down) of block and plate over the "
                    "analysis window; grey: stick (paper Figs. 10/11).",
    "spectra": "Acceleration spectra of block and plate over the analysis window: "
               "third-octave band levels (IEC 61260-1 class 1 filter bank) and Welch "
               "narrow band, "
               "dB re 1e-6 m/s² (paper Fig. 14).",
    "wavenumber": "Wavenumber spectra of the global roughness input profile and of the "
                  "stretch of it one contact crosses in the analysis window (paper Fig. 5).",
    "events": "Regimes: tangential velocity, total normal force, lift-off of each contact "
              "and the block's stick phases.",
}


# --------------------------------------------------------------------------------------------
# sections
# --------------------------------------------------------------------------------------------

def _levels_section(summary: dict) -> str:
    m = summary.get("metrics", {})
    cal = summary.get("calibration", {})
    rows = [
        ("analysis window start", m.get("window_start"), "s"),
        ("analysis window end", m.get("window_end"), "s"),
        ("force amplitude T0", summary.get("force_amplitude"), "N"),
        ("target rms velocity", cal.get("target_rms_velocity"), "m/s"),
        ("achieved rms velocity", cal.get("achieved_rms_velocity",
                                          m.get("block_tangential_velocity_rms")), "m/s"),
        ("stick fraction", m.get("stick_fraction"), "-"),
        ("block vertical acceleration rms", m.get("block_vertical_acceleration_rms"), "m/s²"),
        ("block vertical acceleration level",
         m.get("block_vertical_acceleration_level_db_re_1e-6"), "dB re 1e-6 m/s²"),
        ("plate vertical acceleration rms", m.get("plate_vertical_acceleration_rms"), "m/s²"),
        ("plate vertical acceleration level",
         m.get("plate_vertical_acceleration_level_db_re_1e-6"), "dB re 1e-6 m/s²"),
        ("tangential displacement rms", m.get("block_tangential_displacement_rms"), "m"),
        ("friction force rms", m.get("friction_force_rms"), "N"),
        ("normal force mean", m.get("normal_force_mean"), "N"),
        ("normal force min", m.get("normal_force_min"), "N"),
        ("closed contacts, mean", m.get("active_contacts_mean"), "-"),
    ]
    note = single_draw_note(summary)
    return kv_table(rows) + (f"<p class='note'>{esc(note)}</p>" if note else "")


def _model_section(summary: dict) -> str:
    mo = summary.get("model", {})
    prof = mo.get("profile", {})
    c = mo.get("contact", {})
    rows = [("plate modes", mo.get("modes"), "-"), ("contacts", mo.get("contacts"), "-"),
            ("contact points from", c.get("points_source"), "-"),
            ("micro-contacts (statistical model)", c.get("micro_contacts"), "-"),
            ("contact selection", c.get("selection"), "-"),
            ("states", mo.get("states"), "-"),
            ("residual compliance", (mo.get("residual_compliance") or {}).get("source"), "-"),
            ("largest residual compliance at a contact",
             (mo.get("residual_compliance") or {}).get("largest"), "m/N"),
            ("total contact stiffness", mo.get("contact_stiffness_total"), "N/m"),
            ("contact stiffness from", c.get("stiffness_source"), "-"),
            ("vertical damping r1", c.get("vertical_damping"), "N s/m"),
            ("initially closed contacts", mo.get("initially_closed_contacts"), "-"),
            ("profile rms", prof.get("rms"), "m"),
            ("profile rms slope", prof.get("rms_slope"), "-"),
            ("profile rms curvature", prof.get("rms_curvature"), "1/m")]
    return kv_table(rows)


#: solver statistic (key of ``summary["solver"]``) -> label and unit ("" for a count or a name)
_SOLVER_ROWS = {
    "method": ("method", ""),
    "accuracy": ("accuracy preset", ""),
    "rtol": ("relative tolerance (rtol)", "-"),
    "atol": ("absolute tolerance of displacements (atol)", "m"),
    "atol_acceleration": ("absolute tolerance of the modal accelerations", "m/s²"),
    "atol_acceleration_relative": ("same, relative to the pilot's acceleration level", "-"),
    "step": ("time step of the fixed-step methods (solver.step)", "s"),
    "step_size": ("time step", "s"),
    "largest_step": ("largest step taken", "s"),
    "steps": ("steps", ""),
    "blocks": ("error-control blocks (kept steps checked against one long step)", ""),
    "rejected_steps": ("rejected steps", ""),
    "extrapolated_steps": ("steps kept extrapolated to third order", ""),
    "error_test_failures": ("error test failures", ""),
    "step_evaluations": ("implicit step evaluations", ""),
    "root_evaluations": ("trial steps of the event searches", ""),
    "propagator_evaluations": ("modal propagators computed", ""),
    "nonlinear_iterations": ("Newton iterations", ""),
    "nonlinear_convergence_failures": ("Newton convergence failures", ""),
    "linear_iterations": ("linear (Krylov) iterations", ""),
    "linear_convergence_failures": ("linear convergence failures", ""),
    "residual_evaluations": ("residual evaluations", ""),
    "jacobian_evaluations": ("Jacobian evaluations", ""),
    "restarts": ("restarts after events", ""),
    "refires_ignored": ("repeated roots ignored at one instant", ""),
    "switches_at_zero_margin": ("switches of contacts at zero margin", ""),
    "events_total": ("events, total", ""),
    "events_truncated": ("event log truncated", ""),
    "checkpoints": ("checkpoints written", ""),
    "resumes": ("resumed from a checkpoint", ""),
    "wall_time": ("solver wall time", "s"),
    "cpu_time": ("solver CPU time", "s"),
    "preprocessing_time": ("preprocessing time", "s"),
    "note": ("note", ""),
}


def _solver_row(key: str, value) -> tuple[str, object, str]:
    """Label, value and unit of one solver statistic (a key not in ``_SOLVER_ROWS`` with its
    underscores as spaces)."""
    if key in _SOLVER_ROWS:
        label, unit = _SOLVER_ROWS[key]
    elif key.startswith("events_"):
        label, unit = f"events: {key.removeprefix('events_').replace('_', ' ')}", ""
    elif key.startswith("guard_"):
        label, unit = f"guard activations: {key.removeprefix('guard_').replace('_', ' ')}", ""
    else:
        label, unit = key.replace("_", " "), ("s" if key.endswith("_time") else "")
    return label, value, unit


def _accuracy_section(summary: dict) -> str:
    from roughvib.analysis.accuracy import verdict_line
    from roughvib.analysis.spectra import nominal_centre

    acc = summary.get("accuracy")
    if not acc:
        return ("<p class='note'>This run was not verified. <code>roughvib run --verify</code> "
                "(or <code>simulate(scene, verify=True)</code>) solves the scene a second, "
                "independent way and states the deviations against the accuracy contract "
                "(docs/accuracy.md).</p>")
    ok = acc.get("verdict") == "pass"
    head = (f"<p><b class='{'status-success' if ok else 'status-failed'}'>"
            f"{esc(verdict_line(acc))}</b></p>")
    fails = acc.get("failures") or []
    if fails:
        head += "<ul>" + "".join(f"<li>{esc(f)}</li>" for f in fails) + "</ul>"
    info = acc.get("verification", {})
    rows = [("second solve", acc.get("reference"), ""),
            ("second solve settings", info.get("settings"), ""),
            ("second solve status", info.get("status"), ""),
            ("second solve wall time", info.get("wall_time"), "s")]
    if "bands" not in acc:
        return head + kv_table(rows)
    c = acc.get("contract", {})
    win = acc.get("window", [None, None])
    rows += [("analysis window start", win[0], "s"), ("analysis window end", win[1], "s")]
    for name, b in acc["bands"].items():
        rows += [(f"{name}: largest band deviation", b.get("deviation_db"), "dB"),
                 (f"{name}: in band", b.get("worst_band_hz"), "Hz"),
                 (f"{name}: bands checked (within {c.get('dynamic_range_db', 80):g} dB of "
                  f"the strongest)", b.get("bands_checked"), "-")]
    ev = acc.get("events", {})
    rows += [("events matched one to one", ev.get("matched"), "-"),
             ("events without a partner", ev.get("unmatched"), "-"),
             ("largest event-time deviation", ev.get("max_dt"), "s"),
             ("tangential velocity, relative rms deviation", acc.get("velocity_rel_rms"), "-"),
             ("energy audit, relative residual (this run)", acc.get("energy_rel_residual"),
              "-"),
             ("energy audit, relative residual (second solve)",
              acc.get("reference_energy_rel_residual"), "-")]
    limits = (f"<p class='note'>contract: bands {c.get('f_min', 100):g} Hz to "
              f"{c.get('f_max', 50e3):g} Hz within {c.get('band_db', 1):g} dB where the "
              f"reference lies within {c.get('dynamic_range_db', 80):g} dB of its strongest "
              f"band; event times within {c.get('event_dt', 1e-6):g} s; velocity within "
              f"{c.get('velocity_rel_rms', 1e-4):g} rms; energy audit within "
              f"{c.get('energy_rel_residual', 1e-6):g} (docs/accuracy.md).</p>")
    per = {name: {f: (r, d) for f, r, d in b.get("per_band", [])}
           for name, b in acc["bands"].items()}
    freqs = sorted(set().union(*[set(v) for v in per.values()]))
    data = {"band centre [Hz]": nominal_centre(np.array(freqs, float))}
    for name in per:
        data[f"{name} reference [dB]"] = [per[name].get(f, (None, None))[0] for f in freqs]
        data[f"{name} deviation [dB]"] = [per[name].get(f, (None, None))[1] for f in freqs]
    df = pd.DataFrame(data)
    fmt = {col: (lambda v: num(v, ".3g")) for col in df.columns[1:]}
    fmt["band centre [Hz]"] = lambda v: num(float(v), "g")
    return head + kv_table(rows) + limits + frame_table(df, fmt)


def _solver_section(summary: dict) -> str:
    s = summary.get("solver", {})
    order = list(_SOLVER_ROWS)
    after_events = order.index("events_total") + 0.5

    def rank(key: str) -> float:
        if key in _SOLVER_ROWS:
            return order.index(key)
        return after_events if key.startswith(("events_", "guard_")) else len(order)

    keys = sorted((k for k, v in s.items() if not isinstance(v, dict | list)),
                  key=lambda k: (rank(k), k))
    rows = [_solver_row(k, s[k]) for k in keys]
    if s.get("from_preset"):
        rows.insert(2, ("settings from the preset", ", ".join(s["from_preset"]), ""))
    ev = summary.get("events_by_kind", {})
    rows += [(f"events: {k.replace('_', ' ')}", v, "") for k, v in sorted(ev.items())
             if f"events_{k}" not in s]
    pilot = s.get("pilot")
    if isinstance(pilot, dict) and pilot.get("duration") is not None:
        rows += [("pilot solve for the acceleration level", pilot.get("duration"), "s"),
                 ("pilot solve wall time (numba's kernels not included)",
                  pilot.get("wall_time"), "s")]
    k = s.get("kernels")
    if isinstance(k, dict) and k.get("time") is not None:
        rows.append((f"numba kernels compiled ({k.get('compiled')}, not in numba's cache yet)"
                     if k.get("compiled") else "numba kernels loaded from numba's cache",
                     k.get("time"), "s"))
        if k.get("solve"):
            rows.append(("of which within the solver wall time", k.get("solve"), "s"))
    return kv_table(rows)


#: energy audit entry -> label (work and dissipation integrated from 0 to t_end)
_ENERGY_LABELS = {
    "excitation_work": "work of the tangential excitation",
    "friction_dissipation": "dissipated by friction",
    "tangential_damping": "dissipated by the tangential damper",
    "vertical_damping": "dissipated by the vertical (contact) damper",
    "plate_damping": "dissipated by the plate's modal damping",
    "roughness_work": "work of the roughness input",
    "stored_energy_change": "change of stored energy",
    "residual": "residual",
    "energy_scale": "energy scale: sum of |terms| and |change|, at least its floor",
    "energy_scale_floor": "floor of the energy scale: larger stored energy, start or end",
    "relative_residual": "residual relative to the energy scale",
    "t_end": "end of the audit",
}


def _energy_section(summary: dict) -> str:
    a = summary.get("energy_audit", {})
    if not a:
        return "<p class='note'>no energy audit in this result</p>"
    note = summary.get("energy_audit_note")
    if note or a.get("residual") is None:  # the paper's scheme; a state that is not finite
        return f"<p class='note'>energy audit {esc(note or 'not computed')}</p>"
    rows = [(_ENERGY_LABELS.get(k, k.replace("_", " ")), v,
             "-" if k == "relative_residual" else ("s" if k == "t_end" else "J"))
            for k, v in a.items()]
    return (kv_table(rows) + "<p class='note'>residual = inputs (excitation and roughness "
            "work) − dissipation − change of stored energy; of the order of the integration "
            "tolerance.</p>")


def _resonance_and_bands(result) -> tuple[str, str]:
    from roughvib.analysis import figures_data as fd
    from roughvib.analysis.spectra import nominal_centre

    sp = fd.acceleration_spectra(result)
    cr = fd.contact_resonance(result, spectra=sp)
    res = kv_table([
        ("spring-mass estimate sqrt(s_closed/m)/2π", cr.spring_mass, "Hz"),
        ("peak of block/contact-base transmissibility", cr.transmissibility_peak, "Hz"),
        ("transmissibility at that peak", cr.transmissibility_max, "-"),
        ("loudest third-octave band, block", cr.block_maximum, "Hz"),
        ("loudest third-octave band, plate", cr.plate_maximum, "Hz"),
        ("block below plate above (0 dB crossing of L_block − L_plate)", cr.crossover, "Hz"),
    ])
    ok = np.isfinite(sp.band_db["block"]) | np.isfinite(sp.band_db["plate"])
    df = pd.DataFrame({"band centre [Hz]": nominal_centre(sp.centres[ok]),
                       "block [dB re 1e-6 m/s²]": sp.band_db["block"][ok],
                       "plate [dB re 1e-6 m/s²]": sp.band_db["plate"][ok],
                       "plate − block [dB]": (sp.band_db["plate"] - sp.band_db["block"])[ok]})
    fmt = {c: (lambda v: num(v, ".1f")) for c in df.columns[1:]}
    fmt["band centre [Hz]"] = lambda v: num(float(v), "g")
    bands = (f"<p class='note'>Band levels of an IEC 61260-1:2014 class 1 third-octave filter "
             f"bank, the filters run from t = 0 and their outputs averaged over "
             f"{sp.window[0]:.4f} … {sp.window[1]:.4f} s (bands too narrow for the window, "
             f"bandwidth × duration < 4, omitted). Total: block "
             f"{sp.total_db['block']:.1f} dB, plate "
             f"{sp.total_db['plate']:.1f} dB re 1e-6 m/s².</p>" + frame_table(df, fmt))
    return res, bands


def _stick_slip_section(result) -> str:
    from roughvib.analysis.figures_data import stick_slip_levels

    lv = stick_slip_levels(result)
    if not lv["block"]["stick_fraction"] > 0:
        return "<p class='note'>no stick phase in the analysis window</p>"
    rows = []
    for key, label, unit in (("block", "block vertical acceleration", "m/s²"),
                             ("plate", "plate vertical acceleration", "m/s²"),
                             ("input_rate", "rate of the roughness input", "m/s")):
        d = lv[key]
        rows += [(f"{label}, rms in stick", d["stick_rms"], unit),
                 (f"{label}, rms in slip", d["slip_rms"], unit),
                 (f"{label}, stick − slip", d["stick_minus_slip_db"], "dB")]
    return (kv_table(rows) + "<p class='note'>samples of the analysis window split by the "
            "logged stick phases; the roughness input rate is the excitation itself, the "
            "accelerations include the ring-down of the slip response.</p>")


def _phase_section(result) -> str:
    from roughvib.analysis.events import phase_table
    from roughvib.analysis.figures_data import scene_of

    scene = scene_of(result)
    t_end = float(result.dataset["time"].values[-1])
    K = int(result.dataset.sizes["contact"])
    table = phase_table(result.events, t_end, scene.period, K)
    if table.empty:
        return "<p class='note'>no excitation cycle recorded</p>"
    cols = ["cycle", "start", "end", "stick_fraction", "stick_phases", "mean_stick_duration"]
    out = table[cols].copy()
    out["lift_offs"] = sum(table[f"lift_offs_{k}"] for k in range(K))
    out["open_time"] = sum(table[f"lift_off_time_{k}"] for k in range(K))
    out["guard_activations"] = table["guard_activations"]
    out.columns = ["cycle", "start [s]", "end [s]", "stick fraction [-]", "stick phases",
                   "mean stick duration [s]", "lift-offs (all contacts)",
                   "open time (sum over contacts) [s]", "guard activations"]
    return frame_table(out) + ("<p class='note'>per excitation cycle from the event log "
                                "(roughvib events DIR shows the same table).</p>")


def _last_events_section(result) -> str:
    """The last 20 events of a failed run (the whole log is in events.csv)."""
    ev = result.events
    if not len(ev):  # no events.csv: the summary keeps the last ones
        ev = pd.DataFrame(result.summary.get("last_events") or [])
    if not len(ev):
        return "<p class='note'>no events were logged before the failure</p>"
    cols = [c for c in ("time", "kind", "contact", "regime_before", "regime_after",
                        "tangential_velocity", "normal_force") if c in ev.columns]
    ev = ev.tail(20)[cols].copy()
    if "contact" in ev:  # an integer, empty for block-level events
        ev["contact"] = [("" if pd.isna(c) else int(c)) for c in ev["contact"]]
    return frame_table(ev)


def _failed_banner(result, has_series: bool) -> str:
    s = result.summary
    t_end = (s.get("partial_result") or {}).get("t_end")
    at = f" at t = {t_end:.6g} s" if t_end is not None else ""
    shown = ("The phase table and the figures below show what was recorded up to the failure "
             "(partial.nc and the event log in events.csv); levels, spectra and the contact "
             "resonance are computed for complete runs only." if has_series else
             "The run stopped before its first output sample: there is no time series to "
             "show, only the statistics and the last events.")
    return (f"<div class='banner' role='alert'><b>This run FAILED ({esc(s.get('status', '?'))}"
            f"{esc(at)}).</b> {esc(shown)}</div>")


def _figures_section(result, dpi: int, noise_rms: float | None) -> tuple[str, list[str]]:
    from roughvib.views.figures import FIGURES, _plt, plot_spectra

    parts, drawn = [], []
    for name, draw in FIGURES.items():
        try:
            if name == "spectra" and noise_rms:
                fig = plot_spectra(result, noise_rms=noise_rms)[0].figure
            else:
                fig = draw(result)
            try:
                if fig.get_layout_engine() is None:  # FIGURES lay themselves out
                    fig.tight_layout()
                uri = figure_data_uri(fig, dpi=dpi)
            finally:
                _plt().close(fig)
        except Exception as exc:  # one broken figure must not cost the whole report
            parts.append(f"<figure id='fig-{esc(name)}'><p class='status-failed'>figure "
                         f"{esc(name)} could not be drawn: {esc(type(exc).__name__)}: "
                         f"{esc(exc)}</p></figure>")
            continue
        drawn.append(name)
        parts.append(figure(uri, alt=f"figure {name}", id=f"fig-{name}",
                            caption_html=f"<b>{esc(name)}</b>: {esc(_CAPTIONS.get(name, ''))}"))
    if result.extra.get("radiation") is not None:  # output.radiation: one more figure
        parts.append(_radiation_figure(result, dpi))
        drawn.append("radiation")
    return "".join(parts), drawn


def _radiation_figure(result, dpi: int) -> str:
    from roughvib.views.figures import _plt, plot_radiation

    try:
        fig = plot_radiation(result)[0].figure
        try:
            fig.tight_layout()
            uri = figure_data_uri(fig, dpi=dpi)
        finally:
            _plt().close(fig)
    except Exception as exc:  # one broken figure must not cost the whole report
        return (f"<figure id='fig-radiation'><p class='status-failed'>figure radiation could "
                f"not be drawn: {esc(type(exc).__name__)}: {esc(exc)}</p></figure>")
    s = result.summary.get("radiation", {})
    total = s.get("sound_power_level_db_re_1pW")
    text = (f"Radiated sound of the plate in an infinite baffle (docs/radiation.md): "
            f"third-octave sound power level (total {total:.1f} dB re 1 pW) and space-averaged "
            f"mean-square velocity level of the plate, and the band radiation efficiency, from "
            f"modal radiation efficiencies with the coupling between modes neglected; the "
            f"table is radiation.csv." if total is not None else
            "Radiated sound of the plate; the table is radiation.csv.")
    return figure(uri, alt="figure radiation", id="fig-radiation",
                  caption_html=f"<b>radiation</b>: {esc(text)}")


def _failed(exc: Exception) -> str:
    return (f"<p class='status-failed'>this section could not be made: "
            f"{esc(type(exc).__name__)}: {esc(exc)}</p>")


def _safe(fn, *args) -> str:
    """A section's HTML, or a note saying why it could not be made."""
    try:
        return fn(*args)
    except Exception as exc:  # one failing table must not cost the whole report
        return _failed(exc)


def build_report(result, *, title: str | None = None, dpi: int = 90,
                 noise_rms: float | None = None, run_dir: str | Path | None = None) -> str:
    """The report of a result as one HTML document (a string).

    Parameters
    ----------
    result : Result
        Fresh or loaded; a failed run (loaded with ``partial=True``) gives a page with a
        banner, its status, statistics, last events and scene, and the phase table and the
        figures of what it recorded up to the failure.
    title : str, optional
        Page title (default: "roughvib report: <scene>").
    dpi : int
        Resolution of the embedded PNG figures [dots per inch].
    noise_rms : float, optional
        Simulated accelerometer noise on the block in the spectra figure [m/s^2 rms].
    run_dir : str or Path, optional
        The run's directory: its validations against measurements (``validation/``,
        ``roughvib validate``) get a section.

    Returns
    -------
    str
        A complete HTML5 document.
    """
    from roughvib._version import __version__

    s = result.summary
    scene_name = s.get("scene", "?")
    title = title or f"roughvib report: {scene_name}"
    status = s.get("status", "unknown")
    ok = status == "success"
    has_series = result.dataset.sizes.get("time", 0) > 0  # a failed run: partial.nc
    sections: list[tuple[str, str, str]] = []  # (id, heading, html)
    if ok:  # a failed run has no levels: they need the whole analysis window
        sections.append(("levels", "Summary", _levels_section(s)))
    if ok:
        try:
            res, bands = _resonance_and_bands(result)
        except Exception as exc:  # reported in the page instead
            res = bands = _failed(exc)
        sections.append(("stick-slip", "Response in stick and in slip",
                         _safe(_stick_slip_section, result)))
        sections.append(("resonance", "Contact resonance", res))
        sections.append(("bands", "Third-octave band levels", bands))
    sections.append(("model", "Model", _model_section(s)))
    sections.append(("solver", "Solver statistics", _solver_section(s)))
    sections.append(("energy", "Energy audit", _energy_section(s)))
    if ok:
        sections.append(("accuracy", "Accuracy", _safe(_accuracy_section, s)))
    if not ok:
        sections.append(("last-events", "Last events before the failure",
                         _safe(_last_events_section, result)))
    if has_series:
        sections.append(("phases", "Event phase table", _safe(_phase_section, result)))
        figs, _ = _figures_section(result, dpi, noise_rms)
        sections.append(("figures", "Figures", figs))
    if run_dir is not None:  # measured records compared with this run (roughvib validate)
        from roughvib.views.validation import validation_section

        val = _safe(validation_section, run_dir)
        if val:
            sections.append(("validation", "Validation against measurements", val))
    if run_dir is not None and ok:  # roughvib sources DIR: the band energy's sources
        from roughvib.views.sources import sources_section

        src = _safe(lambda: sources_section(run_dir, s, dpi=dpi))
        if src:
            sections.append(("sources", "Where the band energy comes from", src))
    sections.append(("scene", "Scene (resolved, repeatable)",
                     f"<pre>{esc(result.scene_toml or '(no scene.toml)')}</pre>"))
    created = result.dataset.attrs.get("created", "")
    status_cls = "status-success" if ok else "status-failed"
    header = (
        ("" if ok else _failed_banner(result, has_series)) +
        f"<p>status: <b class='{status_cls}'>{esc(status)}</b>: {esc(s.get('message', ''))}"
        f"<br>run created {esc(created)}; report by roughvib {esc(__version__)} on "
        f"{esc(time.strftime('%Y-%m-%d %H:%M:%S'))}<br>model after J. Feldmann, "
        f"J. Vib. Acoust. 134 (2012) 041002. Vertical quantities positive down.</p>")
    return page(title, sections, header_html=header)


def write_report(result_dir: str | Path, *, out: str | Path | None = None, dpi: int = 90,
                 noise_rms: float | None = None, overwrite: bool = False) -> Path:
    """Write ``report.html`` for a result directory.

    The file appears complete or not at all (written under a temporary name and renamed).

    Parameters
    ----------
    result_dir : str or Path
        Directory written by ``roughvib run`` / :meth:`Result.save <roughvib.results.Result.save>`.
    out : str or Path, optional
        HTML file (default ``result_dir/report.html``, which a new report replaces); its
        folder is created if missing.
    dpi : int
        Resolution of the embedded figures [dots per inch].
    noise_rms : float, optional
        Simulated accelerometer noise on the block in the spectra figure [m/s^2 rms].
    overwrite : bool
        Replace ``out`` if it exists (without it, an existing ``out`` is refused).

    Returns
    -------
    Path
        The HTML file.

    Raises
    ------
    FileNotFoundError, ValueError
        Not a result directory, or an unsupported format version.
    roughvib.rundir.OutputError
        ``out`` exists (without ``overwrite``), is a directory, or its folder cannot be
        created (one line).
    roughvib.rundir.WriteError
        The file cannot be written (a full disk: the space needed and free).
    """
    from roughvib.results import load_result
    from roughvib.rundir import claim_files, output_folder, write_file

    result = load_result(result_dir, partial=True)
    path = Path(out) if out is not None else Path(result_dir) / "report.html"
    claim_files([path], overwrite=overwrite or out is None)
    output_folder(path.parent)
    text = build_report(result, dpi=dpi, noise_rms=noise_rms, run_dir=result_dir)
    data = text.encode("utf-8")
    return write_file(path, lambda tmp: tmp.write_bytes(data), need=len(data))
