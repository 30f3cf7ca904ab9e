"""The plate modes' exact first-order-hold step maps, their per-step-length cache, and the
modal forces they propagate (docs/theory.md, "The adaptive exact-modal scheme").

Over a step of length h with the modal force linear in time (first-order hold), a mode is
propagated exactly, whatever omega h is:

    [q, q']_{n+1} = Phi(h) [q, q']_n + G0(h) u_n + G1(h) u_{n+1},   u = phi^T F / M.

For omega h > 1 the maps come from the closed form of the damped oscillator; below, from a
power series (``N_SERIES`` terms) of the same matrix exponential, because the closed form's
``1 - cos`` terms lose all digits for omega h -> 0 (both branches are tested against scipy's
expm). Step sizes are dyadic fractions of the output step, so the maps of each size are
computed once and kept in a cache slot (:func:`fill_slot`).
"""

from __future__ import annotations

import collections
import math

import numpy as np
from numba import njit

from roughvib.model import kernels as kn
from roughvib.solvers import hermite as hm
from roughvib.solvers.adaptive.layout import N_SLOTS
from roughvib.solvers.base import MODE_DQ, MODE_Q

__all__ = ["N_MAP", "Propagators", "fill_slot", "modal_force", "moment_force", "moment_map",
           "new_propagators", "state_modal_force", "step_maps"]

SERIES_LIMIT = 1.0   # omega h below which the propagators come from the power series
N_SERIES = 22        # terms: 1 / 22! < 1e-21
# the series' divisors as factors (numba keeps module-level arrays as constants): a division
# per term and mode made the propagator computations a twentieth of a solve
_INV_N1 = 1.0 / np.arange(1.0, N_SERIES + 1.0)                          # 1 / (n + 1)
_INV_N12 = 1.0 / (np.arange(1.0, N_SERIES + 1.0) * np.arange(2.0, N_SERIES + 2.0))  # 1/((n+1)(n+2))

# rows of the propagators' mode-contiguous copy P (Propagators.P): Phi's four entries, G0, G1
MAP_QQ = 0
MAP_QD = 1
MAP_DQ = 2
MAP_DD = 3
MAP_G0Q = 4
MAP_G0D = 5
MAP_G1Q = 6
MAP_G1D = 7
N_MAP = 8


#: the propagator cache of the trapezoidal loop (:func:`.trapezoidal_loop.advance`): ``P``
#: (N_SLOTS, N_MAP, R) the maps Phi, G0 and G1 of :func:`step_maps` of each slot, one
#: contiguous row per entry (``MAP_*``), so that the step's loops over the modes read them at
#: unit stride; ``G1c`` (N_SLOTS, K, K) G1 in contact
#: coordinates and ``hslot`` (N_SLOTS,) the step of each slot (0: empty); with a friction
#: moment ``Hm`` (N_SLOTS, K, K) the moment's G1 in contact coordinates,
#: ``H_kj = sum_r phi_rk G1_r Psi_rj / M``, and ``hmslot`` (N_SLOTS,) the step it was computed
#: for (both of size 0 along K without the moment); ``Phi`` (R, 2, 2), ``G0``, ``G1`` (R, 2)
#: receive :func:`step_maps` for the slot being filled. numba passes a namedtuple of arrays at
#: the cost of its fields (:func:`new_propagators` makes one)
Propagators = collections.namedtuple("Propagators",
                                     ["Phi", "G0", "G1", "G1c", "hslot", "Hm", "hmslot", "P"])


def new_propagators(R: int, K: int, moment: bool) -> Propagators:
    """An empty propagator cache for R modes and K contacts (``Hm`` sized for the friction
    moment when ``moment``)."""
    km = K if moment else 0
    return Propagators(np.zeros((R, 2, 2)), np.zeros((R, 2)), np.zeros((R, 2)),
                       np.zeros((N_SLOTS, K, K)), np.zeros(N_SLOTS),
                       np.zeros((N_SLOTS, km, km)), np.zeros(N_SLOTS),
                       np.zeros((N_SLOTS, N_MAP, R)))


@njit(cache=True)
def step_maps(omega2, cdamp, h, Phi, G0, G1):
    """Exact first-order-hold step maps of q'' + c q' + w^2 q = u(t), for every mode.

    Parameters
    ----------
    omega2, cdamp : ndarray, shape (R,)
        w_r^2 [rad^2/s^2] and c_r = 2 zeta_r w_r [1/s] (underdamped: c^2 < 4 w^2).
    h : float
        Step [s].
    Phi : ndarray, shape (R, 2, 2)
    G0, G1 : ndarray, shape (R, 2)
        Filled so that ``[q, q'](h) = Phi [q, q'](0) + G0 u(0) + G1 u(h)`` for u linear in t.
    """
    R = omega2.size
    for r in range(R):
        w2 = omega2[r]
        c = cdamp[r]
        if math.sqrt(w2) * h <= SERIES_LIMIT:
            # exp of [[0, 1], [-w2, -c]] h by its series; with v_n = (A h)^n e2 / n!:
            # Phi e2 = sum v_n, Phi e1 = e1 - w2 h sum v_{n-1} / n,
            # Gamma_const = h sum v_n / (n+1), Gamma_ramp = h^2 sum v_n / ((n+1)(n+2))
            v0, v1 = 0.0, 1.0
            p01, p11 = 0.0, 0.0
            p00, p10 = 1.0, 0.0
            gc0, gc1 = 0.0, 0.0
            gr0, gr1 = 0.0, 0.0
            w2h = w2 * h
            for n in range(N_SERIES):
                i1 = _INV_N1[n]
                i12 = _INV_N12[n]
                p01 += v0
                p11 += v1
                gc0 += v0 * i1
                gc1 += v1 * i1
                gr0 += v0 * i12
                gr1 += v1 * i12
                p00 -= w2h * v0 * i1
                p10 -= w2h * v1 * i1
                # v_{n+1} = A h v_n / (n + 1)
                a = h * v1 * i1
                b = h * (-w2 * v0 - c * v1) * i1
                v0, v1 = a, b
            gc0 *= h
            gc1 *= h
            gr0 *= h * h
            gr1 *= h * h
        else:
            p00, p01, p10, p11 = hm.damped_propagator(w2, c, h)
            # constant unit force: particular solution q = 1/w2
            gc0 = (1.0 - p00) / w2
            gc1 = -p10 / w2
            # unit ramp u = t: particular solution q = t/w2 - c/w2^2, q' = 1/w2
            gr0 = (h - p01) / w2 - c * (1.0 - p00) / (w2 * w2)
            gr1 = (1.0 - p11) / w2 + c * p10 / (w2 * w2)
        Phi[r, MODE_Q, MODE_Q] = p00
        Phi[r, MODE_Q, MODE_DQ] = p01
        Phi[r, MODE_DQ, MODE_Q] = p10
        Phi[r, MODE_DQ, MODE_DQ] = p11
        G1[r, MODE_Q] = gr0 / h
        G1[r, MODE_DQ] = gr1 / h
        G0[r, MODE_Q] = gc0 - gr0 / h
        G0[r, MODE_DQ] = gc1 - gr1 / h


@njit(cache=True)
def fill_slot(slot, h, omega2, cdamp, phi, cres, M, prop):
    """Propagators of step h into cache slot ``slot`` of ``prop``, with G1 in contact
    coordinates."""
    Phi, G0, G1, G1c, hslot = prop.Phi, prop.G0, prop.G1, prop.G1c, prop.hslot
    step_maps(omega2, cdamp, h, Phi, G0, G1)
    R = omega2.size
    P = prop.P[slot]
    for r in range(R):
        P[MAP_QQ, r] = Phi[r, MODE_Q, MODE_Q]
        P[MAP_QD, r] = Phi[r, MODE_Q, MODE_DQ]
        P[MAP_DQ, r] = Phi[r, MODE_DQ, MODE_Q]
        P[MAP_DD, r] = Phi[r, MODE_DQ, MODE_DQ]
        P[MAP_G0Q, r] = G0[r, MODE_Q]
        P[MAP_G0D, r] = G0[r, MODE_DQ]
        P[MAP_G1Q, r] = G1[r, MODE_Q]
        P[MAP_G1D, r] = G1[r, MODE_DQ]
    K = cres.shape[0]
    for k in range(K):
        for j in range(K):
            G1c[slot, k, j] = cres[k, j]
    g1q = P[MAP_G1Q]
    for r in range(R):
        gr = g1q[r] / M
        for k in range(K):
            a = phi[r, k] * gr
            for j in range(K):
                G1c[slot, k, j] += a * phi[r, j]
    hslot[slot] = h


@njit(cache=True)
def modal_force(F, u, phiT, M):
    """u_r = sum_k phi_rk F_k / M: the modal force per unit modal mass [m/s^2].

    ``phiT`` is the mode-shape matrix transposed, shape (K, R), C-contiguous: the sum runs as
    K contiguous axpys over the modes, which vectorise (a reduction over k does not).

    This is the contact forces' part. With a friction moment (``contact.friction_moment``)
    the modal force also holds ``mu(v) sum_k Psi_rk F_k / M`` (``moment_force``), which
    depends on the regime and the velocity; the buffers ``U`` of the step loop carry the
    whole modal force (``state_modal_force``): every step starts from the whole force.
    """
    R = u.size
    for r in range(R):
        u[r] = 0.0
    for k in range(F.size):
        f = F[k] / M
        if f != 0.0:
            for r in range(R):
                u[r] += phiT[k, r] * f


@njit(cache=True)
def moment_force(F, mu, M, off, fp, u):
    """u_r = mu sum_k Psi_rk F_k / M: the friction moment's modal force [m/s^2], shape (R,).

    ``Psi`` is packed contact-major in ``fp`` from ``off[OFF_IPSI]`` (K contiguous axpys).
    """
    ip, R = off[kn.OFF_IPSI], off[kn.OFF_R]
    for r in range(R):
        u[r] = 0.0
    for k in range(F.size):
        f = F[k] * mu / M
        if f != 0.0:
            base = ip + k * R
            for r in range(R):
                u[r] += fp[base + r] * f


@njit(cache=True)
def moment_map(slot, prop, phiT, off, fp):
    """The moment's G1 in contact coordinates, ``Hm[slot]``, for the slot's step, computed
    once per step length: ``H_kj = sum_r phi_rk G1_r Psi_rj / M`` [m/N]."""
    if prop.hmslot[slot] == prop.hslot[slot]:
        return
    Hm = prop.Hm
    g1q = prop.P[slot, MAP_G1Q]
    ip, R = off[kn.OFF_IPSI], off[kn.OFF_R]
    K = Hm.shape[1]
    M = fp[kn.FP_MMODAL]
    for k in range(K):
        for j in range(K):
            base = ip + j * R
            acc = 0.0
            for r in range(R):
                acc += phiT[k, r] * g1q[r] * fp[base + r]
            Hm[slot, k, j] = acc / M
    prop.hmslot[slot] = prop.hslot[slot]


@njit(cache=True)
def state_modal_force(y, u, phiT, off, fp, reg, scratch):
    """The whole modal force u (R,) of the state y [m/s^2]: the contact forces' part
    (:func:`modal_force`) and, with a friction moment, the moment's (``moment_force``, with
    the share ``c`` of :func:`.kernels.moment_share`: ``mu(v)`` for the Feldmann law,
    ``lambda / F_N`` for a set-valued law). ``scratch``: length >= R."""
    iF, K, R = off[kn.OFF_IF], off[kn.OFF_K], off[kn.OFF_R]
    M = fp[kn.FP_MMODAL]
    modal_force(y[iF:iF + K], u, phiT, M)
    if off[kn.OFF_IX] >= 0 and kn.moment_on(off):
        c, _, _, _ = kn.moment_share(0.0, y, off, fp, reg)  # t: only prescribed motion reads it
        um = scratch[:R]
        moment_force(y[iF:iF + K], c, M, off, fp, um)
        for r in range(R):
            u[r] += um[r]
