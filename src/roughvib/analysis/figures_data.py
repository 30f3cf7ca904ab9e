"""Data behind the paper's figures: windows, friction loops, spectra, contact resonance.

This module owns the reductions that the figures (:mod:`roughvib.views.figures`) and the run report
(:mod:`roughvib.views.report`) draw, so that they can be tested and reused without matplotlib:

* the analysis window of a run (whole excitation periods after the run-in);
* friction loops against velocity (paper Figs. 3 and 8) and against tangential displacement
  with the global tangential stiffness dT/dx (Fig. 9);
* acceleration spectra of block and plate (Fig. 14): third-octave band levels and a Welch narrow
  band in dB re 1e-6 m/s^2, with an optional simulated accelerometer noise floor on the block;
* the regimes over time (lift-off per contact, stick, guards) of the events figure;
* the wavenumber spectra of the global input profile and of the stretch of it one contact
  actually crosses (Fig. 5), and the ranges the surface report's spectrum figure shows;
* estimates of the contact resonance, and the velocity exponent over a set of runs.

Third-octave levels of the accelerations (:func:`acceleration_spectra`) come from the IEC
61260-1 class 1 filter bank of :mod:`roughvib.analysis.bands`; the filters run from the start of
the record and their outputs are averaged over the analysis window (docs/bands.md compares them
with the FFT band sums). :func:`tapered_band_levels` gives the FFT alternative, from a
**Hann-tapered** record. The rectangular-window band sums of
:func:`roughvib.analysis.spectra.band_levels` are Parseval-exact, but the jump between the two
ends of a record of a non-periodic response leaks into every band with a power falling only as
1/f^2 per bin. On the ``paper`` scene that leakage floor lies 55-80 dB below the spectral
maximum, above the block's own roll-off beyond the contact resonance, and would hide it
(docs/paper-comparison.md gives the numbers). With the taper the sidelobes fall off at 18 dB per
octave and the roll-off shows.

Units: SI throughout; levels in dB re 1e-6 m/s^2 (accelerations) unless stated otherwise.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from roughvib.analysis.bands import band_levels as filtered_band_levels
from roughvib.analysis.levels import (
    VelocityExponent,
    global_tangential_stiffness,
    rms,
    velocity_exponent,
    whole_period_window,
)
from roughvib.analysis.spectra import (
    add_noise_floor,
    band_levels,
    narrowband_psd,
    total_level,
    wavenumber_spectrum,
)
from roughvib.results import Result
from roughvib.scene import Scene, scene_from_dict

__all__ = ["ACCELERATIONS", "AccelerationSpectra", "ContactInputSpectra", "ContactResonance",
           "FrictionLoop", "RegimeTimeline", "StiffnessScale", "SurfaceSpectrumView",
           "acceleration_spectra", "analysis_window", "contact_input_spectra",
           "contact_resonance", "friction_loop", "regime_timeline", "scene_of",
           "stick_slip_levels", "stiffness_scale", "surface_spectrum_view",
           "tangential_stiffness", "tapered_band_levels", "transmissibility", "velocity_sweep"]

#: block and plate acceleration variables (the paper's "mass" and "plate")
ACCELERATIONS = ("block_vertical_acceleration", "plate_vertical_acceleration")


# --------------------------------------------------------------------------------------------
# scene and window
# --------------------------------------------------------------------------------------------

def scene_of(result: Result) -> Scene:
    """The scene a result was made from, rebuilt from its resolved ``scene_toml``.

    Parameters
    ----------
    result : Result
        A fresh or loaded result.

    Returns
    -------
    Scene
        For a loaded result the resolved scene (calibrated T0 filled in); for a fresh one the
        scene it was run with.
    """
    system = result.extra.get("system")
    if system is not None:
        return system.scene
    if not result.scene_toml:
        raise ValueError("the result carries no scene (scene.toml missing)")
    return scene_from_dict(tomllib.loads(result.scene_toml))


def _fs(result: Result) -> float:
    t = result.dataset["time"].values
    if t.size < 2:
        raise ValueError("a result needs at least two output samples")
    return 1.0 / float(t[1] - t[0])


def analysis_window(result: Result, *, periods: float | None = None) -> slice:
    """Index window of the analysis: whole excitation periods after the run-in.

    The window is the one the run's summary metrics use (:func:`.whole_period_window` with
    ``output.transient``), so spectra and levels of a figure describe the same samples. A run
    shorter than its run-in is analysed from t = 0, as the summary does.

    Parameters
    ----------
    result : Result
    periods : float, optional
        Length of the window in excitation periods (e.g. 2.5 for Fig. 9), starting at the
        run-in; cut to the end of the record. Default: the largest whole number of periods.

    Returns
    -------
    slice
        Into the time axis of ``result.dataset``.
    """
    scene = scene_of(result)
    t = result.dataset["time"].values
    transient = scene.output.transient if scene.output.transient < t[-1] else 0.0
    period = scene.period if math.isfinite(scene.period) else 0.0
    win = whole_period_window(t, period, transient)
    if periods is not None:
        if not periods > 0:
            raise ValueError(f"periods must be > 0, got {periods}")
        if period > 0:
            n = int(round(periods * period * _fs(result)))
            win = slice(win.start, min(win.start + n, t.size))
        else:
            win = slice(win.start, t.size)
    return win


# --------------------------------------------------------------------------------------------
# regimes over time (the events figure)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class RegimeTimeline:
    """The regimes of a run over time: what the events figure's bottom panel draws.

    Attributes
    ----------
    t_end : float
        End of the run [s].
    lift_off : list of list of (float, float)
        Per contact, its lift-off phases (start, end) [s].
    stick : list of (float, float)
        The block's stick phases (start, end) [s].
    guards : ndarray, shape (g,)
        Times of the solver's guard events [s] (event storms left out).
    """

    t_end: float
    lift_off: list[list[tuple[float, float]]]
    stick: list[tuple[float, float]]
    guards: np.ndarray

    @property
    def lifts_off(self) -> bool:
        """Whether any contact lifts off during the run."""
        return any(self.lift_off)


def regime_timeline(result: Result) -> RegimeTimeline:
    """Lift-off phases per contact, stick phases and guard events of a run, from its log.

    Parameters
    ----------
    result : Result

    Returns
    -------
    RegimeTimeline
    """
    from roughvib.analysis.events import GUARD_KINDS, lift_off_intervals, stick_intervals

    ds = result.dataset
    t_end = float(ds["time"].values[-1])
    ev = result.events
    guards = ev[ev["kind"].isin([k for k in GUARD_KINDS if k != "event_storm"])]
    return RegimeTimeline(
        t_end=t_end,
        lift_off=[lift_off_intervals(ev, k, t_end) for k in range(ds.sizes["contact"])],
        stick=stick_intervals(ev, t_end),
        guards=np.asarray(guards["time"], dtype=float))


# --------------------------------------------------------------------------------------------
# friction loops (Figs. 3, 8, 9)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FrictionLoop:
    """Friction against velocity and displacement over a window.

    Attributes
    ----------
    time : ndarray, shape (n,)
        [s]
    velocity : ndarray, shape (n,)
        Friction (relative tangential) velocity [m/s].
    displacement : ndarray, shape (n,)
        Tangential block displacement [m].
    friction : ndarray, shape (n,)
        Friction force T [N], positive when it opposes a positive velocity.
    coefficient : ndarray, shape (n,)
        T / F_N [-].
    normal_force : ndarray, shape (n,)
        Total normal force F_N [N].
    stick : ndarray of bool, shape (n,)
        Samples inside a logged stick phase.
    """

    time: np.ndarray
    velocity: np.ndarray
    displacement: np.ndarray
    friction: np.ndarray
    coefficient: np.ndarray
    normal_force: np.ndarray
    stick: np.ndarray


def _stick_mask(result: Result, t: np.ndarray) -> np.ndarray:
    from roughvib.analysis.events import stick_intervals

    mask = np.zeros(t.size, dtype=bool)
    t_end = float(result.dataset["time"].values[-1])
    for a, b in stick_intervals(result.events, t_end):
        mask |= (t >= a) & (t < b)
    return mask


def friction_loop(result: Result, *, periods: float | None = 1.0) -> FrictionLoop:
    """Friction, velocity and displacement over ``periods`` excitation periods after run-in.

    Parameters
    ----------
    result : Result
    periods : float or None
        Window length in periods (1 for the paper's Figs. 3 and 8, 2.5 for Fig. 9); None for
        the whole analysis window.

    Returns
    -------
    FrictionLoop
    """
    win = analysis_window(result, periods=periods)
    ds = result.dataset
    t = ds["time"].values[win]
    return FrictionLoop(
        time=t,
        velocity=ds["block_tangential_velocity"].values[win],
        displacement=ds["block_tangential_displacement"].values[win],
        friction=ds["friction_force"].values[win],
        coefficient=ds["friction_coefficient"].values[win],
        normal_force=ds["normal_force"].values[win],
        stick=_stick_mask(result, t),
    )


def tangential_stiffness(result: Result, *, periods: float | None = 2.5,
                         v_guard: float | None = None) -> tuple[FrictionLoop, np.ndarray, float]:
    """Global tangential stiffness dT/dx along the friction loop (paper Fig. 9b).

    dT/dx is the ratio of the time derivatives of friction force and displacement
    (:func:`roughvib.analysis.levels.global_tangential_stiffness`). Where the velocity is near
    zero the ratio is a quotient of two small, noisy numbers: those samples are NaN.

    Parameters
    ----------
    result : Result
    periods : float or None
        Window in excitation periods after the run-in (2.5 as in the paper).
    v_guard : float, optional
        Velocity below which dT/dx is not evaluated [m/s]. Default ``1e-4`` times the rms
        velocity of the window: it removes the reversals, where the solver's displacement error
        (``solver.atol`` ≈ 1e-12 m per 1e-5 s sample, i.e. 1e-7 m/s) is no longer small against
        the velocity, and keeps the creeping, stiff stick branch visible.

    Returns
    -------
    loop : FrictionLoop
    stiffness : ndarray, shape (n,)
        dT/dx [N/m]; NaN where ``|v| < v_guard``.
    v_guard : float
        The guard used [m/s].
    """
    loop = friction_loop(result, periods=periods)
    if loop.time.size < 2:
        raise ValueError("the analysis window holds fewer than two samples")
    if v_guard is None:
        v_guard = 1e-4 * rms(loop.velocity)
    dt = float(loop.time[1] - loop.time[0])
    k = global_tangential_stiffness(loop.friction, loop.displacement, loop.velocity, dt,
                                    v_guard=v_guard)
    return loop, k, float(v_guard)


@dataclass(frozen=True)
class StiffnessScale:
    """The linear ordinate of the tangential-stiffness panel (paper Fig. 9b), from its data.

    In slip dT/dx fluctuates about zero; in stick it is the stiff branch, an order of magnitude
    and more above, with spikes at the transitions. One axis cannot show both readably: the panel's
    axis covers the slip branch, and the stick branch is named by its median (the stick phases
    are shaded).

    Attributes
    ----------
    limit : float
        Half range of the ordinate [N/m]: the ``coverage`` quantile of ``|dT/dx|`` over the
        slip samples (1e3 N/m without any evaluated slip sample).
    coverage : float
        Share of the evaluated slip samples within ±``limit`` [-].
    stick_median : float
        Median dT/dx over the evaluated stick samples [N/m]; NaN without stick.
    beyond : float
        Share of all evaluated samples beyond ±``limit`` [-] (drawn cut at the frame).
    """

    limit: float
    coverage: float
    stick_median: float
    beyond: float


def stiffness_scale(stiffness: ArrayLike, stick: ArrayLike, *, coverage: float = 0.95
                    ) -> StiffnessScale:
    """The ordinate of the tangential-stiffness panel: the slip branch's range.

    Parameters
    ----------
    stiffness : array_like, shape (n,)
        dT/dx [N/m] (NaN where not evaluated), from :func:`tangential_stiffness`.
    stick : array_like of bool, shape (n,)
        Samples inside a stick phase.
    coverage : float
        Share of the slip samples the ordinate shows uncut, in (0, 1].

    Returns
    -------
    StiffnessScale
    """
    k = np.asarray(stiffness, dtype=float)
    st = np.asarray(stick, dtype=bool)
    if not 0.0 < coverage <= 1.0:
        raise ValueError(f"coverage must be in (0, 1], got {coverage}")
    ok = np.isfinite(k)
    slip = np.abs(k[ok & ~st])
    limit = float(np.quantile(slip, coverage)) if slip.size else 0.0
    if not limit > 0.0:
        limit = 1e3
    held = k[ok & st]
    evaluated = np.abs(k[ok])
    return StiffnessScale(limit=limit, coverage=coverage,
                          stick_median=float(np.median(held)) if held.size else math.nan,
                          beyond=float(np.mean(evaluated > limit)) if evaluated.size else 0.0)


def stick_slip_levels(result: Result, *, settle: float = 0.0) -> dict[str, dict[str, float]]:
    """rms vertical acceleration of block and plate during stick and during slip.

    The samples of the analysis window are split by the logged stick phases (paper Figs.
    10/11: "quiet during stick"). ``settle`` drops that many seconds at the start of each
    stick phase, so that the ring-down of the preceding slip does not count as stick
    response.

    Parameters
    ----------
    result : Result
    settle : float
        Time skipped at the start of each stick phase [s], >= 0.

    Returns
    -------
    dict
        ``{"block": {...}, "plate": {...}, "input_rate": {...}}`` each with ``stick_rms`` and
        ``slip_rms`` ([m/s^2] for the accelerations; [m/s] for ``input_rate``, the time
        derivative of the roughness input of each contact, rms over the contacts: the
        excitation itself), ``stick_minus_slip_db`` [dB] (NaN without stick samples), and
        ``stick_fraction``, the fraction of the window counted as stick.
    """
    if not settle >= 0:
        raise ValueError(f"settle must be >= 0 s, got {settle}")
    from roughvib.analysis.events import stick_intervals

    win = analysis_window(result)
    ds = result.dataset
    t = ds["time"].values[win]
    stick = np.zeros(t.size, dtype=bool)
    in_any = np.zeros(t.size, dtype=bool)
    for a, b in stick_intervals(result.events, float(ds["time"].values[-1])):
        in_any |= (t >= a) & (t < b)
        stick |= (t >= a + settle) & (t < b)
    slip = ~in_any
    # the excitation itself: rate of change of the roughness input, rms over the contacts
    r_in = ds["roughness_input"].values[win]
    rate = np.sqrt(np.mean(np.gradient(r_in, 1.0 / _fs(result), axis=0) ** 2, axis=1))
    out = {}
    for key, x in (("block", ds[ACCELERATIONS[0]].values[win]),
                   ("plate", ds[ACCELERATIONS[1]].values[win]), ("input_rate", rate)):
        st = rms(x[stick]) if stick.any() else math.nan
        sl = rms(x[slip]) if slip.any() else math.nan
        ratio = 20.0 * math.log10(st / sl) if st > 0 and sl > 0 else math.nan
        out[key] = {"stick_rms": st, "slip_rms": sl, "stick_minus_slip_db": ratio,
                    "stick_fraction": float(np.mean(stick))}
    return out


# --------------------------------------------------------------------------------------------
# spectra (Fig. 14)
# --------------------------------------------------------------------------------------------

def tapered_band_levels(x: ArrayLike, fs: float, *, fmin: float = 20.0, fmax: float = 50e3,
                        ref: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Third-octave band levels of a Hann-tapered record [dB re ref].

    The mean is removed, the whole record is multiplied by a periodic Hann window ``w`` and
    rescaled by ``1 / sqrt(mean(w**2))``, and the one-sided FFT bin powers are summed per IEC
    base-10 band (bin j in the band when ``lower <= f_j < upper``, as in
    :func:`roughvib.analysis.spectra.band_powers`). The rescaling keeps the mean square:
    the band powers of a stationary signal are unbiased, and they add up to the mean square
    of the tapered record (Parseval). The taper trades the rectangular window's 1/f^2 leakage
    for a main lobe of ±2 bins, so a band must hold a few bins: the record length ``n / fs``
    should exceed about ``4 / (0.23 fmin)`` (0.9 s for 20 Hz; bands holding fewer than 4 bins
    are NaN).

    Parameters
    ----------
    x : array_like, shape (n,)
        Signal [unit], uniformly sampled.
    fs : float
        Sampling rate [Hz].
    fmin, fmax : float
        Range of the nominal band centres [Hz]; bands above fs/2 are dropped.
    ref : float
        Reference of the levels [unit].

    Returns
    -------
    centres : ndarray, shape (n_bands,)
        Exact band centres [Hz].
    levels : ndarray, shape (n_bands,)
        [dB re ref]; NaN for bands with fewer than 4 FFT bins, -inf for zero power.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size < 8:
        raise ValueError(f"tapered_band_levels needs a 1-D record of >= 8 samples, got shape "
                         f"{x.shape}")
    return band_levels(x, fs, fmin=fmin, fmax=fmax, ref=ref, detrend="constant",
                       window="hann")


@dataclass(frozen=True)
class AccelerationSpectra:
    """Spectra of block and plate acceleration over the analysis window.

    Attributes
    ----------
    centres : ndarray, shape (n_bands,)
        Third-octave band centres [Hz].
    band_db : dict[str, ndarray]
        Band levels [dB re 1e-6 m/s^2] under the keys ``block``, ``plate`` and, with a noise
        floor, ``block_noisy``.
    frequency : ndarray, shape (n_f,)
        Narrow-band frequencies [Hz].
    psd_db : dict[str, ndarray]
        Welch densities [dB re (1e-6 m/s^2)^2/Hz], same keys.
    total_db : dict[str, float]
        Overall levels of the mean-removed window [dB re 1e-6 m/s^2], same keys.
    resolution : float
        Narrow-band bin spacing [Hz].
    noise_rms : float
        rms of the simulated accelerometer noise added to ``block_noisy`` [m/s^2] (0: none).
    window : tuple of float
        Start and end of the analysed samples [s].
    band_method : str
        How ``band_db`` was measured: ``"filter"`` (IEC 61260-1 filter bank) or ``"fft"``
        (Hann-tapered FFT band sums), see :func:`roughvib.analysis.bands.band_levels`.
    """

    centres: np.ndarray
    band_db: dict
    frequency: np.ndarray
    psd_db: dict
    total_db: dict
    resolution: float
    noise_rms: float
    window: tuple[float, float]
    band_method: str = "filter"


def acceleration_spectra(result: Result, *, resolution: float = 25.0,
                         noise_rms: float | None = None, noise_seed: int = 0,
                         fmin: float = 20.0, fmax: float = 50e3,
                         band_method: str = "filter") -> AccelerationSpectra:
    """Third-octave and narrow-band spectra of block and plate acceleration (paper Fig. 14).

    Both describe the analysis window (:func:`analysis_window`). Band levels:
    :func:`roughvib.analysis.bands.band_levels`. With ``band_method="filter"`` (default) the
    IEC 61260-1 class 1 filter bank runs over the record from its first sample to the end of
    the window and averages its outputs over the window only, so that the run-in settles the
    filters (started at the window, the bands' onset ringing would add up to 22 dB to the
    quiet bands of the ``paper`` scene); ``"fft"`` gives the Hann-tapered FFT band sums of the
    window (:func:`tapered_band_levels`). Narrow band:
    :func:`roughvib.analysis.spectra.narrowband_psd` (Welch, periodic Hann segments of
    ``fs / resolution`` samples, 50 % overlap).

    Parameters
    ----------
    result : Result
    resolution : float
        Narrow-band bin spacing [Hz] (25 Hz: 4000-sample segments at the 1e-5 s grid).
    noise_rms : float, optional
        rms [m/s^2] of white Gaussian noise (0 ... fs/2) added to the block acceleration as the
        electrical floor of the measuring chain the paper simulates in its Fig. 14 (1e-3 m/s^2 is
        an estimate of it, docs/theory.md). The clean block spectrum is kept as well.
    noise_seed : int
        Seed of that noise.
    fmin, fmax : float
        Range of band centres [Hz].
    band_method : {'filter', 'fft'}
        How the band levels are measured (see above).

    Returns
    -------
    AccelerationSpectra
    """
    if band_method not in ("filter", "fft"):
        raise ValueError(f"band_method must be 'filter' or 'fft', got {band_method!r}")
    win = analysis_window(result)
    fs = _fs(result)
    ds = result.dataset
    t = ds["time"].values[win]
    # the band filters see the record from its start; everything else sees the window
    first = 0 if band_method == "filter" else win.start
    span = slice(first, win.stop)
    signals = {"block": ds[ACCELERATIONS[0]].values[span],
               "plate": ds[ACCELERATIONS[1]].values[span]}
    noise = float(noise_rms or 0.0)
    if noise > 0:
        signals["block_noisy"] = add_noise_floor(signals["block"], fs, noise, noise_seed)
    settle = (win.start - first) / fs
    band, psd, tot = {}, {}, {}
    centres = frequency = None
    for key, x in signals.items():
        bl = filtered_band_levels(x, fs, fmin=fmin, fmax=fmax, method=band_method,
                                  settle=settle)
        centres, band[key] = bl.exact_hz, bl.level_db
        xw = x[win.start - first:]
        frequency, psd[key] = narrowband_psd(xw, fs, resolution=resolution, ref=1e-6)
        tot[key] = float(total_level(xw))
    return AccelerationSpectra(centres=centres, band_db=band, frequency=frequency, psd_db=psd,
                               total_db=tot, resolution=float(frequency[1] - frequency[0]),
                               noise_rms=noise, window=(float(t[0]), float(t[-1])),
                               band_method=band_method)


# --------------------------------------------------------------------------------------------
# contact resonance
# --------------------------------------------------------------------------------------------

def _contact_base_displacement(result: Result, win: slice) -> np.ndarray:
    """Mean vertical displacement of the surface under the closed contacts [m], positive down.

    Each closed spring obeys F_k = s_k (z - w_k - r_k) with r_k the roughness input, so the
    displacement of its base (plate plus roughness) is ``z - F_k / s_k``. Open contacts carry
    no information and are left out; samples with every contact open take the block's own
    displacement (no transmission).
    """
    ds = result.dataset
    K = int(ds.sizes["contact"])
    s_k = float(result.summary["model"]["contact_stiffness_total"]) / K
    F = ds["contact_force"].values[win]
    z = ds["block_vertical_displacement"].values[win]
    closed = F > 0
    n = closed.sum(axis=1)
    comp = np.where(closed, F / s_k, 0.0).sum(axis=1) / np.maximum(n, 1)
    return np.where(n > 0, z - comp, z)


def transmissibility(result: Result, *, resolution: float = 25.0
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Block/plate transfer across the contact springs: ``|T(f)|`` = sqrt(S_zz / S_uu).

    ``z`` is the block's vertical displacement and ``u`` the displacement of the surface under
    the closed contacts (plate plus roughness, from the contact forces; see the source). For
    a mass on springs this is the base-excitation transmissibility, 1 well below the contact
    resonance, peaking at it and falling as (f_c/f)^2 above. Welch spectra as in
    :func:`roughvib.analysis.spectra.narrowband_psd`.

    Parameters
    ----------
    result : Result
    resolution : float
        Bin spacing [Hz].

    Returns
    -------
    f : ndarray, shape (n_f,)
        [Hz]
    T : ndarray, shape (n_f,)
        ``|T|`` [-]; NaN where the base has no power.
    """
    win = analysis_window(result)
    fs = _fs(result)
    u = _contact_base_displacement(result, win)
    z = result.dataset["block_vertical_displacement"].values[win]
    f, Suu = narrowband_psd(u, fs, resolution=resolution)
    _, Szz = narrowband_psd(z, fs, resolution=resolution)
    with np.errstate(divide="ignore", invalid="ignore"):
        T = np.sqrt(np.where(Suu > 0, Szz / Suu, np.nan))
    return f, T


@dataclass(frozen=True)
class ContactResonance:
    """Estimates of the contact resonance [Hz] (None where the data show none).

    Attributes
    ----------
    spring_mass : float
        sqrt(s_closed / m) / 2 pi with s_closed the contact stiffness times the mean fraction
        of closed contacts (rigid plate, no roughness).
    transmissibility_peak : float or None
        Frequency of the maximum of :func:`transmissibility` between 0.3 and 3 times
        ``spring_mass``.
    transmissibility_max : float or None
        ``|T|`` at that peak [-].
    block_maximum, plate_maximum : float
        Centre of the loudest third-octave band of block and plate acceleration.
    crossover : float or None
        Frequency above which the block's band levels stay below the plate's up to 20 kHz
        (log-interpolated 0 dB crossing of L_block - L_plate); the paper's "mass below plate
        above the contact resonance". It is not itself an estimate of the resonance: it also
        depends on the block mass against the plate's point impedance.

    Notes
    -----
    The transmissibility needs closed contacts: with frequent lift-off its base motion (taken
    from the closed contacts only) is no longer the input of a linear system, and its peak
    can be meaningless. Band maxima are NaN when no band holds enough FFT bins.
    """

    spring_mass: float
    transmissibility_peak: float | None
    transmissibility_max: float | None
    block_maximum: float
    plate_maximum: float
    crossover: float | None


def _crossover(fc: np.ndarray, diff: np.ndarray, f_hi: float = 20e3) -> float | None:
    ok = np.isfinite(diff) & (fc <= f_hi)
    fc, diff = fc[ok], diff[ok]
    above = np.flatnonzero(diff >= 0.0)
    if above.size == 0 or above[-1] == fc.size - 1:
        return None
    i = int(above[-1])
    d0, d1 = diff[i], diff[i + 1]
    frac = d0 / (d0 - d1)
    return float(fc[i] * (fc[i + 1] / fc[i]) ** frac)


def contact_resonance(result: Result, *, spectra: AccelerationSpectra | None = None
                      ) -> ContactResonance:
    """Estimate the contact resonance of a run in four ways (see :class:`ContactResonance`).

    Parameters
    ----------
    result : Result
    spectra : AccelerationSpectra, optional
        Reuse already computed spectra (without noise floor).

    Returns
    -------
    ContactResonance
    """
    scene = scene_of(result)
    win = analysis_window(result)
    F = result.dataset["contact_force"].values[win]
    closed_fraction = float(np.mean(F > 0)) if F.size else 1.0
    s = float(result.summary["model"]["contact_stiffness_total"]) * closed_fraction
    f_sm = math.sqrt(s / scene.block.mass) / (2.0 * math.pi)
    f, T = transmissibility(result)
    sel = (f >= 0.3 * f_sm) & (f <= 3.0 * f_sm) & np.isfinite(T)
    if sel.any():
        j = int(np.argmax(T[sel]))
        f_t, t_max = float(f[sel][j]), float(T[sel][j])
    else:
        f_t = t_max = None
    sp = spectra if spectra is not None else acceleration_spectra(result)
    b, p = sp.band_db["block"], sp.band_db["plate"]

    def loudest(levels: np.ndarray) -> float:
        ok = np.isfinite(levels)
        return float(sp.centres[ok][np.argmax(levels[ok])]) if ok.any() else math.nan

    return ContactResonance(
        spring_mass=f_sm, transmissibility_peak=f_t, transmissibility_max=t_max,
        block_maximum=loudest(b), plate_maximum=loudest(p),
        crossover=_crossover(sp.centres, b - p))


# --------------------------------------------------------------------------------------------
# wavenumber spectra (Fig. 5)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ContactInputSpectra:
    """Wavenumber spectra of the global input profile and of one contact's stretch of it.

    Attributes
    ----------
    k_global, psd_global : ndarray
        Angular wavenumber [rad/m] and density [m^2/(rad/m)] of the whole profile (Welch).
    k_contact, psd_contact : ndarray
        The same for the stretch of profile the contact crossed in the analysis window (one
        Hann-windowed segment: its bin spacing is 2 pi / stretch length).
    stroke : float
        Peak-to-peak tangential displacement in the window [m] (the stretch length).
    contact : int
        Contact index.
    """

    k_global: np.ndarray
    psd_global: np.ndarray
    k_contact: np.ndarray
    psd_contact: np.ndarray
    stroke: float
    contact: int


def contact_input_spectra(result: Result, *, contact: int = 0) -> ContactInputSpectra:
    """Wavenumber spectra of the input profile and of the input seen by one contact (Fig. 5).

    The profile is rebuilt from the run's scene
    (:func:`roughvib.physics.surface.roughness.build_profile`). Contact ``k`` at profile coordinate
    ``s_k`` (dataset coordinate ``contact_profile_position``) runs over ``s_k + x(t)``; in the
    analysis window it sees the profile between ``s_k + min x`` and ``s_k + max x`` and nothing
    else. Wavelengths longer than that stretch (the peak-to-peak stroke) never reach it, which
    is the paper's cut-on of the "actual input".

    Parameters
    ----------
    result : Result
    contact : int
        Contact index.

    Returns
    -------
    ContactInputSpectra
    """
    from roughvib.physics.surface.roughness import build_profile

    scene = scene_of(result)
    ds = result.dataset
    K = int(ds.sizes["contact"])
    if not 0 <= contact < K:
        raise ValueError(f"contact must be in [0, {K - 1}], got {contact}")
    prof = build_profile(scene.roughness, scene.block, scene.base_dir)
    k_g, p_g = wavenumber_spectrum(prof.z, prof.dx)
    win = analysis_window(result)
    x = ds["block_tangential_displacement"].values[win]
    s_k = float(ds["contact_profile_position"].values[contact])
    i0 = int(math.floor((s_k + x.min() - prof.s0) / prof.dx))
    i1 = int(math.ceil((s_k + x.max() - prof.s0) / prof.dx)) + 1
    seg = prof.z[max(i0, 0):min(i1, prof.z.size)]
    if seg.size < 8:
        raise ValueError(f"contact {contact} crossed only {seg.size} profile samples "
                         f"(stroke {np.ptp(x):.3g} m, grid {prof.dx:.3g} m): too short for a "
                         f"spectrum")
    k_c, p_c = wavenumber_spectrum(seg, prof.dx, resolution=2.0 * np.pi / (seg.size * prof.dx))
    return ContactInputSpectra(k_global=k_g, psd_global=p_g, k_contact=k_c, psd_contact=p_c,
                               stroke=float(np.ptp(x)), contact=contact)


#: half the width of a third-octave band as a wavenumber ratio
_THIRD_HALF = 10.0 ** 0.05


@dataclass(frozen=True)
class SurfaceSpectrumView:
    """The axes of a surface report's spectrum figure (``spectrum.png``), from its data.

    Both panels run over angular wavenumber (increasing to the right) across the bands where
    the profile has content; the band levels and the narrow-band density are shown down to a
    floor below that content, not down to the numerical floor of emptied bands (about -300
    dB) or of the density beyond the shortest wavelength (down to 1e-36 m^2/(rad/m)).

    Attributes
    ----------
    k_range : (float, float)
        Wavenumbers shown [rad/m]: the content bands' edges, one third octave wider.
    level_range : (float, float)
        Band levels shown [dB re 1 µm]: from ``margin_db`` below the lowest content band of
        the whole profile to 5 dB above the highest level.
    psd_range : (float, float)
        Densities shown [m^2/(rad/m)]: from ``decades`` below the lowest band average of the
        density over the content bands to 3 times its highest value.
    margin_db : float
        Decibels shown below the lowest content band.
    decades : float
        Decades shown below the density's lowest band average.
    content : ndarray of bool, shape (n_bands,)
        The content bands: a finite level of the whole profile within ``span_db`` of its
        highest band.
    """

    k_range: tuple[float, float]
    level_range: tuple[float, float]
    psd_range: tuple[float, float]
    margin_db: float
    decades: float
    content: np.ndarray


def surface_spectrum_view(k_bands: ArrayLike, levels: ArrayLike, k_psd: ArrayLike,
                          psd: ArrayLike, *, others: Iterable[ArrayLike] = (),
                          span_db: float = 60.0, margin_db: float = 10.0,
                          decades: float = 3.0) -> SurfaceSpectrumView:
    """The ranges a surface spectrum figure shows: where the profile's spectrum lives.

    Parameters
    ----------
    k_bands : array_like, shape (n_bands,)
        Centre wavenumbers of the third-octave bands [rad/m].
    levels : array_like, shape (n_bands,)
        Band levels of the whole profile [dB re 1 µm] (NaN or very low where a band is empty).
    k_psd, psd : array_like, shape (n,)
        Narrow-band wavenumber [rad/m] and density [m^2/(rad/m)] of the profile.
    others : iterable of array_like, shape (n_bands,)
        Further band levels drawn in the same panel (their highest level sets the top).
    span_db : float
        A band within ``span_db`` of the highest is content.
    margin_db : float
        Shown below the lowest content band [dB].
    decades : float
        Decades of density shown below its lowest band average over the content bands.

    Returns
    -------
    SurfaceSpectrumView
    """
    kb = np.asarray(k_bands, dtype=float)
    lev = np.asarray(levels, dtype=float)
    k = np.asarray(k_psd, dtype=float)
    p = np.asarray(psd, dtype=float)
    finite = np.isfinite(lev)
    if not finite.any():
        raise ValueError("no band of the profile has a finite level")
    content = finite & (lev >= np.max(lev[finite]) - span_db)
    k_lo = float(kb[content].min()) / _THIRD_HALF**3
    k_hi = float(kb[content].max()) * _THIRD_HALF**3
    top = max([float(np.max(lev[finite]))]
              + [float(np.nanmax(o)) for o in map(np.asarray, others)
                 if np.isfinite(o).any()])
    level_range = (float(np.min(lev[content])) - margin_db, top + 5.0)
    means = []
    for kc in kb[content]:
        sel = (k >= kc / _THIRD_HALF) & (k < kc * _THIRD_HALF) & (p > 0)
        if sel.any():
            means.append(float(np.mean(p[sel])))
    shown = (k >= k_lo) & (k <= k_hi) & (p > 0)
    if not means or not shown.any():
        raise ValueError("the narrow-band density has no positive value in the content bands")
    psd_range = (min(means) * 10.0**-decades, 3.0 * float(np.max(p[shown])))
    return SurfaceSpectrumView(k_range=(k_lo, k_hi), level_range=level_range,
                               psd_range=psd_range, margin_db=margin_db, decades=decades,
                               content=content)


# --------------------------------------------------------------------------------------------
# velocity sweep
# --------------------------------------------------------------------------------------------

def velocity_sweep(results: Iterable[Result]) -> tuple[pd.DataFrame, dict[str, VelocityExponent]]:
    """Overall acceleration levels over friction velocity, and their velocity exponents.

    Parameters
    ----------
    results : iterable of Result
        Runs that differ in friction velocity (at least two distinct ones).

    Returns
    -------
    table : DataFrame
        One row per run, sorted by velocity: ``scene``, ``v_rms`` [m/s], ``block_db`` and
        ``plate_db`` [dB re 1e-6 m/s^2] (the summary's rms levels over whole periods),
        ``stick_fraction``.
    exponents : dict
        ``block`` and ``plate`` -> :class:`~roughvib.analysis.levels.VelocityExponent`
        (dB per doubling and the power-basis exponent).
    """
    rows = []
    for r in results:
        m = r.summary.get("metrics", {})
        rows.append({"scene": r.summary.get("scene"),
                     "v_rms": m.get("block_tangential_velocity_rms"),
                     "block_db": m.get("block_vertical_acceleration_level_db_re_1e-6"),
                     "plate_db": m.get("plate_vertical_acceleration_level_db_re_1e-6"),
                     "stick_fraction": m.get("stick_fraction")})
    table = pd.DataFrame(rows).sort_values("v_rms", ignore_index=True)
    fits = {key: velocity_exponent(table["v_rms"], table[f"{key}_db"])
            for key in ("block", "plate")}
    return table, fits
