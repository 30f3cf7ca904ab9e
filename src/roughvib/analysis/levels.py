"""Scalar levels and windows: rms, dB levels, stick fraction, whole-period analysis windows."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["level_db", "rms", "stick_fraction", "velocity_exponent", "whole_period_window"]


def rms(x: np.ndarray) -> float:
    """Root mean square of a signal (NaNs are an error, not ignored)."""
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        raise ValueError("rms of an empty signal")
    return float(np.sqrt(np.mean(x * x)))


def level_db(x_rms: float, ref: float = 1e-6) -> float:
    """20 log10(x_rms / ref) [dB re ref] (default reference 1e-6 m/s^2)."""
    return 20.0 * math.log10(x_rms / ref) if x_rms > 0 else -math.inf


def stick_fraction(v: np.ndarray, threshold: float) -> float:
    """Fraction of samples with |v| < threshold [-]."""
    v = np.asarray(v, dtype=float)
    return float(np.mean(np.abs(v) < threshold)) if v.size else math.nan


def whole_period_window(t: np.ndarray, period: float, transient: float) -> slice:
    """Index window of the largest whole number of periods that starts at ``transient``.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Uniform time grid [s].
    period : float
        Excitation period [s]; 0 or inf means "no periodicity": everything after the transient.
    transient : float
        Run-in to skip [s].

    Returns
    -------
    slice
        Covers ``[transient, transient + N period)``; if not one whole period fits, the whole
        record after the transient.
    """
    t = np.asarray(t, dtype=float)
    i0 = int(np.searchsorted(t, transient - 1e-12))
    if i0 >= t.size:
        return slice(0, t.size)
    if not math.isfinite(period) or period <= 0:
        return slice(i0, t.size)
    dt = t[1] - t[0] if t.size > 1 else period
    n_per = int(math.floor((t[-1] - t[i0] + dt) / period + 1e-9))
    if n_per < 1:
        return slice(i0, t.size)
    i1 = i0 + int(round(n_per * period / dt))
    return slice(i0, min(i1, t.size))


def velocity_exponent(velocities, levels_db) -> tuple[float, float, float]:
    """Fit level = c + s log2(v): returns (s dB per doubling, exponent n = s / 6.02, stderr).

    The exponent is on an amplitude basis (level 20 log10 of an amplitude proportional to v^n
    rises 6.02 n dB per doubling). The paper's "3-3.5" is on a power basis (3.01 n dB per
    doubling, physics.md §6.1): compare dB per doubling, not the exponents.
    """
    x = np.log2(np.asarray(velocities, dtype=float))
    y = np.asarray(levels_db, dtype=float)
    if x.size < 2:
        raise ValueError("velocity_exponent needs at least two velocities")
    A = np.column_stack([x, np.ones_like(x)])
    coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
    s = float(coef[0])
    dof = x.size - 2
    if dof > 0:
        sigma2 = float(np.sum((y - A @ coef) ** 2)) / dof
        se = math.sqrt(sigma2 / float(np.sum((x - x.mean()) ** 2)))
    else:
        se = math.nan
    return s, s / (20 * math.log10(2)), se
