"""The tangential-only reference model and the calibration of the force amplitude T0.

The block under a constant normal force, no roughness, driven by ``T0 cos(omega t)``: each law
declares the model it is calibrated in (``FrictionLaw.tangential``): the Feldmann law's
trapezoidal step with its latch, the set-valued laws' Moreau-Jean step with exact stick
(``setvalued.tangential_set_valued``), a dynamic law's own step on velocity and states.
:func:`calibrate_force_amplitude`
finds the T0 whose steady rms velocity is ``excitation.target_rms_velocity``, and
:func:`calibrated_force_amplitude` keeps each result in the on-disk cache of
``roughvib._cache``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from roughvib._cache import cached_values, code_fingerprint
from roughvib.physics.friction.laws import LAWS, model_keys
from roughvib.physics.friction.table import TAB_HEAD, TAB_N
from roughvib.scene import Friction

__all__ = ["calibrate_force_amplitude", "calibrated_force_amplitude", "law_parameters",
           "rms_over_periods", "simulate_tangential"]

#: the files whose code decides a calibration (the cache's fingerprint)
_CODE = sorted(Path(__file__).parent.glob("*.py"))


def law_parameters(friction: Friction) -> tuple[float, float, float, float]:
    """``(mu_slip, mu_stick, a1, a2)`` of the Feldmann law's model of a
    :class:`~roughvib.scene.Friction` as floats (a1, a2: the section's own for the Feldmann
    law, that law's defaults otherwise)."""
    par = model_keys(friction, "feldmann")
    return (float(friction.mu_slip), float(friction.mu_stick), float(par["a1"]),
            float(par["a2"]))


def simulate_tangential(T0: float, mass: float, r2: float, normal_force: float, omega: float,
                        friction: Friction, duration: float, dt: float = 1e-6,
                        table: np.ndarray | None = None,
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tangential-only block under a constant normal force (docs/theory.md).

    The model is the one the law declares (``LAWS[law].tangential``): the Feldmann law as
    described next; a set-valued law by the backward-Euler (Moreau-Jean) step with exact stick
    (``setvalued.tangential_set_valued``), first order in ``dt``; a dynamic law by its own step on
    velocity and internal states.

    ``m v' = T0 cos(omega t) - mu(v + s v_h) F_N - r2 v``, ``x' = v``, from rest at t = 0 with
    the latch on the accelerating branch (``s = -1``, running maximum 0). The regularised law is
    stiff (slope ~ mu_stick a2 F_N), so each step is the trapezoidal rule (second order,
    A-stable) solved for v by Newton; the latch is updated after each step with
    epsilon_v = max(latch_velocity, hysteresis_velocity) (``friction.parameters``).

    Parameters
    ----------
    T0 : float
        Force amplitude [N].
    mass : float
        Block mass m [kg].
    r2 : float
        Tangential viscous damping [N s/m].
    normal_force : float
        Constant normal force F_N [N] (m g for the paper's block).
    omega : float
        Excitation angular frequency [rad/s].
    friction : Friction
        Law parameters.
    duration : float
        Simulated time [s].
    dt : float, optional
        Fixed step [s]; keep dt well below m / (mu_stick a2 F_N) (~1.3e-5 s for the defaults).
    table : ndarray, optional
        The packed kinetic curve of the ``table`` law (``table.law_table``).

    Returns
    -------
    t, v, x : ndarray, shape (n + 1,)
        Time [s], velocity [m/s] and displacement [m] on the grid t = k dt,
        n = ceil(duration / dt).
    """
    if not (dt > 0.0 and duration > 0.0):
        raise ValueError(f"dt and duration must be > 0 s, got dt={dt}, duration={duration}")
    if mass <= 0.0:
        raise ValueError(f"mass must be > 0 kg, got {mass}")
    # the grid covers the whole duration (t[-1] >= duration up to round-off)
    n = int(math.ceil(duration / dt - 1e-9))
    v = np.empty(n + 1)
    x = np.empty(n + 1)
    LAWS[friction.law].tangential(float(T0), float(mass), float(r2), float(normal_force),
                                  float(omega), friction, float(dt), n, v, x, table)
    t = np.arange(n + 1) * dt
    return t, v, x


def rms_over_periods(t: np.ndarray, v: np.ndarray, period: float, transient: float) -> float:
    """Rms of ``v`` over the largest whole number of periods after ``transient``.

    The mean square is the trapezoidal integral of v^2 over [transient, transient + n period],
    the window ends linearly interpolated, so the result is second-order accurate in the grid
    spacing (and independent of how the period falls on the grid).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Increasing times [s].
    v : ndarray, shape (n,)
        Samples [any unit].
    period : float
        Averaging period [s].
    transient : float
        Start of the window [s].

    Returns
    -------
    float
        Rms [unit of v].

    Raises
    ------
    ValueError
        Less than one whole period after ``transient``.
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    if period <= 0.0 or t.size < 2:
        raise ValueError(f"period must be > 0 s and t must have >= 2 samples, got {period}")
    # a window end up to half a grid step past the last sample is clipped to it
    slack = 0.5 * (t[-1] - t[0]) / (t.size - 1)
    n_per = int(math.floor((t[-1] + slack - transient) / period))
    if n_per < 1 or transient < t[0]:
        raise ValueError(f"need at least one whole period ({period} s) between transient "
                         f"({transient} s) and the end ({t[-1]} s)")
    ta = transient
    tb = min(transient + n_per * period, t[-1])
    inside = (t > ta) & (t < tb)
    tt = np.concatenate(([ta], t[inside], [tb]))
    vv = np.concatenate(([np.interp(ta, t, v)], v[inside], [np.interp(tb, t, v)]))
    return float(math.sqrt(np.trapezoid(vv * vv, tt) / (tb - ta)))


def _steady_rms(T0, mass, r2, normal_force, omega, friction, transient_periods, periods, dt,
                table=None):
    period = 2.0 * math.pi / omega
    t, v, _ = simulate_tangential(T0, mass, r2, normal_force, omega, friction,
                                  (transient_periods + periods) * period, dt, table)
    return rms_over_periods(t, v, period, transient_periods * period)


class _Converged(Exception):
    def __init__(self, T0: float) -> None:
        super().__init__(T0)
        self.T0 = T0


def calibrate_force_amplitude(target_rms: float, mass: float, r2: float, normal_force: float,
                              omega: float, friction: Friction, *, transient_periods: int = 3,
                              periods: int = 2, rtol: float = 1e-3, dt: float = 1e-6,
                              table: np.ndarray | None = None) -> float:
    """Force amplitude T0 whose steady-state rms velocity in the tangential model is the target.

    The rms over ``periods`` whole periods after ``transient_periods`` periods of
    :func:`simulate_tangential` increases monotonically with T0, so T0 is the root of
    ``rms(T0) / target - 1`` (Brent's method, stopped once the rms is within ``rtol`` of the
    target).

    Bracket: with V = sqrt(2) target and Z = r2 + i m omega the mass-damper impedance,
    ``T_lo = |Z| V`` is the amplitude the frictionless system needs, and friction only adds
    resistance, so rms(T_lo) <= target. ``T_hi = |Z| V + (4/pi) mu_stick F_N`` adds the largest
    first-harmonic amplitude a friction force bounded by mu_stick F_N can have (describing function
    of a relay). Both ends are checked and widened geometrically if the estimate fails.

    Parameters
    ----------
    target_rms : float
        Target rms velocity [m/s].
    mass, r2, normal_force, omega : float
        As in :func:`simulate_tangential` [kg, N s/m, N, rad/s].
    friction : Friction
    transient_periods, periods : int, optional
        Periods discarded and averaged.
    rtol : float, optional
        Relative tolerance on the rms velocity.
    dt : float, optional
        Time step [s].
    table : ndarray, optional
        The packed kinetic curve of the ``table`` law (``table.law_table``).

    Returns
    -------
    float
        T0 [N].
    """
    if target_rms <= 0.0:
        raise ValueError(f"target_rms must be > 0 m/s, got {target_rms}")
    # |mu| <= mu_slip + (mu_stick - mu_slip) e^(-a1 |X|) <= mu_stick for every X
    mu_max = max(float(friction.mu_stick), float(friction.mu_slip))
    if LAWS[friction.law].calibration == "set-valued" and table is not None and table.size:
        # a tabulated kinetic curve: its largest coefficient
        n_tab = int(table[TAB_N])
        mu_max = max(mu_max, float(np.max(table[TAB_HEAD + n_tab:TAB_HEAD + 2 * n_tab])))

    def g(T0: float) -> float:
        r = _steady_rms(T0, mass, r2, normal_force, omega, friction, transient_periods,
                        periods, dt, table) / target_rms - 1.0
        if abs(r) <= rtol:
            raise _Converged(T0)
        return r

    amp = math.sqrt(2.0) * target_rms
    lo = amp * math.hypot(r2, mass * omega)
    hi = lo + 4.0 / math.pi * mu_max * normal_force
    try:
        g_lo = g(lo)
        while g_lo >= 0.0 and lo > 1e-12 * hi:
            lo *= 0.25
            g_lo = g(lo)
        g_hi = g(hi)
        while g_hi <= 0.0 and hi < 1e6 * lo:
            lo, g_lo = hi, g_hi
            hi *= 1.5
            g_hi = g(hi)
        if not (g_lo < 0.0 < g_hi):
            raise RuntimeError(f"no bracket for target_rms={target_rms} m/s found "
                               f"(T0 in [{lo}, {hi}] N)")
        from scipy.optimize import brentq

        return float(brentq(g, lo, hi, xtol=1e-9 * hi, rtol=1e-12, maxiter=100))
    except _Converged as c:
        return c.T0


def calibrated_force_amplitude(target_rms: float, mass: float, r2: float, normal_force: float,
                               omega: float, friction: Friction,
                               table: np.ndarray | None = None) -> tuple[float, str]:
    """:func:`calibrate_force_amplitude` at its default settings, through the on-disk cache.

    The calibration integrates the tangential model about ten times (about a second); its
    result depends only on the arguments, the friction law's parameters and this module's code,
    so it is stored once per distinct input (``roughvib._cache``: exact floats, keyed by the
    inputs, this file's SHA-256 and the library versions) and read back by later runs.

    Parameters
    ----------
    target_rms, mass, r2, normal_force, omega, friction, table
        As in :func:`calibrate_force_amplitude` [m/s, kg, N s/m, N, rad/s].

    Returns
    -------
    T0 : float
        Force amplitude [N], bit-identical to ``calibrate_force_amplitude(...)``.
    cache : {"hit", "miss", "off"}
        Read from the cache, computed now, or computed with the cache switched off
        (``ROUGHVIB_CACHE=off``).
    """
    model = LAWS[friction.law].calibration
    inputs = {"target_rms": float(target_rms), "mass": float(mass), "r2": float(r2),
              "normal_force": float(normal_force), "omega": float(omega),
              "mu_slip": float(friction.mu_slip), "mu_stick": float(friction.mu_stick),
              "law": friction.law, "model": model}
    # the numbers of the keys the model reads (a file by its packed curve's hash, below)
    keys = model_keys(friction, model if model in LAWS else friction.law)
    inputs.update({f"parameters.{k}": float(v) for k, v in sorted(keys.items())
                   if isinstance(v, int | float) and not isinstance(v, bool)})
    if table is not None and table.size:
        import hashlib

        inputs["table_sha256"] = hashlib.sha256(
            np.ascontiguousarray(table, dtype=float).tobytes()).hexdigest()

    def compute() -> dict[str, float]:
        return {"T0": calibrate_force_amplitude(target_rms, mass, r2, normal_force, omega,
                                                friction, table=table)}

    values, status = cached_values("force-calibration", inputs, compute,
                                   code=code_fingerprint(_CODE))
    return values["T0"], status
