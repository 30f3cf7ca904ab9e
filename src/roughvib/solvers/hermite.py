"""Exact modal propagation under a Hermite-cubic hold of the modal force (adaptive-modal's
Hermite step).

A plate mode ``q'' + c q' + w^2 q = u(t)`` is propagated exactly over a step of length h when
u is a polynomial in t. ``adaptive-modal``'s trapezoidal step holds u linear (its values at both
ends); docs/performance.md ("What limits a step of one output interval") measured that this
hold, not the coupling of the modes through the contact, is what limits a step of one output
interval, and that the cubic through the values *and rates* of u at both ends (Hermite) is
accurate at the whole interval. This module gives the step maps of that hold:

    [q, q'](h) = Phi [q, q'](0) + H_u0 u(0) + H_du0 u'(0) + H_u1 u(h) + H_du1 u'(h).

They are built from the exact responses W_k to the monomials ``u = tau^k`` (k = 0..3),

    W_k = int_0^h exp(A (h - tau)) e2 tau^k dtau = k! h^(k+1) sum_n (A h)^n e2 / (n + k + 1)!,

by the power series for omega h up to ``HERMITE_SERIES_LIMIT`` and, above, from the
polynomial particular solution of the forced oscillator (``W_k = p(h) - Phi p(0)``, with p the
polynomial solution of ``p'' + c p' + w^2 p = tau^k`` and its derivative). The Hermite basis in
monomials, ``s = (u1 - u0) / h``:

    u(tau) = u0 + u0' tau + (3 s - 2 u0' - u1') tau^2 / h + (u0' + u1' - 2 s) tau^3 / h^2.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from roughvib.model import kernels as kn
from roughvib.model.krylov import lu_factor_checked, lu_solve
from roughvib.physics.friction import single_valued_mu, single_valued_mu_d2
from roughvib.physics.surface.interp import profile_eval
from roughvib.solvers.base import MODE_DQ, MODE_Q

#: the friction law's dispatch (laws.py) and the profile inlined (numba IR) into the step's
#: Newton residual (the dispatch into carried() too), and the residual and the step into their
#: callers (``inline="always"``): each call of a compiled function that is not inlined
#: increments and decrements the reference count of every array it is passed (about 6 ns per
#: array; ``perf``: 16 % of a default solve's reference counting came from ``_residual``'s
#: calls alone). Same Python functions, same results to the bit; the first compilation takes
#: about 13 s longer.
# (``py_func``: the Python function of a dispatcher; with NUMBA_DISABLE_JIT it is the function)
_mu_d2_inline = njit(inline="always")(getattr(single_valued_mu_d2, "py_func",
                                              single_valued_mu_d2))
_mu_inline = njit(inline="always")(getattr(single_valued_mu, "py_func", single_valued_mu))
_profile_inline = njit(inline="always")(getattr(profile_eval, "py_func", profile_eval))

__all__ = ["HOLD_DU0", "HOLD_DU1", "HOLD_U0", "HOLD_U1", "N_HOLD", "carried", "carry_size",
           "hermite_maps", "hermite_slot", "hermite_step", "scratch_sizes", "slot_shapes"]

#: positions of the hold's four data in the step maps' ``H[r, HOLD_*, :]``
HOLD_U0 = 0    #: u(0)
HOLD_DU0 = 1   #: u'(0)
HOLD_U1 = 2    #: u(h)
HOLD_DU1 = 3   #: u'(h)
N_HOLD = 4
# positions of a mode's state in the maps' last axis: MODE_Q, MODE_DQ (solvers/base.py)
N_MONOMIALS = 4        # tau^0 .. tau^3
#: rows of the monomial responses W (N_MONOMIALS, 2): the response to tau^k is row k
W_1, W_T, W_T2, W_T3 = 0, 1, 2, 3
#: the particular solution's coefficients a_j of tau^j: p(0) = a[A_CONST], p'(0) = a[A_LIN]
A_CONST, A_LIN = 0, 1
#: omega h up to which the maps come from the power series. The particular solution above it
#: subtracts terms of size k! / w^(2(k+1))-ish that are (omega h)^-(2(k+1)) k! times the
#: result's h^(k+1) scale relative: at omega h = 2 at most 6 / 2^8 of a digit's worth for k=3
HERMITE_SERIES_LIMIT = 2.0
N_TERMS = 40           # series terms: 2^40 / 44! < 1e-42
#: the series' coefficients n! / (n + k + 1)! (row n, column k) and 1 / (n + 1), tabulated:
#: the loop had five divisions per term, which made the maps of a new step length (after an
#: event, each root-search trial) cost about 75 us on the ``paper`` scene
SERIES_RATIO = np.array([[math.factorial(n) / math.factorial(n + k + 1)
                          for k in range(N_MONOMIALS)] for n in range(N_TERMS)])
SERIES_INV = np.array([1.0 / (n + 1.0) for n in range(N_TERMS)])


@njit(cache=True)
def _monomial_series(w2, c, h, W):
    """W[k, :] = exact response [q, q'](h) to u = tau^k from rest, by the power series."""
    # v_n = (A h)^n e2 / n!, A = [[0, 1], [-w2, -c]]; W_k = k! h^(k+1) sum_n v_n n!/(n+k+1)!
    for k in range(N_MONOMIALS):
        W[k, MODE_Q] = 0.0
        W[k, MODE_DQ] = 0.0
    v0, v1 = 0.0, 1.0
    for n in range(N_TERMS):
        for k in range(N_MONOMIALS):
            ratio = SERIES_RATIO[n, k]   # n! / (n + k + 1)!
            W[k, MODE_Q] += v0 * ratio
            W[k, MODE_DQ] += v1 * ratio
        hn = h * SERIES_INV[n]
        a = hn * v1
        b = hn * (-w2 * v0 - c * v1)
        v0, v1 = a, b
        # the sums start at v_0 = e2 (and |v0| / h is v's first component's scale): the
        # remaining terms are below 1e-18 of the leading ones once v is (|A h| <= 2 + c h:
        # v_n falls by omega h / n per term from there on)
        if abs(v0) < 1e-18 * h and abs(v1) < 1e-18:
            break
    scale = h
    fact = 1.0  # k!
    for k in range(N_MONOMIALS):
        scale_k = scale * fact
        W[k, MODE_Q] *= scale_k
        W[k, MODE_DQ] *= scale_k
        scale *= h
        fact *= k + 1.0


@njit(cache=True)
def _monomial_particular(w2, c, h, P00, P01, P10, P11, W, a):
    """W[k, :] from the polynomial particular solution (omega h above the series limit);
    ``a``: scratch of length N_MONOMIALS + 2."""
    for k in range(N_MONOMIALS):
        for j in range(N_MONOMIALS + 2):
            a[j] = 0.0
        # w2 a_j + c (j + 1) a_{j+1} + (j + 2)(j + 1) a_{j+2} = [j == k], from j = k down
        for j in range(k, -1, -1):
            rhs = 1.0 if j == k else 0.0
            a[j] = (rhs - c * (j + 1.0) * a[j + 1] - (j + 2.0) * (j + 1.0) * a[j + 2]) / w2
        # p(h), p'(h) by Horner; p(0) = a_0, p'(0) = a_1
        ph = 0.0
        dph = 0.0
        for j in range(k, -1, -1):
            ph = ph * h + a[j]
        for j in range(k, 0, -1):
            dph = dph * h + j * a[j]
        W[k, MODE_Q] = ph - (P00 * a[A_CONST] + P01 * a[A_LIN])
        W[k, MODE_DQ] = dph - (P10 * a[A_CONST] + P11 * a[A_LIN])


@njit(cache=True)
def damped_propagator(w2, c, h):
    """The free propagator exp(A h), A = [[0, 1], [-w2, -c]], of an underdamped oscillator by
    its closed form: ``(p00, p01, p10, p11)`` with ``[q, q'](h) = [[p00, p01], [p10, p11]]
    [q, q'](0)``. Its ``1 - cos`` terms lose digits for omega h -> 0: the step maps take their
    force terms from a power series there."""
    sig = 0.5 * c
    wd = math.sqrt(w2 - sig * sig)
    e = math.exp(-sig * h)
    co = math.cos(wd * h)
    si = math.sin(wd * h)
    return (e * (co + sig / wd * si), e * si / wd, -e * w2 * si / wd,
            e * (co - sig / wd * si))


@njit(cache=True)
def hermite_maps(omega2, cdamp, h, Phi, H):
    """Exact step maps of ``q'' + c q' + w^2 q = u(t)`` under the Hermite-cubic hold of u.

    Parameters
    ----------
    omega2, cdamp : ndarray, shape (R,)
        w_r^2 [rad^2/s^2] and c_r = 2 zeta_r w_r [1/s] (underdamped: c^2 < 4 w^2).
    h : float
        Step [s].
    Phi : ndarray, shape (R, 2, 2)
        Filled with the free propagator.
    H : ndarray, shape (R, N_HOLD, 2)
        Filled so that ``[q, q'](h) = Phi [q, q'](0) + sum_i H[r, i] d_i`` with the hold data
        ``d = (u(0), u'(0), u(h), u'(h))`` in the order ``HOLD_*``.
    """
    W = np.zeros((N_MONOMIALS, 2))
    a = np.zeros(N_MONOMIALS + 2)
    R = omega2.size
    for r in range(R):
        w2 = omega2[r]
        c = cdamp[r]
        p00, p01, p10, p11 = damped_propagator(w2, c, h)
        if math.sqrt(w2) * h <= HERMITE_SERIES_LIMIT:
            _monomial_series(w2, c, h, W)
        else:
            _monomial_particular(w2, c, h, p00, p01, p10, p11, W, a)
        Phi[r, MODE_Q, MODE_Q] = p00
        Phi[r, MODE_Q, MODE_DQ] = p01
        Phi[r, MODE_DQ, MODE_Q] = p10
        Phi[r, MODE_DQ, MODE_DQ] = p11
        for i in range(2):
            w0, w1, w2k, w3 = W[W_1, i], W[W_T, i], W[W_T2, i], W[W_T3, i]
            H[r, HOLD_U0, i] = w0 - 3.0 * w2k / (h * h) + 2.0 * w3 / (h * h * h)
            H[r, HOLD_DU0, i] = w1 - 2.0 * w2k / h + w3 / (h * h)
            H[r, HOLD_U1, i] = 3.0 * w2k / (h * h) - 2.0 * w3 / (h * h * h)
            H[r, HOLD_DU1, i] = -w2k / h + w3 / (h * h)


# --- the whole step (a single-valued law, force-driven block, no friction moment) ----------

#: rows of a slot's per-mode maps ``Pm`` (shape (N_PMAP, R)): the free propagator and the
#: four hold maps, each on q and q'
PM_QQ, PM_QD, PM_DQ, PM_DD = 0, 1, 2, 3
PM_U0Q, PM_U0D, PM_DU0Q, PM_DU0D = 4, 5, 6, 7
PM_U1Q, PM_U1D, PM_DU1Q, PM_DU1D = 8, 9, 10, 11
N_PMAP = 12
#: the end-value maps in contact coordinates ``Cc`` (shape (N_CMAP, K, K)): displacement and
#: velocity of the plate at contact k per unit end force / end force rate at contact j
#: (the residual compliance included where it acts: on the displacement per force and the
#: velocity per force rate)
CM_WF, CM_WD, CM_VF, CM_VD = 0, 1, 2, 3
N_CMAP = 4
#: up to this many contacts the step does not form the modal force: the hold maps of each
#: contact's force and rate are folded with its mode shape per modal mass (``Pm`` rows
#: ``N_PMAP + FOLD + PM_U0Q .. PM_DU1D``, FOLD = N_PMAP - PM_U0Q: 8 more rows), and the start
#: hold's plate motion at the contacts is in ``Cc[CM0_*]`` (like ``CM_*`` for the start's
#: force and rate); the passes over the modes read fewer rows. Above it, u = phi F / M and
#: its rate are formed and carried (R each)
FOLD_K_MAX = 1
FOLD = N_PMAP - PM_U0Q
N_PMAP_FOLDED = N_PMAP + FOLD
CM0_WF, CM0_WD, CM0_VF, CM0_VD = 4, 5, 6, 7
N_CMAP_FOLDED = 8
#: Newton of the Hermite step
HERMITE_NEWTON_MAX = 30
NEWTON_TOL_REL = 1e-6  # Newton update, in units of the tolerance weights
#: a Newton update this large in those units (or NaN) ends the step as failed: the matrix was
#: singular or the iterate runs away (the caller takes a smaller step)
NEWTON_RUNAWAY = 1e300


@njit(cache=True)
def hermite_slot(h, omega2, cdamp, phi, cres, M, Pm, Cc):
    """Fill a step length's maps: per mode ``Pm``, at the contacts ``Cc`` (shapes of
    :func:`slot_shapes`; folded for up to ``FOLD_K_MAX`` contacts); ``phi`` (R, K) the mode
    shapes at the contacts, ``M`` the modal mass [kg] (mode shapes phi per sqrt of it)."""
    R = omega2.size
    K = cres.shape[0]
    if K <= FOLD_K_MAX and (Pm.shape[0] < N_PMAP_FOLDED or Cc.shape[0] < N_CMAP_FOLDED):
        raise ValueError("hermite_slot: Pm and Cc must have the shapes of slot_shapes(R, K)")
    Phi = np.zeros((R, 2, 2))
    H = np.zeros((R, N_HOLD, 2))
    hermite_maps(omega2, cdamp, h, Phi, H)
    for r in range(R):
        Pm[PM_QQ, r] = Phi[r, MODE_Q, MODE_Q]
        Pm[PM_QD, r] = Phi[r, MODE_Q, MODE_DQ]
        Pm[PM_DQ, r] = Phi[r, MODE_DQ, MODE_Q]
        Pm[PM_DD, r] = Phi[r, MODE_DQ, MODE_DQ]
        Pm[PM_U0Q, r] = H[r, HOLD_U0, MODE_Q]
        Pm[PM_U0D, r] = H[r, HOLD_U0, MODE_DQ]
        Pm[PM_DU0Q, r] = H[r, HOLD_DU0, MODE_Q]
        Pm[PM_DU0D, r] = H[r, HOLD_DU0, MODE_DQ]
        Pm[PM_U1Q, r] = H[r, HOLD_U1, MODE_Q]
        Pm[PM_U1D, r] = H[r, HOLD_U1, MODE_DQ]
        Pm[PM_DU1Q, r] = H[r, HOLD_DU1, MODE_Q]
        Pm[PM_DU1D, r] = H[r, HOLD_DU1, MODE_DQ]
    for k in range(K):
        for j in range(K):
            Cc[CM_WF, k, j] = cres[k, j]
            Cc[CM_WD, k, j] = 0.0
            Cc[CM_VF, k, j] = 0.0
            Cc[CM_VD, k, j] = cres[k, j]
            for r in range(R):
                pp = phi[r, k] * phi[r, j] / M
                Cc[CM_WF, k, j] += pp * Pm[PM_U1Q, r]
                Cc[CM_WD, k, j] += pp * Pm[PM_DU1Q, r]
                Cc[CM_VF, k, j] += pp * Pm[PM_U1D, r]
                Cc[CM_VD, k, j] += pp * Pm[PM_DU1D, r]
    if K > FOLD_K_MAX:
        return
    for row in range(PM_U0Q, N_PMAP):
        for r in range(R):
            Pm[row + FOLD, r] = Pm[row, r] * phi[r, ONE] / M
    for k in range(K):
        for j in range(K):
            Cc[CM0_WF, k, j] = 0.0
            Cc[CM0_WD, k, j] = 0.0
            Cc[CM0_VF, k, j] = 0.0
            Cc[CM0_VD, k, j] = 0.0
            for r in range(R):
                pp = phi[r, k] * phi[r, j] / M
                Cc[CM0_WF, k, j] += pp * Pm[PM_U0Q, r]
                Cc[CM0_WD, k, j] += pp * Pm[PM_DU0Q, r]
                Cc[CM0_VF, k, j] += pp * Pm[PM_U0D, r]
                Cc[CM0_VD, k, j] += pp * Pm[PM_DU0D, r]


@njit(cache=True, inline="always")
def vertical_rates(vz, fsum, dfsum, fp):
    """The block's vertical acceleration [m/s^2] and its rate [m/s^3]."""
    m = fp[kn.FP_MASS]
    rho = fp[kn.FP_R1] / m
    a = fp[kn.FP_GRAV] - rho * vz - fsum / m
    return a, -rho * a - dfsum / m


@njit(cache=True)
def _block_end(h, z0, vz0, az0, jz0, S1, dS1, fp):
    """The block's vertical (z1, vz1) by the Obreschkoff (2,2) rule for normal force S1 and
    its rate dS1 at the end (linear in them: solved in closed form)."""
    m = fp[kn.FP_MASS]
    rho = fp[kn.FP_R1] / m
    g = fp[kn.FP_GRAV]
    h2 = h * h / 12.0
    vz1 = ((vz0 + 0.5 * h * (az0 + g - S1 / m) + h2 * (jz0 + rho * g - rho * S1 / m + dS1 / m))
           / (1.0 + 0.5 * h * rho + h2 * rho * rho))
    az1 = g - rho * vz1 - S1 / m
    z1 = z0 + 0.5 * h * (vz0 + vz1) + h2 * (az0 - az1)
    return z1, vz1


#: a step's constants for its residual (``cst`` of ``_step_constants``)
CS_TEXC, CS_DTEXC = 0, 1    # excitation force [N] and its rate [N/s] at the end
CS_XC, CS_VC = 2, 3         # x1 and the velocity residual's part known at the start
CS_ZC, CS_VZC = 4, 5        # the block's z1, vz1 for no force at the end ...
CS_Z_S, CS_Z_D = 6, 7       # ... and their derivatives in the end's total force and rate
CS_VZ_S, CS_VZ_D = 8, 9
N_CS = 10


@njit(cache=True)
def _step_constants(t1, h, x0, v0, a0, j0, z0, vz0, az0, jz0, fp, cst):
    """Fill ``cst`` with what the residual needs of the step's start (``CS_*``)."""
    w = fp[kn.FP_OMEGA]
    m = fp[kn.FP_MASS]
    rho = fp[kn.FP_R1] / m
    h12 = h * h / 12.0
    cst[CS_TEXC] = fp[kn.FP_T0] * math.cos(w * t1)
    cst[CS_DTEXC] = -fp[kn.FP_T0] * w * math.sin(w * t1)
    cst[CS_XC] = x0 + 0.5 * h * v0 + h12 * a0
    cst[CS_VC] = v0 + 0.5 * h * a0 + h12 * j0
    z, vz = _block_end(h, z0, vz0, az0, jz0, 0.0, 0.0, fp)
    cst[CS_ZC] = z
    cst[CS_VZC] = vz
    den = 1.0 + 0.5 * h * rho + h12 * rho * rho
    vz_s = (-0.5 * h / m - h12 * rho / m) / den
    vz_d = h12 / m / den
    cst[CS_VZ_S] = vz_s
    cst[CS_VZ_D] = vz_d
    cst[CS_Z_S] = 0.5 * h * vz_s + h12 * (rho * vz_s + 1.0 / m)
    cst[CS_Z_D] = 0.5 * h * vz_d + h12 * rho * vz_d


@njit(cache=True, inline="always")
def _residual(cst, h, unk, res, nc, idx, wq, wd, Cc, law, fp, stiff, spos, prof, reg, jac,
              with_jac, dhs):
    """Residuals of the Hermite step's unknowns ``unk = [F_c (nc), dF_c (nc), v1]``, and with
    ``with_jac`` their Jacobian in ``jac`` (n, n), for the step's constants ``cst``; the
    profile's slope and curvature at the closed contacts in ``dhs`` (2, K). ``law``: the
    friction law's id (``off[OFF_LAW]``; a single-valued law, :func:`single_valued_mu_d2`).
    Returns x1, z1, vz1 and the tangential a1, j1, mu, dmu at v1."""
    m = fp[kn.FP_MASS]
    r2 = fp[kn.FP_R2]
    v1 = unk[2 * nc]
    S1 = 0.0
    dS1 = 0.0
    for a in range(nc):
        S1 += unk[a]
        dS1 += unk[nc + a]
    mu, dmu, d2mu = _mu_d2_inline(law, v1 + reg[kn.REG_S] * fp[kn.FP_VH], reg[kn.REG_B],
                                  fp[kn.FP_MU_SLIP], fp[kn.FP_MU_STICK], fp[kn.FP_A1],
                                  fp[kn.FP_A2])
    a1, j1 = _tangential(cst[CS_TEXC], cst[CS_DTEXC], v1, mu, dmu, S1, dS1, fp)
    h12 = h * h / 12.0
    x1 = cst[CS_XC] + 0.5 * h * v1 - h12 * a1
    z_s, z_d, vz_s, vz_d = cst[CS_Z_S], cst[CS_Z_D], cst[CS_VZ_S], cst[CS_VZ_D]
    z1 = cst[CS_ZC] + z_s * S1 + z_d * dS1
    vz1 = cst[CS_VZC] + vz_s * S1 + vz_d * dS1
    for a in range(nc):
        k = idx[a]
        hh, dh, d2h = _profile_inline(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + x1)
        dhs[DH_SLOPE, k] = dh
        dhs[DH_CURV, k] = d2h
        w = wq[k]
        wdot = wd[k]
        for c in range(nc):
            j = idx[c]
            w += Cc[CM_WF, k, j] * unk[c] + Cc[CM_WD, k, j] * unk[nc + c]
            wdot += Cc[CM_VF, k, j] * unk[c] + Cc[CM_VD, k, j] * unk[nc + c]
        res[a] = unk[a] / stiff[k] - (z1 - w + hh)
        res[nc + a] = unk[nc + a] / stiff[k] - (vz1 - wdot + dh * v1)
    res[2 * nc] = v1 - cst[CS_VC] - 0.5 * h * a1 + h12 * j1
    if not with_jac:
        return x1, z1, vz1, a1, j1, mu, dmu
    # derivatives: of a1, j1, x1 in v1 and in each F_c (not in the rates: a1's is 0, j1's -mu/m)
    a_v = (-dmu * S1 - r2) / m
    a_f = -mu / m
    j_v = (-d2mu * a1 * S1 - dmu * a_v * S1 - dmu * dS1 - r2 * a_v) / m
    j_f = (-dmu * (a_f * S1 + a1) - r2 * a_f) / m
    x_v = 0.5 * h - h12 * a_v
    x_f = -h12 * a_f
    for a in range(nc):
        k = idx[a]
        dh = dhs[DH_SLOPE, k]
        d2h = dhs[DH_CURV, k]
        for c in range(nc):
            j = idx[c]
            jac[a, c] = Cc[CM_WF, k, j] - z_s - dh * x_f
            jac[a, nc + c] = Cc[CM_WD, k, j] - z_d
            jac[nc + a, c] = Cc[CM_VF, k, j] - vz_s - d2h * x_f * v1
            jac[nc + a, nc + c] = Cc[CM_VD, k, j] - vz_d
        jac[a, a] += 1.0 / stiff[k]
        jac[nc + a, nc + a] += 1.0 / stiff[k]
        jac[a, 2 * nc] = -dh * x_v
        jac[nc + a, 2 * nc] = -(d2h * x_v * v1 + dh)
    for c in range(nc):
        jac[2 * nc, c] = -0.5 * h * a_f + h12 * j_f
        jac[2 * nc, nc + c] = -h12 * mu / m
    jac[2 * nc, 2 * nc] = 1.0 - 0.5 * h * a_v + h12 * j_v
    return x1, z1, vz1, a1, j1, mu, dmu


#: layout of the step's carried data ``c`` (length :func:`carry_size`): the powers and their
#: rates, the block's tangential acceleration and its rate, then (after N_CARRY) the contact
#: forces' second derivatives and, above FOLD_K_MAX contacts, the modal force
#: u = phi F / M and its rate at the state
C_POWER = 0
C_POWER_RATE = C_POWER + kn.N_ENERGY
C_ACC = C_POWER_RATE + kn.N_ENERGY    # tangential acceleration [m/s^2]
C_JERK = C_ACC + 1                    # its rate [m/s^3]
N_CARRY = C_JERK + 1
#: after N_CARRY: the contact forces' second derivatives [N/s^2] (K; the last step's Hermite
#: cubic at its end: Newton's predictor only, 0 from carried()), then u and du (R each; not
#: for up to FOLD_K_MAX contacts)
#: scratch of hermite_step: lengths by :func:`scratch_sizes`; the Newton matrix stays in the
#: float scratch from step to step, valid while ``iws[IWS_JAC_VALID] == 1`` (the caller sets
#: 0 when h, the regime or the contacts change)
IWS_JAC_VALID = -1
#: rows of the residual's profile slopes at the contacts (scratch ``dhs``, shape (2, K))
DH_SLOPE = 0   #: h'(s + x1)
DH_CURV = 1    #: h''(s + x1)
#: the contact of the folded path (K = 1)
ONE = 0
IWS_ITERS = -2        # Newton iterations of the last step (a statistic for the caller)
IWS_JACS = -3         # Newton matrices formed in the last step
CHORD_MAX = 4   # chord iterations with one Jacobian before it is formed again


def slot_shapes(R, K):
    """Shapes of a step length's maps for :func:`hermite_slot`: ``(pm_shape, cc_shape)``."""
    if K <= FOLD_K_MAX:
        return (N_PMAP_FOLDED, R), (N_CMAP_FOLDED, K, K)
    return (N_PMAP, R), (N_CMAP, K, K)


def carry_size(R, K):
    """Length of the carried data ``c`` of :func:`carried` / :func:`hermite_step`."""
    return N_CARRY + K + (0 if K <= FOLD_K_MAX else 2 * R)


def scratch_sizes(R, K):
    """Lengths ``(n_ws, n_iws)`` of :func:`hermite_step`'s float and int scratch."""
    return 2 * R + 4 * K + N_CS + 3 * (2 * K + 1) + (2 * K + 1) ** 2, 3 * K + 4


@njit(cache=True, fastmath=kn.SUM_FASTMATH)
def _free_pass(Pm, q0, dq0, u0, du0, phiT, sq, sdq, wq, wd):
    """The free response and the start's hold of every mode (sq, sdq), and their plate
    displacement and velocity at the contacts (wq, wd)."""
    R = q0.size
    pqq, pqd, pdq, pdd = Pm[PM_QQ], Pm[PM_QD], Pm[PM_DQ], Pm[PM_DD]
    u0q, u0d, du0q, du0d = Pm[PM_U0Q], Pm[PM_U0D], Pm[PM_DU0Q], Pm[PM_DU0D]
    for r in range(R):
        sq[r] = pqq[r] * q0[r] + pqd[r] * dq0[r] + u0q[r] * u0[r] + du0q[r] * du0[r]
        sdq[r] = pdq[r] * q0[r] + pdd[r] * dq0[r] + u0d[r] * u0[r] + du0d[r] * du0[r]
    for k in range(phiT.shape[0]):
        row = phiT[k]
        aq = 0.0
        ad = 0.0
        for r in range(R):
            aq += row[r] * sq[r]
            ad += row[r] * sdq[r]
        wq[k] = aq
        wd[k] = ad


@njit(cache=True, fastmath=kn.SUM_FASTMATH)
def _free_pass_folded(Pm, q0, dq0, row, fq, fd):
    """The free response of every mode (fq, fd) and its plate displacement and velocity at
    the contact of mode shape ``row``: one pass."""
    pqq, pqd, pdq, pdd = Pm[PM_QQ], Pm[PM_QD], Pm[PM_DQ], Pm[PM_DD]
    aq = 0.0
    ad = 0.0
    for r in range(q0.size):
        a = pqq[r] * q0[r] + pqd[r] * dq0[r]
        b = pdq[r] * q0[r] + pdd[r] * dq0[r]
        fq[r] = a
        fd[r] = b
        aq += row[r] * a
        ad += row[r] * b
    return aq, ad


@njit(cache=True, fastmath=kn.SUM_FASTMATH)
def _end_pass_folded(Pm, fq, fd, row, F0, dF0, F1, dF1, M, q, dq, omega2, cdamp):
    """The modes at the end (q, dq) from their free response and the folded hold maps of the
    contact's force and rate at both ends, and the plate-damping sums: one pass."""
    g0q, g0d = Pm[PM_U0Q + FOLD], Pm[PM_U0D + FOLD]
    gd0q, gd0d = Pm[PM_DU0Q + FOLD], Pm[PM_DU0D + FOLD]
    g1q, g1d = Pm[PM_U1Q + FOLD], Pm[PM_U1D + FOLD]
    gd1q, gd1d = Pm[PM_DU1Q + FOLD], Pm[PM_DU1D + FOLD]
    f1 = F1 / M
    pd = 0.0
    pdd = 0.0
    for r in range(fq.size):
        qr = fq[r] + g0q[r] * F0 + gd0q[r] * dF0 + g1q[r] * F1 + gd1q[r] * dF1
        dqr = fd[r] + g0d[r] * F0 + gd0d[r] * dF0 + g1d[r] * F1 + gd1d[r] * dF1
        q[r] = qr
        dq[r] = dqr
        cdq = cdamp[r] * dqr
        pd += cdq * dqr
        pdd += cdq * (row[r] * f1 - cdq - omega2[r] * qr)
    return pd, pdd


@njit(cache=True, fastmath=kn.SUM_FASTMATH)
def _plate_damping_sums_folded(dq, q, row, f, omega2, cdamp):
    """:func:`_plate_damping_sums` with the modal force ``row f`` of one contact."""
    pd = 0.0
    pdd = 0.0
    for r in range(dq.size):
        cdq = cdamp[r] * dq[r]
        pd += cdq * dq[r]
        pdd += cdq * (row[r] * f - cdq - omega2[r] * q[r])
    return pd, pdd


@njit(cache=True)
def _modal_force(phiT, F, dF, M, u, du):
    """u = phi F / M, du = phi dF / M [m/s^2, m/s^3] (R,) of the contact forces F, rates dF."""
    R = u.size
    for r in range(R):
        u[r] = 0.0
        du[r] = 0.0
    for k in range(phiT.shape[0]):
        f = F[k] / M
        df = dF[k] / M
        row = phiT[k]
        for r in range(R):
            u[r] += row[r] * f
            du[r] += row[r] * df


@njit(cache=True, fastmath=kn.SUM_FASTMATH)
def _end_pass(Pm, sq, sdq, phiT, F, dF, M, u, du, q, dq, omega2, cdamp):
    """The end's modal force and rate (u, du), the modes at the end (q, dq) and the
    plate-damping power's sums ``(sum c dq^2, sum c dq (u - c dq - w^2 q))``."""
    u1q, u1d, du1q, du1d = Pm[PM_U1Q], Pm[PM_U1D], Pm[PM_DU1Q], Pm[PM_DU1D]
    _modal_force(phiT, F, dF, M, u, du)
    pd = 0.0
    pdd = 0.0
    for r in range(sq.size):
        qr = sq[r] + u1q[r] * u[r] + du1q[r] * du[r]
        dqr = sdq[r] + u1d[r] * u[r] + du1d[r] * du[r]
        q[r] = qr
        dq[r] = dqr
        cdq = cdamp[r] * dqr
        pd += cdq * dqr
        pdd += cdq * (u[r] - cdq - omega2[r] * qr)
    return pd, pdd


@njit(cache=True, fastmath=kn.SUM_FASTMATH)
def _plate_damping_sums(dq, q, u, omega2, cdamp):
    """``(sum c dq^2, sum c dq (u - c dq - w^2 q))`` over the modes."""
    pd = 0.0
    pdd = 0.0
    for r in range(dq.size):
        cdq = cdamp[r] * dq[r]
        pd += cdq * dq[r]
        pdd += cdq * (u[r] - cdq - omega2[r] * q[r])
    return pd, pdd


@njit(cache=True, inline="always")
def _tangential(texc, dtexc, v, mu, dmu, fsum, dfsum, fp):
    """The block's tangential acceleration [m/s^2] and its rate [m/s^3] at velocity v under
    normal force ``fsum`` changing at ``dfsum`` [N/s], from the excitation force ``texc`` [N],
    its rate ``dtexc`` [N/s] and the law's ``mu``, ``dmu`` at v."""
    m = fp[kn.FP_MASS]
    r2 = fp[kn.FP_R2]
    a = (texc - mu * fsum - r2 * v) / m
    j = (dtexc - dmu * a * fsum - mu * dfsum - r2 * a) / m
    return a, j


@njit(cache=True)
def _block_powers(c, texc, dtexc, v, a, mu, dmu, S, dS, vz, az, fp):
    """The block's four powers and their rates into ``c`` (excitation, friction, tangential
    and vertical damping)."""
    r1 = fp[kn.FP_R1]
    r2 = fp[kn.FP_R2]
    c[C_POWER + kn.E_EXCITATION] = texc * v
    c[C_POWER_RATE + kn.E_EXCITATION] = dtexc * v + texc * a
    c[C_POWER + kn.E_FRICTION] = mu * S * v
    c[C_POWER_RATE + kn.E_FRICTION] = (dmu * a * S + mu * dS) * v + mu * S * a
    c[C_POWER + kn.E_TANGENTIAL_DAMPING] = r2 * v * v
    c[C_POWER_RATE + kn.E_TANGENTIAL_DAMPING] = 2.0 * r2 * v * a
    c[C_POWER + kn.E_VERTICAL_DAMPING] = r1 * vz * vz
    c[C_POWER_RATE + kn.E_VERTICAL_DAMPING] = 2.0 * r1 * vz * az


@njit(cache=True)
def carried(t, y, dF, c, off, fp, omega2, cdamp, phiT, spos, prof, reg, with_force=True):
    """Fill ``c`` with what a step needs of its start state (and the next step of its end):
    the six energy powers [W] (order of ``ENERGY_TERMS``), their rates [W/s], the block's
    tangential acceleration [m/s^2] and its rate [m/s^3], the modal force [m/s^2] and its rate
    [m/s^3] (a single-valued law, force-driven block, no friction moment). A step fills its end's;
    the caller calls this for a state it made or changed otherwise, and after a change of the
    regime (the powers and the acceleration depend on it).
    ``with_force=False``: the modal force and rate in ``c`` are already those of ``y``."""
    iq, idq, _iz, ivz, ix, ivx, iF, _iE, R, K = kn.state_offsets(off)
    M = fp[kn.FP_MMODAL]
    w = fp[kn.FP_OMEGA]
    S = 0.0
    dS = 0.0
    for k in range(K):
        S += y[iF + k]
        dS += dF[k]
    for k in range(K):
        c[N_CARRY + k] = 0.0
    fold = K <= FOLD_K_MAX
    if not fold and with_force:
        iu = N_CARRY + K
        _modal_force(phiT, y[iF:iF + K], dF, M, c[iu:iu + R], c[iu + R:iu + 2 * R])
    v = y[ivx]
    x = y[ix]
    vz = y[ivz]
    mu, dmu = _mu_inline(off[kn.OFF_LAW], v + reg[kn.REG_S] * fp[kn.FP_VH], reg[kn.REG_B],
                         fp[kn.FP_MU_SLIP], fp[kn.FP_MU_STICK], fp[kn.FP_A1], fp[kn.FP_A2])
    texc = fp[kn.FP_T0] * math.cos(w * t)
    dtexc = -fp[kn.FP_T0] * w * math.sin(w * t)
    a, j = _tangential(texc, dtexc, v, mu, dmu, S, dS, fp)
    az, _ = vertical_rates(vz, S, dS, fp)
    c[C_ACC] = a
    c[C_JERK] = j
    _block_powers(c, texc, dtexc, v, a, mu, dmu, S, dS, vz, az, fp)
    if fold:
        pd, pdd = _plate_damping_sums_folded(y[idq:idq + R], y[iq:iq + R], phiT[ONE],
                                             y[iF] / M, omega2, cdamp)
    else:
        pd, pdd = _plate_damping_sums(y[idq:idq + R], y[iq:iq + R],
                                      c[N_CARRY + K:N_CARRY + K + R], omega2, cdamp)
    c[C_POWER + kn.E_PLATE_DAMPING] = M * pd
    c[C_POWER_RATE + kn.E_PLATE_DAMPING] = 2.0 * M * pdd
    pr = 0.0
    prd = 0.0
    for k in range(K):
        _, dh, d2h = profile_eval(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + x)
        F = y[iF + k]
        pr += F * dh * v
        prd += dF[k] * dh * v + F * d2h * v * v + F * dh * a
    c[C_POWER + kn.E_ROUGHNESS] = pr
    c[C_POWER_RATE + kn.E_ROUGHNESS] = prd


@njit(cache=True)
def _all_finite(a, n):
    """Whether the first n entries of a are finite."""
    for i in range(n):
        if not abs(a[i]) < math.inf:
            return False
    return True


# --- the steps of hermite_step (inlined: it compiles as one function) -------------------------

@njit(cache=True, inline="always")  # a step of hermite_step, as fast as if written there
def _closed_contacts(y0, dF0, reg, iF, K, idx):
    """The closed contacts in ``idx`` (their number first), and the start's total normal
    force [N] and its rate [N/s]: ``(nc, S0, dS0)``."""
    nc = 0
    S0 = 0.0
    dS0 = 0.0
    for k in range(K):
        S0 += y0[iF + k]
        dS0 += dF0[k]
        if reg[kn.REG_CLOSED + k] == 1:
            idx[nc] = k
            nc += 1
    return nc, S0, dS0


@njit(cache=True, inline="always")  # a step of hermite_step, as fast as if written there
def _start_motion(Pm, Cc, y0, dF0, c0, phiT, iq, idq, iF, R, K, fold, sq, sdq, wq, wd):
    """What the end owes to the start: the modes' free response in ``sq``, ``sdq`` (and,
    unfolded, the start's hold), the plate's displacement and velocity at the contacts from
    it and from the start's hold in ``wq``, ``wd`` (K,) [m, m/s]."""
    if fold:
        # sq, sdq: the free response only; the start's hold is folded into the end pass
        aq, ad = _free_pass_folded(Pm, y0[iq:iq + R], y0[idq:idq + R], phiT[ONE], sq, sdq)
        wq[ONE] = aq + Cc[CM0_WF, ONE, ONE] * y0[iF] + Cc[CM0_WD, ONE, ONE] * dF0[ONE]
        wd[ONE] = ad + Cc[CM0_VF, ONE, ONE] * y0[iF] + Cc[CM0_VD, ONE, ONE] * dF0[ONE]
    else:
        iu = N_CARRY + K
        _free_pass(Pm, y0[iq:iq + R], y0[idq:idq + R], c0[iu:iu + R], c0[iu + R:iu + 2 * R],
                   phiT, sq, sdq, wq, wd)


@njit(cache=True, inline="always")  # a step of hermite_step, as fast as if written there
def _predict(h, y0, dF0, c0, a0, j0, wts, iF, ivx, nc, idx, unk, scale):
    """Newton's start ``unk`` (Taylor terms to the second derivative: the Hermite predictor)
    and the unknowns' scales ``scale`` (their tolerance weights)."""
    for a in range(nc):
        d2F = c0[N_CARRY + idx[a]]
        unk[a] = y0[iF + idx[a]] + h * (dF0[idx[a]] + 0.5 * h * d2F)
        unk[nc + a] = dF0[idx[a]] + h * d2F
        scale[a] = wts[iF + idx[a]]
        scale[nc + a] = wts[iF + idx[a]] / h
    unk[2 * nc] = y0[ivx] + h * a0 + 0.5 * h * h * j0
    scale[2 * nc] = wts[ivx]


@njit(cache=True, inline="always")  # a step of hermite_step, as fast as if written there
def _newton(cst, h, unk, scale, res, jac, piv, n, nc, idx, wq, wd, Cc, law, fp, stiff, spos,
            prof, reg, dhs, iws):
    """Newton on the step's n unknowns ``unk`` from the predictor, with the matrix kept in
    ``jac`` (``piv``) while ``iws[IWS_JAC_VALID]`` says so and formed again after
    ``CHORD_MAX`` chord iterations; counts in ``iws[IWS_ITERS]``, ``iws[IWS_JACS]``. False on
    a runaway iterate, a singular matrix or no convergence in ``HERMITE_NEWTON_MAX``."""
    fresh = iws[IWS_JAC_VALID] == 0  # a Jacobian kept from an earlier step is reused
    since = 0                        # chord iterations with the current Jacobian
    iws[IWS_ITERS] = 0
    iws[IWS_JACS] = 0
    for _it in range(HERMITE_NEWTON_MAX):
        iws[IWS_ITERS] += 1
        form = fresh or since >= CHORD_MAX
        _residual(cst, h, unk, res, nc, idx, wq, wd, Cc, law, fp, stiff, spos, prof, reg, jac,
                  form, dhs)
        if not _all_finite(res, n):  # a runaway iterate: the caller takes a shorter step
            return False
        if form:
            if not lu_factor_checked(jac, piv):  # singular: the caller takes a shorter step
                iws[IWS_JAC_VALID] = 0
                return False
            iws[IWS_JAC_VALID] = 1
            iws[IWS_JACS] += 1
            fresh = False
            since = 0
        for a in range(n):
            res[a] = -res[a]
        lu_solve(jac, piv, res)
        since += 1
        worst = 0.0
        for col in range(n):
            unk[col] += res[col]
            e = abs(res[col]) / scale[col]
            if not e <= worst:  # NaN counts as the worst
                worst = e
        if not worst < NEWTON_RUNAWAY:  # a singular matrix or a runaway iterate
            return False
        if worst <= NEWTON_TOL_REL:
            return True
    return False


@njit(cache=True, inline="always")  # a step of hermite_step, as fast as if written there
def _end_forces(h, y0, dF0, unk, nc, idx, iF, K, y1, dF1, c1):
    """The end's contact forces and rates (0 on the open contacts) into ``y1``, ``dF1``, the
    Hermite cubic's second derivatives into ``c1``; returns their sums ``(S1, dS1)``."""
    S1 = 0.0
    dS1 = 0.0
    for k in range(K):
        y1[iF + k] = 0.0
        dF1[k] = 0.0
        c1[N_CARRY + k] = 0.0
    for a in range(nc):
        k = idx[a]
        y1[iF + k] = unk[a]
        dF1[k] = unk[nc + a]
        # the Hermite cubic's second derivative at the end: the next step's predictor
        c1[N_CARRY + k] = (2.0 * dF0[k] + 4.0 * unk[nc + a]
                           - 6.0 * (unk[a] - y0[iF + k]) / h) / h
        S1 += unk[a]
        dS1 += unk[nc + a]
    return S1, dS1


@njit(cache=True, inline="always")  # a step of hermite_step, as fast as if written there
def _end_modes(Pm, sq, sdq, phiT, y0, dF0, y1, dF1, c1, M, iq, idq, iF, R, K, fold, omega2,
               cdamp):
    """The end's modes into ``y1`` (and, unfolded, its modal force and rate into ``c1``);
    returns the plate-damping power's sums (one pass over the modes)."""
    if fold:
        return _end_pass_folded(Pm, sq, sdq, phiT[ONE], y0[iF], dF0[ONE], y1[iF], dF1[ONE], M,
                                y1[iq:iq + R], y1[idq:idq + R], omega2, cdamp)
    iu = N_CARRY + K
    return _end_pass(Pm, sq, sdq, phiT, y1[iF:iF + K], dF1, M, c1[iu:iu + R],
                     c1[iu + R:iu + 2 * R], y1[iq:iq + R], y1[idq:idq + R], omega2, cdamp)


@njit(cache=True, inline="always")  # a step of hermite_step, as fast as if written there
def _roughness_power(unk, nc, idx, dhs, v1, a1):
    """The roughness power [W] at the end and its rate [W/s], from the closed contacts' forces
    and rates and the profile's slope and curvature the residual left in ``dhs``."""
    pr = 0.0
    prd = 0.0
    for a in range(nc):
        k = idx[a]
        dh = dhs[DH_SLOPE, k]
        F = unk[a]
        pr += F * dh * v1
        prd += unk[nc + a] * dh * v1 + F * dhs[DH_CURV, k] * v1 * v1 + F * dh * a1
    return pr, prd


@njit(cache=True, inline="always")  # a step of hermite_step, as fast as if written there
def _energy_quadrature(h, y0, c0, y1, c1, iE):
    """The energy integrals at the end by the Hermite quadrature of the powers:
    ``int P = h (P0 + P1) / 2 + h^2 (P0' - P1') / 12``."""
    for i in range(kn.N_ENERGY):
        y1[iE + i] = (y0[iE + i] + 0.5 * h * (c0[C_POWER + i] + c1[C_POWER + i])
                      + h * h / 12.0 * (c0[C_POWER_RATE + i] - c1[C_POWER_RATE + i]))


@njit(cache=True, inline="always")
def hermite_step(t0, h, y0, dF0, c0, y1, dF1, c1, Pm, Cc, off, fp, omega2, cdamp, phiT, stiff,
                 spos, prof, reg, wts, ws, iws):
    """One step of Hermite holds from (y0, dF0, c0) to (y1, dF1, c1); False if Newton fails.

    The modes exact under the Hermite hold of their force (``Pm``, ``Cc`` of
    :func:`hermite_slot` for this h); the block's vertical and tangential motion by the
    Obreschkoff (2,2) rule (values and rates at both ends); the contact relation and its rate
    at the end. Unknowns: the closed contacts' forces and force rates and the tangential
    velocity, by Newton from the Hermite predictor (Taylor terms to the second derivative)
    with the analytic Jacobian, kept from step to step while valid (chord iterations, formed
    again after ``CHORD_MAX`` of them). The energy integrals by the Hermite quadrature of the
    powers. ``dF`` (K,): contact force rates [N/s] (0 on open contacts); ``c``: the carried
    data of the state (c1 is filled for the next step; :func:`carried` gives them for a state
    made otherwise or after a change of the regime);
    ``ws``, ``iws``: float and int scratch (lengths of :func:`scratch_sizes`); ``Pm``,
    ``Cc`` of the shapes of :func:`slot_shapes`. Scope of this version: a single-valued law
    (``off[OFF_LAW]``, through ``laws.single_valued_mu_d2``), a force-driven block, no
    friction moment.

    Its steps, in order (each inlined): ``_closed_contacts``, ``_start_motion``,
    ``_step_constants``, ``_predict``, ``_newton``, ``_end_forces``, ``_end_modes``, the
    end's carried data (``_block_powers``, ``_roughness_power``) and ``_energy_quadrature``.
    """
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = kn.state_offsets(off)
    t1 = t0 + h
    idx = iws[:K]
    nc, S0, dS0 = _closed_contacts(y0, dF0, reg, iF, K, idx)
    a0 = c0[C_ACC]
    j0 = c0[C_JERK]
    az0, jz0 = vertical_rates(y0[ivz], S0, dS0, fp)
    # the float scratch: the modes' free response, the plate's motion at the contacts, the
    # profile's slopes, the step's constants, then Newton's unknowns, scales, residual, matrix
    sq = ws[0:R]
    sdq = ws[R:2 * R]
    base = 2 * R
    wq = ws[base:base + K]
    wd = ws[base + K:base + 2 * K]
    fold = K <= FOLD_K_MAX
    _start_motion(Pm, Cc, y0, dF0, c0, phiT, iq, idq, iF, R, K, fold, sq, sdq, wq, wd)
    base += 2 * K
    dhs = ws[base:base + 2 * K].reshape((2, K))
    base += 2 * K
    cst = ws[base:base + N_CS]
    _step_constants(t1, h, y0[ix], y0[ivx], a0, j0, y0[iz], y0[ivz], az0, jz0, fp, cst)
    base += N_CS
    n = 2 * nc + 1
    unk = ws[base:base + n]
    scale = ws[base + n:base + 2 * n]
    res = ws[base + 2 * n:base + 3 * n]
    jac = ws[base + 3 * n:base + 3 * n + n * n].reshape((n, n))
    piv = iws[K:K + n]
    _predict(h, y0, dF0, c0, a0, j0, wts, iF, ivx, nc, idx, unk, scale)
    law = off[kn.OFF_LAW]
    if not _newton(cst, h, unk, scale, res, jac, piv, n, nc, idx, wq, wd, Cc, law, fp, stiff,
                   spos, prof, reg, dhs, iws):
        return False
    x1, z1, vz1, a1, j1, mu1, dmu1 = _residual(cst, h, unk, res, nc, idx, wq, wd, Cc, law, fp,
                                               stiff, spos, prof, reg, jac, False, dhs)
    S1, dS1 = _end_forces(h, y0, dF0, unk, nc, idx, iF, K, y1, dF1, c1)
    v1 = unk[2 * nc]
    y1[iz] = z1
    y1[ivz] = vz1
    y1[ix] = x1
    y1[ivx] = v1
    M = fp[kn.FP_MMODAL]
    pd, pdd = _end_modes(Pm, sq, sdq, phiT, y0, dF0, y1, dF1, c1, M, iq, idq, iF, R, K, fold,
                         omega2, cdamp)
    # the end's carried data from what the step has (as carried() would give them)
    az1, _ = vertical_rates(vz1, S1, dS1, fp)
    c1[C_ACC] = a1
    c1[C_JERK] = j1
    _block_powers(c1, cst[CS_TEXC], cst[CS_DTEXC], v1, a1, mu1, dmu1, S1, dS1, vz1, az1, fp)
    c1[C_POWER + kn.E_PLATE_DAMPING] = M * pd
    c1[C_POWER_RATE + kn.E_PLATE_DAMPING] = 2.0 * M * pdd
    pr, prd = _roughness_power(unk, nc, idx, dhs, v1, a1)
    c1[C_POWER + kn.E_ROUGHNESS] = pr
    c1[C_POWER_RATE + kn.E_ROUGHNESS] = prd
    _energy_quadrature(h, y0, c0, y1, c1, iE)
    return True
