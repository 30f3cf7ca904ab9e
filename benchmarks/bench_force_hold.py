"""Benchmark: what limits one exact-modal step per output interval -- the coupling or the hold?

Run on demand, not by the tests (issue 28):

    python benchmarks/bench_force_hold.py                         # paper, reference made here
    python benchmarks/bench_force_hold.py paper --reference RUN   # reuse a converged run

The default solver keeps steps of half the output interval because, at the interval, the
``paper`` plate's 10 kHz band is 0.28 dB low. Issue 28 proposed to propagate the coupled modes
of block, contact springs and plate exactly. This benchmark separates the two errors a step
of exact modal propagation can make -- the coupling of the modes through the contact, and the
hold (the polynomial in time) of what drives them over the step -- on the vertical problem
alone:

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

from roughvib.analysis.accuracy import analysis_window, band_deviations  # noqa: E402
from roughvib.model import kernels as kn  # noqa: E402
from roughvib.model.system import assemble  # noqa: E402
from roughvib.physics.surface.interp import profile_eval  # noqa: E402
from roughvib.results import load_result  # noqa: E402
from roughvib.scene import load_scene  # noqa: E402
from roughvib.simulation import simulate  # noqa: E402
from roughvib.solvers.checkpoint import start_state  # noqa: E402

N_PHI = 4           # phi_1 .. phi_4: holds up to cubic
N_SERIES = 30       # terms of the phi-function series for |z| < 1
HERMITE = "hermite"
LINEAR = "linear"


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


def prescribed_input(system, ds, sub: int) -> Input:
    """Roughness input and its rate at ``sub`` points per output interval of run ``ds``."""
    t = ds["time"].values
    spline = CubicSpline(t, ds["block_tangential_displacement"].values)
    ts = np.linspace(t[0], t[-1], (len(t) - 1) * sub + 1)
    x, v = spline(ts), spline(ts, 1)
    fp = system.fp
    u = np.empty((len(ts), system.n_contacts))
    du = np.empty_like(u)
    for k, s in enumerate(system.contact_s):
        for i, xi in enumerate(x):
            hgt, slope, _ = profile_eval(system.prof, fp[kn.FP_S0], fp[kn.FP_DX], s + xi)
            u[i, k] = hgt
            du[i, k] = slope * v[i]
    return Input(u, du)


def outputs(vp: Vertical, q, dq, vz, force) -> tuple[float, float]:
    """Block and plate (observation point) vertical acceleration [m/s^2]."""
    block = vp.gravity - vp.r1 / vp.mass * vz - force.sum() / vp.mass
    plate = vp.phi_obs @ (vp.phi @ force / vp.modal_mass - vp.cdamp * dq - vp.omega2 * q)
    return block, plate


def solve_modes(vp: Vertical, start: np.ndarray, inp: Input, h: float, hold: str):
    """Modes and block exact, contact force held (linear or Hermite); returns outputs per step.

    ``start`` is ``[q (R), z, dq (R), vz]``. Each of the R + 1 oscillators ``x'' + c x' +
    w2 x = f(t)`` is propagated in its two complex modal coordinates; the force on it is
    ``phi F / M`` (modes) or ``g - F_sum / m`` (block).
    """
    R, K = vp.R, vp.K
    w2 = np.r_[vp.omega2, 0.0]
    c = np.r_[vp.cdamp, vp.r1 / vp.mass]
    root = np.sqrt((c / 2.0) ** 2 - w2 + 0j)
    if np.any(root == 0):
        raise SystemExit("a critically damped oscillator (r1 = 0?): not handled here")
    lam1, lam2 = -c / 2.0 + root, -c / 2.0 - root
    gap = lam2 - lam1
    e1, wk1 = forced_weights(lam1, h)
    e2, wk2 = forced_weights(lam2, h)
    force_map = np.zeros((R + 1, K))           # generalised force per unit contact force
    force_map[:R] = vp.phi / vp.modal_mass
    force_map[R] = -1.0 / vp.mass
    const = np.zeros(R + 1)
    const[R] = vp.gravity

    def propagate(a1, a2, coeffs, with_gravity=True):
        f = [force_map @ ck for ck in coeffs]
        if with_gravity:
            f[0] = f[0] + const
        s1 = sum(w * fk for w, fk in zip(wk1, f, strict=True))
        s2 = sum(w * fk for w, fk in zip(wk2, f, strict=True))
        return e1 * a1 - s1 / gap, e2 * a2 + s2 / gap

    def physical(a1, a2):
        return (a1 + a2).real, (lam1 * a1 + lam2 * a2).real

    def compression(x, v):
        return x[R] - vp.phi.T @ x[:R], v[R] - vp.phi.T @ v[:R]

    zero = np.zeros(K)
    za = np.zeros(R + 1, dtype=complex)
    # the end state's sensitivity to (F1, dF1): unit responses from rest, without gravity
    sens = np.zeros((2 * K, 2 * K))
    for j in range(K):
        for col, (f1, d1) in ((j, (np.eye(K)[j], zero)), (K + j, (zero, np.eye(K)[j]))):
            if hold == LINEAR and col >= K:
                continue
            x, v = physical(*propagate(za, za, hold_coefficients(hold, h, zero, zero, f1, d1),
                                       with_gravity=False))
            cx, cv = compression(x, v)
            sens[:K, col] = -cx
            sens[K:, col] = -cv
    sens[:K, :K] += vp.compliance
    sens[K:, K:] += vp.compliance
    if hold == LINEAR:
        sens = sens[:K, :K]
    x0, v0 = start[:R + 1], start[R + 1:]
    a1, a2 = (lam2 * x0 - v0) / gap, (v0 - lam1 * x0) / gap
    cx, cv = compression(x0, v0)
    force = np.linalg.solve(vp.compliance, cx + inp.u[0])
    rate = np.linalg.solve(vp.compliance, cv + inp.du[0])
    n = len(inp.u)
    out = np.empty((n, 2))
    forces = np.empty((n, K))
    out[0] = outputs(vp, x0[:R], v0[:R], v0[R], force)
    forces[0] = force
    for i in range(1, n):
        fa1, fa2 = propagate(a1, a2, hold_coefficients(hold, h, force, rate, zero, zero))
        cx, cv = compression(*physical(fa1, fa2))
        if hold == LINEAR:
            f1, d1 = np.linalg.solve(sens, cx + inp.u[i]), zero
        else:
            sol = np.linalg.solve(sens, np.r_[cx + inp.u[i], cv + inp.du[i]])
            f1, d1 = sol[:K], sol[K:]
        a1, a2 = propagate(a1, a2, hold_coefficients(hold, h, force, rate, f1, d1))
        force, rate = f1, d1
        x, v = physical(a1, a2)
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
    reg, rf = system.new_regime_arrays()
    _, y, _ = start_state(system, reg, rf, None, 0, 0)
    lay = system.layout
    start = np.r_[y[lay.slice("plate.q")], y[lay.index("block.z")],
                  y[lay.slice("plate.dq")], y[lay.index("block.vz")]]
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
            out, forces = solve_modes(vp, start, inp, dt / sub, hold)
            eig = None
        else:
            out, forces, eig = solve_coupled(vp, start, inp, dt / sub, hold)
        cpu = time.process_time() - cpu
        out, forces = out[::sub], forces[::sub]
        cells = []
        for col, name in enumerate(("block_vertical_acceleration",
                                    "plate_vertical_acceleration")):
            bd = band_deviations(out[win, col], ds[name].values[win], 1.0 / dt)
            chk = bd["checked"]
            dev, centres = bd["deviation_db"][chk], bd["centres"][chk]
            worst = int(np.nanargmax(np.abs(dev)))
            cells.append(f"{dev[worst]:+.4f} @ {centres[worst] / 1000:.3g} kHz")
            if col == 1:
                at10 = np.isclose(centres, 10000.0)
                cells.append(f"{dev[at10][0]:+.4f}" if at10.any() else "not checked")
        extra = "" if eig is None else f" (of it eigendecomposition {eig:.2f})"
        print(f"| {label} | {dt / sub:g} | {cells[0]} | {cells[1]} | {cells[2]} | "
              f"{np.max(np.abs(forces - f_ref)):.2g} | {cpu:.1f}{extra} |", flush=True)


if __name__ == "__main__":
    main()
