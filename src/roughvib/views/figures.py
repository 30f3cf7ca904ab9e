"""Figures of a run, after the paper's figure set (Feldmann 2012, Figs. 3 and 5-14).

Pure functions: each takes a :class:`~roughvib.results.Result` and ``ax`` (or ``axes``) =
None, draws, and returns the Axes it drew on; matplotlib is imported lazily and nothing is
shown. Every axis is labelled with its unit. The numbers behind the figures come from
:mod:`roughvib.analysis.figures_data`, so they can be checked without matplotlib.

``FIGURES`` maps the names accepted by ``roughvib plot DIR --figure NAME`` to functions that
draw a whole figure and return it:

* ``velocity``: tangential velocity against time, stick shaded (paper Figs. 6/7);
* ``friction-velocity``: friction coefficient (one period) and friction force against
  velocity (Figs. 3/8);
* ``friction-displacement``: friction force against displacement, and the global tangential
  stiffness dT/dx against time with a velocity guard (Fig. 9);
* ``acceleration``: vertical acceleration of block and plate against time (Figs. 10/11);
* ``spectra``: third-octave and narrow-band spectra of block and plate (Fig. 14);
* ``wavenumber``: wavenumber spectra of the global profile and one contact's input (Fig. 5);
* ``events``: regimes per contact under velocity and normal force.

Two more take several runs and are not in ``FIGURES``: :func:`plot_velocity_sweep` (the
velocity exponent) and :func:`plot_band_comparison` (third-octave spectra overlaid).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from roughvib.analysis import figures_data as fd
from roughvib.analysis.events import stick_intervals

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from roughvib.results import Result

__all__ = ["FIGURES", "plot_acceleration", "plot_band_comparison", "plot_events",
           "plot_radiation",
           "plot_friction_displacement", "plot_friction_velocity", "plot_friction_velocity_pair",
           "plot_regime_timeline", "plot_spectra", "plot_tangential_stiffness", "plot_velocity",
           "plot_velocity_sweep", "plot_wavenumber", "save_figure"]

_STICK_SHADE = {"color": "0.88", "lw": 0, "zorder": 0}


def _plt():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "module://matplotlib_inline.backend_inline"):
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _ax(ax, figsize=(8, 3)):
    # a figure made here lays itself out (constrained layout) wherever it is shown: saved,
    # in the report, in a notebook or the docs gallery, without a tight_layout by the caller
    if ax is None:
        _, ax = _plt().subplots(figsize=figsize, layout="constrained")
    return ax


def _axes(axes, n: int, figsize, **kw):
    if axes is None:
        _, axes = _plt().subplots(n, 1, figsize=figsize, layout="constrained", **kw)
    axes = list(np.atleast_1d(axes))
    if len(axes) != n:
        raise ValueError(f"axes must hold {n} Axes, got {len(axes)}")
    return axes


def _shade_stick(ax, result: Result, t0: float, t1: float) -> None:
    t_end = float(result.dataset["time"].values[-1])
    for s, e in stick_intervals(result.events, t_end):
        if e > t0 and s < t1:
            ax.axvspan(max(s, t0), min(e, t1), **_STICK_SHADE)


# --------------------------------------------------------------------------------------------
# time histories
# --------------------------------------------------------------------------------------------

def plot_velocity(result: Result, *, ax: Axes | None = None) -> Axes:
    """Tangential block velocity against time (the paper's Figs. 6/7), stick phases shaded.

    Parameters
    ----------
    result : Result
    ax : Axes, optional
        Drawn into; a new figure otherwise.

    Returns
    -------
    Axes
    """
    ax = _ax(ax)
    ds = result.dataset
    t = ds["time"].values
    ax.plot(t, ds["block_tangential_velocity"].values * 1e3, lw=0.8, color="C0")
    _shade_stick(ax, result, float(t[0]), float(t[-1]))
    ax.set_xlim(t[0], t[-1])
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tangential velocity [mm/s]")
    ax.set_title("friction velocity (grey: stick)")
    return ax


def plot_acceleration(result: Result, *, axes=None):
    """Vertical acceleration of block (a) and plate (b) against time (Figs. 10/11).

    The analysis window (whole periods after the run-in) is shown, stick phases shaded: the
    response comes in bursts while the block slides and is quiet while it sticks.

    Parameters
    ----------
    result : Result
    axes : sequence of 2 Axes, optional

    Returns
    -------
    list of Axes
        [block, plate].
    """
    axes = _axes(axes, 2, (9, 5.5))
    ds = result.dataset
    win = fd.analysis_window(result)
    t = ds["time"].values[win]
    for ax, name, label, color in zip(
            axes, fd.ACCELERATIONS, ("(a) block (mass)", "(b) plate, observation point"),
            ("C0", "C3"), strict=True):
        ax.plot(t, ds[name].values[win], lw=0.5, color=color)
        _shade_stick(ax, result, float(t[0]), float(t[-1]))
        ax.set_ylabel("acceleration [m/s²]")
        ax.set_title(f"{label}: vertical acceleration, positive down (grey: stick)",
                     fontsize=9)
        ax.set_xlim(t[0], t[-1])
    axes[0].set_xlabel("time [s]")
    axes[1].set_xlabel("time [s]")
    return axes


def plot_regime_timeline(result: Result, *, ax: Axes | None = None) -> Axes:
    """Regimes over time: one row per contact (bar = lift-off) and one for the block (stick).

    A run in which no contact lifts off has one row that says so instead of empty contact rows.

    Parameters
    ----------
    result : Result
    ax : Axes, optional

    Returns
    -------
    Axes
    """
    ax = _ax(ax)
    tl = fd.regime_timeline(result)
    K = len(tl.lift_off)
    if tl.lifts_off:
        for k, iv in enumerate(tl.lift_off):
            if iv:
                ax.broken_barh([(s, e - s) for s, e in iv], (k - 0.4, 0.8), color="C3")
        rows = [f"contact {k}" for k in range(K)]
        title = "regimes (red: contact open, blue: stick)"
    else:  # one row for all contacts, saying that none opens
        K = 1
        n = len(tl.lift_off)
        who = "the contact stays" if n == 1 else f"all {n} contacts stay"
        ax.text(0.5 * tl.t_end, 0.0, f"none: {who} closed throughout", ha="center",
                va="center", fontsize=9, color="0.25")
        rows = ["lift-off"]
        title = "regimes (blue: stick; no lift-off)"
    if tl.stick:
        ax.broken_barh([(s, e - s) for s, e in tl.stick], (K - 0.4 + 0.5, 0.8), color="C0")
    if tl.guards.size:
        ax.plot(tl.guards, np.full(tl.guards.size, K + 0.5), "k|", ms=8, label="guard")
        ax.legend(loc="upper right", fontsize=7)
    ax.set_yticks(list(range(K)) + [K + 0.5])
    ax.set_yticklabels(rows + ["block stick"], fontsize=7)
    ax.set_ylim(-0.7, K + 1.2)
    ax.set_xlim(0, tl.t_end)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("regime")
    ax.set_title(title)
    return ax


def plot_events(result: Result, *, axes=None):
    """Timeline of regimes per contact under the tangential velocity and normal force.

    Parameters
    ----------
    result : Result
    axes : sequence of 3 Axes, optional

    Returns
    -------
    list of Axes
        [velocity, normal force, regimes].
    """
    axes = _axes(axes, 3, (9, 7), sharex=True, gridspec_kw={"height_ratios": [1, 1, 1.4]})
    ds = result.dataset
    t = ds["time"].values
    plot_velocity(result, ax=axes[0])
    axes[1].plot(t, ds["normal_force"].values, lw=0.6, color="C2")
    axes[1].set_xlabel("time [s]")
    axes[1].set_ylabel("normal force [N]")
    axes[1].set_title("total normal contact force")
    plot_regime_timeline(result, ax=axes[2])
    for ax in axes[:-1]:  # on a shared time axis only the bottom panel says what it is
        if ax.get_shared_x_axes().joined(ax, axes[-1]):
            ax.set_xlabel("")
    return axes


# --------------------------------------------------------------------------------------------
# friction loops
# --------------------------------------------------------------------------------------------

def plot_friction_velocity(result: Result, *, ax: Axes | None = None,
                           quantity: str = "coefficient", periods: float | None = 1.0) -> Axes:
    """Friction against friction velocity over whole periods after the run-in.

    ``quantity='coefficient'`` is the paper's Fig. 3 (the friction law as the run lived it:
    steep stick branch, overshoot, decay to mu_slip, hysteresis); ``'force'`` is Fig. 8, where
    the normal-force fluctuations during sliding spread the curve (not during stick).

    Parameters
    ----------
    result : Result
    ax : Axes, optional
    quantity : {'coefficient', 'force'}
    periods : float or None
        Excitation periods shown (None: the whole analysis window).

    Returns
    -------
    Axes
    """
    if quantity not in ("coefficient", "force"):
        raise ValueError(f"quantity must be 'coefficient' or 'force', got {quantity!r}")
    ax = _ax(ax, (5, 4))
    loop = fd.friction_loop(result, periods=periods)
    y = loop.coefficient if quantity == "coefficient" else loop.friction
    v = loop.velocity * 1e3
    ax.plot(v, y, lw=0.5, color="C0", label="slip")
    if loop.stick.any():
        ys = np.where(loop.stick, y, np.nan)
        ax.plot(np.where(loop.stick, v, np.nan), ys, lw=1.2, color="C1", label="stick")
        ax.legend(loc="lower right", fontsize=7)
    ax.axvline(0.0, color="0.6", lw=0.5)
    ax.set_xlabel("friction velocity [mm/s]")
    if quantity == "coefficient":
        ax.set_ylabel("friction coefficient T/F_N [-]")
        ax.set_title("friction coefficient vs velocity (Fig. 3)", fontsize=9)
    else:
        ax.set_ylabel("friction force T [N]")
        ax.set_title("friction force vs velocity (Fig. 8)", fontsize=9)
    return ax


def plot_friction_velocity_pair(result: Result, *, axes=None):
    """Friction coefficient (Fig. 3) and friction force (Fig. 8) against velocity, one period.

    Returns
    -------
    list of Axes
        [coefficient, force].
    """
    if axes is None:
        _, axes = _plt().subplots(1, 2, figsize=(10, 4), layout="constrained")
    axes = _axes(axes, 2, None)
    plot_friction_velocity(result, ax=axes[0], quantity="coefficient")
    plot_friction_velocity(result, ax=axes[1], quantity="force")
    return axes


def plot_tangential_stiffness(result: Result, *, ax: Axes | None = None,
                              periods: float | None = 2.5, v_guard: float | None = None
                              ) -> Axes:
    """Global tangential stiffness dT/dx against time (paper Fig. 9b), stick shaded.

    dT/dx is not evaluated where ``|v| < v_guard`` (gaps in the line); see
    :func:`roughvib.analysis.figures_data.tangential_stiffness`. The ordinate is linear, in
    kN/m, and covers the slip branch (95 % of its samples,
    :func:`roughvib.analysis.figures_data.stiffness_scale`): in stick dT/dx is the stiff
    branch, an order of magnitude and more above, cut at the frame; the title gives its
    median.

    Parameters
    ----------
    result : Result
    ax : Axes, optional
    periods : float or None
        Excitation periods after the run-in (2.5 as in the paper).
    v_guard : float, optional
        Velocity guard [m/s]; default 1e-4 x rms velocity.

    Returns
    -------
    Axes
    """
    ax = _ax(ax)
    loop, k, guard = fd.tangential_stiffness(result, periods=periods, v_guard=v_guard)
    scale = fd.stiffness_scale(k, loop.stick)
    ax.plot(loop.time, k / 1e3, lw=0.5, color="C2")
    _shade_stick(ax, result, float(loop.time[0]), float(loop.time[-1]))
    ax.axhline(0.0, color="0.6", lw=0.5)
    ax.set_ylim(-1.1 * scale.limit / 1e3, 1.1 * scale.limit / 1e3)
    ax.set_xlim(loop.time[0], loop.time[-1])
    ax.set_xlabel("time [s]")
    ax.set_ylabel("dT/dx [kN/m]")
    med = scale.stick_median
    stick = (f"; grey: stick, median {med / 1e6:.3g} MN/m, off the scale" if abs(med) >= 1e6
             else f"; grey: stick, median {med / 1e3:.3g} kN/m, off the scale"
             if math.isfinite(med) else "")
    ax.set_title(f"(b) global tangential stiffness (gaps: |v| < {guard * 1e6:.2g} µm/s"
                 f"{stick})", fontsize=9)
    return ax


def plot_friction_displacement(result: Result, *, axes=None, periods: float | None = 2.5,
                               v_guard: float | None = None):
    """Friction force against tangential displacement (a) and its derivative (b), Fig. 9.

    Parameters
    ----------
    result : Result
    axes : sequence of 2 Axes, optional
    periods : float or None
        Excitation periods after the run-in (2.5 as in the paper).
    v_guard : float, optional
        Velocity guard of dT/dx [m/s] (see :func:`plot_tangential_stiffness`).

    Returns
    -------
    list of Axes
        [loop, stiffness].
    """
    axes = _axes(axes, 2, (8, 7), gridspec_kw={"height_ratios": [1.2, 1]})
    loop = fd.friction_loop(result, periods=periods)
    ax = axes[0]
    ax.plot(loop.displacement * 1e3, loop.friction, lw=0.6, color="C0")
    if loop.stick.any():
        ax.plot(np.where(loop.stick, loop.displacement * 1e3, np.nan),
                np.where(loop.stick, loop.friction, np.nan), lw=1.2, color="C1", label="stick")
        ax.legend(loc="lower right", fontsize=7)
    ax.set_xlabel("tangential displacement [mm]")
    ax.set_ylabel("friction force T [N]")
    ax.set_title("(a) friction force vs tangential displacement", fontsize=9)
    plot_tangential_stiffness(result, ax=axes[1], periods=periods, v_guard=v_guard)
    return axes


# --------------------------------------------------------------------------------------------
# spectra
# --------------------------------------------------------------------------------------------

def plot_spectra(result: Result, *, axes=None, noise_rms: float | None = None,
                 resolution: float = 25.0):
    """Acceleration spectra of block and plate (paper Fig. 14): third octaves and narrow band.

    Band levels are those of the IEC 61260-1 class 1 filter bank averaged over the analysis
    window (:func:`roughvib.analysis.figures_data.acceleration_spectra`), the narrow band is Welch
    (Hann, 50 % overlap, ``resolution``). The dashed line marks the spring-mass estimate of
    the contact resonance, sqrt(s/m)/2 pi.

    Parameters
    ----------
    result : Result
    axes : sequence of 2 Axes, optional
        [third-octave, narrow band].
    noise_rms : float, optional
        rms [m/s^2] of a simulated white accelerometer noise added to the block (drawn as a
        further thin line); 1e-3 is an estimate of the paper's.
    resolution : float
        Narrow-band bin spacing [Hz].

    Returns
    -------
    list of Axes
    """
    if axes is None:
        _, axes = _plt().subplots(1, 2, figsize=(11, 4.2), layout="constrained")
    axes = _axes(axes, 2, None)
    sp = fd.acceleration_spectra(result, resolution=resolution, noise_rms=noise_rms)
    cr = fd.contact_resonance(result, spectra=sp)
    style = {"block": ("C0", 1.0, "block (mass)"), "plate": ("C3", 2.0, "plate"),
             "block_noisy": ("0.4", 0.8, f"block + noise {sp.noise_rms:.2g} m/s² rms")}
    for key in sp.band_db:
        color, lw, label = style[key]
        total = sp.total_db[key]
        axes[0].step(sp.centres, sp.band_db[key], where="mid", color=color, lw=lw,
                     label=f"{label}, total {total:.1f} dB")
        axes[1].plot(sp.frequency[1:], sp.psd_db[key][1:], color=color, lw=lw * 0.5,
                     label=label)
    for ax in axes:
        ax.set_xscale("log")
        ax.axvline(cr.spring_mass, color="0.5", ls="--", lw=0.8)
        ax.set_xlabel("frequency [Hz]")
        ax.legend(fontsize=7, loc="lower left")
    axes[0].set_xlim(sp.centres[0] / 1.12, sp.centres[-1] * 1.12)
    axes[1].set_xlim(max(sp.frequency[1], 10.0), sp.frequency[-1])
    axes[0].set_ylabel("third-octave level [dB re 1e-6 m/s²]")
    axes[1].set_ylabel("PSD [dB re (1e-6 m/s²)²/Hz]")
    axes[0].set_title(f"third-octave bands (IEC 61260-1 filters); dashed: sqrt(s/m)/2π = "
                      f"{cr.spring_mass:.0f} Hz", fontsize=9)
    axes[1].set_title(f"narrow band, Welch Hann, Δf = {sp.resolution:.3g} Hz", fontsize=9)
    return axes


def plot_wavenumber(result: Result, *, ax: Axes | None = None, contact: int = 0) -> Axes:
    """Wavenumber spectra of the global input profile and of one contact's input (Fig. 5).

    The thin line is the whole (filtered, 2-D reduced) profile, the thick one the stretch of
    it that contact ``contact`` crossed in the analysis window; the dotted line marks
    k = 2 pi / (peak-to-peak stroke), below which the contact sees no input.

    Parameters
    ----------
    result : Result
    ax : Axes, optional
    contact : int
        Contact index.

    Returns
    -------
    Axes
    """
    ax = _ax(ax, (7, 4.2))
    cs = fd.contact_input_spectra(result, contact=contact)
    g = cs.k_global > 0
    c = cs.k_contact > 0
    ax.loglog(cs.k_global[g], cs.psd_global[g], lw=0.7, color="0.3", label="global profile")
    ax.loglog(cs.k_contact[c], cs.psd_contact[c], lw=2.0, color="C0",
              label=f"input at contact {cs.contact} (stroke {cs.stroke * 1e3:.3g} mm p-p)")
    ax.axvline(2.0 * math.pi / cs.stroke, color="C0", ls=":", lw=1.0)
    # numerical tails far below the profile's band (filter roll-off, window side lobes)
    # would stretch the axis over 20 decades
    peak = float(np.max(cs.psd_global[g]))
    ax.set_ylim(peak * 1e-10, peak * 30.0)
    ax.set_xlabel("wavenumber k [rad/m]")
    ax.set_ylabel("PSD [m²/(rad/m)]")
    ax.set_title("roughness input: wavenumber spectra (dotted: 2π / stroke)", fontsize=9)
    ax.legend(fontsize=7, loc="lower left")
    return ax


def plot_radiation(result: Result, *, axes=None):
    """Radiated sound of the plate (``output.radiation``): band levels and efficiency.

    (a) sound power level [dB re 1 pW] and space-averaged mean-square velocity level of the
    plate [dB re (1e-9 m/s)^2]; (b) radiation efficiency [dB], the dashed line at the
    coincidence frequency. From ``result.extra["radiation"]`` (``radiation.csv``).

    Parameters
    ----------
    result : Result
        A run made with ``output.radiation = true``.
    axes : sequence of 2 Axes, optional

    Returns
    -------
    list of Axes

    Raises
    ------
    ValueError
        The run has no radiation table.
    """
    from roughvib.physics.radiation import coincidence_frequency

    table = result.extra.get("radiation")
    if table is None:
        raise ValueError("this run has no radiation table (run it with output.radiation = "
                         "true)")
    if axes is None:
        _, axes = _plt().subplots(1, 2, figsize=(11, 4.2))
    axes = _axes(axes, 2, None)
    f = np.asarray(table["band_hz"], dtype=float)
    scene = fd.scene_of(result)
    fc = coincidence_frequency(scene.plate, scene.output.sound_speed)
    sides = scene.output.radiating_sides
    axes[0].step(f, table["sound_power_db"], where="mid", color="C3", lw=2.0,
                 label=f"sound power, {sides} side{'s' if sides > 1 else ''} [dB re 1 pW]")
    axes[0].step(f, table["mean_square_velocity_db"], where="mid", color="C0", lw=1.2,
                 label="plate mean-square velocity [dB re (1e-9 m/s)²]")
    axes[0].set_ylabel("third-octave level [dB]")
    axes[0].legend(fontsize=7, loc="lower left")
    axes[0].set_title("radiated sound power and plate velocity (Hann window)", fontsize=9)
    axes[1].step(f, table["radiation_efficiency_db"], where="mid", color="C2", lw=1.5)
    axes[1].set_ylabel("radiation efficiency [dB re 1]")
    axes[1].set_title(f"band radiation efficiency; dashed: coincidence f_c = {fc:.0f} Hz",
                      fontsize=9)
    for ax in axes:
        ax.set_xscale("log")
        ax.axvline(fc, color="0.5", ls="--", lw=0.8)
        ax.set_xlabel("third-octave band [Hz]")
        shown = f[np.isfinite(np.asarray(table["sound_power_db"], dtype=float))]
        if shown.size:
            ax.set_xlim(shown[0] / 1.12, shown[-1] * 1.12)
    return axes


# --------------------------------------------------------------------------------------------
# files and the registry
# --------------------------------------------------------------------------------------------

def save_figure(fig: Figure, path, *, dpi: int = 100) -> None:
    """Write a figure and close it.

    The file appears complete or not at all (written under a temporary name and renamed);
    its format follows the suffix (PNG without one).

    Parameters
    ----------
    fig : Figure
    path : str or path-like
        PNG file (or another format matplotlib writes, by its suffix).
    dpi : int
        Resolution [dots per inch].

    Raises
    ------
    roughvib.rundir.WriteError
        The file cannot be written (a full disk: one line naming it, the space needed and
        free).
    """
    from pathlib import Path

    from roughvib.rundir import writing

    try:
        if fig.get_layout_engine() is None:  # the figures made here lay themselves out
            fig.tight_layout()
        with writing(path, "wb") as fh:  # in memory first: its size is known on a full disk
            fig.savefig(fh, dpi=dpi, format=Path(path).suffix[1:].lower() or "png")
    finally:
        _plt().close(fig)


def _whole(fn: Callable, **kw) -> Callable[[Result], Figure]:
    def draw(result: Result) -> Figure:
        drawn = fn(result, **kw)
        ax = drawn[0] if isinstance(drawn, list | tuple | np.ndarray) else drawn
        return ax.figure

    draw.__doc__ = fn.__doc__
    return draw


#: figure name -> drawing function (``roughvib plot --figure NAME`` and the run report)
FIGURES: dict[str, Callable[[Result], Figure]] = {
    "velocity": _whole(plot_velocity),
    "friction-velocity": _whole(plot_friction_velocity_pair),
    "friction-displacement": _whole(plot_friction_displacement),
    "acceleration": _whole(plot_acceleration),
    "spectra": _whole(plot_spectra),
    "wavenumber": _whole(plot_wavenumber),
    "events": _whole(plot_events),
}


# --------------------------------------------------------------------------------------------
# several runs
# --------------------------------------------------------------------------------------------

def plot_velocity_sweep(results, *, ax: Axes | None = None) -> Axes:
    """Overall acceleration levels of block and plate over friction velocity, with fits.

    The levels are the runs' summary rms levels over whole periods; the lines are the
    least-squares fits of :func:`roughvib.analysis.figures_data.velocity_sweep`, labelled in
    dB per doubling and as the power-basis exponent n (mean square ∝ v^n; the paper: 3-3.5).

    Parameters
    ----------
    results : iterable of Result
        Runs at different friction velocities.
    ax : Axes, optional

    Returns
    -------
    Axes
    """
    ax = _ax(ax, (6, 4))
    table, fits = fd.velocity_sweep(results)
    v = table["v_rms"].to_numpy(dtype=float)
    vv = np.geomspace(v.min(), v.max(), 50)
    for key, color, label in (("block", "C0", "block (mass)"), ("plate", "C3", "plate")):
        y = table[f"{key}_db"].to_numpy(dtype=float)
        fit = fits[key]
        c = np.mean(y) - fit.db_per_doubling * np.mean(np.log2(v))
        ax.plot(v * 1e3, y, "o", color=color)
        ax.plot(vv * 1e3, c + fit.db_per_doubling * np.log2(vv), "-", color=color, lw=1,
                label=f"{label}: {fit.db_per_doubling:.1f} dB/doubling (n = {fit.exponent:.2f})")
    ax.set_xscale("log")
    ax.set_xticks(v * 1e3)
    ax.set_xticklabels([f"{x:.3g}" for x in v * 1e3])
    ax.minorticks_off()
    ax.set_xlabel("friction velocity v_rms [mm/s]")
    ax.set_ylabel("overall acceleration level [dB re 1e-6 m/s²]")
    ax.set_title("velocity exponent (paper: 9-12 dB per doubling)", fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    return ax


def plot_band_comparison(results, labels, *, ax: Axes | None = None,
                         quantity: str = "block") -> Axes:
    """Third-octave spectra of one acceleration from several runs, overlaid.

    Parameters
    ----------
    results : sequence of Result
    labels : sequence of str
        Legend entries, one per run.
    ax : Axes, optional
    quantity : {'block', 'plate'}
        Which acceleration.

    Returns
    -------
    Axes
    """
    if quantity not in ("block", "plate"):
        raise ValueError(f"quantity must be 'block' or 'plate', got {quantity!r}")
    results, labels = list(results), list(labels)
    if len(results) != len(labels):
        raise ValueError(f"need one label per run, got {len(labels)} for {len(results)}")
    ax = _ax(ax, (6, 4))
    for i, (r, label) in enumerate(zip(results, labels, strict=True)):
        sp = fd.acceleration_spectra(r)
        ax.step(sp.centres, sp.band_db[quantity], where="mid", color=f"C{i}", lw=1.2,
                label=f"{label} ({sp.total_db[quantity]:.1f} dB)")
    ax.set_xscale("log")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("third-octave level [dB re 1e-6 m/s²]")
    name = "block (mass)" if quantity == "block" else "plate"
    ax.set_title(f"{name} acceleration, third octaves (IEC 61260-1 filters)", fontsize=9)
    ax.legend(fontsize=7, loc="lower left")
    return ax
