"""Exact modal propagation under a Hermite-cubic hold of the modal force (issue 28, in work).

A plate mode ``q'' + c q' + w^2 q = u(t)`` is propagated exactly over a step of length h when
u is a polynomial in t. The ``adaptive-modal`` step holds u linear (its values at both ends);
docs/performance.md ("What limits a step of one output interval") measured that this hold, not
the coupling of the modes through the contact, is what keeps that step at half the output
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

__all__ = ["HOLD_DU0", "HOLD_DU1", "HOLD_U0", "HOLD_U1", "N_HOLD", "hermite_maps"]

#: positions of the hold's four data in the step maps' ``H[r, HOLD_*, :]``
HOLD_U0 = 0    #: u(0)
HOLD_DU0 = 1   #: u'(0)
HOLD_U1 = 2    #: u(h)
HOLD_DU1 = 3   #: u'(h)
N_HOLD = 4
#: positions of a mode's state in the maps' last axis
MODE_Q = 0
MODE_DQ = 1
N_MONOMIALS = 4        # tau^0 .. tau^3
#: omega h up to which the maps come from the power series. The particular solution above it
#: subtracts terms of size k! / w^(2(k+1))-ish that are (omega h)^-(2(k+1)) k! times the
#: result's h^(k+1) scale relative: at omega h = 2 at most 6 / 2^8 of a digit's worth for k=3
HERMITE_SERIES_LIMIT = 2.0
N_TERMS = 40           # series terms: 2^40 / 44! < 1e-42


@njit(cache=True)
def _monomial_series(w2, c, h, W):
    """W[k, :] = exact response [q, q'](h) to u = tau^k from rest, by the power series."""
    # v_n = (A h)^n e2 / n!, A = [[0, 1], [-w2, -c]]; W_k = k! h^(k+1) sum_n v_n n!/(n+k+1)!
    for k in range(N_MONOMIALS):
        W[k, MODE_Q] = 0.0
        W[k, MODE_DQ] = 0.0
    v0, v1 = 0.0, 1.0
    for n in range(N_TERMS):
        ratio = 1.0 / (n + 1.0)          # n! / (n + 1)!
        for k in range(N_MONOMIALS):
            W[k, MODE_Q] += v0 * ratio
            W[k, MODE_DQ] += v1 * ratio
            ratio /= n + k + 2.0         # n! / (n + k + 2)!
        a = h * v1 / (n + 1.0)
        b = h * (-w2 * v0 - c * v1) / (n + 1.0)
        v0, v1 = a, b
    scale = h
    for k in range(N_MONOMIALS):
        scale_k = scale * math.gamma(k + 1.0)
        W[k, MODE_Q] *= scale_k
        W[k, MODE_DQ] *= scale_k
        scale *= h


@njit(cache=True)
def _monomial_particular(w2, c, h, P00, P01, P10, P11, W):
    """W[k, :] from the polynomial particular solution (omega h above the series limit)."""
    a = np.zeros(N_MONOMIALS + 2)
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
        W[k, MODE_Q] = ph - (P00 * a[0] + P01 * a[1])
        W[k, MODE_DQ] = dph - (P10 * a[0] + P11 * a[1])


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
    R = omega2.size
    for r in range(R):
        w2 = omega2[r]
        c = cdamp[r]
        sig = 0.5 * c
        wd = math.sqrt(w2 - sig * sig)
        e = math.exp(-sig * h)
        co = math.cos(wd * h)
        si = math.sin(wd * h)
        p00 = e * (co + sig / wd * si)
        p01 = e * si / wd
        p10 = -e * w2 * si / wd
        p11 = e * (co - sig / wd * si)
        if math.sqrt(w2) * h <= HERMITE_SERIES_LIMIT:
            _monomial_series(w2, c, h, W)
        else:
            _monomial_particular(w2, c, h, p00, p01, p10, p11, W)
        Phi[r, MODE_Q, MODE_Q] = p00
        Phi[r, MODE_Q, MODE_DQ] = p01
        Phi[r, MODE_DQ, MODE_Q] = p10
        Phi[r, MODE_DQ, MODE_DQ] = p11
        for i in range(2):
            w0, w1, w2k, w3 = W[0, i], W[1, i], W[2, i], W[3, i]
            H[r, HOLD_U0, i] = w0 - 3.0 * w2k / (h * h) + 2.0 * w3 / (h * h * h)
            H[r, HOLD_DU0, i] = w1 - 2.0 * w2k / h + w3 / (h * h)
            H[r, HOLD_U1, i] = 3.0 * w2k / (h * h) - 2.0 * w3 / (h * h * h)
            H[r, HOLD_DU1, i] = -w2k / h + w3 / (h * h)
