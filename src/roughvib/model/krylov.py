"""Numba kernels for IDA's Krylov path: the exact block-elimination preconditioner and J v.

IDA's Newton matrix is ``J = dF/dy + cj dF/dyp`` of the residual in
:mod:`roughvib.model.kernels`. Its structure (an "arrow"):

* a 2x2 block per plate mode (q_r, dq_r), coupled to the rest only through the K contact
  forces (column ``-phi_rk / M``);
* the block's vertical pair (z, vz) and tangential pair (x, vx, and the Coulomb friction force
  lambda), coupled to the forces through their sum S = sum_k F_k;
* K contact rows, dense in the forces (residual compliance), in z, q (mode shapes) and x
  (profile slope);
* six energy-integral rows that nothing else depends on (lower triangular).

:func:`precond_solve` eliminates every 2x2 modal block and the block pairs in closed form, which
leaves a K x K Schur system in the contact forces; it is solved by Gaussian elimination with
partial pivoting, then everything is back-substituted and the energy rows come last. All of it
is evaluated at the current iterate (t, y, cj), so it is the *exact* inverse of ``J``:
preconditioned GMRES converges in one iteration (``krylov_dim=1``) and no matrix is formed.
The modal part of the Schur matrix, ``P_kj = sum_r phi_rk phi_rj / (M d_r)`` with
``d_r = omega_r^2 + cj (cj + 2 zeta_r omega_r)``, depends on cj only and is cached until cj
changes. Cost per call O(R K) (+ O(R K^2) when cj changed, + O(K^3)), no allocation.

:func:`jac_vec` forms J v without forming J. Neither kernel differentiates the friction law
itself: both read the law's linearisation (coefficient, slopes, the set-valued friction row,
the friction moment's share and power) from :func:`roughvib.model.jacobian.friction_terms`,
the function whose terms the sparse Jacobian's entries (``jacobian_entries``) are built from,
so the sparse-direct and the Krylov paths differentiate the model once. They keep their own
arithmetic on those terms (grouped as the elimination needs them, e.g. ``mu / (m e_x)``, or
summed over S = sum_k v_k): the runs of the Krylov path stay what they were to the bit. The
unit tests check J v against the sparse Jacobian and ``precond_solve(J v) == v`` in every
regime.

Friction moment (``contact.friction_moment``): the modal rows gain the moment's force
``c sum_k Psi_rk F_k`` (:func:`roughvib.model.kernels.moment_share`), linear in the force
corrections and, through c, in the tangential velocity (Feldmann) or lambda (set-valued
laws), which the tangential pair's elimination already writes as affine in S = sum_k dF_k.
So the elimination stays exact: the Schur matrix gains
``sum_r phi_rk (c Psi_rj + P_r e1) / (M d_r)`` (``P_r = sum_k Psi_rk F_k``), rebuilt with
every factorisation (O(R K^2)), and the right-hand side ``e0 sum_r phi_rk P_r / (M d_r)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from roughvib.model import kernels as kn
from roughvib.model.jacobian import friction_terms

__all__ = ["jac_vec", "krylov_workspace", "precond_solve"]


# positions in the ``cache`` array of krylov_workspace
C_CJ_P = 0   # cj of P and dinv
C_T_A = 1    # t of the factorised Schur matrix A
C_CJ_A = 2   # cj of A
C_N_Y = 3    # number of valid entries in ycache
N_CACHE = 4


def krylov_workspace(n_states: int, n_modes: int, n_contacts: int) -> tuple[np.ndarray, ...]:
    """Scratch arrays for :func:`precond_solve`: (cache, ycache, piv, P, A, b, a, dinv).

    ``cache`` holds [cj of P and dinv, t and cj of the factorised Schur matrix A, number of
    valid entries in ycache]; ``ycache`` (n,) the iterate A was factorised at (IDA calls the
    preconditioner twice per Newton iteration at the same iterate); ``piv`` (K,) its pivots.
    """
    K = n_contacts
    cache = np.full(N_CACHE, np.nan)
    return (cache, np.zeros(n_states), np.zeros(K, dtype=np.int64), np.zeros((K, K)),
            np.zeros((K, K)), np.zeros(K), np.zeros(n_modes), np.zeros(n_modes))


@njit(cache=True)
def lu_factor(A, piv):
    """LU factorisation with partial pivoting of A in place (row swaps recorded in piv)."""
    lu_factor_checked(A, piv)


@njit(cache=True)
def lu_factor_checked(A, piv):
    """:func:`lu_factor` that stops and returns False at a pivot that is zero or not finite
    (A singular, or holding NaN or inf), True otherwise."""
    n = piv.size
    for c in range(n):
        p = c
        big = abs(A[c, c])
        for i in range(c + 1, n):
            if abs(A[i, c]) > big:
                big = abs(A[i, c])
                p = i
        piv[c] = p
        if p != c:
            for j in range(n):
                tmp = A[c, j]
                A[c, j] = A[p, j]
                A[p, j] = tmp
        if not 0.0 < abs(A[c, c]) < math.inf:
            return False
        inv = 1.0 / A[c, c]
        for i in range(c + 1, n):
            A[i, c] *= inv
            f = A[i, c]
            if f != 0.0:
                for j in range(c + 1, n):
                    A[i, j] -= f * A[c, j]
    return True


@njit(cache=True)
def lu_solve(A, piv, b):
    """Solve with the factors of :func:`lu_factor` (b is overwritten by the solution)."""
    n = piv.size
    for c in range(n):
        p = piv[c]
        if p != c:
            tmp = b[c]
            b[c] = b[p]
            b[p] = tmp
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= A[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= A[i, j] * b[j]
        b[i] = acc / A[i, i]


@njit(cache=True)
def _same_iterate(t, y, cj, cache, ycache):
    """Whether the Schur matrix in the workspace was factorised at this (t, y, cj)."""
    if cache[C_T_A] != t or cache[C_CJ_A] != cj or cache[C_N_Y] != y.size:
        return False
    for i in range(y.size):
        if ycache[i] != y[i]:
            return False
    return True


@njit(cache=True)
def precond_solve(t, y, cj, rv, zv, off, fp, omega2, cdamp, phi, stiff, cres, spos, prof, reg,
                  work, cache, ycache, piv, P, A, b, a, dinv):
    """Solve ``J zv = rv`` exactly for the Newton matrix J at (t, y, cj) (module docstring).

    Parameters
    ----------
    t : float [s]
    y : ndarray (n,)
        Current Newton iterate.
    cj : float [1/s]
        IDA's scalar ``alpha / h``.
    rv, zv : ndarray (n,)
        Right-hand side and solution (zv is overwritten; may not alias rv).
    off ... reg, work
        The kernels' argument tail (:mod:`roughvib.model.kernels`); ``work`` must keep the
        compressions of the last factorisation (the residual kernels overwrite it, so the
        solver passes a separate array).
    cache ... dinv
        From :func:`krylov_workspace`.
    """
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = kn.state_offsets(off)
    iL = off[kn.OFF_IL]
    m = fp[kn.FP_MASS]
    M = fp[kn.FP_MMODAL]
    r1 = fp[kn.FP_R1]
    r2 = fp[kn.FP_R2]
    if cache[C_CJ_P] != cj:
        for k in range(K):
            for j in range(K):
                P[k, j] = 0.0
        for r in range(R):  # row-wise over phi (C order), upper triangle, then mirrored
            d = 1.0 / (omega2[r] + cj * (cj + cdamp[r]))
            dinv[r] = d
            for k in range(K):
                pk = phi[r, k] * d
                for j in range(k, K):
                    P[k, j] += pk * phi[r, j]
        for k in range(K):
            for j in range(k, K):
                P[k, j] /= M
                P[j, k] = P[k, j]
        cache[C_CJ_P] = cj
        cache[C_T_A] = np.nan
    ft = friction_terms(t, y, off, fp, reg)
    fsum, mu, dmu, alpha, beta = ft.fsum, ft.mu, ft.dmu, ft.alpha, ft.beta
    # vertical pair: zvz = vz0 + rho_z S, zz = (r_z + zvz) / cj
    ez = cj + r1 / m
    rho_z = -1.0 / (m * ez)
    vz0 = rv[ivz] / ez
    # tangential pair: zvx = vx0 + rho_x S, zx = (r_x + zvx) / cj
    vx0 = 0.0
    rho_x = 0.0
    if ix >= 0:
        if kn.set_valued(off):
            ex = cj + (r2 - alpha) / m
            vx0 = (rv[ivx] - rv[iL] / m) / ex
            rho_x = beta / (m * ex)
        else:
            ex = cj + (dmu * fsum + r2) / m
            vx0 = rv[ivx] / ex
            rho_x = -mu / (m * ex)
    # friction moment: modal force c Psi^T dF + P (e0 + e1 S), P_r = sum_k Psi_rk F_k
    moment = ix >= 0 and kn.moment_on(off)
    cm = 0.0
    e0 = 0.0
    e1 = 0.0
    ip = off[kn.OFF_IPSI]
    if moment:
        cm, dcv, dcl, dcf = ft.cm, ft.dcv, ft.dcl, ft.dcf
        if kn.set_valued(off):  # zL = rv_L - alpha zvx - beta S, zvx = vx0 + rho_x S
            e0 = dcl * (rv[iL] - alpha * vx0)
            e1 = dcf - dcl * (alpha * rho_x + beta)
        else:
            e0 = dcv * vx0
            e1 = dcv * rho_x
    if not _same_iterate(t, y, cj, cache, ycache):
        # contact rows -> K x K Schur matrix in the forces, factorised once per iterate
        kn.compressions(t, y, off, fp, phi, cres, spos, prof, work)
        for k in range(K):
            if reg[kn.REG_CLOSED + k] == 1:
                dh = work[K + k] if ix >= 0 else 0.0
                shift = -(rho_z + dh * rho_x) / cj
                for j in range(K):
                    A[k, j] = cres[k, j] + P[k, j] + shift
                A[k, k] += 1.0 / stiff[k]
                if moment:
                    for r in range(R):
                        wr = phi[r, k] * dinv[r] / M
                        pe = kn.moment_arm(r, y, off, fp) * e1
                        for j in range(K):
                            A[k, j] += wr * (cm * fp[ip + j * R + r] + pe)
            else:
                for j in range(K):
                    A[k, j] = 0.0
                A[k, k] = 1.0 / stiff[k]
        lu_factor(A, piv)
        for i in range(y.size):
            ycache[i] = y[i]
        cache[C_T_A] = t
        cache[C_CJ_A] = cj
        cache[C_N_Y] = y.size
    # modal blocks: zq_r = a_r + (sum_k phi_rk zF_k) / (M d_r)
    for r in range(R):
        a[r] = (rv[idq + r] + (cj + cdamp[r]) * rv[iq + r]) * dinv[r]
    zz0 = (rv[iz] + vz0) / cj
    xx0 = (rv[ix] + vx0) / cj if ix >= 0 else 0.0
    for k in range(K):
        if reg[kn.REG_CLOSED + k] == 1:
            dh = work[K + k] if ix >= 0 else 0.0
            acc = 0.0
            for r in range(R):
                acc += phi[r, k] * a[r]
            if moment and e0 != 0.0:
                for r in range(R):
                    acc += phi[r, k] * dinv[r] * kn.moment_arm(r, y, off, fp) * e0 / M
            b[k] = rv[iF + k] + zz0 - acc + dh * xx0
        else:
            b[k] = rv[iF + k]
    lu_solve(A, piv, b)
    S = 0.0
    for k in range(K):
        zv[iF + k] = b[k]
        S += b[k]
    # back-substitution
    for r in range(R):
        g = 0.0
        for k in range(K):
            g += phi[r, k] * b[k]
        if moment:
            for k in range(K):
                g += cm * fp[ip + k * R + r] * b[k]
            g += kn.moment_arm(r, y, off, fp) * (e0 + e1 * S)
        zq = a[r] + g * dinv[r] / M
        zv[iq + r] = zq
        zv[idq + r] = cj * zq - rv[iq + r]
    zv[ivz] = vz0 + rho_z * S
    zv[iz] = (rv[iz] + zv[ivz]) / cj
    zvx = 0.0
    zL = 0.0
    if ix >= 0:
        zvx = vx0 + rho_x * S
        zv[ivx] = zvx
        zv[ix] = (rv[ix] + zvx) / cj
        if kn.set_valued(off):
            zL = rv[iL] - alpha * zvx - beta * S
            zv[iL] = zL
    # energy rows (lower triangular: cj zE + coupling = r)
    for i in range(6):
        zv[iE + i] = rv[iE + i]
    _energy_rows(t, y, zv, zv, off, fp, cdamp, work, ft, -1.0)
    for i in range(6):
        zv[iE + i] /= cj


@njit(cache=True)
def _energy_rows(t, y, v, out, off, fp, cdamp, work, ft, sign):
    """out[iE + i] += sign * (coupling of energy row i to the other states) . v.

    The coupling is the Jacobian of the energy rows without their ``cj`` diagonal (nothing
    depends on the energy states, so they never enter it): ``sign = +1`` adds it to a
    product J v, ``sign = -1`` moves it to the right-hand side of a solve. ``work`` holds
    the compressions and profile slopes at y (:func:`roughvib.model.kernels.compressions`),
    ``ft`` the friction's terms at y (:func:`roughvib.model.jacobian.friction_terms`).
    """
    _iq, idq, _iz, ivz, ix, ivx, iF, iE, R, K = kn.state_offsets(off)
    iL = off[kn.OFF_IL]
    vx, fsum, mu, dmu = ft.vx, ft.fsum, ft.mu, ft.dmu
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    if ix >= 0:
        c0 = -fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t) * v[ivx]
        if kn.set_valued(off):
            c1 = -y[iL] * v[ivx] - vx * v[iL]
        else:
            sv = 0.0
            for k in range(K):
                sv += v[iF + k]
            c1 = -(dmu * fsum * vx + mu * fsum) * v[ivx] - mu * vx * sv
        c2 = -2.0 * fp[kn.FP_R2] * vx * v[ivx]
    c3 = -2.0 * fp[kn.FP_R1] * y[ivz] * v[ivz]
    acc = 0.0
    for r in range(R):
        acc += cdamp[r] * y[idq + r] * v[idq + r]
    c4 = -2.0 * fp[kn.FP_MMODAL] * acc
    s1 = 0.0
    s2 = 0.0
    acc = 0.0
    for k in range(K):
        s1 += y[iF + k] * work[K + k]
        s2 += y[iF + k] * work[2 * K + k]
        acc += work[K + k] * v[iF + k]
    c5 = -vx * acc
    if ix >= 0:
        c5 -= s2 * vx * v[ix] + s1 * v[ivx]
    if ix >= 0 and kn.moment_on(off):
        # the friction power is lambda v - c W (kernels.residual): + d(c W) . v
        cm, dcv, dcl, dcf, wm = ft.cm, ft.dcv, ft.dcl, ft.dcf, ft.wm
        sv = 0.0
        acc = 0.0
        for k in range(K):
            sv += v[iF + k]
            acc += kn.surface_velocity(k, y, off, fp) * v[iF + k]
        c1 += wm * (dcv * v[ivx] + dcf * sv + (dcl * v[iL] if iL >= 0 else 0.0)) + cm * acc
        acc = 0.0
        for r in range(R):
            acc += kn.moment_arm(r, y, off, fp) * v[idq + r]
        c1 += cm * acc
    out[iE] += sign * c0
    out[iE + kn.E_FRICTION] += sign * c1
    out[iE + kn.E_TANGENTIAL_DAMPING] += sign * c2
    out[iE + kn.E_VERTICAL_DAMPING] += sign * c3
    out[iE + kn.E_PLATE_DAMPING] += sign * c4
    out[iE + kn.E_ROUGHNESS] += sign * c5


@njit(cache=True)
def jac_vec(t, y, cj, v, out, off, fp, omega2, cdamp, phi, stiff, cres, spos, prof, reg, work):
    """out = J v for the Newton matrix J = dF/dy + cj dF/dyp at (t, y), without forming J.

    The same matrix as :func:`roughvib.model.jacobian.jacobian_values`, from the same
    friction terms (module docstring; the unit tests compare them); O(R K) per call.
    """
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = kn.state_offsets(off)
    iL = off[kn.OFF_IL]
    m = fp[kn.FP_MASS]
    M = fp[kn.FP_MMODAL]
    ft = friction_terms(t, y, off, fp, reg)
    fsum, mu, dmu, alpha, beta = ft.fsum, ft.mu, ft.dmu, ft.alpha, ft.beta
    kn.compressions(t, y, off, fp, phi, cres, spos, prof, work)
    sv = 0.0
    for k in range(K):
        sv += v[iF + k]
    moment = ix >= 0 and kn.moment_on(off)
    cm = 0.0
    dtan = 0.0  # the moment coefficient's change along v: dc/dv v_x + dc/dlambda v_L + dc/dF S
    ip = off[kn.OFF_IPSI]
    if moment:
        cm, dcv, dcl, dcf = ft.cm, ft.dcv, ft.dcl, ft.dcf
        dtan = dcv * v[ivx] + dcf * sv + (dcl * v[iL] if iL >= 0 else 0.0)
    for r in range(R):
        f = 0.0
        for k in range(K):
            f += phi[r, k] * v[iF + k]
        if moment:
            for k in range(K):
                f += cm * fp[ip + k * R + r] * v[iF + k]
            f += kn.moment_arm(r, y, off, fp) * dtan
        out[iq + r] = cj * v[iq + r] - v[idq + r]
        out[idq + r] = omega2[r] * v[iq + r] + (cj + cdamp[r]) * v[idq + r] - f / M
    out[iz] = cj * v[iz] - v[ivz]
    out[ivz] = (cj + fp[kn.FP_R1] / m) * v[ivz] + sv / m
    if ix >= 0:
        out[ix] = cj * v[ix] - v[ivx]
        if kn.set_valued(off):
            out[ivx] = (cj + fp[kn.FP_R2] / m) * v[ivx] + v[iL] / m
            out[iL] = v[iL] + alpha * v[ivx] + beta * sv
        else:
            out[ivx] = (cj + (dmu * fsum + fp[kn.FP_R2]) / m) * v[ivx] + mu * sv / m
    for k in range(K):
        if reg[kn.REG_CLOSED + k] == 1:
            acc = v[iF + k] / stiff[k] - v[iz]
            for j in range(K):
                acc += cres[k, j] * v[iF + j]
            for r in range(R):
                acc += phi[r, k] * v[iq + r]
            if ix >= 0:
                acc -= work[K + k] * v[ix]
            out[iF + k] = acc
        else:
            out[iF + k] = v[iF + k] / stiff[k]
    for i in range(6):
        out[iE + i] = cj * v[iE + i]
    _energy_rows(t, y, v, out, off, fp, cdamp, work, ft, 1.0)
