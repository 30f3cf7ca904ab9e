"""Dense output of the Hermite step: the state at a time inside a step, without a new step.

Within a step of :func:`roughvib.solvers.hermite.hermite_step` the modal force is the Hermite
cubic through its values and rates at both ends, and the modes are exact under it. At a time
tau inside the step they are exact too, from the start state and the same four hold data:

    [q, q'](tau) = Phi(tau) [q, q'](0) + sum_i D_i(tau; h) d_i,   d = (u0, u0', u1, u1'),

with ``D_i`` the response at tau to the hold's monomial coefficients (``dense_maps``). The
contact forces are that cubic (values and rates at both ends); the block's position and
velocity, and the energy integrals, are the quintic Hermite interpolants of their values and
first two derivatives at both ends (the Obreschkoff rule's data), fourth order or better, as
the step. An output time that falls inside a step is written from this state; the margins of
the events are checked there too.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from roughvib.model import kernels as kn
from roughvib.solvers import hermite as hm

__all__ = ["N_DMAP", "dense_maps", "dense_state"]

#: rows of the dense maps ``Pd`` (N_DMAP, R): Phi(tau), then the maps of the four hold data
#: (u0, u0', u1, u1') on q and q'
DM_QQ, DM_QD, DM_DQ, DM_DD = 0, 1, 2, 3
DM_U0Q, DM_U0D, DM_DU0Q, DM_DU0D = 4, 5, 6, 7
DM_U1Q, DM_U1D, DM_DU1Q, DM_DU1D = 8, 9, 10, 11
N_DMAP = 12


@njit(cache=True)
def dense_maps(omega2, cdamp, h, tau, Pd):
    """Maps of every mode from a step's start to time ``tau`` inside it [s], under the Hermite
    hold of the modal force over the step of length ``h`` [s]: fills ``Pd`` (N_DMAP, R) so
    that ``q(tau) = Pd[DM_QQ] q0 + Pd[DM_QD] q0' + Pd[DM_U0Q] u0 + Pd[DM_DU0Q] u0'
    + Pd[DM_U1Q] u1 + Pd[DM_DU1Q] u1'`` (and the ``*D`` rows for q'). At ``tau = h`` these are
    the step's own maps (:func:`roughvib.solvers.hermite.hermite_maps`)."""
    W = np.zeros((hm.N_MONOMIALS, 2))
    a = np.zeros(hm.N_MONOMIALS + 2)
    for r in range(omega2.size):
        w2 = omega2[r]
        c = cdamp[r]
        sig = 0.5 * c
        wd = math.sqrt(w2 - sig * sig)
        e = math.exp(-sig * tau)
        co = math.cos(wd * tau)
        si = math.sin(wd * tau)
        p00 = e * (co + sig / wd * si)
        p01 = e * si / wd
        p10 = -e * w2 * si / wd
        p11 = e * (co - sig / wd * si)
        # the responses at tau to the monomials s^k, s from the step's start
        if math.sqrt(w2) * tau <= hm.HERMITE_SERIES_LIMIT:
            hm._monomial_series(w2, c, tau, W)
        else:
            hm._monomial_particular(w2, c, tau, p00, p01, p10, p11, W, a)
        Pd[DM_QQ, r] = p00
        Pd[DM_QD, r] = p01
        Pd[DM_DQ, r] = p10
        Pd[DM_DD, r] = p11
        Pd[DM_U0Q, r], Pd[DM_DU0Q, r], Pd[DM_U1Q, r], Pd[DM_DU1Q, r] = _hold_maps(
            W[hm.W_1, hm.MODE_Q], W[hm.W_T, hm.MODE_Q], W[hm.W_T2, hm.MODE_Q],
            W[hm.W_T3, hm.MODE_Q], h)
        Pd[DM_U0D, r], Pd[DM_DU0D, r], Pd[DM_U1D, r], Pd[DM_DU1D, r] = _hold_maps(
            W[hm.W_1, hm.MODE_DQ], W[hm.W_T, hm.MODE_DQ], W[hm.W_T2, hm.MODE_DQ],
            W[hm.W_T3, hm.MODE_DQ], h)


@njit(cache=True, inline="always")
def _hold_maps(w0, w1, w2k, w3, h):
    """The maps of the hold data (u0, u0', u1, u1') from the monomial responses w0..w3 of one
    state component: the hold is u(s) = u0 + u0' s + (3 (u1 - u0) / h^2 - (2 u0' + u1') / h)
    s^2 + ((u0' + u1') / h^2 - 2 (u1 - u0) / h^3) s^3."""
    h2 = h * h
    h3 = h2 * h
    return (w0 - 3.0 * w2k / h2 + 2.0 * w3 / h3, w1 - 2.0 * w2k / h + w3 / h2,
            3.0 * w2k / h2 - 2.0 * w3 / h3, -w2k / h + w3 / h2)


@njit(cache=True, inline="always")
def _quintic(theta, h, p0, d0, dd0, p1, d1, dd1):
    """The quintic Hermite interpolant at fraction ``theta`` of a step of length h, from the
    values, first and second derivatives at both ends."""
    t2 = theta * theta
    t3 = t2 * theta
    t4 = t3 * theta
    t5 = t4 * theta
    b_p1 = 10.0 * t3 - 15.0 * t4 + 6.0 * t5
    b_d0 = theta - 6.0 * t3 + 8.0 * t4 - 3.0 * t5
    b_dd0 = 0.5 * (t2 - 3.0 * t3 + 3.0 * t4 - t5)
    b_d1 = -4.0 * t3 + 7.0 * t4 - 3.0 * t5
    b_dd1 = 0.5 * (t3 - 2.0 * t4 + t5)
    return ((1.0 - b_p1) * p0 + b_p1 * p1 + h * (b_d0 * d0 + b_d1 * d1)
            + h * h * (b_dd0 * dd0 + b_dd1 * dd1))


@njit(cache=True)
def dense_state(theta, h, t0, y0, dF0, c0, y1, dF1, c1, Pd, yd, dFd, off, fp, phiT, reg):
    """The state ``yd`` and contact force rates ``dFd`` at ``t0 + theta h``, inside the step
    of length h from (y0, dF0, c0) to (y1, dF1, c1) (``c``: the carried powers and their
    rates, :func:`roughvib.solvers.hermite.carried`), with the dense maps ``Pd`` of
    :func:`dense_maps` for this h and ``tau = theta h``. Feldmann law, force-driven block."""
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = kn.state_offsets(off)
    M = fp[kn.FP_MMODAL]
    t1 = t0 + h
    t2 = theta * theta
    t3 = t2 * theta
    # contact forces: the cubic of the hold (values and rates at both ends)
    b00 = 2.0 * t3 - 3.0 * t2 + 1.0
    b10 = t3 - 2.0 * t2 + theta
    b01 = 3.0 * t2 - 2.0 * t3
    b11 = t3 - t2
    db00 = 6.0 * (t2 - theta) / h
    db10 = 3.0 * t2 - 4.0 * theta + 1.0
    db11 = 3.0 * t2 - 2.0 * theta
    S0 = 0.0
    dS0 = 0.0
    S1 = 0.0
    dS1 = 0.0
    for k in range(K):
        f0, f1, g0, g1 = y0[iF + k], y1[iF + k], dF0[k], dF1[k]
        yd[iF + k] = b00 * f0 + b01 * f1 + h * (b10 * g0 + b11 * g1)
        dFd[k] = db00 * (f0 - f1) + db10 * g0 + db11 * g1
        S0 += f0
        dS0 += g0
        S1 += f1
        dS1 += g1
    # the modes: exact under the hold, from the start
    qd = yd[iq:iq + R]
    dqd = yd[idq:idq + R]
    q0 = y0[iq:iq + R]
    dq0 = y0[idq:idq + R]
    pqq, pqd, pdq, pdd = Pd[DM_QQ], Pd[DM_QD], Pd[DM_DQ], Pd[DM_DD]
    for r in range(R):
        qd[r] = pqq[r] * q0[r] + pqd[r] * dq0[r]
        dqd[r] = pdq[r] * q0[r] + pdd[r] * dq0[r]
    u0q, u0d, du0q, du0d = Pd[DM_U0Q], Pd[DM_U0D], Pd[DM_DU0Q], Pd[DM_DU0D]
    u1q, u1d, du1q, du1d = Pd[DM_U1Q], Pd[DM_U1D], Pd[DM_DU1Q], Pd[DM_DU1D]
    for k in range(K):
        f0 = y0[iF + k] / M
        g0 = dF0[k] / M
        f1 = y1[iF + k] / M
        g1 = dF1[k] / M
        if f0 == 0.0 and g0 == 0.0 and f1 == 0.0 and g1 == 0.0:
            continue
        row = phiT[k]
        for r in range(R):
            p = row[r]
            qd[r] += p * (u0q[r] * f0 + du0q[r] * g0 + u1q[r] * f1 + du1q[r] * g1)
            dqd[r] += p * (u0d[r] * f0 + du0d[r] * g0 + u1d[r] * f1 + du1d[r] * g1)
    # the block: quintic interpolants of position and velocity
    az0, jz0 = hm.vertical_rates(y0[ivz], S0, dS0, fp)
    az1, jz1 = hm.vertical_rates(y1[ivz], S1, dS1, fp)
    yd[iz] = _quintic(theta, h, y0[iz], y0[ivz], az0, y1[iz], y1[ivz], az1)
    yd[ivz] = _quintic(theta, h, y0[ivz], az0, jz0, y1[ivz], az1, jz1)
    ax0, jx0 = hm.tangential_rates(t0, y0[ivx], S0, dS0, off, fp, reg)
    ax1, jx1 = hm.tangential_rates(t1, y1[ivx], S1, dS1, off, fp, reg)
    yd[ix] = _quintic(theta, h, y0[ix], y0[ivx], ax0, y1[ix], y1[ivx], ax1)
    yd[ivx] = _quintic(theta, h, y0[ivx], ax0, jx0, y1[ivx], ax1, jx1)
    # the energy integrals: quintic in their values, powers and power rates
    for i in range(kn.N_ENERGY):
        yd[iE + i] = _quintic(theta, h, y0[iE + i], c0[hm.C_POWER + i],
                              c0[hm.C_POWER_RATE + i], y1[iE + i], c1[hm.C_POWER + i],
                              c1[hm.C_POWER_RATE + i])
