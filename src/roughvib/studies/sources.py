"""Where a run's band energy comes from: the scene rerun with one source changed at a time.

The vertical vibration of block and plate has a few sources in the model, each with a switch
that removes or replaces it while leaving the others as they are:

* ``tail``: the surface's wavelengths below 50 um (the paper's measured band); removed by
  stopping the surface there (``roughness.shortest_wavelength = 50e-6``);
* ``contact filter``: the averaging of each contact over its spot; removed by
  ``contact.filter = "none"`` (the removal adds short-wavelength input: the level rises);
* ``stick-slip``: the stops and starts of the sliding, and with them the friction's feedback
  on the tangential motion; replaced by a prescribed sinusoidal sliding of the run's own rms
  velocity and frequency (``excitation.kind = "prescribed"``);
* ``friction moment``: the moment of the friction force on the plate (the paper's model leaves
  it out); added or removed (``contact.friction_moment`` toggled, where the scene's solver
  can run it).

Lift-off and impact have no switch (a bilateral contact is not a model of roughvib): the study
counts the lift-offs of each run instead, so that a band that moves with them can be read.
Each variant's band levels (third-octave, block and plate, the scene's analysis window, the
band method of the accuracy contract) are set against the run as it is: a source matters in a
band where removing it moves the level.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from roughvib.analysis.accuracy import SIGNALS, analysis_window
from roughvib.analysis.bands import band_levels
from roughvib.scene import Scene, SceneError, scene_from_dict
from roughvib.simulation import simulate
from roughvib.solvers import registry

__all__ = ["SOURCES", "Variant", "source_variants", "source_study"]


@dataclass(frozen=True)
class Variant:
    """One run of the study.

    Attributes
    ----------
    name : str
        ``"as is"`` or the source changed.
    change : str
        What was changed, in scene keys.
    scene : Scene
    label : str
        What the run is, in words (a figure's legend).
    """

    name: str
    change: str
    scene: Scene
    label: str = ""


#: the sources the study can change, in the order of its table
SOURCES = ("tail", "contact filter", "stick-slip", "friction moment")


def source_variants(scene: Scene, v_rms: float | None = None) -> list[Variant]:
    """The scene as it is and one variant per source that applies to it.

    Parameters
    ----------
    scene : Scene
    v_rms : float, optional
        The run's rms sliding velocity [m/s], for the ``stick-slip`` variant's prescribed
        sliding (default: the scene's target, if any).

    Returns
    -------
    list of Variant
        ``tail`` only for a synthetic surface whose tail reaches below 50 um, ``stick-slip``
        only for a force-driven block with a known rms velocity, ``friction moment`` only
        on a structure with modes and where the scene's solver runs it.
    """
    out = [Variant("as is", "", scene, "as it is")]
    r, c, exc = scene.roughness, scene.contact, scene.excitation
    below = isinstance(r.shortest_wavelength, str) or r.shortest_wavelength < 50e-6
    if r.kind == "synthetic" and not r.reduce_3d and below:
        out.append(Variant("tail", "roughness.shortest_wavelength = 50e-6",
                           scene.with_overrides({"roughness.shortest_wavelength": 50e-6}),
                           "without the surface below 50 um"))
    if c.filter != "none" and r.kind in ("synthetic", "file"):
        out.append(Variant("contact filter", "contact.filter = 'none'",
                           scene.with_overrides({"contact.filter": "none"}),
                           "without the contact filter"))
    v = v_rms if v_rms is not None else exc.target_rms_velocity
    if exc.kind == "force" and v:
        amp = math.sqrt(2.0) * v / exc.omega
        out.append(Variant(
            "stick-slip", f"excitation.kind = 'prescribed', amplitude = {amp:.4g} m "
            f"(sinusoidal sliding at {v:.4g} m/s rms)",
            scene.with_overrides({"excitation.kind": "prescribed", "excitation.velocity": 0.0,
                                  "excitation.amplitude": amp,
                                  "excitation.target_rms_velocity": "none"}),
            "sinusoidal sliding, no stick-slip"))
    if (exc.kind == "force" and scene.plate.kind != "rigid"
            and registry.get(scene.resolved_solver().method).friction_moment):
        on = not c.friction_moment
        try:  # a law whose force's moment no solver integrates (a dynamic law) has no variant
            toggled = scene.with_overrides({"contact.friction_moment": on})
        except SceneError:
            toggled = None
        if toggled is not None:
            out.append(Variant("friction moment", f"contact.friction_moment = {str(on).lower()}",
                               toggled, f"{'with' if on else 'without'} the friction moment"))
    return out


def _levels(result, period: float, transient: float) -> dict[str, np.ndarray]:
    ds = result.dataset
    t = ds["time"].values
    win = analysis_window(t, period, transient)
    fs = 1.0 / float(np.mean(np.diff(t)))
    out = {}
    for name, var in SIGNALS.items():
        bl = band_levels(ds[var].values[win], fs, fmin=20.0, method="fft")
        out[name] = bl.level_db
        out["centre"] = bl.center_hz
    return out


def source_study(scene: Scene, *, progress: Callable[[str], None] | None = None
                 ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Run the scene and its source variants, and tabulate their band levels.

    Parameters
    ----------
    scene : Scene
    progress : callable, optional
        Called with one line per run.

    Returns
    -------
    bands : DataFrame
        One row per third-octave band (``band_hz``) and per variant and signal: columns
        ``variant``, ``label`` (the variant in words), ``signal`` ("block", "plate"),
        ``band_hz``, ``level_db`` [dB re 1e-6 m/s^2], ``change_db`` (the variant's level
        less the run as it is; NaN where either is not finite: a band too narrow for the
        window, a signal that is zero).
    runs : DataFrame
        One row per variant: ``variant``, ``change``, ``status``, ``lift_offs``,
        ``stick_fraction``, ``block_db``, ``plate_db`` (overall levels), ``wall_time`` [s].
    """
    import tomllib

    say = progress or (lambda line: None)
    base = simulate(scene, progress=False)
    if not base.ok:
        raise RuntimeError(f"the scene itself failed ({base.status}): "
                           f"{base.summary.get('message')}")
    # the variants start from the scene as it ran (its saved scene.toml: the calibrated force,
    # the contact module's points, stiffness and spot, the input's tail limit and grid as
    # numbers), so that each changes its one source and nothing that follows from it
    resolved = scene_from_dict(tomllib.loads(base.scene_toml), base_dir=scene.base_dir)
    period, transient = scene.period, scene.output.transient
    v_rms = float(base.summary["metrics"].get("block_tangential_velocity_rms") or 0.0) or None
    rows, bands = [], []
    ref = _levels(base, period, transient)
    for var in source_variants(resolved, v_rms):
        r = base if var.name == "as is" else simulate(var.scene, progress=False)
        say(f"{var.name}: {r.status}")
        m = r.summary.get("metrics", {})
        rows.append({"variant": var.name, "change": var.change, "status": r.status,
                     "lift_offs": int(r.summary.get("events_by_kind", {}).get("lift_off", 0)),
                     "stick_fraction": m.get("stick_fraction", math.nan),
                     "block_db": m.get("block_vertical_acceleration_level_db_re_1e-6",
                                       math.nan),
                     "plate_db": m.get("plate_vertical_acceleration_level_db_re_1e-6",
                                       math.nan),
                     "wall_time": float(r.summary["solver"].get("wall_time", math.nan))})
        if not r.ok:
            continue
        lv = _levels(r, period, transient)
        for sig in SIGNALS:
            for f, level, level_ref in zip(lv["centre"], lv[sig], ref[sig], strict=True):
                both = math.isfinite(level) and math.isfinite(level_ref)
                bands.append({"variant": var.name, "label": var.label, "signal": sig,
                              "band_hz": float(f),
                              "level_db": float(level),
                              "change_db": float(level - level_ref) if both else math.nan})
    return pd.DataFrame(bands), pd.DataFrame(rows)
