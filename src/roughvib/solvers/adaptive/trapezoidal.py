"""The trapezoidal step of adaptive-modal and its Newton solve (docs/theory.md, "The adaptive
exact-modal scheme").

The plate modes couple to the block only through the K contact forces, and each mode is a
linear oscillator propagated exactly (:mod:`.propagators`). The block's vertical and
tangential motion use the trapezoidal rule, so the only implicit problem per step is the K
contact forces and the tangential velocity, solved by Newton on a (K+1)-square system (no
matrix of the plate's size is ever formed). The step is second order; unlike BDF2 it has no
error at all in the modes' own dynamics, only in the force history.

Friction: every law of ``roughvib.physics.friction.LAWS`` (or prescribed motion). The
Feldmann law is a smooth function of the velocity in each branch. A set-valued law
(``coulomb``, ``table``) slides with its kinetic curve and its exact slope in the Newton row
of the velocity; in its stick regime the block is held (v = 0, x fixed, no tangential unknown)
and the friction force is the algebraic ``friction.force`` that holds it.
"""

from __future__ import annotations

import collections
import math

import numpy as np
from numba import njit

from roughvib.model import kernels as kn
from roughvib.model.krylov import lu_factor, lu_solve
from roughvib.physics.surface.interp import profile_eval
from roughvib.solvers.adaptive.layout import D_AX, D_AZ, D_POWER, I_NEWTON
from roughvib.solvers.adaptive.propagators import (
    MAP_DD,
    MAP_DQ,
    MAP_G0D,
    MAP_G0Q,
    MAP_G1D,
    MAP_G1Q,
    MAP_QD,
    MAP_QQ,
    modal_force,
    moment_force,
    moment_map,
)

__all__ = ["N_WS", "WS_F", "WS_IDX", "WS_NOISE", "WS_RHS", "WS_SDQ", "WS_SQ", "WS_UM",
           "WS_WFREE", "WS_WM", "Scratch", "derivatives", "forced_response", "free_response",
           "friction_force", "holds_stick", "implicit_step", "moment_coefficient",
           "new_scratch", "ws_length", "ws_size", "ws_slice", "ws_start"]

NEWTON_TOL = 1e-6    # Newton update, in units of the tolerance weights ...
NEWTON_ULPS = 8.0    # ... or within this many round-offs of its equation's terms
NEWTON_MAX_ITER = 25  # Newton iterations before the step is given up (retried smaller)
EPS = 2.220446049250313e-16  # double-precision unit round-off (numpy.finfo(float).eps)

#: scratch of the kernels and of implicit_step: ``work`` (kernels), ``ws`` (>= :func:`ws_size`),
#: ``jac`` (K + 1, K + 1), ``ipiv`` (K + 1,) int64
Scratch = collections.namedtuple("Scratch", ["work", "ws", "jac", "ipiv"])

#: the slices of implicit_step's float scratch ``ws``, in this order (lengths :func:`ws_length`,
#: starts :func:`ws_start`, views :func:`ws_slice`)
WS_SQ = 0      #: the modes' free response q over the step (R)
WS_SDQ = 1     #: and its rate q' (R)
WS_WFREE = 2   #: the plate's free displacement at the contacts [m] (K)
WS_F = 3       #: the contact forces, Newton's iterate [N] (K)
WS_RHS = 4     #: Newton's right-hand side, then its update (K + 1: forces, velocity)
WS_IDX = 5     #: the closed contacts' indices, as floats (K + 1)
WS_NOISE = 6   #: the round-off level of each update (K + 1)
WS_UM = 7      #: the friction moment's modal force at t1 [m/s^2] (R)
WS_WM = 8      #: its plate displacement at the contacts [m], divided by the coefficient c (K)
N_WS = 9


@njit(cache=True, inline="always")
def ws_length(i, R, K):
    """Length of slice ``i`` (``WS_*``) of implicit_step's float scratch for R modes and K
    contacts."""
    if i == WS_SQ or i == WS_SDQ or i == WS_UM:
        return R
    if i == WS_RHS or i == WS_IDX or i == WS_NOISE:
        return K + 1  # the Newton unknowns: the forces and the velocity
    return K


@njit(cache=True, inline="always")
def ws_start(i, R, K):
    """Start of slice ``i`` (``WS_*``) of implicit_step's float scratch: the lengths of the
    slices before it (``i = N_WS``: the scratch's whole length)."""
    start = 0
    for j in range(i):
        start += ws_length(j, R, K)
    return start


@njit(cache=True, inline="always")
def ws_slice(ws, i, R, K):
    """The view of slice ``i`` (``WS_*``) of implicit_step's float scratch ``ws``."""
    start = ws_start(i, R, K)
    return ws[start:start + ws_length(i, R, K)]


def ws_size(R: int, K: int) -> int:
    """Length of implicit_step's float scratch ``ws`` for R modes and K contacts."""
    return int(ws_start(N_WS, R, K))


def new_scratch(work: np.ndarray, R: int, K: int) -> Scratch:
    """implicit_step's scratch for R modes and K contacts, with the kernels' ``work``."""
    return Scratch(work, np.zeros(ws_size(R, K)), np.zeros((K + 1, K + 1)),
                   np.zeros(K + 1, dtype=np.int64))


@njit(cache=True)
def friction_force(t, y, vx, fsum, off, fp, reg):
    """Friction force on the block [N] and its slopes, for the scene's law and regime.

    The force is the one of :func:`.kernels.residual`: the Feldmann law ``mu(v + s v_h) F_N``
    of the branch and latch; a set-valued law in slip b ``b mu_k(b v) F_N`` (the law's kinetic
    curve, :func:`.kernels.kinetic`), in stick ``T_exc - r2 v``, whatever holds the block
    (:func:`.kernels.set_valued_friction`).

    Parameters
    ----------
    t : float
        Time [s].
    y : ndarray, shape (n_states,)
        State; only the stick force of a set-valued law reads it (its ``block.vx``).
    vx, fsum : float
        Tangential velocity [m/s] and normal force (sum of the contact forces) [N] at which
        the kinetic force is evaluated.
    off, fp, reg : ndarray
        The kernels' header, scalars and regime.

    Returns
    -------
    fric : float
        [N].
    dfric_dv : float
        d fric / d vx at fixed normal force [N s/m] (0 in stick: vx is no unknown there).
    dfric_dfn : float
        d fric / d fsum [-]: the signed friction coefficient (0 in stick).
    """
    if kn.set_valued(off):
        b = reg[kn.REG_B]
        if b == 0:
            return kn.set_valued_friction(t, y, off, fp, reg), 0.0, 0.0
        muk, dmuk = kn.kinetic(b * vx, off, fp)
        # d/dv of b mu_k(b v): b^2 mu_k' = mu_k'
        return b * muk * fsum, dmuk * fsum, b * muk
    mu, dmu = kn.velocity_law(vx, off, fp, reg)  # raises for a law of another kind
    return mu * fsum, dmu * fsum, mu


@njit(cache=True)
def holds_stick(off, reg):
    """Whether the block is held in the stick regime of a set-valued law (v = 0, no unknown)."""
    return kn.set_valued(off) and reg[kn.REG_B] == 0


@njit(cache=True)
def moment_coefficient(t1, v1, S1, off, fp, reg):
    """The friction moment's share c (T_k = c F_k) at the end of a step, and its slopes.

    The step's unknowns are the velocity v1 and the closed contacts' forces (sum S1), so c is
    written in them rather than read from a state (:func:`.kernels.moment_share` is the same c
    of a whole state). Feldmann law: ``c = mu(v1)`` of the regime's branch and latch. A
    set-valued law in slip b: ``c = b mu_k(b v1)`` (its ``lambda / F_N``, whatever F_N); in
    stick ``c = lambda / S1`` with the holding force ``lambda = T_exc(t1)`` (v = 0), and 0
    when no contact carries load.

    Returns
    -------
    c : float
        [-].
    dc_dv : float
        d c / d v1 [s/m].
    dc_ds : float
        d c / d S1 [1/N]: the same for every closed contact's force.
    """
    if kn.set_valued(off):
        b = reg[kn.REG_B]
        if b != 0:
            muk, dmuk = kn.kinetic(b * v1, off, fp)
            return b * muk, dmuk, 0.0  # d/dv of b mu_k(b v): b^2 mu_k' = mu_k'
        if not S1 > 0.0:
            return 0.0, 0.0, 0.0
        lam = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t1)
        return lam / S1, 0.0, -lam / (S1 * S1)
    mu, dmu = kn.velocity_law(v1, off, fp, reg)  # raises for a law of another kind
    return mu, dmu, 0.0


@njit(cache=True)
def derivatives(t, y, d, off, fp, cdamp, spos, prof, reg):
    """Block accelerations and the six energy powers of a consistent state.

    ``d[D_AZ]`` = z'' [m/s^2], ``d[D_AX]`` = x'' [m/s^2] (0 for prescribed motion), ``d[2:8]`` the
    time derivatives of the energy integrals [W], exactly as in :func:`.kernels.residual`, with
    the friction force of :func:`friction_force` for every law: in the stick regime of a
    set-valued law it balances the drive (x'' = 0) and, at v = 0, does no work. With a
    friction moment the friction's power is ``mu sum_k F_k (v - u'_k)``: the rest goes into
    the plate.
    """
    _iq, idq, _iz, ivz, ix, _ivx, iF, _iE, R, K = kn.state_offsets(off)
    m = fp[kn.FP_MASS]
    M = fp[kn.FP_MMODAL]
    fsum = 0.0
    for k in range(K):
        fsum += y[iF + k]
    vz = y[ivz]
    d[D_AZ] = fp[kn.FP_GRAV] - fp[kn.FP_R1] * vz / m - fsum / m
    x, vx = kn.tangential_kinematics(t, y, off, fp)
    if ix >= 0:
        texc = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t)
        fric, _, _ = friction_force(t, y, vx, fsum, off, fp, reg)
        d[D_AX] = (texc - fric - fp[kn.FP_R2] * vx) / m
        d[D_POWER + kn.E_EXCITATION] = texc * vx
        d[D_POWER + kn.E_FRICTION] = fric * vx
        if kn.moment_on(off):  # the moment's power goes into the plate, not into heat
            # its share c of the friction force per unit contact force (a set-valued law's
            # c = lambda / F_N reads the state's lambda: set before derivatives is called)
            c, _, _, _ = kn.moment_share(t, y, off, fp, reg)
            d[D_POWER + kn.E_FRICTION] = fric * vx - c * kn.moment_power(y, off, fp)
        d[D_POWER + kn.E_TANGENTIAL_DAMPING] = fp[kn.FP_R2] * vx * vx
    else:
        d[D_AX] = 0.0
        d[D_POWER + kn.E_EXCITATION] = 0.0
        d[D_POWER + kn.E_FRICTION] = 0.0
        d[D_POWER + kn.E_TANGENTIAL_DAMPING] = 0.0
    d[D_POWER + kn.E_VERTICAL_DAMPING] = fp[kn.FP_R1] * vz * vz
    d[D_POWER + kn.E_PLATE_DAMPING] = M * kn.weighted_square_sum(cdamp, y[idq:idq + R])
    rough = 0.0
    for k in range(K):
        _, dh, _ = profile_eval(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + x)
        rough += y[iF + k] * dh * vx
    d[D_POWER + kn.E_ROUGHNESS] = rough


@njit(cache=True, inline="always")  # inlined into implicit_step: a call costs speed here
def free_response(P, q, dq, u0, phiT, sq, sdq, wfree):
    """The modes' response at the step end without the force's end value, and the plate
    displacement it gives at the contacts (implicit_step's first loop over the modes).

    Parameters
    ----------
    P : ndarray, shape (N_MAP, R)
        The slot's maps (``Propagators.P[slot]``).
    q, dq : ndarray, shape (R,)
        Modal coordinates and velocities at the step start [sqrt(kg) m, sqrt(kg) m/s].
    u0 : ndarray, shape (R,)
        Modal force per unit modal mass at the step start [m/s^2].
    phiT : ndarray, shape (K, R)
        Mode shapes at the contacts, transposed.
    sq, sdq : ndarray, shape (R,)
        Receive ``Phi [q, q'] + G0 u0``.
    wfree : ndarray, shape (K,)
        Receives ``sum_r phi_rk sq_r`` [m].
    """
    pqq, pqd, pdq, pdd = P[MAP_QQ], P[MAP_QD], P[MAP_DQ], P[MAP_DD]
    g0q, g0d = P[MAP_G0Q], P[MAP_G0D]
    for r in range(q.size):
        qr = q[r]
        dqr = dq[r]
        ur = u0[r]
        sq[r] = pqq[r] * qr + pqd[r] * dqr + g0q[r] * ur
        sdq[r] = pdq[r] * qr + pdd[r] * dqr + g0d[r] * ur
    for k in range(wfree.size):
        wfree[k] = kn.vdot(phiT[k], sq)


@njit(cache=True, inline="always")  # inlined into implicit_step: a call costs speed here
def forced_response(P, sq, sdq, u1, q1, dq1):
    """The modes at the step end: ``[q1, q1'] = [sq, sdq] + G1 u1`` (P, sq, sdq as in
    :func:`free_response`; u1 the modal force at the step end [m/s^2], shape (R,))."""
    g1q, g1d = P[MAP_G1Q], P[MAP_G1D]
    for r in range(sq.size):
        q1[r] = sq[r] + g1q[r] * u1[r]
        dq1[r] = sdq[r] + g1d[r] * u1[r]


@njit(cache=True, inline="always")  # a part of implicit_step, as fast as if written there
def _moment_displacements(Hm, F, wm):
    """wm_k = sum_j Hm_kj F_j: the friction moment's displacement at the contacts per unit
    share c [m] (``Hm`` of the step's slot, :func:`.propagators.moment_map`)."""
    K = wm.size
    for k in range(K):
        acc = 0.0
        for j in range(K):
            acc += Hm[k, j] * F[j]
        wm[k] = acc


@njit(cache=True, inline="always")  # a part of implicit_step, as fast as if written there
def _contact_rows(h, x1, S1, mu1, dmu1, dmus, nc, idx, F, zc, beta, wfree, wm, G1c, slot, Hm,
                  stiff, spos, prof, fp, moment, sliding, jac, rhs, noise):
    """The Newton rows of the closed contacts ``idx[:nc]`` at the iterate (F, v1 -> x1):
    the contact relation ``F_k / s_k = z1 - w_k(t1) + h(s_k + x1)`` with the block's
    trapezoidal z1 = zc - beta S1 and the plate's forced response ``G1c F`` (and, with the
    friction moment, its share ``mu1 Hm F``). Fills ``jac[:nc]`` (with the column of the
    velocity when ``sliding``), the residuals ``rhs[:nc]`` (negated) and their round-off
    levels ``noise[:nc]`` (see :func:`implicit_step`)."""
    for a in range(nc):
        k = int(idx[a])
        hh, dh, _ = profile_eval(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + x1)
        acc = 0.0
        for c in range(nc):
            j = int(idx[c])
            acc += G1c[slot, k, j] * F[j]
            jac[a, c] = G1c[slot, k, j] + beta
            if moment:
                jac[a, c] += mu1 * Hm[k, j] + dmus * wm[k]
        jac[a, a] += 1.0 / stiff[k]
        if moment:
            acc += mu1 * wm[k]
        rhs[a] = -(F[k] / stiff[k] - (zc - beta * S1 - wfree[k] - acc + hh))
        noise[a] = NEWTON_ULPS * EPS * (abs(F[k]) / stiff[k] + abs(zc) + abs(beta * S1)
                                        + abs(wfree[k]) + abs(acc) + abs(hh)) / jac[a, a]
        if sliding:
            jac[a, nc] = -dh * 0.5 * h
            if moment:
                jac[a, nc] += dmu1 * wm[k]


@njit(cache=True, inline="always")  # a part of implicit_step, as fast as if written there
def _velocity_row(t1, h, y0, d0, v0, v1, S1, nc, texc1, off, fp, reg, jac, rhs, noise):
    """The Newton row of the tangential velocity v1 (row ``nc``) of a sliding block: the
    trapezoidal rule ``m (v1 - v0) / h = (m a0 + T_exc(t1) - fric(v1, S1) - r2 v1) / 2``.
    Fills ``jac[nc, :nc + 1]``, ``rhs[nc]`` and ``noise[nc]`` (see :func:`implicit_step`)."""
    m = fp[kn.FP_MASS]
    r2 = fp[kn.FP_R2]
    fric, dfric_dv, dfric_dfn = friction_force(t1, y0, v1, S1, off, fp, reg)
    rhs[nc] = -(m * (v1 - v0) / h - 0.5 * m * d0[D_AX]
                - 0.5 * (texc1 - fric - r2 * v1))
    for c in range(nc):
        jac[nc, c] = 0.5 * dfric_dfn
    jac[nc, nc] = m / h + 0.5 * (dfric_dv + r2)
    noise[nc] = NEWTON_ULPS * EPS * (m * (abs(v1) + abs(v0)) / h + 0.5 * m * abs(d0[D_AX])
                                     + 0.5 * (abs(texc1) + abs(fric) + abs(r2 * v1))
                                     ) / abs(jac[nc, nc])


@njit(cache=True, inline="always")  # a part of implicit_step, as fast as if written there
def _newton_update(nc, idx, F, v1, sliding, rhs, noise, wts, iF, ivx):
    """Add the solved Newton update ``rhs`` to the forces ``F`` of ``idx[:nc]`` and (when
    ``sliding``) to v1. Returns ``(v1, worst)``: the new velocity [m/s] and the largest update
    in units of its tolerance weight, or of its round-off level / ``NEWTON_TOL`` where that is
    larger."""
    worst = 0.0
    for a in range(nc):
        k = int(idx[a])
        F[k] += rhs[a]
        e = abs(rhs[a]) / max(wts[iF + k], noise[a] / NEWTON_TOL)
        if e > worst:
            worst = e
    if sliding:
        v1 += rhs[nc]
        e = abs(rhs[nc]) / max(wts[ivx], noise[nc] / NEWTON_TOL)
        if e > worst:
            worst = e
    return v1, worst


@njit(cache=True, inline="always")  # a part of implicit_step, as fast as if written there
def _end_state(t1, h, y0, d0, y1, d1, u1, F, v1, x0, v0, av, cz, zc, beta, sq, sdq, um, P,
               phiT, moment, sliding, force_driven, off, fp, cdamp, spos, prof, reg):
    """The state (y1, d1, u1) at the end t1 of a converged step from the contact forces F
    [N] and the velocity v1 [m/s]: the modes' forced response, the block's trapezoidal rule
    (``av``, ``cz``, ``zc``, ``beta`` of :func:`implicit_step`), the algebraic friction force
    of a set-valued law, the derivatives and the energy integrals (trapezoidal)."""
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = kn.state_offsets(off)
    m = fp[kn.FP_MASS]
    M = fp[kn.FP_MMODAL]
    S1 = 0.0
    for k in range(K):
        S1 += F[k]
        y1[iF + k] = F[k]
    modal_force(F, u1, phiT, M)
    if moment:
        mu1, _, _ = moment_coefficient(t1, v1, S1, off, fp, reg)
        moment_force(F, mu1, M, off, fp, um)
        for r in range(R):
            u1[r] += um[r]
    forced_response(P, sq, sdq, u1, y1[iq:iq + R], y1[idq:idq + R])
    vz1 = (av - 0.5 * h * S1 / m) / cz
    y1[ivz] = vz1
    y1[iz] = zc - beta * S1
    if sliding:
        y1[ix] = x0 + 0.5 * h * (v0 + v1)
        y1[ivx] = v1
    elif force_driven:  # held in stick
        y1[ix] = x0
        y1[ivx] = 0.0
    if kn.set_valued(off) and force_driven:
        # the algebraic friction force of the new state (kernels.residual's row of it)
        y1[off[kn.OFF_IL]] = kn.set_valued_friction(t1, y1, off, fp, reg)
    derivatives(t1, y1, d1, off, fp, cdamp, spos, prof, reg)
    for i in range(kn.N_ENERGY):
        y1[iE + i] = y0[iE + i] + 0.5 * h * (d0[D_POWER + i] + d1[D_POWER + i])


@njit(cache=True)
def implicit_step(t0, h, y0, d0, u0, y1, d1, u1, slot, prop, wts, off, fp, cdamp, phi, phiT,
                  stiff, spos, prof, reg, scratch, ist):
    """One step of length h (propagators in ``slot``) from the consistent (y0, d0) to (y1, d1).

    ``u0`` is :func:`.propagators.modal_force` of y0; ``u1`` receives that of y1.

    Unknowns: the forces of the closed contacts and, for a force-driven block that slides, the
    tangential velocity at t0 + h, with the friction force of :func:`friction_force` (the
    law's kinetic curve and its exact slope). In the stick regime of a set-valued law the
    block stays where it is (v = 0, x fixed: no tangential unknown) and the friction force
    ``friction.force`` is what holds it, ``T_exc - r2 v``. Newton until every update is below
    ``NEWTON_TOL`` tolerance weights ``wts`` or, for tolerances near round-off, below
    ``NEWTON_ULPS`` times the round-off of its equation (unit round-off times the sum of the
    magnitudes of the equation's terms, divided by the diagonal of the Newton matrix): an
    update at that level is noise, which no further iteration removes. Returns False when
    Newton does not converge within ``NEWTON_MAX_ITER`` iterations (the caller takes a
    smaller step).

    ``prop``: the ``Propagators`` cache; ``scratch``: ``Scratch`` (``ws`` of length
    >= :func:`ws_size`, cut by :func:`ws_slice`), ``jac`` of shape >= (K + 1, K + 1), ``ipiv``
    (int64) of length >= K + 1).
    """
    G1c = prop.G1c
    ws, jac, ipiv = scratch.ws, scratch.jac, scratch.ipiv
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = kn.state_offsets(off)
    m = fp[kn.FP_MASS]
    r1 = fp[kn.FP_R1]
    t1 = t0 + h
    sq = ws_slice(ws, WS_SQ, R, K)
    sdq = ws_slice(ws, WS_SDQ, R, K)
    wfree = ws_slice(ws, WS_WFREE, R, K)
    F = ws_slice(ws, WS_F, R, K)
    rhs = ws_slice(ws, WS_RHS, R, K)
    idx = ws_slice(ws, WS_IDX, R, K)
    noise = ws_slice(ws, WS_NOISE, R, K)  # round-off level of each update
    # friction moment (contact.friction_moment): the modal force holds c Psi^T F / M too
    # (c: moment_coefficient); u0 is the whole modal force of y0 (state_modal_force), u1
    # receives that of y1
    moment = ix >= 0 and kn.moment_on(off)
    um = ws_slice(ws, WS_UM, R, K)  # the moment's modal force at t1
    wm = ws_slice(ws, WS_WM, R, K)  # its displacement at the contacts / c
    # free modal response and plate displacement at the contacts (unit-stride loops over the
    # modes: the maps' rows of P, the state's plate.q and plate.dq)
    P = prop.P[slot]
    free_response(P, y0[iq:iq + R], y0[idq:idq + R], u0, phiT, sq, sdq, wfree)
    # the moment's part at t1 moves the contacts by c1 Hm F (moment_map)
    Hm = prop.Hm[slot]
    if moment:
        moment_map(slot, prop, phiT, off, fp)
    # vertical trapezoidal rule: vz1 = (av - h S1 / (2 m)) / cz, z1 = zc - beta S1
    z0 = y0[iz]
    vz0 = y0[ivz]
    cz = 1.0 + h * r1 / (2.0 * m)
    # trapezoidal rule for vz with z''(t1) = g - r1 vz1 / m - S1 / m
    av = vz0 + 0.5 * h * d0[D_AZ] + 0.5 * h * fp[kn.FP_GRAV]
    zc = z0 + 0.5 * h * vz0 + 0.5 * h * av / cz
    beta = h * h / (4.0 * m * cz)
    force_driven = ix >= 0
    # the stick of a set-valued law holds the block: no tangential unknown
    sliding = force_driven and not holds_stick(off, reg)
    x0 = 0.0
    v0 = 0.0
    if force_driven:
        x0 = y0[ix]
        v0 = y0[ivx]
    # closed contacts
    nc = 0
    for k in range(K):
        F[k] = 0.0
        if reg[kn.REG_CLOSED + k] == 1:
            idx[nc] = k
            F[k] = y0[iF + k]
            nc += 1
    nu = nc + (1 if sliding else 0)
    v1 = v0 + h * d0[D_AX] if sliding else 0.0
    texc1 = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t1) if sliding else 0.0
    ok = False
    for _it in range(NEWTON_MAX_ITER):
        ist[I_NEWTON] += 1
        S1 = 0.0
        for a in range(nc):
            S1 += F[int(idx[a])]
        if sliding:
            x1 = x0 + 0.5 * h * (v0 + v1)
        elif force_driven:  # held in stick
            x1 = x0
        else:
            x1, v1 = kn.prescribed_motion(t1, fp)
        mu1 = 0.0
        dmu1 = 0.0
        dmus = 0.0
        if moment:
            mu1, dmu1, dmus = moment_coefficient(t1, v1, S1, off, fp, reg)
            _moment_displacements(Hm, F, wm)
        _contact_rows(h, x1, S1, mu1, dmu1, dmus, nc, idx, F, zc, beta, wfree, wm, G1c, slot,
                      Hm, stiff, spos, prof, fp, moment, sliding, jac, rhs, noise)
        if sliding:
            _velocity_row(t1, h, y0, d0, v0, v1, S1, nc, texc1, off, fp, reg, jac, rhs, noise)
        if nu == 0:
            ok = True
            break
        piv = ipiv[:nu]
        lu_factor(jac[:nu, :nu], piv)
        lu_solve(jac[:nu, :nu], piv, rhs[:nu])
        v1, worst = _newton_update(nc, idx, F, v1, sliding, rhs, noise, wts, iF, ivx)
        if not worst <= NEWTON_TOL:
            continue
        ok = True
        break
    if not ok:
        return False
    _end_state(t1, h, y0, d0, y1, d1, u1, F, v1, x0, v0, av, cz, zc, beta, sq, sdq, um, P,
               phiT, moment, sliding, force_driven, off, fp, cdamp, spos, prof, reg)
    return True
