"""Fixed-step baselines on the same model and the same Result contract as IDA.

``exact-modal`` (docs/theory.md): each plate mode is propagated exactly over a step with a
first-order-hold (piecewise-linear) modal force, ``s_{n+1} = Phi s_n + G0 u_n + G1 u_{n+1}``,
which is unconditionally stable and free of period error even for modes with omega h > pi.
The plate displacement at the contacts is then ``w_{n+1} = w_free + G1c F_{n+1}`` (plus the
residual compliance), so the only implicit problem per step is the K contact forces coupled to
the block, solved with an active set on the unilateral springs (at most K + 1 passes).

``newmark``: the same step with the plate modes integrated by average-acceleration Newmark
(trapezoidal, second order); for a linear mode this is again an affine map (Phi, G0, G1), so
both schemes share one numba loop and differ only in the precomputed per-mode coefficients.

Both use average-acceleration Newmark for the block's vertical motion and the trapezoidal rule
with a scalar Newton iteration for the tangential motion, staggered: the tangential step uses
the normal force of the previous step (a staggering that costs little accuracy). Events are
located by sign changes between steps with linear interpolation and written to the same event log.
"""

from __future__ import annotations

import collections
import math
import time

import numpy as np
from numba import njit
from scipy.linalg import expm

from roughvib.model import kernels as kn
from roughvib.model.regimes import initial_regime
from roughvib.model.system import System
from roughvib.physics.friction import (
    LAWS,
    kinetic_coefficient,
    latch_update,
    single_valued_mu_law,
)
from roughvib.physics.surface.interp import profile_eval
from roughvib.scene import SceneError
from roughvib.solvers.base import FIRST_ROW, MODE_DQ, MODE_Q, RawSolution
from roughvib.solvers.events import EventRecord, initial_phase_events

__all__ = ["modal_propagators", "solve_fixed_step"]

EV_KINDS = ("lift_off", "touch_down", "stick", "slip", "latch_flip")
#: bisection steps of Moreau's slip velocity: 200 halvings reach the relative 1e-14 bracket
#: from any start (the loop stops there, after about 50)
MOREAU_BISECTION_MAX = 200

# the tangential loop state ``tang``: x [m], vx [m/s], latch sign s, latch extremum [m/s],
# stick phase (1.0 / 0.0); the paper scheme appends the static plate deflections (K)
TG_X = 0
TG_VX = 1
TG_LATCH = 2
TG_VEXT = 3
TG_STICK = 4
TG_WSTAT = 5
N_TANG = 5
# the vertical loop state ``zv``: z [m], vz [m/s], az [m/s^2]
ZV_Z = 0
ZV_VZ = 1
ZV_AZ = 2
N_ZV = 3
# a mode's state [q, q'] in the propagators Phi (R, 2, 2), G0, G1 (R, 2): MODE_Q, MODE_DQ
# (solvers/base.py); the augmented state [q, q', u, u'] of the exact first-order-hold step
# (modal_propagators) adds
AUG_U = 2
AUG_DU = 3


def modal_propagators(omega: np.ndarray, zeta: np.ndarray, h: float, scheme: str
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-mode step maps for q'' + 2 zeta w q' + w^2 q = u(t).

    Parameters
    ----------
    omega, zeta : ndarray, shape (R,)
        Angular frequencies [rad/s] and damping ratios.
    h : float
        Step [s].
    scheme : {"exact-modal", "newmark"}
        ``exact-modal``: exact solution for u linear within the step (augmented matrix
        exponential). ``newmark``: average-acceleration Newmark.

    Returns
    -------
    Phi : ndarray, shape (R, 2, 2)
    G0, G1 : ndarray, shape (R, 2)
        ``[q, q']_{n+1} = Phi [q, q']_n + G0 u_n + G1 u_{n+1}``.
    """
    R = omega.size
    Phi = np.empty((R, 2, 2))
    G0 = np.empty((R, 2))
    G1 = np.empty((R, 2))
    for r in range(R):
        w, c = float(omega[r]), 2.0 * float(zeta[r]) * float(omega[r])
        if scheme == "exact-modal":
            A = np.zeros((4, 4))
            A[MODE_Q, MODE_DQ] = 1.0
            A[MODE_DQ, MODE_Q] = -w * w
            A[MODE_DQ, MODE_DQ] = -c
            A[MODE_DQ, AUG_U] = 1.0       # u drives the acceleration
            A[AUG_U, AUG_DU] = 1.0   # u' = (u_{n+1} - u_n) / h, constant over the step
            E = expm(A * h)
            Phi[r] = E[:AUG_U, :AUG_U]
            G0[r] = E[:AUG_U, AUG_U] - E[:AUG_U, AUG_DU] / h
            G1[r] = E[:AUG_U, AUG_DU] / h
        elif scheme == "newmark":
            L = np.array([[1 + h * h * w * w / 4, h * h * c / 4], [h * w * w / 2, 1 + h * c / 2]])
            P = np.array([[1 - h * h * w * w / 4, h - h * h * c / 4],
                          [-h * w * w / 2, 1 - h * c / 2]])
            p = np.array([h * h / 4, h / 2])
            Li = np.linalg.inv(L)
            Phi[r] = Li @ P
            G0[r] = Li @ p
            G1[r] = Li @ p
        else:  # pragma: no cover - guarded by the scene
            raise ValueError(f"unknown fixed-step scheme {scheme!r}")
    return Phi, G0, G1


@njit(cache=True)
def log_step_events(t0, h, comp_old, comp, v0, v1, tang, vth, exact_stick, log_latch, eps,
                    ev_t, ev_kind, ev_contact, n_ev, tangential):
    """Events of one step by sign change, with linear interpolation (shared by the loops).

    Contacts: the compression changes sign (lift-off / touch-down). Tangential: ``|v|`` crosses
    ``vth`` (stick / slip; ``exact_stick``: stick means v == 0), and the hysteresis latch is
    advanced (``latch_flip`` logged when ``log_latch``). Updates ``comp_old`` and ``tang`` in
    place and returns the new event count.
    """
    cap = ev_t.size
    for k in range(comp.size):
        if (comp_old[k] > 0.0) != (comp[k] > 0.0) and n_ev < cap:
            frac = comp_old[k] / (comp_old[k] - comp[k]) if comp_old[k] != comp[k] else 1.0
            ev_t[n_ev] = t0 + h * frac
            ev_kind[n_ev] = 0 if comp_old[k] > 0.0 else 1
            ev_contact[n_ev] = k
            n_ev += 1
        comp_old[k] = comp[k]
    if not tangential:
        return n_ev
    was_stick = tang[TG_STICK] > 0.5
    now_stick = (v1 == 0.0) if exact_stick else abs(v1) < vth
    if was_stick != now_stick and n_ev < cap:
        a_ = abs(v0) - vth
        b_ = abs(v1) - vth
        frac = a_ / (a_ - b_) if a_ != b_ else 1.0
        ev_t[n_ev] = t0 + h * frac
        ev_kind[n_ev] = 2 if now_stick else 3
        ev_contact[n_ev] = -1
        n_ev += 1
        tang[TG_STICK] = 1.0 if now_stick else 0.0
    s_new, vext_new, flipped = latch_update(tang[TG_LATCH], tang[TG_VEXT], v1, eps)
    tang[TG_LATCH] = s_new
    tang[TG_VEXT] = vext_new
    if flipped and log_latch and n_ev < cap:
        ev_t[n_ev] = t0 + h
        ev_kind[n_ev] = 4
        ev_contact[n_ev] = -1
        n_ev += 1
    return n_ev


@njit(cache=True)
def _solve_contacts(active, stiff, beta, G1c, rhs, F, comp, K):
    """Active-set solve of F_k/s_k + beta sum(F) + sum_j G1c_kj F_j = rhs_k on closed k."""
    for _it in range(K + 2):
        idx = np.flatnonzero(active)
        for k in range(K):
            F[k] = 0.0
        if idx.size > 0:
            n = idx.size
            A = np.empty((n, n))
            b = np.empty(n)
            for a in range(n):
                ka = idx[a]
                b[a] = rhs[ka]
                for c in range(n):
                    kc = idx[c]
                    A[a, c] = beta + G1c[ka, kc]
                A[a, a] += 1.0 / stiff[ka]
            sol = np.linalg.solve(A, b)
            for a in range(n):
                F[idx[a]] = sol[a]
        S = 0.0
        for k in range(K):
            S += F[k]
        changed = False
        for k in range(K):
            acc = 0.0
            for j in range(K):
                acc += G1c[k, j] * F[j]
            comp[k] = rhs[k] - beta * S - acc
            if active[k] == 1 and F[k] < 0.0:
                active[k] = 0
                changed = True
            elif active[k] == 0 and comp[k] > 0.0:
                active[k] = 1
                changed = True
        if not changed:
            return True
    return False


#: the state the fixed-step loop advances in place: modal q, q' (R,), ``zv`` (ZV_*), contact
#: forces ``Fv`` (K,), the active contact set ``active`` (K,) int64, ``tang`` (TG_*) and the
#: running energy integrals ``energy`` (E_*)
LoopState = collections.namedtuple("LoopState",
                                   ["q", "dq", "zv", "Fv", "active", "tang", "energy"])
#: the event log of a fixed-step loop: times, kinds (EV_KINDS) and contacts, preallocated
EventArrays = collections.namedtuple("EventArrays", ["t", "kind", "contact"])


@njit(cache=True)
def _run(h, n_steps, out_every, Phi, G0, G1, phi, phi_obs, omega2, cdamp, stiff, cres, spos,
         prof, fp, law, tangential, moreau, state, out, evs):
    """:func:`_step_loop` on views of its arrays without memory records
    (:func:`roughvib.model.kernels.unowned`: no reference counting of them in the loop); the
    same arguments and results. Called from Python, which holds the arrays."""
    u = kn.unowned
    return _step_loop(h, n_steps, out_every, u(Phi), u(G0), u(G1), u(phi), u(phi_obs),
                      u(omega2), u(cdamp), u(stiff), u(cres), u(spos), u(prof), u(fp), law,
                      tangential, moreau,
                      LoopState(u(state.q), u(state.dq), u(state.zv), u(state.Fv),
                                u(state.active), u(state.tang), u(state.energy)),
                      u(out), EventArrays(u(evs.t), u(evs.kind), u(evs.contact)))


@njit(cache=True)
def _step_loop(h, n_steps, out_every, Phi, G0, G1, phi, phi_obs, omega2, cdamp, stiff, cres,
               spos, prof, fp, law, tangential, moreau, state, out, evs):
    """The fixed-step loop. Mutates ``state`` (``LoopState``), ``out`` and ``evs``
    (``EventArrays``); returns (n_events, status code, step).

    ``zv`` = [z, vz, az]; ``tang`` = [x, vx, latch s, v_ext, stick phase]; ``energy`` the six
    running integrals; status 0 ok, 1 Newton failure (tangential), 2 active set failure.

    Each step: the tangential velocity (``_moreau_velocity``, ``_trapezoidal_velocity`` or the
    prescribed motion), the modes' free response (``_free_response``), the block's
    predictor (``_block_predictor``), the contacts' right-hand side (``_contact_rhs``) and
    active-set solve (``_solve_contacts``), the modes' end state (``_end_modes``), the
    events (:func:`log_step_events`), the energy integrals (``_end_powers``,
    ``_add_energy``), and at an output time the row (``_output_row``).
    """
    q, dq, zv, Fv, active, tang, energy = state
    ev_t, ev_kind, ev_contact = evs
    R = Phi.shape[0]
    K = stiff.size
    M = fp[kn.FP_MMODAL]
    m, g, r1, r2, mu_sl, mu_st, a1, a2, vh, eps, vst = kn.block_parameters(fp)
    G1c = _contact_compliance(G1, phi, cres, M)
    u = np.empty(R)
    u_new = np.empty(R)
    sq = np.empty(R)
    sdq = np.empty(R)
    wfree = np.empty(K)
    rhs = np.empty(K)
    comp = np.empty(K)
    comp_old = np.empty(K)
    hk = np.empty(K)
    dhk = np.empty(K)
    Fn = np.empty(K)
    S0 = _start(q, Fv, zv, tang, phi, cres, spos, prof, fp, u, comp_old, dhk)
    x0 = tang[TG_X]
    v0 = tang[TG_VX]
    n_ev = 0
    # the powers at the step's start and end (E_*), swapped after each step
    pw = np.empty(kn.N_ENERGY)
    qw = np.empty(kn.N_ENERGY)
    _start_powers(tangential, moreau, v0, S0, zv[ZV_VZ], tang[TG_LATCH], Fv, dhk, dq, cdamp,
                  law, fp, pw)
    lam = 0.0
    row = 0
    for n in range(n_steps):
        t0 = n * h
        t1 = t0 + h
        # the tangential step (normal force of step n)
        if tangential and moreau:
            v1, lam = _moreau_velocity(t1, h, v0, S0, law, fp)
            x1 = x0 + h * v1
        elif tangential:
            v1, ok = _trapezoidal_velocity(t0, t1, h, v0, S0, tang[TG_LATCH], law, fp)
            if not ok:
                return n_ev, 1, n
            x1 = x0 + 0.5 * h * (v0 + v1)
        else:
            x1, v1 = kn.prescribed_motion(t1, fp)
        _free_response(Phi, G0, q, dq, u, phi, sq, sdq, wfree)
        zc, beta, Q, mp = _block_predictor(h, zv, m, g, r1)
        _contact_rhs(x1, zc, wfree, spos, prof, fp, hk, dhk, rhs)
        if not _solve_contacts(active, stiff, beta, G1c, rhs, Fn, comp, K):
            return n_ev, 2, n
        S1 = _end_modes(Fn, phi, G1, M, sq, sdq, u_new, q, dq, u)
        az0 = zv[ZV_AZ]
        az1 = (Q - S1) / mp
        vz1 = zv[ZV_VZ] + h / 2 * (az0 + az1)
        z1 = zc - beta * S1
        # events by sign change (Moreau: stick is v = 0 exactly)
        n_ev = log_step_events(t0, h, comp_old, comp, v0, v1, tang, 0.0 if moreau else vst,
                               moreau, not moreau, eps, ev_t, ev_kind, ev_contact, n_ev,
                               tangential)
        fric1, mu1 = _end_powers(tangential, moreau, t1, v1, vz1, S0, S1, lam,
                                 tang[TG_LATCH], Fn, dhk, dq, cdamp, law, fp, qw)
        _add_energy(energy, h, tangential, pw, qw)
        pw, qw = qw, pw
        # advance
        zv[ZV_Z], zv[ZV_VZ], zv[ZV_AZ] = z1, vz1, az1
        for k in range(K):
            Fv[k] = Fn[k]
        x0, v0, S0 = x1, v1, S1
        tang[TG_X] = x1
        tang[TG_VX] = v1
        if (n + 1) % out_every == 0:
            row += 1
            _output_row(out[row], tangential, z1, vz1, az1, x1, v1, fric1, S1, mu1, Fn, hk, q,
                        dq, phi, phi_obs, omega2, cdamp, fp)
    return n_ev, 0, n_steps


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _contact_compliance(G1, phi, cres, M):
    """G1 in contact coordinates [m/N]: ``G1c_kj = sum_r phi_rk phi_rj G1_r[q] / M + C_res``,
    the plate displacement at contact k per unit force at contact j at the step's end."""
    R = G1.shape[0]
    K = cres.shape[0]
    G1c = cres.copy()
    for r in range(R):
        gr = G1[r, MODE_Q] / M
        for k in range(K):
            for j in range(K):
                G1c[k, j] += phi[r, k] * phi[r, j] * gr
    return G1c


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _start(q, Fv, zv, tang, phi, cres, spos, prof, fp, u, comp_old, dhk):
    """The loop's start: the modal force per modal mass ``u`` [N/kg] of the forces Fv, the
    compressions ``comp_old`` [m] (for the events) and profile slopes ``dhk`` [-] at the
    start; returns the total normal force [N]."""
    R = q.size
    K = Fv.size
    M = fp[kn.FP_MMODAL]
    for r in range(R):
        acc = 0.0
        for k in range(K):
            acc += phi[r, k] * Fv[k]
        u[r] = acc / M
    S0 = 0.0
    for k in range(K):
        S0 += Fv[k]
    x0 = tang[TG_X]
    for k in range(K):
        w = 0.0
        for r in range(R):
            w += phi[r, k] * q[r]
        for j in range(K):
            w += cres[k, j] * Fv[j]
        hh, dh, _ = profile_eval(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + x0)
        comp_old[k] = zv[ZV_Z] - w + hh
        dhk[k] = dh
    return S0


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _start_powers(tangential, moreau, v0, S0, vz0, latch, Fv, dhk, dq, cdamp, law, fp, pw):
    """The powers [W] at the start into ``pw``, at the energy integrals' positions ``E_*``
    (``law``: the friction law's id, ``off[OFF_LAW]``)."""
    M = fp[kn.FP_MMODAL]
    m, g, r1, r2, mu_sl, mu_st, a1, a2, vh, eps, vst = kn.block_parameters(fp)
    p_exc = 0.0
    p_fric = 0.0
    if tangential and moreau:
        p_exc = fp[kn.FP_T0] * v0
    elif tangential:
        mu0, _ = single_valued_mu_law(law, v0 + latch * vh, mu_sl, mu_st, a1, a2)
        p_exc = fp[kn.FP_T0] * v0
        p_fric = mu0 * S0 * v0
    p_r2 = r2 * v0 * v0
    p_r1, p_pl, p_ro = _vertical_powers(v0, vz0, r1, Fv, dhk, dq, cdamp, M)
    _powers_at(p_exc, p_fric, p_r2, p_r1, p_pl, p_ro, pw)


@njit(cache=True, inline="always")
def _vertical_powers(v, vz, r1, F, dhk, dq, cdamp, M):
    """The vertical damper's, the plate's damping and the roughness input's powers [W] at
    block velocities v, vz [m/s], contact forces F [N] and profile slopes dhk [-]: the part
    the start and the end of a step share (``_start_powers``, ``_end_powers``)."""
    p_r1 = r1 * vz * vz
    p_pl = M * kn.weighted_square_sum(cdamp, dq)
    p_ro = 0.0
    for k in range(F.size):
        p_ro += F[k] * dhk[k] * v
    return p_r1, p_pl, p_ro


@njit(cache=True, inline="always")
def _powers_at(exc, fric, r2, r1, pl, ro, pw):
    """The six powers [W] into ``pw`` at the energy integrals' positions ``E_*``."""
    pw[kn.E_EXCITATION] = exc
    pw[kn.E_FRICTION] = fric
    pw[kn.E_TANGENTIAL_DAMPING] = r2
    pw[kn.E_VERTICAL_DAMPING] = r1
    pw[kn.E_PLATE_DAMPING] = pl
    pw[kn.E_ROUGHNESS] = ro


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _moreau_velocity(t1, h, v0, S0, law, fp):
    """Moreau-Jean's velocity at t1 [m/s] and friction force [N] over the step (Acary &
    Brogliato 2008): the free velocity, then the friction impulse as the projection onto
    [-h mu_stick F_N, h mu_stick F_N] (stick: v = 0 exactly); in slip
    ``|v1| = |vfree| - h mu_k(|v1|) S0 / (m + h r2)``, a scalar fixed point solved by
    bisection."""
    m, g, r1, r2, mu_sl, mu_st, a1, a2, vh, eps, vst = kn.block_parameters(fp)
    t_new = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t1)
    vfree = (v0 + h * t_new / m) / (1.0 + h * r2 / m)
    bound = h * mu_st * S0 / (m + h * r2)
    if abs(vfree) <= bound:
        v1 = 0.0
    else:
        lo, hi = 0.0, abs(vfree)
        for _it in range(MOREAU_BISECTION_MAX):
            mid = 0.5 * (lo + hi)
            muk, _ = kinetic_coefficient(law, mid, mu_sl, mu_st, fp[kn.FP_VSTRIB],
                                         fp[kn.N_FP:])
            if mid - (abs(vfree) - h * muk * S0 / (m + h * r2)) > 0.0:
                hi = mid
            else:
                lo = mid
            if hi - lo <= 1e-16 + 1e-14 * hi:
                break
        v1 = math.copysign(0.5 * (lo + hi), vfree)
    lam = (m + h * r2) * (vfree - v1) / h
    return v1, lam


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _trapezoidal_velocity(t0, t1, h, v0, S0, s_l, law, fp):
    """The velocity at t1 [m/s] under a single-valued law (id ``law``) by the trapezoidal
    rule, Newton on v1 with the latch s_l and the normal force S0 [N] of the step's start;
    ``(v1, converged)``."""
    m, g, r1, r2, mu_sl, mu_st, a1, a2, vh, eps, vst = kn.block_parameters(fp)
    t_old = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t0)
    t_new = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t1)
    mu0, _ = single_valued_mu_law(law, v0 + s_l * vh, mu_sl, mu_st, a1, a2)
    f0 = t_old - mu0 * S0 - r2 * v0
    v1 = v0
    for _it in range(60):
        mu1, dmu1 = single_valued_mu_law(law, v1 + s_l * vh, mu_sl, mu_st, a1, a2)
        gval = m * (v1 - v0) / h - 0.5 * f0 - 0.5 * (t_new - mu1 * S0 - r2 * v1)
        dg = m / h + 0.5 * (dmu1 * S0 + r2)
        dv = gval / dg
        v1 -= dv
        if abs(dv) <= 1e-15 + 1e-13 * abs(v1):
            return v1, True
    return v1, False


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _free_response(Phi, G0, q, dq, u, phi, sq, sdq, wfree):
    """The modes' free response over the step (the force held at its start value's share):
    ``sq``, ``sdq`` (R,), and the plate displacement it gives at the contacts ``wfree``
    (K,) [m], summed in vectorisable order (:func:`roughvib.model.kernels.vdot`)."""
    for r in range(q.size):
        sq[r] = (Phi[r, MODE_Q, MODE_Q] * q[r] + Phi[r, MODE_Q, MODE_DQ] * dq[r]
                 + G0[r, MODE_Q] * u[r])
        sdq[r] = (Phi[r, MODE_DQ, MODE_Q] * q[r] + Phi[r, MODE_DQ, MODE_DQ] * dq[r]
                  + G0[r, MODE_DQ] * u[r])
    for k in range(wfree.size):
        wfree[k] = kn.vdot(phi[:, k], sq)


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _block_predictor(h, zv, m, g, r1):
    """The block's average-acceleration Newmark step, affine in the total contact force S1
    [N]: ``z1 = zc - beta S1``, ``az1 = (Q - S1) / mp``; returns ``(zc, beta, Q, mp)``."""
    z0, vz0, az0 = zv[ZV_Z], zv[ZV_VZ], zv[ZV_AZ]
    mp = m + r1 * h / 2
    Q = m * g - r1 * (vz0 + h * az0 / 2)
    zc = z0 + h * vz0 + h * h / 4 * (az0 + Q / mp)
    beta = h * h / (4 * mp)
    return zc, beta, Q, mp


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _contact_rhs(x1, zc, wfree, spos, prof, fp, hk, dhk, rhs):
    """The profile heights ``hk`` [m] and slopes ``dhk`` [-] at the contacts at x1 and the
    right-hand side of the contact solve ``rhs = zc - wfree + h`` [m]."""
    for k in range(rhs.size):
        hh, dh, _ = profile_eval(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + x1)
        hk[k] = hh
        dhk[k] = dh
        rhs[k] = zc - wfree[k] + hh


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _end_modes(Fn, phi, G1, M, sq, sdq, u_new, q, dq, u):
    """The modes at the step's end under the contact forces Fn [N]: q, dq and the modal
    force per modal mass ``u`` updated in place; returns the total normal force [N]."""
    S1 = 0.0
    for k in range(Fn.size):
        S1 += Fn[k]
    inv_m = 1.0 / M
    for r in range(q.size):
        acc = 0.0
        for k in range(Fn.size):
            acc += phi[r, k] * Fn[k]
        u_new[r] = acc * inv_m
        q[r] = sq[r] + G1[r, MODE_Q] * u_new[r]
        dq[r] = sdq[r] + G1[r, MODE_DQ] * u_new[r]
        u[r] = u_new[r]
    return S1


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _end_powers(tangential, moreau, t1, v1, vz1, S0, S1, lam, latch, Fn, dhk, dq, cdamp, law,
                fp, qw):
    """The friction force [N] and coefficient [-] at the step's end, ``(fric1, mu1)``, and
    the powers [W] there into ``qw`` (at the positions ``E_*``; ``law``: the friction law's
    id, ``off[OFF_LAW]``)."""
    M = fp[kn.FP_MMODAL]
    m, g, r1, r2, mu_sl, mu_st, a1, a2, vh, eps, vst = kn.block_parameters(fp)
    q_exc = 0.0
    q_fric = 0.0
    mu1 = 0.0
    fric1 = 0.0
    if tangential and moreau:
        fric1 = lam
        mu1 = lam / S0 if S0 > 0.0 else np.nan
        q_exc = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t1) * v1
        q_fric = lam * v1
    elif tangential:
        mu1, _ = single_valued_mu_law(law, v1 + latch * vh, mu_sl, mu_st, a1, a2)
        fric1 = mu1 * S1
        q_exc = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t1) * v1
        q_fric = mu1 * S1 * v1
    q_r2 = r2 * v1 * v1 if tangential else 0.0
    q_r1, q_pl, q_ro = _vertical_powers(v1, vz1, r1, Fn, dhk, dq, cdamp, M)
    _powers_at(q_exc, q_fric, q_r2, q_r1, q_pl, q_ro, qw)
    return fric1, mu1


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _add_energy(energy, h, tangential, p, q):
    """The energy integrals [J] over the step: trapezoidal quadrature of the powers p at its
    start and q at its end (``E_*``; no tangential damping under prescribed motion)."""
    energy[kn.E_EXCITATION] += 0.5 * h * (p[kn.E_EXCITATION] + q[kn.E_EXCITATION])
    energy[kn.E_FRICTION] += 0.5 * h * (p[kn.E_FRICTION] + q[kn.E_FRICTION])
    if tangential:  # prescribed motion: the integral stays 0
        energy[kn.E_TANGENTIAL_DAMPING] += 0.5 * h * (p[kn.E_TANGENTIAL_DAMPING]
                                                      + q[kn.E_TANGENTIAL_DAMPING])
    energy[kn.E_VERTICAL_DAMPING] += 0.5 * h * (p[kn.E_VERTICAL_DAMPING]
                                                + q[kn.E_VERTICAL_DAMPING])
    energy[kn.E_PLATE_DAMPING] += 0.5 * h * (p[kn.E_PLATE_DAMPING] + q[kn.E_PLATE_DAMPING])
    energy[kn.E_ROUGHNESS] += 0.5 * h * (p[kn.E_ROUGHNESS] + q[kn.E_ROUGHNESS])


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _output_row(out, tangential, z1, vz1, az1, x1, v1, fric1, S1, mu1, Fn, hk, q, dq, phi,
                phi_obs, omega2, cdamp, fp):
    """The output row of the step's end: the plate's acceleration at the observation point
    and ``kernels.write_output_row``."""
    acc = kn.observed_acceleration(q, dq, Fn, phi, phi_obs, omega2, cdamp, fp[:0], 0.0,
                                   fp[kn.FP_MMODAL])
    kn.write_output_row(out, tangential, z1, vz1, az1, acc, x1, v1, fric1, S1, mu1, Fn, hk)


def step_grid(scene) -> tuple[float, int, int, int]:
    """Fixed step h, output stride, output samples and steps; checks h divides output.step.

    Raises
    ------
    SceneError
        When ``output.step / solver.step`` is not a whole number.
    """
    h = scene.solver.step
    ratio = scene.output.step / h
    out_every = int(round(ratio))
    if out_every < 1 or abs(ratio - out_every) > 1e-9 * ratio:
        raise SceneError(f"solver.step must divide output.step ({scene.output.step} s) into a "
                         f"whole number of steps, got {h} s")
    n_out = int(round(scene.output.duration / scene.output.step)) + 1
    return h, out_every, n_out, (n_out - 1) * out_every


def event_records(n_ev: int, ev_t: np.ndarray, ev_kind: np.ndarray, ev_contact: np.ndarray
                  ) -> list[EventRecord]:
    """Event arrays of a fixed-step loop to sorted event-log records (kinds ``EV_KINDS``)."""
    return sorted((EventRecord(float(ev_t[i]), EV_KINDS[int(ev_kind[i])], int(ev_contact[i]),
                               "", "", 0.0, 0.0, np.nan, np.nan, np.nan, np.nan, np.nan)
                   for i in range(n_ev)), key=lambda e: e.time)


def solve_fixed_step(system: System, *, progress: bool | None = None) -> RawSolution:
    """Integrate with a fixed-step scheme (``scene.solver.method``) on the output grid.

    The solver step must divide the output step (``output.step / solver.step`` an integer);
    outputs are the states at those steps, not interpolations.
    """
    scene = system.scene
    method = scene.solver.method
    moreau = method == "moreau"
    if kn.moment_on(system.off):  # scene/core.py refuses it; this guards a direct call
        raise SceneError(f"contact.friction_moment = true needs solver.method 'ida' or "
                         f"'adaptive-modal', got {method!r}")
    law = LAWS[scene.friction.law]
    # the scene check's rule, again for a direct call
    if system.tangential and method not in law.solvers:
        raise SceneError(f"solver.method = {method!r} does not run friction.law = {law.name!r} "
                         f"({law.kind}; it runs with {', '.join(law.solvers)})")
    h, out_every, n_out, n_steps = step_grid(scene)
    K = system.n_contacts
    lay = system.layout
    omega = np.sqrt(system.omega2)
    zeta = np.where(omega > 0, system.cdamp / (2 * np.maximum(omega, 1e-300)), 0.0)
    Phi, G0, G1 = modal_propagators(omega, zeta, h, "exact-modal" if moreau else method)

    y0, closed = system.static_equilibrium()
    # the law's own initial regime (the Coulomb law: stick unless the block cannot hold)
    regime = initial_regime(closed, system.fp, lay.tangential, system.scene.friction.law)
    reg, rf = system.new_regime_arrays()
    regime.pack(reg, rf)
    y, _ = system.consistent(0.0, y0, reg, rf)
    q = y[lay.slice("plate.q")].copy()
    dq = y[lay.slice("plate.dq")].copy()
    Fv = y[lay.slice("contact.force")].copy()
    zv = np.zeros(N_ZV)
    zv[ZV_Z] = y[lay.index("block.z")]
    zv[ZV_VZ] = y[lay.index("block.vz")]
    zv[ZV_AZ] = system.fp[kn.FP_GRAV] - Fv.sum() / system.fp[kn.FP_MASS]
    # initial phase as IDA's: stick at rest; with the Coulomb law only if the block cannot move
    start_stick = regime.stick
    tang = np.zeros(N_TANG)
    tang[TG_LATCH] = float(regime.latch)
    tang[TG_STICK] = 1.0 if start_stick else 0.0
    energy = np.zeros(kn.N_ENERGY)
    out = np.full((n_out, kn.n_output_columns(K)), np.nan)
    args = system.kernel_args(reg, rf)
    kn.outputs(0.0, y, out[FIRST_ROW], *args)
    cap = 2_000_000
    ev_t = np.empty(cap)
    ev_kind = np.empty(cap, dtype=np.int8)
    ev_contact = np.empty(cap, dtype=np.int64)
    active = closed.astype(np.int64).copy()
    wall0 = time.perf_counter()
    cpu0 = time.process_time()
    n_ev, code, n_done = _run(h, n_steps, out_every, Phi, G0, G1, system.phi, system.phi_obs,
                              system.omega2, system.cdamp, system.stiff, system.cres,
                              system.input_s, system.prof, system.fp,
                              int(system.off[kn.OFF_LAW]), lay.tangential, moreau,
                              LoopState(q, dq, zv, Fv, active, tang, energy), out,
                              EventArrays(ev_t, ev_kind, ev_contact))
    wall = time.perf_counter() - wall0
    status, message = "success", "reached the end of the output grid"
    if code == 1:
        status = "newton_failure"
        message = (f"tangential Newton iteration failed at t = {n_done * h:.6g} s "
                   f"(solver.step {h} s); hint: reduce solver.step")
    elif code == 2:
        status = "active_set_failure"
        message = f"contact active set did not converge at t = {n_done * h:.6g} s"
    events = (initial_phase_events(system, 0.0, y, reg, rf, start_stick)
              + event_records(n_ev, ev_t, ev_kind, ev_contact))
    # final state vector in the IDA layout (for the energy audit)
    yf = np.zeros(lay.size)
    yf[lay.slice("plate.q")] = q
    yf[lay.slice("plate.dq")] = dq
    yf[lay.index("block.z")] = zv[ZV_Z]
    yf[lay.index("block.vz")] = zv[ZV_VZ]
    if lay.tangential:
        yf[lay.index("block.x")] = tang[TG_X]
        yf[lay.index("block.vx")] = tang[TG_VX]
    yf[lay.slice("contact.force")] = Fv
    if lay.has("friction.force"):
        yf[lay.index("friction.force")] = 0.0
    for i, name in enumerate(lay.names[-6:]):
        yf[lay.index(name)] = energy[i]
    rows = (n_done // out_every) + 1 if code else n_out
    stats = {"steps": int(n_done), "step_size": h, "residual_evaluations": None,
             "jacobian_evaluations": None, "restarts": 0, "wall_time": wall,
             "cpu_time": time.process_time() - cpu0, "events_total": len(events),
             "events_truncated": n_ev >= cap}
    return RawSolution(time=np.arange(n_out) * scene.output.step, outputs=out, events=events,
                       stats=stats, status=status, message=message, y_initial=y,
                       y_final=yf, t_final=float(n_done * h), extra={"rows_filled": rows})
