"""The paper's time-stepping scheme (Feldmann 2012; docs/theory.md), as a baseline.

Per step of length h: backward Euler for the block's vertical and tangential motion, the
contact forces F_k = s_k H(d_k) d_k with the Heaviside H kept *inside* a Newton-Raphson
iteration (LU solve per iteration), and the plate displacement at the contacts from the
discrete convolution of the contact-force history with the sampled plate impulse responses,

    w_i(t_{n+1}) = sum_{m=1}^{n+1} sum_j h g_ij(m h) F_j(t_{n+1-m}) ,   g_ij(0) = 0 .

Because g(0) = 0 the plate reacts one step late: the scheme is explicit in the plate, which is
why it is only stable while s h / Z_inf << 1 (docs/theory.md). The history sum costs
O(n K^2) per step, so O(N^2 K^2) per run: this is the formulation that the modal states of the
DAE replace. The plate acceleration at the observation point is the second central difference
of the plate displacement there, from the same convolution (``impulse_responses``): this keeps
the direct (instantaneous) term of the force-to-acceleration response consistent with what the
sampled impulse response represents of each mode. Convolving the sampled *acceleration* impulse
response instead and adding the exact direct term sum_r phi_r(o) phi_r(j) / M leaves, for the
modes near w_r h = pi whose sampled response misses most of that term's counterpart, a false
quasi-static acceleration proportional to the load moving between the contacts (a 19 dB
excess at 0-150 Hz on the paper scene). No residual compliance is included (paper-faithful).
The energy audit is not available (the plate has no energy states here).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from roughvib.model import kernels as kn
from roughvib.model.regimes import initial_regime
from roughvib.model.system import System
from roughvib.physics.friction import LAW_FELDMANN, LAWS, feldmann_mu_law
from roughvib.physics.surface.interp import profile_eval
from roughvib.scene import SceneError
from roughvib.solvers.base import FIRST_ROW, RawSolution
from roughvib.solvers.events import initial_phase_events
from roughvib.solvers.fixed_step import (
    N_TANG,
    TG_LATCH,
    TG_STICK,
    TG_VX,
    TG_WSTAT,
    TG_X,
    ZV_VZ,
    ZV_Z,
    event_records,
    log_step_events,
    step_grid,
)

__all__ = ["impulse_responses", "solve_paper_scheme"]


# the Newton step of _run_paper: unknowns (columns) and equations (rows)
U_Z = 0
U_VZ = 1
U_X = 2
U_VX = 3
EQ_MOM_Z = 0  # vertical momentum
EQ_KIN_Z = 1  # z' = vz
EQ_MOM_X = 2  # tangential momentum
EQ_KIN_X = 3  # x' = vx
N_NEWTON = 4

@njit(cache=True)
def impulse_responses(phi, phi_obs, omega, zeta, M, h, n):
    """Sampled plate impulse responses for m = 0..n (paper Eq. 5).

    Returns ``G`` (n+1, K, K) = h g_ij(m h), the displacement at contact i per impulse at
    contact j, and ``Ga`` (n+1, K), the acceleration kernel at the observation point o:
    ``Ga[m, j] = (g_oj((m+1) h) - 2 g_oj(m h) + g_oj((m-1) h)) / h`` with g(t <= 0) = 0.
    ``sum_m Ga[m] F_{n-m}`` is the second central difference, divided by h^2, of the plate
    displacement at o that the same convolution gives, and also the exact acceleration of
    the modes under the force interpolated linearly between the samples. ``Ga[0] = g(h)/h``
    carries the direct term sum_r phi_r(o) phi_rj / M of the force-to-acceleration response
    for the modes with w_r h << 1 and drops it for the modes near w_r h = pi, in step with
    what the sampled g represents of them: a constant force gives zero acceleration for any
    h (sum_m Ga[m] = 0), as the modes do.
    g_ij(t) = sum_r phi_ri phi_rj exp(-zeta_r w_r t) sin(w_d,r t) / (M w_d,r).
    """
    R, K = phi.shape
    G = np.zeros((n + 1, K, K))
    Ga = np.zeros((n + 1, K))
    gr = np.zeros(n + 2)  # g_r(m h) M / (phi_ri phi_rj), m = 0..n+1; g_r(0) = 0
    for r in range(R):
        a = zeta[r] * omega[r]
        wd = omega[r] * math.sqrt(1.0 - zeta[r] * zeta[r])
        for m in range(1, n + 2):
            t = m * h
            gr[m] = math.exp(-a * t) * math.sin(wd * t) / (M * wd)
        for m in range(n + 1):
            gdd = (gr[m + 1] - 2.0 * gr[m] + (gr[m - 1] if m > 0 else 0.0)) / h
            for i in range(K):
                Ga[m, i] += phi_obs[r] * phi[r, i] * gdd
                if m > 0:
                    ai = phi[r, i] * h * gr[m]
                    for j in range(K):
                        G[m, i, j] += ai * phi[r, j]
    return G, Ga


@njit(cache=True)
def _run_paper(h, n_steps, out_every, G, Ga, stiff, spos, prof, fp, tangential, zv, tang, Fv,
               Fhist, out, ev_t, ev_kind, ev_contact):
    """:func:`_paper_loop` on views of its arrays without memory records
    (:func:`roughvib.model.kernels.unowned`: no reference counting of them in the loop); the
    same arguments and results. Called from Python, which holds the arrays."""
    u = kn.unowned
    return _paper_loop(h, n_steps, out_every, u(G), u(Ga), u(stiff), u(spos), u(prof), u(fp),
                       tangential, u(zv), u(tang), u(Fv), u(Fhist), u(out), u(ev_t),
                       u(ev_kind), u(ev_contact))


@njit(cache=True)
def _paper_loop(h, n_steps, out_every, G, Ga, stiff, spos, prof, fp, tangential, zv, tang, Fv,
                Fhist, out, ev_t, ev_kind, ev_contact):
    K = stiff.size
    m, g, r1, r2, mu_sl, mu_st, a1, a2, vh, eps, vst = kn.block_parameters(fp)
    w = np.empty(K)
    d = np.empty(K)
    dh = np.empty(K)
    hk = np.empty(K)
    comp_old = np.empty(K)
    n_ev = 0
    for k in range(K):
        hh, _, _ = profile_eval(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + tang[TG_X])
        comp_old[k] = Fv[k] / stiff[k] if Fv[k] > 0 else -1e-30
    # the run starts from static equilibrium: the convolution carries the force *deviations*
    # from the static forces, and the static plate deflection (tang[5:]) is added to it
    Fst = Fv.copy()
    row = 0
    for n in range(n_steps):
        t1 = (n + 1) * h
        # plate at the contacts from the history of force *deviations* (explicit: g(0) = 0)
        for i in range(K):
            acc = 0.0
            for mm in range(1, n + 2):
                for j in range(K):
                    acc += G[mm, i, j] * Fhist[n + 1 - mm, j]
            w[i] = acc + tang[TG_WSTAT + i]  # + static plate deflection at contact i
        # Newton-Raphson on (z1, vz1, x1, vx1), Heaviside inside the iteration
        z0, vz0, x0, vx0 = zv[ZV_Z], zv[ZV_VZ], tang[TG_X], tang[TG_VX]
        if not tangential:  # prescribed motion: x1 is known
            x0, _ = kn.prescribed_motion(t1, fp)
        z1, vz1, x1, vx1 = z0, vz0, x0, vx0
        s_l = tang[TG_LATCH]
        texc = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t1)
        ok = False
        for _it in range(60):
            S = 0.0
            dSdz = 0.0
            dSdx = 0.0
            for k in range(K):
                hh, dd, _ = profile_eval(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + x1)
                hk[k] = hh
                dh[k] = dd
                d[k] = z1 - w[k] + hh
                if d[k] > 0.0:
                    S += stiff[k] * d[k]
                    dSdz += stiff[k]
                    dSdx += stiff[k] * dd
            A = np.zeros((N_NEWTON, N_NEWTON))
            b = np.zeros(N_NEWTON)
            b[EQ_MOM_Z] = m * (vz1 - vz0) / h - (m * g - r1 * vz1 - S)
            A[EQ_MOM_Z, U_VZ] = m / h + r1
            A[EQ_MOM_Z, U_Z] = dSdz
            A[EQ_MOM_Z, U_X] = dSdx
            b[EQ_KIN_Z] = z1 - z0 - h * vz1
            A[EQ_KIN_Z, U_Z] = 1.0
            A[EQ_KIN_Z, U_VZ] = -h
            if tangential:
                mu, dmu = feldmann_mu_law(vx1 + s_l * vh, mu_sl, mu_st, a1, a2)
                b[EQ_MOM_X] = m * (vx1 - vx0) / h - (texc - mu * S - r2 * vx1)
                A[EQ_MOM_X, U_VX] = m / h + dmu * S + r2
                A[EQ_MOM_X, U_Z] = mu * dSdz
                A[EQ_MOM_X, U_X] = mu * dSdx
                b[EQ_KIN_X] = x1 - x0 - h * vx1
                A[EQ_KIN_X, U_X] = 1.0
                A[EQ_KIN_X, U_VX] = -h
            else:
                A[EQ_MOM_X, U_X] = 1.0
                A[EQ_KIN_X, U_VX] = 1.0
            du = np.linalg.solve(A, b)
            z1 -= du[U_Z]
            vz1 -= du[U_VZ]
            if tangential:
                x1 -= du[U_X]
                vx1 -= du[U_VX]
            if abs(du[U_Z]) < 1e-16 + 1e-12 * abs(z1) and abs(du[U_VX]) < 1e-15 + 1e-12 * abs(vx1):
                ok = True
                break
        if not ok:
            return n_ev, 1, n
        if not tangential:
            x1, vx1 = kn.prescribed_motion(t1, fp)
        S = 0.0
        for k in range(K):
            hh, _, _ = profile_eval(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + x1)
            hk[k] = hh
            d[k] = z1 - w[k] + hh
            Fv[k] = stiff[k] * d[k] if d[k] > 0.0 else 0.0
            S += Fv[k]
            Fhist[n + 1, k] = Fv[k] - Fst[k]
        n_ev = log_step_events(t1 - h, h, comp_old, d, vx0, vx1, tang, vst,
                               kn.runtime_bool(False), kn.runtime_bool(True), eps, ev_t, ev_kind,
                               ev_contact, n_ev, tangential)
        mu1 = 0.0
        if tangential:
            mu1, _ = feldmann_mu_law(vx1 + tang[TG_LATCH] * vh, mu_sl, mu_st, a1, a2)
        az1 = (vz1 - vz0) / h
        zv[ZV_Z], zv[ZV_VZ] = z1, vz1
        tang[TG_X], tang[TG_VX] = x1, vx1
        if (n + 1) % out_every == 0:
            row += 1
            # the force history convolved with the acceleration kernel (see impulse_responses)
            ao = 0.0
            for mm in range(0, n + 2):
                for j in range(K):
                    ao += Ga[mm, j] * Fhist[n + 1 - mm, j]
            kn.write_output_row(out[row], tangential, z1, vz1, az1, ao, x1, vx1, mu1 * S, S, mu1,
                                Fv, hk)
    return n_ev, 0, n_steps


def solve_paper_scheme(system: System, *, progress: bool | None = None) -> RawSolution:
    """Integrate with the paper's scheme (see the module docstring)."""
    scene = system.scene
    if kn.moment_on(system.off):  # scene/core.py refuses it; this guards a direct call
        raise SceneError("contact.friction_moment = true needs solver.method 'ida' or "
                         "'adaptive-modal', got 'paper'")
    law = LAWS[scene.friction.law]
    # the scene check's rule, again for a direct call
    if system.tangential and "paper" not in law.solvers:
        raise SceneError(f"solver.method = 'paper' does not run friction.law = {law.name!r} "
                         f"({law.kind}; it runs with {', '.join(law.solvers)})")
    # the paper's scheme calls the paper's law itself (feldmann_mu_law), not the kernels'
    # dispatch: a system of any other law, single-valued or not, is refused here
    if system.tangential and int(system.off[kn.OFF_LAW]) != LAW_FELDMANN:
        raise SceneError(f"solver.method = 'paper' runs the paper's law only (friction.law = "
                         f"'feldmann'), got friction.law = {law.name!r} (law id "
                         f"{int(system.off[kn.OFF_LAW])} in the kernels)")
    if system.n_modes == 0:
        if scene.plate.kind == "rigid":
            raise SceneError("solver.method = 'paper' needs a structure with modes (the plate "
                             "is its impulse response), got plate.kind = 'rigid'")
        raise SceneError(f"solver.method = 'paper' needs at least one plate mode below "
                         f"plate.max_frequency (the plate is its impulse response), got "
                         f"{scene.plate.max_frequency} Hz")
    h, out_every, n_out, n_steps = step_grid(scene)
    K = system.n_contacts
    lay = system.layout
    mem = (n_steps + 1) * K * (K + 1) * 8
    if mem > 4e9:
        raise SceneError(f"solver.step gives {n_steps} steps: the paper scheme's impulse "
                         f"responses would need {mem / 1e9:.1f} GB, raise solver.step or "
                         f"shorten output.duration, got {h} s")
    omega = np.sqrt(system.omega2)
    zeta = system.cdamp / (2 * omega)
    G, Ga = impulse_responses(system.phi, system.phi_obs, omega, zeta,
                                 float(system.fp[kn.FP_MMODAL]), h, n_steps + 1)
    y0, closed = system.static_equilibrium()
    regime = initial_regime(closed, system.fp, lay.tangential, system.scene.friction.law)
    reg, rf = system.new_regime_arrays()
    regime.pack(reg, rf)
    y, _ = system.consistent(0.0, y0, reg, rf)
    Fv = y[lay.slice("contact.force")].copy()
    wstat = system.static_compliance_matrix() @ Fv  # static plate deflection at the contacts
    zv = np.zeros(ZV_VZ + 1)
    zv[ZV_Z] = y[lay.index("block.z")]
    tang = np.zeros(N_TANG + K)
    tang[TG_LATCH] = float(regime.latch)
    tang[TG_STICK] = 1.0
    tang[TG_WSTAT:] = wstat
    Fhist = np.zeros((n_steps + 2, K))
    out = np.full((n_out, kn.n_output_columns(K)), np.nan)
    kn.outputs(0.0, y, out[FIRST_ROW], *system.kernel_args(reg, rf))
    cap = 2_000_000
    ev_t = np.empty(cap)
    ev_kind = np.empty(cap, dtype=np.int8)
    ev_contact = np.empty(cap, dtype=np.int64)
    wall0 = time.perf_counter()
    n_ev, code, n_done = _run_paper(h, n_steps, out_every, G, Ga, system.stiff,
                                    system.input_s, system.prof, system.fp, lay.tangential,
                                    zv, tang, Fv, Fhist, out, ev_t, ev_kind, ev_contact)
    wall = time.perf_counter() - wall0
    status, message = "success", "reached the end of the output grid"
    if code:
        status = "newton_failure"
        message = (f"Newton-Raphson did not converge at t = {n_done * h:.6g} s (solver.step "
                   f"{h} s); hint: reduce solver.step")
    events = (initial_phase_events(system, 0.0, y, reg, rf, True)  # starts in stick, as IDA
              + event_records(n_ev, ev_t, ev_kind, ev_contact))
    yf = np.full(lay.size, np.nan)  # no modal states: the energy audit is not available
    rows = (n_done // out_every) + 1 if code else n_out
    stats = {"steps": int(n_done), "step_size": h, "residual_evaluations": None,
             "jacobian_evaluations": None, "restarts": 0, "wall_time": wall,
             "events_total": len(events), "note": "energy audit not available for the convolution "
                                           "scheme"}
    return RawSolution(time=np.arange(n_out) * scene.output.step, outputs=out, events=events,
                       stats=stats, status=status, message=message, y_initial=y,
                       y_final=yf, t_final=float(n_done * h), extra={"rows_filled": rows})
