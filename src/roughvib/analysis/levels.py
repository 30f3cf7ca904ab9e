"""Scalar levels, analysis windows and friction-loop helpers.

This module owns the one-number reductions of a result: rms and dB levels, the velocity
exponent of levels over a velocity sweep (docs/theory.md), the stick fraction, the
whole-period analysis window, the global tangential stiffness dT/dx of the friction loop
(paper Fig. 9b), and the note that a synthetic-roughness run's levels are one random draw.
"""

from __future__ import annotations

import math
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["VelocityExponent", "global_tangential_stiffness", "level_db", "rms",
           "single_draw_note", "stick_fraction", "velocity_exponent", "whole_period_window"]

_DB_PER_DOUBLING_POWER = 10.0 * math.log10(2.0)      # 3.0103 dB per doubling for n = 1, power
_DB_PER_DOUBLING_AMPLITUDE = 20.0 * math.log10(2.0)  # 6.0206 dB per doubling for n = 1, amplitude


def rms(x: ArrayLike) -> float:
    """Root mean square of a signal, ``sqrt(mean(x**2))`` (no mean removed).

    Parameters
    ----------
    x : array_like, shape (n,) or any
        Samples [unit]; all of them are used (a NaN gives NaN rather than being skipped).

    Returns
    -------
    float
        rms [unit].
    """
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        raise ValueError("rms of an empty signal")
    return float(np.sqrt(np.mean(x * x)))


def single_draw_note(summary: dict) -> str | None:
    """The caveat to print next to the levels of a run on synthetic roughness.

    A synthetic profile is one random draw (``roughness.seed``); the levels of other draws
    differ by more than the solver error. No spread is invented for a single run: the note
    names the command that measures it, from what the user ran (``run_command`` of the
    summary, written by ``roughvib run``: the scene as given and its ``--set`` options), or
    else from the run directory's saved scene.

    Parameters
    ----------
    summary : dict
        A run's ``summary.json``.

    Returns
    -------
    str or None
        One sentence, or None when the roughness is not random (``none``, ``sinusoid``,
        ``file``).
    """
    prof = summary.get("model", {}).get("profile", {})
    if prof.get("kind") != "synthetic":
        return None
    command = summary.get("run_command")
    if not isinstance(command, str) or not command.startswith("roughvib run"):
        # a run not made by 'roughvib run' (the Python API, a sweep case): its saved scene
        # repeats it (a synthetic draw's contact and calibration do not depend on the seed)
        command = "roughvib run RUN_DIR/scene.toml"
    return (f"one draw of a random surface (roughness.seed = {prof.get('seed')}); "
            f"seed-to-seed spread: {command} --seeds 10")


def level_db(x_rms: float, ref: float = 1e-6) -> float:
    """Level ``20 log10(x_rms / ref)`` [dB re ref]; ``-inf`` for a zero rms.

    Parameters
    ----------
    x_rms : float
        rms value [unit], >= 0.
    ref : float
        Reference [unit]; 1e-6 (m/s^2) by default.
    """
    if not ref > 0:
        raise ValueError(f"ref must be > 0, got {ref}")
    if x_rms < 0 or math.isnan(x_rms):
        raise ValueError(f"an rms value must be >= 0, got {x_rms}")
    return 20.0 * math.log10(x_rms / ref) if x_rms > 0 else -math.inf


class VelocityExponent(NamedTuple):
    """Fit of level against log2(velocity); see :func:`velocity_exponent`."""

    db_per_doubling: float
    """Slope [dB per doubling of the velocity] (independent of the basis)."""
    exponent: float
    """Exponent n on the chosen basis [-]."""
    stderr: float
    """Standard error of ``db_per_doubling`` [dB]; NaN with only two velocities."""


def velocity_exponent(velocities: ArrayLike, levels_db: ArrayLike, *,
                      basis: Literal["power", "amplitude"] = "power") -> VelocityExponent:
    """Least-squares fit ``L = c + s log2(v)`` of levels over a velocity sweep.

    The slope ``s`` [dB per doubling] is the robust number to compare. The exponent follows
    from it and depends on what is said to scale as v**n:

    * ``basis='power'`` (default, the paper's reading, docs/theory.md): the mean square
      ``a**2 ∝ v**n``, ``L = 10 log10 a**2 + c``, so ``n = s / (10 log10 2) = s / 3.01``; the
      paper's "3 to 3.5" is 9 to 10.5 dB per doubling.
    * ``basis='amplitude'``: ``a ∝ v**n``, ``n = s / (20 log10 2) = s / 6.02`` (half the
      power-basis value).

    Parameters
    ----------
    velocities : array_like, shape (m,)
        Friction velocities (e.g. v_rms [m/s]), > 0, at least two distinct values.
    levels_db : array_like, shape (m,)
        Levels [dB re any fixed reference].
    basis : {'power', 'amplitude'}
        Basis of the returned exponent.

    Returns
    -------
    VelocityExponent
        ``(db_per_doubling, exponent, stderr)``; the standard error of the slope is the usual
        ordinary-least-squares one, ``sqrt(RSS / (m - 2) / sum((x - mean x)**2))`` with
        ``x = log2 v``.
    """
    v = np.asarray(velocities, dtype=float).ravel()
    y = np.asarray(levels_db, dtype=float).ravel()
    if v.shape != y.shape:
        raise ValueError(f"velocities and levels_db differ in length: {v.size} vs {y.size}")
    if np.any(~(v > 0)) or not np.all(np.isfinite(y)):
        raise ValueError("velocity_exponent needs velocities > 0 and finite levels")
    if basis not in ("power", "amplitude"):
        raise ValueError(f"basis must be 'power' or 'amplitude', got {basis!r}")
    x = np.log2(v)
    sxx = float(np.sum((x - x.mean()) ** 2))
    if v.size < 2 or sxx == 0.0:
        raise ValueError("velocity_exponent needs at least two distinct velocities")
    s = float(np.sum((x - x.mean()) * (y - y.mean())) / sxx)
    resid = y - y.mean() - s * (x - x.mean())
    dof = v.size - 2
    se = math.sqrt(float(np.sum(resid**2)) / dof / sxx) if dof > 0 else math.nan
    per_unit = _DB_PER_DOUBLING_POWER if basis == "power" else _DB_PER_DOUBLING_AMPLITUDE
    return VelocityExponent(s, s / per_unit, se)


def stick_fraction(v: ArrayLike, threshold: float) -> float:
    """Fraction of samples in stick, ``|v| < threshold`` [-].

    Parameters
    ----------
    v : array_like, shape (n,)
        Relative tangential (slip) velocity on a uniform grid [m/s]. NaN samples (a failed
        stretch of a run) are left out of both counts.
    threshold : float
        Stick velocity [m/s], > 0 (``friction.stick_velocity``).

    Returns
    -------
    float
        Stick fraction in [0, 1]; NaN if there is no finite sample.
    """
    if not threshold > 0:
        raise ValueError(f"stick threshold must be > 0 m/s, got {threshold}")
    v = np.asarray(v, dtype=float)
    ok = np.isfinite(v)
    if not ok.any():
        return math.nan
    return float(np.count_nonzero(np.abs(v[ok]) < threshold) / np.count_nonzero(ok))


def whole_period_window(t: ArrayLike, period: float, transient: float) -> slice:
    """Index window holding the largest whole number of periods after a run-in.

    The window starts at the first sample with ``t >= transient`` and holds
    ``round(N period / dt)`` samples, N the largest integer with ``N period`` no longer than
    the rest of the record (counting each sample as dt long, so a record of exactly N periods
    sampled at ``t_i = i dt`` fits N). A spectrum over this window sees whole excitation
    cycles, without a partial one biasing the stick/slip mix.

    Parameters
    ----------
    t : array_like, shape (n,)
        Uniform, increasing time grid [s].
    period : float
        Excitation period [s]; 0 or inf means "no periodicity": everything after the run-in.
    transient : float
        Run-in to skip [s], <= t[-1].

    Returns
    -------
    slice
        ``t[window]`` covers ``[transient, transient + N period)``. If not one whole period
        fits, the whole record after the run-in.

    Raises
    ------
    ValueError
        If the run-in is longer than the record (callers decide what to do then).
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError("whole_period_window needs a non-empty 1-D time grid")
    dt = float(t[1] - t[0]) if t.size > 1 else 0.0
    tol = 1e-9 * max(dt, abs(float(t[-1])), 1e-300)
    if transient > t[-1] + tol:
        raise ValueError(f"transient ({transient} s) is longer than the record "
                         f"(ends at {t[-1]} s)")
    i0 = int(np.searchsorted(t, transient - tol))
    if not math.isfinite(period) or period <= 0 or dt <= 0:
        return slice(i0, t.size)
    n_samples = t.size - i0
    n_per = math.floor(n_samples * dt / period + 1e-9)
    if n_per < 1:
        return slice(i0, t.size)
    return slice(i0, min(i0 + int(round(n_per * period / dt)), t.size))


def global_tangential_stiffness(friction: ArrayLike, displacement: ArrayLike,
                                velocity: ArrayLike | None, dt: float, *,
                                v_guard: float) -> np.ndarray:
    """Global tangential stiffness dT/dx along a friction loop (paper Fig. 9b) [N/m].

    Both derivatives are central differences on the same time grid (one-sided at the ends,
    ``numpy.gradient``), and the stiffness is their ratio
    ``(dT/dt) / (dx/dt)``; a friction force that is a linear function of the displacement
    therefore returns its slope exactly. Near a reversal dx/dt passes through zero and the
    ratio means nothing, so samples with ``|v| < v_guard`` are NaN (in stick the stiffness is
    the steep branch; the guard decides how much of it is shown).

    Parameters
    ----------
    friction : array_like, shape (n,)
        Friction (tangential contact) force T [N].
    displacement : array_like, shape (n,)
        Tangential displacement x of the block relative to the plate [m].
    velocity : array_like, shape (n,) or None
        Relative tangential velocity [m/s], used for the guard only; None takes dx/dt.
    dt : float
        Sample spacing [s].
    v_guard : float
        Velocity below which the stiffness is not defined [m/s], >= 0.

    Returns
    -------
    ndarray, shape (n,)
        dT/dx [N/m]; NaN where ``|v| < v_guard`` or where dx/dt is exactly 0.
    """
    if not dt > 0:
        raise ValueError(f"dt must be > 0 s, got {dt}")
    if not v_guard >= 0:
        raise ValueError(f"v_guard must be >= 0 m/s, got {v_guard}")
    T = np.asarray(friction, dtype=float)
    x = np.asarray(displacement, dtype=float)
    if T.shape != x.shape or T.ndim != 1 or T.size < 2:
        raise ValueError(f"friction and displacement must be 1-D of the same length >= 2, got "
                         f"shapes {T.shape} and {x.shape}")
    dT = np.gradient(T, dt)
    dx = np.gradient(x, dt)
    v = dx if velocity is None else np.asarray(velocity, dtype=float)
    if v.shape != T.shape:
        raise ValueError(f"velocity must have shape {T.shape}, got {v.shape}")
    out = np.full(T.shape, np.nan)
    ok = (np.abs(v) >= v_guard) & (dx != 0.0)
    out[ok] = dT[ok] / dx[ok]
    return out
