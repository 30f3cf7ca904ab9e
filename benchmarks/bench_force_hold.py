"""Benchmark: what limits one exact-modal step per output interval -- the coupling or the hold?

Run on demand, not by the tests:

    python benchmarks/bench_force_hold.py                         # paper, reference made here
    python benchmarks/bench_force_hold.py paper --reference RUN   # reuse a converged run

At one step per output interval with the contact force held linear over the step, the ``paper``
plate's 10 kHz band is about 0.27 dB low (docs/performance.md, "What limits a step of one output
interval"); propagating the coupled modes of block, contact springs and plate exactly is one
conceivable cure. This benchmark separates the two errors a step of exact modal propagation can
make -- the coupling of the modes through the contact, and the hold (the polynomial in time) of
what drives them over the step -- on the vertical problem alone:

* the tangential motion is prescribed, taken from a converged run (the ``reference``: the
  adaptive-modal solver at rtol 1e-9, atol 1e-14 m, atol_acceleration 1e-11 m/s^2, as in
  docs/accuracy.md), so the roughness input ``u_k(t) = h(s_k + x(t))`` and its rate
  ``h'(s_k + x) x'`` are known at any time (x through a cubic spline of the run's grid);
* every contact stays closed (the scene must have no lift-off in the run), so the vertical
  problem is linear;
* four schemes take one or two steps per output interval and are compared with the reference,
  band by band (:func:`roughvib.analysis.accuracy.band_deviations`, the contract's bands):

  - ``modes, linear F``: each plate mode and the block propagated exactly as a damped
    oscillator, the contact force held linear over the step, the contact relation
    ``(1/s + C) F = z - w + u`` imposed at the step's end: the vertical part of the
    fixed-step ``exact-modal`` scheme and of ``adaptive-modal``'s steps;
  - ``modes, Hermite F``: the same, the force held by the cubic through its values *and
    rates* at both ends, the relation and its time derivative imposed at the end;
  - ``coupled, linear u`` / ``coupled, Hermite u``: the coupled modes of the first-order
    system (block, closed contacts, plate modes; a dense eigendecomposition) propagated
    exactly, only the roughness input held (linear, or the cubic through u and u').

A second table then couples the tangential motion back in (the Feldmann law's friction on the
normal force, the roughness input at the block's own position), so that the whole step is
tested, still with one step per output interval: the vertical part as above (``modes``), the
tangential motion by the trapezoidal rule (adaptive-modal's trapezoidal step) or by its
fourth-order Hermite counterpart (the Obreschkoff (2,2) formula, which takes the acceleration
*and its rate* at both ends: ``x1 = x0 + h (v0 + v1) / 2 + h^2 (a0 - a1) / 12``, ``v1 = v0 + h
(a0 + a1) / 2 + h^2 (a0' - a1') / 12``). The friction law's regime (branch, latch) is switched
at the converged run's event times, which the steps meet exactly: the events' location is not
what is measured here.

Last, how step doubling would judge the fourth-order step (:func:`doubling_estimates`): along
the Hermite run, at every pair of output intervals without an event, one step over the pair
against the two steps of one, the estimate measured in ``adaptive-modal``'s weights at the
tolerances of a default run of the scene (made here, its pilot included).

The time of the eigendecomposition is reported with one BLAS thread (on a 2-core machine a
threaded OpenBLAS took 20 times longer for it). The loops are numpy, not compiled: their CPU
times compare accuracy, not speed.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from typing import NamedTuple  # noqa: E402

import numpy as np  # noqa: E402
from scipy.interpolate import CubicSpline  # noqa: E402
from scipy.optimize import newton  # noqa: E402

from roughvib.analysis.accuracy import analysis_window, band_deviations  # noqa: E402
from roughvib.model import kernels as kn  # noqa: E402
from roughvib.model.system import assemble  # noqa: E402
from roughvib.physics.friction import LAW_FELDMANN, feldmann_mu  # noqa: E402
from roughvib.physics.surface.interp import profile_eval  # noqa: E402
from roughvib.results import load_result  # noqa: E402
from roughvib.scene import load_scene  # noqa: E402
from roughvib.simulation import simulate  # noqa: E402
from roughvib.solvers.base import atol_vector  # noqa: E402
from roughvib.solvers.checkpoint import start_state  # noqa: E402

N_PHI = 4           # phi_1 .. phi_4: holds up to cubic
N_SERIES = 30       # terms of the phi-function series for |z| < 1
HERMITE = "hermite"
LINEAR = "linear"
TRAPEZOIDAL = "trapezoidal"
HERMITE_ORDER = 4            # of the Hermite step: its step-doubling estimate divides by 15
FIXED_POINT_ITERATIONS = 8   # Hermite tangential rule: x1 <-> a1 (converges by h^2/12 each)


class Vertical(NamedTuple):
    """The vertical problem of a scene, every contact closed (SI units)."""

    R: int                    # plate modes
    K: int                    # contacts
    mass: float               # block mass [kg]
    modal_mass: float         # modal mass [kg]
    gravity: float            # [m/s^2]
    r1: float                 # block damper [N s/m]
    phi: np.ndarray           # (R, K) mode shapes at the contacts
    phi_obs: np.ndarray       # (R,) mode shapes at the observation point
    omega2: np.ndarray        # (R,) [rad^2/s^2]
    cdamp: np.ndarray         # (R,) 2 zeta omega [1/s]
    compliance: np.ndarray    # (K, K) 1/s + residual compliance [m/N]


class Input(NamedTuple):
    """The prescribed roughness input at the scheme's step points."""

    u: np.ndarray             # (n, K) profile height at the contacts [m]
    du: np.ndarray            # (n, K) its rate [m/s]


def phi_functions(z: np.ndarray) -> list[np.ndarray]:
    """phi_1 .. phi_4 of ``z`` (complex, any shape): phi_k(z) = sum_j z^j / (j + k)!.

    The series below |z| = 1 (the recurrence ``phi_{k+1} = (phi_k - 1/k!) / z`` loses digits
    there), the recurrence from ``exp(z)`` above.
    """
    small = np.abs(z) < 1.0
    out = []
    rec = np.exp(z)
    for k in range(1, N_PHI + 1):
        rec = (rec - 1.0 / math.factorial(k - 1)) / np.where(small, 1.0, z)
        ser = sum(z ** j / math.factorial(j + k) for j in range(N_SERIES))
        out.append(np.where(small, ser, rec))
    return out


def hold_coefficients(hold: str, h: float, f0, d0, f1, d1) -> list:
    """Coefficients c_0..c_3 of the hold ``p(tau) = sum_k c_k tau^k`` on [0, h]."""
    if hold == LINEAR:
        return [f0, (f1 - f0) / h, 0.0 * f0, 0.0 * f0]
    slope = (f1 - f0) / h
    return [f0, d0, (3.0 * slope - 2.0 * d0 - d1) / h, (d0 + d1 - 2.0 * slope) / h ** 2]


def forced_weights(lam: np.ndarray, h: float) -> tuple[np.ndarray, list[np.ndarray]]:
    """``exp(lam h)`` and the weights W_k with int_0^h e^{lam (h - tau)} tau^k dtau = W_k."""
    ph = phi_functions(lam * h)
    return np.exp(lam * h), [math.factorial(k) * h ** (k + 1) * ph[k] for k in range(N_PHI)]


def vertical_problem(system) -> Vertical:
    """The vertical data of an assembled :class:`roughvib.model.system.System`."""
    fp = system.fp
    return Vertical(system.n_modes, system.n_contacts, fp[kn.FP_MASS], fp[kn.FP_MMODAL],
                    fp[kn.FP_GRAV], fp[kn.FP_R1], system.phi, system.phi_obs, system.omega2,
                    system.cdamp, np.diag(1.0 / system.stiff) + system.cres)


def roughness_at(system, x: float, v: float) -> tuple[np.ndarray, np.ndarray]:
    """Profile height at the contacts [m] and its rate [m/s] for the block at x moving at v."""
    fp = system.fp
    vals = [profile_eval(system.prof, fp[kn.FP_S0], fp[kn.FP_DX], s + x)
            for s in system.input_s]
    return np.array([p[0] for p in vals]), np.array([p[1] for p in vals]) * v


def start(system) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The run's start: its regime array (packed), state ``y`` (static equilibrium, made
    consistent) and the vertical part as displacements ``[q (R), z]`` and velocities
    ``[dq (R), vz]``."""
    reg, rf = system.new_regime_arrays()
    _, y, _ = start_state(system, reg, rf, None, 0, 0)
    lay = system.layout
    return (reg, y, np.r_[y[lay.slice("plate.q")], y[lay.index("block.z")]],
            np.r_[y[lay.slice("plate.dq")], y[lay.index("block.vz")]])


def prescribed_input(system, ds, sub: int) -> Input:
    """Roughness input and its rate at ``sub`` points per output interval of run ``ds``."""
    t = ds["time"].values
    spline = CubicSpline(t, ds["block_tangential_displacement"].values)
    ts = np.linspace(t[0], t[-1], (len(t) - 1) * sub + 1)
    pairs = [roughness_at(system, x, v) for x, v in zip(spline(ts), spline(ts, 1), strict=True)]
    return Input(np.array([u for u, _ in pairs]), np.array([du for _, du in pairs]))


def outputs(vp: Vertical, q, dq, vz, force) -> tuple[float, float]:
    """Block and plate (observation point) vertical acceleration [m/s^2]."""
    block = vp.gravity - vp.r1 / vp.mass * vz - force.sum() / vp.mass
    plate = vp.phi_obs @ (vp.phi @ force / vp.modal_mass - vp.cdamp * dq - vp.omega2 * q)
    return block, plate


class Oscillators:
    """The plate modes and the block's vertical motion as R + 1 damped oscillators, each
    propagated exactly in its two complex modal coordinates under a polynomial hold of the
    contact forces (``phi F / M`` on a mode, ``g - F_sum / m`` on the block)."""

    def __init__(self, vp: Vertical, hold: str):
        R, K = vp.R, vp.K
        self.vp, self.hold = vp, hold
        w2 = np.r_[vp.omega2, 0.0]
        c = np.r_[vp.cdamp, vp.r1 / vp.mass]
        root = np.sqrt((c / 2.0) ** 2 - w2 + 0j)
        if np.any(root == 0):
            raise SystemExit("a critically damped oscillator (r1 = 0?): not handled here")
        self.lam1, self.lam2 = -c / 2.0 + root, -c / 2.0 - root
        self.gap = self.lam2 - self.lam1
        self.force_map = np.zeros((R + 1, K))
        self.force_map[:R] = vp.phi / vp.modal_mass
        self.force_map[R] = -1.0 / vp.mass
        self.const = np.zeros(R + 1)
        self.const[R] = vp.gravity
        self._weights: dict = {}
        self._sens: dict = {}

    def modal(self, x, v):
        """Modal coordinates of displacements ``x`` and velocities ``v`` (R + 1 each)."""
        return (self.lam2 * x - v) / self.gap, (v - self.lam1 * x) / self.gap

    def physical(self, a1, a2):
        """Displacements and velocities of modal coordinates ``a1, a2``."""
        return (a1 + a2).real, (self.lam1 * a1 + self.lam2 * a2).real

    def compression(self, x, v):
        """``z - phi^T q`` and its rate at the contacts [m, m/s]."""
        R = self.vp.R
        return x[R] - self.vp.phi.T @ x[:R], v[R] - self.vp.phi.T @ v[:R]

    def propagate(self, h, a1, a2, coeffs, with_gravity=True):
        """Modal coordinates after ``h`` [s] under the hold with coefficients ``coeffs``."""
        if h not in self._weights:
            self._weights[h] = (forced_weights(self.lam1, h), forced_weights(self.lam2, h))
        (e1, wk1), (e2, wk2) = self._weights[h]
        f = [self.force_map @ ck for ck in coeffs]
        if with_gravity:
            f[0] = f[0] + self.const
        s1 = sum(w * fk for w, fk in zip(wk1, f, strict=True))
        s2 = sum(w * fk for w, fk in zip(wk2, f, strict=True))
        return e1 * a1 - s1 / self.gap, e2 * a2 + s2 / self.gap

    def end_forces(self, h, free_x, free_v, u1, du1):
        """(F1, dF1) at the step's end from the free response's compressions and the input.

        The contact relation ``(1/s + C) F1 = z1 - w1 + u1`` (and, Hermite hold, its rate) with
        the end state linear in (F1, dF1): its sensitivity is computed once per step length.
        """
        K = self.vp.K
        if h not in self._sens:
            zero, za = np.zeros(K), np.zeros(self.vp.R + 1, dtype=complex)
            sens = np.zeros((2 * K, 2 * K))
            for j in range(K):
                unit = np.eye(K)[j]
                for col, (f1, d1) in ((j, (unit, zero)), (K + j, (zero, unit))):
                    coeffs = hold_coefficients(self.hold, h, zero, zero, f1, d1)
                    cx, cv = self.compression(*self.physical(
                        *self.propagate(h, za, za, coeffs, with_gravity=False)))
                    sens[:K, col] = -cx
                    sens[K:, col] = -cv
            sens[:K, :K] += self.vp.compliance
            sens[K:, K:] += self.vp.compliance
            self._sens[h] = (np.linalg.inv(sens[:K, :K]) if self.hold == LINEAR
                             else np.linalg.inv(sens))
        inv = self._sens[h]
        if self.hold == LINEAR:
            return inv @ (free_x + u1), np.zeros(K)
        sol = inv @ np.r_[free_x + u1, free_v + du1]
        return sol[:K], sol[K:]


def solve_modes(vp: Vertical, start: np.ndarray, inp: Input, h: float, hold: str):
    """Modes and block exact, contact force held (linear or Hermite); outputs per step.

    ``start`` is ``[q (R), z, dq (R), vz]`` (:class:`Oscillators`). Returns the outputs (n, 2)
    and the contact forces (n, K).
    """
    R, K = vp.R, vp.K
    osc = Oscillators(vp, hold)
    x0, v0 = start[:R + 1], start[R + 1:]
    a1, a2 = osc.modal(x0, v0)
    cx, cv = osc.compression(x0, v0)
    force = np.linalg.solve(vp.compliance, cx + inp.u[0])
    rate = np.linalg.solve(vp.compliance, cv + inp.du[0]) if hold == HERMITE else np.zeros(K)
    n = len(inp.u)
    out, forces = np.empty((n, 2)), np.empty((n, K))
    out[0] = outputs(vp, x0[:R], v0[:R], v0[R], force)
    forces[0] = force
    zero = np.zeros(K)
    for i in range(1, n):
        free = osc.compression(*osc.physical(*osc.propagate(
            h, a1, a2, hold_coefficients(hold, h, force, rate, zero, zero))))
        f1, d1 = osc.end_forces(h, *free, inp.u[i], inp.du[i])
        a1, a2 = osc.propagate(h, a1, a2, hold_coefficients(hold, h, force, rate, f1, d1))
        force, rate = f1, d1
        x, v = osc.physical(a1, a2)
        out[i] = outputs(vp, x[:R], v[:R], v[R], force)
        forces[i] = force
    return out, forces


def solve_coupled(vp: Vertical, start: np.ndarray, inp: Input, h: float, hold: str):
    """Coupled modes (dense eigendecomposition) exact, roughness input held; outputs per step.

    Returns the outputs, the contact forces and the CPU time of the decomposition [s].
    """
    R, K = vp.R, vp.K
    N = R + 1
    ainv = np.linalg.inv(vp.compliance)
    ones = np.ones(K)
    stiff = np.zeros((N, N))                   # generalised stiffness on x = [q, z]
    stiff[:R, :R] = np.diag(vp.omega2) + vp.phi @ ainv @ vp.phi.T / vp.modal_mass
    stiff[:R, R] = -(vp.phi @ ainv @ ones) / vp.modal_mass
    stiff[R, :R] = -(ones @ ainv @ vp.phi.T) / vp.mass
    stiff[R, R] = ones @ ainv @ ones / vp.mass
    jac = np.zeros((2 * N, 2 * N))
    jac[:N, N:] = np.eye(N)
    jac[N:, :N] = -stiff
    jac[N:, N:] = -np.diag(np.r_[vp.cdamp, vp.r1 / vp.mass])
    const = np.zeros(2 * N)
    const[N + R] = vp.gravity
    inmap = np.zeros((2 * N, K))               # state rate per unit roughness input
    inmap[N:N + R] = vp.phi @ ainv / vp.modal_mass
    inmap[N + R] = -(ones @ ainv) / vp.mass
    cpu = time.process_time()
    lam, vec = np.linalg.eig(jac)
    left = np.linalg.inv(vec)
    cpu = time.process_time() - cpu
    ez, wk = forced_weights(lam, h)
    lconst, linput = left @ const, left @ inmap
    force_row = np.zeros((K, 2 * N))           # F = ainv (z - phi^T q) + ainv u
    force_row[:, :R] = -(ainv @ vp.phi.T)
    force_row[:, R] = ainv @ ones
    force_row = force_row @ vec
    take = np.zeros((3, 2 * N))                # vz, and the plate acceleration's state part
    take[0, N + R] = 1.0
    take[1, :R] = -vp.phi_obs * vp.omega2
    take[1, N:N + R] = -vp.phi_obs * vp.cdamp
    take = take @ vec
    plate_force = vp.phi_obs @ vp.phi / vp.modal_mass
    n = len(inp.u)
    out = np.empty((n, 2))
    forces = np.empty((n, K))
    coord = left @ start

    def record(i):
        force = (force_row @ coord).real + ainv @ inp.u[i]
        vz, plate = (take[:2] @ coord).real
        out[i] = (vp.gravity - vp.r1 / vp.mass * vz - force.sum() / vp.mass,
                  plate + plate_force @ force)
        forces[i] = force

    record(0)
    for i in range(1, n):
        coeffs = hold_coefficients(hold, h, inp.u[i - 1], inp.du[i - 1], inp.u[i], inp.du[i])
        coord = ez * coord + wk[0] * lconst + sum(
            w * (linput @ ck) for w, ck in zip(wk, coeffs, strict=True))
        record(i)
    return out, forces, cpu


def solve_full(system, vp: Vertical, ds, events, hold: str, rule: str, doubling=None):
    """The whole step (vertical hold ``hold``, tangential ``rule``), one per output interval.

    The Feldmann law's branch and latch switch at ``events`` (time, branch, latch), which the
    steps meet exactly. Returns the outputs (n, 2), the tangential velocity (n,), the contact
    forces (n, K) and the step-doubling estimates (below; empty without ``doubling``).

    ``doubling = (atol, rtol, order)``: at every pair of output intervals without an event,
    one step over the pair is also taken from the pair's start, and the estimate
    ``(y_pair - y_two) / (2^order - 1)`` of the two interval steps' error is measured in
    ``adaptive-modal``'s weights (``rtol max(|y0|, |y|) + atol``; ``atol`` over ``[q, dq, z,
    vz, x, vx, F]``): the RMS over the modes and the largest of the others, with the index of
    that largest (0 z, 1 vz, 2 x, 3 vx, 4 + k the force of contact k). Returns a list of
    (time, modal RMS, largest other, its index).
    """
    fp = system.fp
    K = vp.K
    osc = Oscillators(vp, hold)
    t0_amp, omega = fp[kn.FP_T0], fp[kn.FP_OMEGA]
    r2, mass, v_h = fp[kn.FP_R2], fp[kn.FP_MASS], fp[kn.FP_VH]
    law = (fp[kn.FP_MU_SLIP], fp[kn.FP_MU_STICK], fp[kn.FP_A1], fp[kn.FP_A2])
    reg, y, xv, vv = start(system)
    lay = system.layout
    st = {"branch": float(reg[kn.REG_B]), "latch": float(reg[kn.REG_S])}

    def accel(t, v, normal):
        mu, _ = feldmann_mu(v + st["latch"] * v_h, st["branch"], *law)
        return (t0_amp * math.cos(omega * t) - mu * normal - r2 * v) / mass

    def jerk(t, v, a, normal, dnormal):
        mu, dmu = feldmann_mu(v + st["latch"] * v_h, st["branch"], *law)
        return (-t0_amp * omega * math.sin(omega * t) - dmu * a * normal - mu * dnormal
                - r2 * a) / mass

    st["a"] = osc.modal(xv, vv)
    st["x"], st["v"] = y[lay.index("block.x")], y[lay.index("block.vx")]
    u, du = roughness_at(system, st["x"], st["v"])
    cx, cv = osc.compression(xv, vv)
    st["F"] = np.linalg.solve(vp.compliance, cx + u)
    st["dF"] = np.linalg.solve(vp.compliance, cv + du) if hold == HERMITE else np.zeros(K)

    def restart(t):
        st["acc"] = accel(t, st["v"], st["F"].sum())
        st["jerk"] = jerk(t, st["v"], st["acc"], st["F"].sum(), st["dF"].sum())

    def step(t0, h):
        t1 = t0 + h
        zero = np.zeros(K)
        free = osc.compression(*osc.physical(*osc.propagate(
            h, *st["a"], hold_coefficients(hold, h, st["F"], st["dF"], zero, zero))))
        x0, v0, a0, j0 = st["x"], st["v"], st["acc"], st["jerk"]

        def end(v1):
            x1 = x0 + 0.5 * h * (v0 + v1)
            for _ in range(FIXED_POINT_ITERATIONS if rule == HERMITE else 1):
                f1, d1 = osc.end_forces(h, *free, *roughness_at(system, x1, v1))
                if rule == HERMITE:
                    x1 = x0 + 0.5 * h * (v0 + v1) + h * h / 12.0 * (
                        a0 - accel(t1, v1, f1.sum()))
            f1, d1 = osc.end_forces(h, *free, *roughness_at(system, x1, v1))
            return x1, f1, d1

        def residual(v1):
            _, f1, d1 = end(v1)
            a1 = accel(t1, v1, f1.sum())
            if rule == TRAPEZOIDAL:
                return v1 - v0 - 0.5 * h * (a0 + a1)
            return (v1 - v0 - 0.5 * h * (a0 + a1)
                    - h * h / 12.0 * (j0 - jerk(t1, v1, a1, f1.sum(), d1.sum())))

        v1 = newton(residual, v0 + h * a0, tol=1e-16, maxiter=50)
        x1, f1, d1 = end(v1)
        st["a"] = osc.propagate(h, *st["a"], hold_coefficients(hold, h, st["F"], st["dF"],
                                                                 f1, d1))
        st.update(x=x1, v=v1, F=f1, dF=d1)
        restart(t1)

    t = ds["time"].values
    n = len(t)
    out, vel, forces = np.empty((n, 2)), np.empty(n), np.empty((n, K))

    def record(i):
        x, v = osc.physical(*st["a"])
        out[i] = outputs(vp, x[:vp.R], v[:vp.R], v[vp.R], st["F"])
        vel[i], forces[i] = st["v"], st["F"]

    def state_vector():
        x, v = osc.physical(*st["a"])
        return np.r_[x[:vp.R], v[:vp.R], x[vp.R], v[vp.R], st["x"], st["v"], st["F"]]

    def estimate(i):
        """The step-doubling estimate over the intervals from t[i - 1] (docstring)."""
        saved = {key: (tuple(a.copy() for a in val) if isinstance(val, tuple) else val)
                 for key, val in st.items()}
        y0 = state_vector()
        step(t[i - 1], t[i + 1] - t[i - 1])
        y_pair = state_vector()
        st.update(saved)
        step(t[i - 1], t[i] - t[i - 1])
        step(t[i], t[i + 1] - t[i])
        y_two = state_vector()
        st.update(saved)
        atol, rtol, order = doubling
        err = np.abs(y_pair - y_two) / ((2 ** order - 1)
                                        * (rtol * np.maximum(np.abs(y0), np.abs(y_two)) + atol))
        rest = err[2 * vp.R:]
        return (t[i - 1], float(np.sqrt(np.mean(err[:2 * vp.R] ** 2))), float(rest.max()),
                int(rest.argmax()))

    estimates = []
    restart(0.0)
    record(0)
    pending = [e for e in events if e[0] > 0.0]
    for i in range(1, n):
        quiet = not any(t[i - 1] <= e[0] <= t[min(i + 1, n - 1)] for e in pending[:1])
        if doubling is not None and i % 2 == 1 and i + 1 < n and quiet:
            estimates.append(estimate(i))
        ta = t[i - 1]
        while pending and pending[0][0] < t[i]:
            te, branch, latch = pending.pop(0)
            if te > ta:
                step(ta, te - ta)
                ta = te
            st["branch"], st["latch"] = branch, latch
            restart(ta)
        step(ta, t[i] - ta)
        record(i)
    return out, vel, forces, estimates


def reference_events(ref) -> list[tuple[float, float, float]]:
    """(time, branch, latch) after each event of a converged run's log."""
    out = []
    for time_, after in zip(ref.events["time"], ref.events["regime_after"], strict=True):
        fields = dict(item.split("=") for item in str(after).split() if "=" in item)
        out.append((float(time_), float(fields["b"]), float(fields["s"])))
    return out


def band_cells(out, ds, win, dt) -> list[str]:
    """The table cells: block worst band, plate worst band, plate 10 kHz band [dB]."""
    cells = []
    for col, name in enumerate(("block_vertical_acceleration", "plate_vertical_acceleration")):
        bd = band_deviations(out[win, col], ds[name].values[win], 1.0 / dt)
        chk = bd["checked"]
        dev, centres = bd["deviation_db"][chk], bd["centres"][chk]
        worst = int(np.nanargmax(np.abs(dev)))
        cells.append(f"{dev[worst]:+.4f} @ {centres[worst] / 1000:.3g} kHz")
        if col == 1:
            at10 = np.isclose(centres, 10000.0)
            cells.append(f"{dev[at10][0]:+.4f}" if at10.any() else "not checked")
    return cells


def reference_run(scene_name: str, directory: str | None):
    """The converged run: read from ``directory``, or made here (adaptive-modal, tight)."""
    if directory:
        return load_result(directory)
    scene = load_scene(scene_name)
    solver = replace(scene.solver, method="adaptive-modal", rtol=1e-9, atol=1e-14,
                     atol_acceleration=1e-11)
    print("making the reference run (adaptive-modal at rtol 1e-9) ...", flush=True)
    return simulate(replace(scene, solver=solver), progress=False)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", nargs="?", default="paper")
    ap.add_argument("--reference", help="a converged run of the scene (else one is made)")
    ap.add_argument("--vertical-only", action="store_true",
                    help="only the first table (the tangential motion prescribed)")
    args = ap.parse_args(argv)
    ref = reference_run(args.scene, args.reference)
    ds = ref.dataset
    if not np.all(ds["contact_closed"].values == 1):
        raise SystemExit(f"{args.scene}: a contact opens in the reference run; this benchmark "
                         "needs every contact closed throughout")
    scene = load_scene(args.scene)
    if scene.contact.friction_moment:
        raise SystemExit(f"{args.scene}: contact.friction_moment = true is not modelled here")
    system = assemble(scene, force_amplitude=float(ds.attrs["force_amplitude"]))
    vp = vertical_problem(system)
    _, _, x0, v0 = start(system)
    state0 = np.r_[x0, v0]
    t = ds["time"].values
    dt = t[1] - t[0]
    win = analysis_window(t, scene.period, scene.output.transient)
    f_ref = ds["contact_force"].values
    print(f"\n{args.scene}: R = {vp.R} modes, K = {vp.K} contacts, output step {dt:g} s; "
          "deviation from the reference [dB], worst band and the 10 kHz band\n")
    print("| scheme | step [s] | block: worst band | plate: worst band | plate 10 kHz "
          "| max abs(F - F_ref) [N] | loop CPU [s] |")
    print("|---|---|---|---|---|---|---|")
    for label, kind, hold, sub in (("modes, linear F", "modes", LINEAR, 1),
                                   ("modes, linear F", "modes", LINEAR, 2),
                                   ("modes, Hermite F", "modes", HERMITE, 1),
                                   ("coupled, linear u", "coupled", LINEAR, 1),
                                   ("coupled, Hermite u", "coupled", HERMITE, 1)):
        inp = prescribed_input(system, ds, sub)
        cpu = time.process_time()
        if kind == "modes":
            out, forces = solve_modes(vp, state0, inp, dt / sub, hold)
            eig = None
        else:
            out, forces, eig = solve_coupled(vp, state0, inp, dt / sub, hold)
        cpu = time.process_time() - cpu
        out, forces = out[::sub], forces[::sub]
        cells = band_cells(out, ds, win, dt)
        extra = "" if eig is None else f" (of it eigendecomposition {eig:.2f})"
        print(f"| {label} | {dt / sub:g} | {cells[0]} | {cells[1]} | {cells[2]} | "
              f"{np.max(np.abs(forces - f_ref)):.2g} | {cpu:.1f}{extra} |", flush=True)
    if args.vertical_only:
        return
    if int(system.off[kn.OFF_LAW]) != LAW_FELDMANN:
        raise SystemExit(f"{args.scene}: the coupled table needs the Feldmann friction law")
    events = reference_events(ref)
    v_ref = ds["block_tangential_velocity"].values[win]
    print("\nwith the tangential motion coupled (one step per output interval; regimes "
          "switched at the converged run's event times):\n")
    print("| vertical hold | tangential rule | block: worst band | plate: worst band "
          "| plate 10 kHz | velocity, relative rms | max abs(F - F_ref) [N] | loop CPU [s] |")
    print("|---|---|---|---|---|---|---|---|")
    for hold, rule in ((LINEAR, TRAPEZOIDAL), (HERMITE, TRAPEZOIDAL), (HERMITE, HERMITE)):
        cpu = time.process_time()
        out, vel, forces, _ = solve_full(system, vp, ds, events, hold, rule)
        cpu = time.process_time() - cpu
        cells = band_cells(out, ds, win, dt)
        vrel = np.sqrt(np.mean((vel[win] - v_ref) ** 2) / np.mean(v_ref ** 2))
        print(f"| {hold} F | {rule} | {cells[0]} | {cells[1]} | {cells[2]} | {vrel:.2g} | "
              f"{np.max(np.abs(forces - f_ref)):.2g} | {cpu:.1f} |", flush=True)
    doubling_estimates(scene, system, vp, ds, events)


def doubling_estimates(scene, system, vp: Vertical, ds, events) -> None:
    """Print how the Hermite step's step-doubling estimate over two output intervals sits
    in the default run's tolerances (those a default run of the scene reports, its
    acceleration tolerance set by its pilot)."""
    base = simulate(scene, progress=False).summary["solver"]
    solved = replace(scene.solver, rtol=float(base["rtol"]), atol=float(base["atol"]),
                     atol_acceleration=float(base["atol_acceleration"]))
    weights = assemble(replace(scene, solver=solved),
                       force_amplitude=float(ds.attrs["force_amplitude"]))
    full = atol_vector(weights)
    lay = weights.layout
    atol = np.r_[full[lay.slice("plate.q")], full[lay.slice("plate.dq")],
                 full[lay.index("block.z")], full[lay.index("block.vz")],
                 full[lay.index("block.x")], full[lay.index("block.vx")],
                 full[lay.slice("contact.force")]]
    _, _, _, est = solve_full(system, vp, ds, events, HERMITE, HERMITE,
                              doubling=(atol, solved.rtol, HERMITE_ORDER))
    norm = np.array([max(modal, other) for _, modal, other, _ in est])
    names = ["block.z", "block.vz", "block.x", "block.vx"] + [
        f"contact.force[{k}]" for k in range(vp.K)]
    print(f"\nHermite step over two output intervals against two steps of one (rtol "
          f"{solved.rtol:g}, atol_acceleration {solved.atol_acceleration:.3g} m/s^2, the "
          f"default run's), {len(norm)} pairs without an event:")
    print(f"  error norm: median {np.median(norm):.2g}, 90 % {np.percentile(norm, 90):.2g}, "
          f"largest {norm.max():.2g}; {int(np.sum(norm > 1))} pairs above 1")
    for k in np.argsort(norm)[::-1][:5]:
        t0, modal, other, which = est[k]
        print(f"  t = {t0:.5f} s: modes (RMS) {modal:.2g}, {names[which]} {other:.2g}")


if __name__ == "__main__":
    main()
