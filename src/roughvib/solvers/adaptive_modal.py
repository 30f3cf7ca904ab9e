"""Adaptive exact-modal solver: exact plate propagation, error-controlled steps, located events.

Two steps, one loop each (docs/theory.md, "The adaptive exact-modal scheme"):

* the **Hermite step** (``_advance_hermite``; :mod:`roughvib.solvers.hermite`), fourth order,
  where :func:`hermite_applies`: the Feldmann law with a force-driven block and no friction
  moment. The modal force is held as the cubic through its values and rates at both ends, the
  block follows the Hermite-Obreschkoff rule, and the error is estimated over blocks of up to
  ``PAIR_ROWS`` output intervals: one step over the block against the kept steps of one
  interval each (estimate / (m^4 - 1) for m kept steps);
* the **trapezoidal step** (``_advance``, ``implicit_step``) for every other case, described
  below.

The plate modes couple to the block only through the K contact forces, and each mode is a
linear oscillator. Over a step of length h with the modal force linear in time (first-order
hold), a mode is propagated exactly, whatever omega h is (docs/theory.md; the fixed-step
``exact-modal`` scheme):

    [q, q']_{n+1} = Phi(h) [q, q']_n + G0(h) u_n + G1(h) u_{n+1},   u = phi^T F / M.

The block's vertical and tangential motion use the trapezoidal rule, so the only implicit
problem per step is the K contact forces and the tangential velocity, solved by Newton on a
(K+1)-square system (no matrix of the plate's size is ever formed). The step is second order;
unlike BDF2 it has no error at all in the modes' own dynamics, only in the force history.

What this module adds to the fixed-step scheme, to make it a reference-grade solver:

* **Error control** by step doubling: every step of length h is also taken as two steps of
  h/2; ``(y_h - y_{h/2,h/2}) / 3`` estimates the local error of the two half steps, and the
  state kept is the two half steps with that estimate removed (local extrapolation, third
  order: ``_extrapolate``). The estimate is weighted by IDA's tolerances (``solver.rtol``,
  ``solver.atol``, ``solver.atol_acceleration``:
  ``roughvib.solvers.base.atol_vector``): RMS over the modes as in IDA, max over the
  block, contact and energy states (see ``_err_norm``). Step sizes are
  dyadic fractions of the output step, so the propagators of each size are computed once and
  cached, and every output time is a step boundary (no interpolation of the modes).
* **Events as in IDA**: the regime is fixed within a step (no active set, no max()); the
  margins of :func:`roughvib.model.kernels.events` are checked at every half step, and a
  downward crossing is located by the Illinois method on the margin of a re-taken step of
  variable length from the last state before it (to ``ROOT_TOL``). The regime is then
  switched and the state made consistent by the same code as IDA's restart
  (:class:`roughvib.solvers.events.EventBook`). A one-step method needs no warm-up after a
  restart: an event costs its root search, not a ramp-up of order and step.

Propagators: for omega h > 1 the closed form of the damped oscillator; below, a power series
(20 terms) of the same matrix exponential, because the closed form's ``1 - cos`` terms lose
all digits for omega h -> 0 (both branches are tested against scipy's expm).

Friction: every law of :data:`roughvib.physics.friction.LAWS` (or prescribed motion). The
Feldmann law is a smooth function of the velocity in each branch. A set-valued law
(``coulomb``, ``table``) slides with its kinetic curve and its exact slope in the Newton row
of the velocity; in its stick regime the block is held (v = 0, x fixed, no tangential unknown)
and the friction force is the algebraic ``friction.force`` that holds it. Break-away, velocity
zero and the guards' timers are the roots of :func:`roughvib.model.kernels.events`, switched by
the same :class:`~roughvib.solvers.events.EventBook` as IDA's.

Limits: underdamped modes (plate loss factor < 2).
"""

from __future__ import annotations

import collections
import copy
import math
import os
import time
from pathlib import Path

import numpy as np
from numba import njit

from roughvib.model import kernels as kn
from roughvib.model.krylov import lu_factor, lu_solve
from roughvib.model.system import System
from roughvib.physics.friction import LAWS, feldmann_mu
from roughvib.physics.surface.interp import profile_eval
from roughvib.scene import SceneError, scene_to_toml
from roughvib.solvers import hermite as hm
from roughvib.solvers.base import (
    FIRST_ROW,
    MODE_DQ,
    MODE_Q,
    RawSolution,
    atol_vector,
    check_tolerances,
    output_grid,
    progress_bar,
)
from roughvib.solvers.checkpoint import (
    Checkpoint,
    input_fingerprint,
    start_state,
    write_checkpoint,
)
from roughvib.solvers.events import EventBook, SolverFailure, stall_failure, step_budget

__all__ = ["solve_adaptive_modal", "step_maps"]

NLEV = 40            # dyadic levels below the largest step (h_min = h_max / 2^39)
SLOT_FLY = NLEV      # cache slots for steps that are not dyadic (after an event) ...
SLOT_FLY2 = NLEV + 1  # ... their half step
SLOT_ROOT = NLEV + 2  # ... and the trial steps of the root search
N_SLOTS = NLEV + 3
SERIES_LIMIT = 1.0   # omega h below which the propagators come from the power series
N_SERIES = 22        # terms: 1 / 22! < 1e-21
# the series' divisors as factors (numba keeps module-level arrays as constants): a division
# per term and mode made the propagator computations a twentieth of a solve
_INV_N1 = 1.0 / np.arange(1.0, N_SERIES + 1.0)                          # 1 / (n + 1)
_INV_N12 = 1.0 / (np.arange(1.0, N_SERIES + 1.0) * np.arange(2.0, N_SERIES + 2.0))  # 1/((n+1)(n+2))
ROOT_TOL = 1e-13     # s, width of the bracket that locates an event
#: trials of one root search at most (a search that converges takes a few: 25 were a sign of
#: bisection, see _illinois_trial; 200 bisections halve any step below ROOT_TOL)
ROOT_MAX_TRIALS = 200
NEWTON_TOL = 1e-6    # Newton update, in units of the tolerance weights ...
NEWTON_ULPS = 8.0    # ... or within this many round-offs of its equation's terms
NEWTON_MAX_ITER = 25  # Newton iterations before the step is given up (retried smaller)
EPS = 2.220446049250313e-16  # double-precision unit round-off (numpy.finfo(float).eps)
SAFETY = 0.9  # the step-size controller's safety factor on the optimal step
#: what _err_norm returns for an estimate that is NaN or infinite (and the threshold the loops
#: test it against): the step is rejected as non-finite
ERR_NONFINITE = 1e300

# codes of _advance
ADV_CHUNK = 0
ADV_EVENT = 1
ADV_DONE = 2
ADV_MIN_STEP = -1
ADV_NEWTON = -2
ADV_NONFINITE = -3
ADV_STALL = -4
ADV_GO = 9     # (_loop_guard: attempt a step)

# integer loop state / statistics (int64 array `ist`)
I_K = 0          # next output index
I_LEV = 1        # current dyadic level
I_STEPS = 2      # accepted steps: the trapezoidal loop's (each = two half steps), the
#                  Hermite loop's kept steps (m per accepted block)
I_REJECT = 3     # rejected steps (the Hermite loop: rejected blocks)
I_STEP_EVALS = 4  # implicit steps taken (3 per attempt, plus root-search trials)
I_ROOT_EVALS = 5  # trial steps of the root searches
I_MAPS = 6       # propagator computations
I_NEWTON = 7     # Newton iterations
I_NEWTON_FAIL = 8  # Newton failures (the step was retried smaller)
I_IVL = 9        # step attempts since the last output time (stall guard)
I_EXTRAP = 10    # accepted steps whose end was extrapolated (_extrapolate)
I_JACS = 11      # Newton matrices formed (the Hermite step; the trapezoidal step forms one per
#                  iteration)
I_BLOCKS = 12    # the Hermite loop's accepted blocks (m kept steps against one long step)
N_IST = 13

#: the propagator cache of _advance: ``P`` (N_SLOTS, N_MAP, R) the maps Phi, G0 and G1 of
#: :func:`step_maps` of each slot, one contiguous row per entry (``MAP_*``), so that the step's
#: loops over the modes read them at unit stride; ``G1c`` (N_SLOTS, K, K) G1 in contact
#: coordinates and ``hslot`` (N_SLOTS,) the step of each slot (0: empty); with a friction
#: moment ``Hm`` (N_SLOTS, K, K) the moment's G1 in contact coordinates,
#: ``H_kj = sum_r phi_rk G1_r Psi_rj / M``, and ``hmslot`` (N_SLOTS,) the step it was computed
#: for (both of size 0 along K without the moment); ``Phi`` (R, 2, 2), ``G0``, ``G1`` (R, 2)
#: receive :func:`step_maps` for the slot being filled. numba passes a namedtuple of arrays at
#: the cost of its fields (:func:`new_propagators` makes one)
Propagators = collections.namedtuple("Propagators",
                                     ["Phi", "G0", "G1", "G1c", "hslot", "Hm", "hmslot", "P"])
#: the step loop's buffers: ``Y`` (N_YBUF, n) states, ``D`` (N_DBUF, N_D) derivatives, ``U``
#: (N_DBUF, R) modal forces, ``G`` (N_GBUF, K + N_LAW_ROOTS) margins, ``armed`` / ``fired``
#: (K + N_LAW_ROOTS,) int64
Buffers = collections.namedtuple("Buffers", ["Y", "D", "U", "G", "armed", "fired"])
#: scratch of the kernels and of implicit_step: ``work`` (kernels), ``ws`` (>= 3 R + 6 K + 3),
#: ``jac`` (K + 1, K + 1), ``ipiv`` (K + 1,) int64
Scratch = collections.namedtuple("Scratch", ["work", "ws", "jac", "ipiv"])


def new_propagators(R: int, K: int, moment: bool) -> Propagators:
    """An empty propagator cache for R modes and K contacts (``Hm`` sized for the friction
    moment when ``moment``)."""
    km = K if moment else 0
    return Propagators(np.zeros((R, 2, 2)), np.zeros((R, 2)), np.zeros((R, 2)),
                       np.zeros((N_SLOTS, K, K)), np.zeros(N_SLOTS),
                       np.zeros((N_SLOTS, km, km)), np.zeros(N_SLOTS),
                       np.zeros((N_SLOTS, N_MAP, R)))


def new_scratch(work: np.ndarray, R: int, K: int) -> Scratch:
    """implicit_step's scratch for R modes and K contacts, with the kernels' ``work``."""
    return Scratch(work, np.zeros(3 * R + 6 * K + 3), np.zeros((K + 1, K + 1)),
                   np.zeros(K + 1, dtype=np.int64))

# components of a mode's state [q, q'] in the propagators Phi (R, 2, 2), G0, G1 (R, 2):
# MODE_Q, MODE_DQ (solvers/base.py)
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
# rows of the derivative vector d of derivatives(): z'', x'', then the N_ENERGY powers
D_AZ = 0
D_AX = 1
D_POWER = 2
N_D = D_POWER + 6  # == D_POWER + N_ENERGY (roughvib.model.layout)
# rows of the state buffers Y (B_* all), D and U (the first six) of _advance
B_NOW = 0     # the current state
B_FULL = 1    # one full step
B_HALF = 2    # the first half step
B_END = 3     # the second half step
B_TRIAL = 4   # a root-search trial
B_BEST = 5    # the state at the root
B_WTS = 6     # tolerance weights (Y only)
B_CHAIN = 7   # the Hermite loop's kept steps inside a block after B_HALF (PAIR_ROWS - 2 rows)
N_YBUF = B_CHAIN
N_DBUF = 6
# rows of the margin buffer G: step start, half step, step end, latest trial
G_START = 0
G_HALF = 1
G_END = 2
G_TRIAL = 3
G_LOW = 4     # the Hermite loop: at the last point accepted (a root search's lower bracket)
N_GBUF = 5
T_NOW = 0      # the one entry of the time box ``tt``


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
def _fill_slot(slot, h, omega2, cdamp, phi, cres, M, prop):
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
    the modal force also holds ``mu(v) sum_k Psi_rk F_k / M`` (``_moment_force``), which
    depends on the regime and the velocity; the buffers ``U`` of the step loop carry the
    whole modal force (``_state_modal_force``): every step starts from the whole force.
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
def friction_force(t, y, vx, fsum, off, fp, reg):
    """Friction force on the block [N] and its slopes, for the scene's law and regime.

    The force is the one of :func:`.kernels.residual`: the Feldmann law ``mu(v + s v_h) F_N``
    of the branch and latch; a set-valued law in slip b ``b mu_k(b v) F_N`` (the law's kinetic
    curve, :func:`.kernels.kinetic`), in stick ``T_exc - r2 v``, whatever holds the block
    (:func:`.kernels.coulomb_friction`).

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
            return kn.coulomb_friction(t, y, off, fp, reg), 0.0, 0.0
        muk, dmuk = kn.kinetic(b * vx, off, fp)
        # d/dv of b mu_k(b v): b^2 mu_k' = mu_k'
        return b * muk * fsum, dmuk * fsum, b * muk
    mu, dmu = feldmann_mu(vx + reg[kn.REG_S] * fp[kn.FP_VH], reg[kn.REG_B], fp[kn.FP_MU_SLIP],
                          fp[kn.FP_MU_STICK], fp[kn.FP_A1], fp[kn.FP_A2])
    return mu * fsum, dmu * fsum, mu


@njit(cache=True)
def _holds_stick(off, reg):
    """Whether the block is held in the stick regime of a set-valued law (v = 0, no unknown)."""
    return kn.set_valued(off) and reg[kn.REG_B] == 0


@njit(cache=True)
def _moment_force(F, mu, M, off, fp, u):
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
def _moment_coefficient(t1, v1, S1, off, fp, reg):
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
    mu, dmu = feldmann_mu(v1 + reg[kn.REG_S] * fp[kn.FP_VH], reg[kn.REG_B], fp[kn.FP_MU_SLIP],
                          fp[kn.FP_MU_STICK], fp[kn.FP_A1], fp[kn.FP_A2])
    return mu, dmu, 0.0


@njit(cache=True)
def _moment_map(slot, prop, phiT, off, fp):
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
def _state_modal_force(y, u, phiT, off, fp, reg, scratch):
    """The whole modal force u (R,) of the state y [m/s^2]: the contact forces' part
    (:func:`modal_force`) and, with a friction moment, the moment's (``_moment_force``, with
    the share ``c`` of :func:`.kernels.moment_share`: ``mu(v)`` for the Feldmann law,
    ``lambda / F_N`` for a set-valued law). ``scratch``: length >= R."""
    iF, K, R = off[kn.OFF_IF], off[kn.OFF_K], off[kn.OFF_R]
    M = fp[kn.FP_MMODAL]
    modal_force(y[iF:iF + K], u, phiT, M)
    if off[kn.OFF_IX] >= 0 and kn.moment_on(off):
        c, _, _, _ = kn.moment_share(0.0, y, off, fp, reg)  # t: only prescribed motion reads it
        um = scratch[:R]
        _moment_force(y[iF:iF + K], c, M, off, fp, um)
        for r in range(R):
            u[r] += um[r]


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


@njit(cache=True)
def implicit_step(t0, h, y0, d0, u0, y1, d1, u1, slot, prop, wts, off, fp, cdamp, phi, phiT,
                  stiff, spos, prof, reg, scratch, ist):
    """One step of length h (propagators in ``slot``) from the consistent (y0, d0) to (y1, d1).

    ``u0`` is :func:`modal_force` of y0; ``u1`` receives that of y1.

    Unknowns: the forces of the closed contacts and, for a force-driven block that slides, the
    tangential velocity at t0 + h, with the friction force of :func:`friction_force` (the
    law's kinetic curve and its exact slope). In the stick regime of a set-valued law the
    block stays where it is (v = 0, x fixed: no tangential unknown) and the friction force
    ``friction.force`` is what holds it, ``T_exc - r2 v``. Newton until every update is below
    ``NEWTON_TOL`` tolerance weights ``wts`` or, for tolerances near round-off, below
    ``NEWTON_ULPS`` times the round-off of its equation (unit round-off times the sum of the
    magnitudes of the equation's terms, divided by the diagonal of the Newton matrix): an
    update at that level is noise, which no further iteration removes. Returns False when
    Newton does not converge (the caller takes a smaller step).

    ``prop``: the ``Propagators`` cache; ``scratch``: ``Scratch`` (``ws`` of length
    >= 3 R + 6 K + 3, ``jac`` of shape >= (K + 1, K + 1), ``ipiv`` (int64) of length >= K + 1).
    """
    G1c = prop.G1c
    ws, jac, ipiv = scratch.ws, scratch.jac, scratch.ipiv
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = kn.state_offsets(off)
    m = fp[kn.FP_MASS]
    M = fp[kn.FP_MMODAL]
    r1 = fp[kn.FP_R1]
    r2 = fp[kn.FP_R2]
    t1 = t0 + h
    sq = ws[0:R]
    sdq = ws[R:2 * R]
    wfree = ws[2 * R:2 * R + K]
    F = ws[2 * R + K:2 * R + 2 * K]
    rhs = ws[2 * R + 2 * K:2 * R + 3 * K + 1]
    idx = ws[2 * R + 3 * K + 1:2 * R + 4 * K + 2]
    noise = ws[2 * R + 4 * K + 2:2 * R + 5 * K + 3]  # round-off level of each update
    # friction moment (contact.friction_moment): the modal force holds c Psi^T F / M too
    # (c: _moment_coefficient); u0 is the whole modal force of y0 (_state_modal_force), u1
    # receives that of y1
    moment = ix >= 0 and kn.moment_on(off)
    um = ws[2 * R + 5 * K + 3:3 * R + 5 * K + 3]  # the moment's modal force at t1
    wm = ws[3 * R + 5 * K + 3:3 * R + 6 * K + 3]  # its displacement at the contacts / c
    # free modal response and plate displacement at the contacts (unit-stride loops over the
    # modes: the maps' rows of P, the state's plate.q and plate.dq)
    P = prop.P[slot]
    free_response(P, y0[iq:iq + R], y0[idq:idq + R], u0, phiT, sq, sdq, wfree)
    # the moment's part at t1 moves the contacts by c1 Hm F (_moment_map)
    Hm = prop.Hm[slot]
    if moment:
        _moment_map(slot, prop, phiT, off, fp)
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
    sliding = force_driven and not _holds_stick(off, reg)
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
            mu1, dmu1, dmus = _moment_coefficient(t1, v1, S1, off, fp, reg)
            for k in range(K):
                acc = 0.0
                for j in range(K):
                    acc += Hm[k, j] * F[j]
                wm[k] = acc
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
        if sliding:
            fric, dfric_dv, dfric_dfn = friction_force(t1, y0, v1, S1, off, fp, reg)
            rhs[nc] = -(m * (v1 - v0) / h - 0.5 * m * d0[D_AX]
                        - 0.5 * (texc1 - fric - r2 * v1))
            for c in range(nc):
                jac[nc, c] = 0.5 * dfric_dfn
            jac[nc, nc] = m / h + 0.5 * (dfric_dv + r2)
            noise[nc] = NEWTON_ULPS * EPS * (m * (abs(v1) + abs(v0)) / h + 0.5 * m * abs(d0[D_AX])
                                             + 0.5 * (abs(texc1) + abs(fric) + abs(r2 * v1))
                                             ) / abs(jac[nc, nc])
        if nu == 0:
            ok = True
            break
        piv = ipiv[:nu]
        lu_factor(jac[:nu, :nu], piv)
        lu_solve(jac[:nu, :nu], piv, rhs[:nu])
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
        if not worst <= NEWTON_TOL:
            continue
        ok = True
        break
    if not ok:
        return False
    # assemble the new state
    S1 = 0.0
    for k in range(K):
        S1 += F[k]
        y1[iF + k] = F[k]
    modal_force(F, u1, phiT, M)
    if moment:
        mu1, _, _ = _moment_coefficient(t1, v1, S1, off, fp, reg)
        _moment_force(F, mu1, M, off, fp, um)
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
        y1[off[kn.OFF_IL]] = kn.coulomb_friction(t1, y1, off, fp, reg)
    derivatives(t1, y1, d1, off, fp, cdamp, spos, prof, reg)
    for i in range(kn.N_ENERGY):
        y1[iE + i] = y0[iE + i] + 0.5 * h * (d0[D_POWER + i] + d1[D_POWER + i])
    return True


@njit(cache=True)
def _err_norm(ya, yb, y0, atol, rtol, n_modal, div):
    """Step-doubling estimate (ya - yb) / div in tolerance weights (div = 2^p - 1 for a
    method of order p: 3 for the trapezoidal step, 15 for the Hermite step): RMS over the modes, max
    over everything else.

    The weights are IDA's (``rtol |y| + atol_i``). The first ``n_modal`` states (plate.q,
    plate.dq) are a population of hundreds of similar oscillators: their RMS, as in IDA, is
    the meaningful aggregate. The few block, contact-force and energy states each have a role
    of their own, so each must meet its weight (max norm). Measured against the alternatives
    (docs/theory.md): IDA's RMS over all states let those few carry errors far above their
    weight near impacts (energy audit 7.4e-5 at rtol 1e-6 at 1 m/s sliding; 1.2e-5 with this
    norm); a max over all states resolved the top modes to 100 kHz for their own sake (1.38x
    the steps from 400 to 800 modes; 1.12x with this norm) and needed 1.8x the steps for the
    same plate-acceleration error on the paper scene.
    """
    n = ya.size
    worst = 0.0
    acc = _modal_err_sq(ya, yb, y0, atol, rtol, n_modal, div)
    if not acc < ERR_NONFINITE:  # NaN or inf in a mode: the step is rejected as non-finite
        return ERR_NONFINITE
    for i in range(n_modal, n):
        w = rtol * max(abs(y0[i]), abs(yb[i])) + atol[i]
        e = abs(ya[i] - yb[i]) / (div * w)
        if not e < ERR_NONFINITE:  # NaN or inf anywhere: the step is rejected as non-finite
            return ERR_NONFINITE
        if e > worst:
            worst = e
    if n_modal > 0:
        rms = math.sqrt(acc / n_modal)
        if rms > worst:
            worst = rms
    return worst


@njit(cache=True, fastmath=kn.SUM_FASTMATH, error_model="numpy")
def _modal_err_sq(ya, yb, y0, atol, rtol, n_modal, div):
    """sum over the first n_modal states of ((ya - yb) / (div w))^2, w = rtol max(|y0|, |yb|)
    + atol, summed in whatever order vectorises; NaN or inf in any term makes it so.

    Written so that the loop vectorises: the larger magnitude by a conditional expression
    (the builtin ``max`` compiled to a call per term here, which LLVM did not inline into a
    function with other fast-math flags) and IEEE division (``error_model="numpy"``: no test
    for a zero weight per term; a zero weight gives inf or NaN, which the caller rejects)."""
    acc = 0.0
    for i in range(n_modal):
        a = abs(y0[i])
        b = abs(yb[i])
        w = rtol * (a if a > b else b) + atol[i]
        e = (ya[i] - yb[i]) / (div * w)
        acc += e * e
    return acc


@njit(cache=True)
def _extrapolate(t1, ya, yb, ye, ge, armed, off, fp, phi, cres, spos, prof, reg, rf, work):
    """Replace the accepted step's end ``yb`` (two half steps) by its Richardson
    extrapolation ``yb + (yb - ya) / 3`` (``ya``: one full step), unless that would cross an
    armed event margin. Returns whether it did.

    The scheme is second order, so the two half steps err by about a third of their
    difference from the full step, and removing that leaves a third-order local error
    (local extrapolation; the error test still judges the two half steps, so it
    overestimates the error of what is kept). Every state but the energy integrals (which
    Simpson's rule already gave to fourth order) is extrapolated; the set-valued law's
    friction force, an algebraic state, is recomputed from the new state. The margins at
    the extrapolated state go to ``ge``; if an armed one is not positive there, ``yb`` is
    kept as it is: the event search works on the steps it can re-take, and a crossing only
    the extrapolation makes is left to the next step's test. ``ye``: scratch of the state's
    size.
    """
    iE = off[kn.OFF_IE]
    for j in range(iE, iE + kn.N_ENERGY):
        ye[j] = yb[j]
    for j in range(iE):
        ye[j] = yb[j] + (yb[j] - ya[j]) / 3.0
    for j in range(iE + kn.N_ENERGY, yb.size):
        ye[j] = yb[j] + (yb[j] - ya[j]) / 3.0
    if kn.set_valued(off) and off[kn.OFF_IX] >= 0:
        ye[off[kn.OFF_IL]] = kn.coulomb_friction(t1, ye, off, fp, reg)
    kn.events(t1, ye, ge, off, fp, phi, cres, spos, prof, reg, rf, work)
    for i in range(ge.size):
        if armed[i] == 1 and not ge[i] > 0.0:
            return False
    for j in range(yb.size):
        yb[j] = ye[j]
    return True


@njit(cache=True)
def _illinois_trial(lo, hi, glo, ghi, L):
    """The next trial fraction of a root search on [lo, hi] (fractions of a step of length L
    [s]) with margins glo > 0 >= ghi: the secant point (the margins Illinois-scaled by the
    caller), kept at least half ``ROOT_TOL`` inside the bracket; the midpoint if the secant
    point is not inside.

    Near convergence the secant point lies next to the end that moves; a trial just past it
    (by half the tolerance) collapses the bracket. Bisecting whenever the secant point lay
    within a thousandth of the bracket of an end had made the searches bisections: 25 trials
    per event on the paper scene."""
    th = (lo * ghi - hi * glo) / (ghi - glo)
    if not lo < th < hi:
        return 0.5 * (lo + hi)
    gap = 0.5 * ROOT_TOL / L
    if th - lo < gap:
        th = lo + gap
    elif hi - th < gap:
        th = hi - gap
    return th


@njit(cache=True, inline="always")
def _illinois_update(lo, hi, glo, ghi, side, th, g):
    """The bracket ``(lo, hi, glo, ghi, side)`` of a root search after the trial fraction th
    with margin g: th replaces the end of g's sign; the Illinois rule halves the margin of
    the end that stays a second time in a row (``side``: +1 after a trial that moved ``lo``,
    -1 after one that moved ``hi``, 0 before the first). Both step loops' searches use it."""
    if g > 0.0:
        if side == 1:
            ghi *= 0.5
        return th, hi, g, ghi, 1
    if side == -1:
        glo *= 0.5
    return lo, th, glo, g, -1


@njit(cache=True)
def _is_multiple(rel, h):
    """Whether ``rel`` is (to 1e-7 of h) a whole multiple of h."""
    f = rel / h
    return abs(f - round(f)) <= 1e-7


@njit(cache=True)
def _latch_and_output(t, y, outs, k, args_off, fp, omega2, cdamp, phi, phi_obs, stiff, cres,
                      spos, prof, reg, rf, work, track_latch):
    """Output row k and the latch's running extremum, as solve_ida does at grid points."""
    kn.outputs(t, y, outs[k], args_off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos,
               prof, reg, rf, work)
    if track_latch:
        v = y[args_off[kn.OFF_IVX]]
        if reg[kn.REG_S] < 0:
            if v > rf[kn.RF_VEXT]:
                rf[kn.RF_VEXT] = v
        elif v < rf[kn.RF_VEXT]:
            rf[kn.RF_VEXT] = v


@njit(cache=True)
def _enter(t, y, g0, armed, fresh, grid, outs, ist, off, fp, omega2, cdamp, phi, phi_obs, stiff,
           cres, spos, prof, reg, rf, work, track_latch):
    """A step loop's entry: the outputs at grid points the state at t landed on (after an
    event's switch, as IDA does) and, for a state set from outside (``fresh``), its margins
    in g0 and the roots armed. Returns whether the grid is done."""
    n = grid.size
    k = ist[I_K]
    while k < n and grid[k] - t <= 1e-12 * max(1.0, t):
        _latch_and_output(grid[k], y, outs, k, off, fp, omega2, cdamp, phi, phi_obs, stiff,
                          cres, spos, prof, reg, rf, work, track_latch)
        k += 1
        ist[I_IVL] = 0
    ist[I_K] = k
    if k >= n:
        return True
    if fresh:
        kn.events(t, y, g0, off, fp, phi, cres, spos, prof, reg, rf, work)
        for i in range(g0.size):
            armed[i] = 1 if g0[i] > 0.0 else 0
    return False


@njit(cache=True)
def _loop_guard(tt, t, ist, k_stop, n, max_steps):
    """A step loop's checks before an attempt: the return code (``ADV_DONE``, ``ADV_CHUNK``,
    ``ADV_MIN_STEP``, ``ADV_STALL``) or ``ADV_GO`` to attempt a step (the attempt counted
    against the stall budget)."""
    k = ist[I_K]
    if k >= n:
        return ADV_DONE
    if k >= k_stop:
        return ADV_CHUNK
    if ist[I_LEV] >= NLEV - 1:
        tt[T_NOW] = t
        return ADV_MIN_STEP
    ist[I_IVL] += 1
    if ist[I_IVL] > max_steps:
        tt[T_NOW] = t
        return ADV_STALL
    return ADV_GO


@njit(cache=True)
def _interval_target(rel, hl, span):
    """The end of a step of about hl [s] from ``rel`` into an output interval of length
    ``span``, on the multiples of hl and never less than a hundredth of hl short of one:
    ``(target, last)``, ``last`` when it is the interval's end."""
    nxt = math.floor(rel / hl + 1e-7) + 1.0
    target = nxt * hl
    if target - rel < 0.01 * hl:
        target += hl
    last = target >= span * (1.0 - 1e-9)
    if last:
        target = span
    return target, last


@njit(cache=True)
def _advance(tt, ist, k_stop, grid, h_max, buf, prop, atol, rtol, outs, off, fp, omega2, cdamp,
             phi, phiT, phi_obs, stiff, cres, spos, prof, reg, rf, scratch, track_latch, fresh,
             max_steps):
    """:func:`_trapezoidal_loop` on views of its arrays without memory records
    (:func:`roughvib.model.kernels.unowned`: no reference counting in the loop); the same
    arguments, results and return codes. Called from Python, which holds the arrays."""
    u = kn.unowned
    return _trapezoidal_loop(
        u(tt), u(ist), k_stop, u(grid), h_max,
        Buffers(u(buf.Y), u(buf.D), u(buf.U), u(buf.G), u(buf.armed), u(buf.fired)),
        Propagators(u(prop.Phi), u(prop.G0), u(prop.G1), u(prop.G1c), u(prop.hslot),
                    u(prop.Hm), u(prop.hmslot), u(prop.P)),
        u(atol), rtol, u(outs), u(off), u(fp), u(omega2), u(cdamp), u(phi), u(phiT),
        u(phi_obs), u(stiff), u(cres), u(spos), u(prof), u(reg), u(rf),
        Scratch(u(scratch.work), u(scratch.ws), u(scratch.jac), u(scratch.ipiv)),
        track_latch, fresh, max_steps)


@njit(cache=True)
def _trapezoidal_loop(tt, ist, k_stop, grid, h_max, buf, prop, atol, rtol, outs, off, fp,
                      omega2, cdamp, phi, phiT, phi_obs, stiff, cres, spos, prof, reg, rf,
                      scratch, track_latch, fresh, max_steps):
    """Integrate from ``tt[T_NOW]`` until output index ``k_stop``, the end, or an event.

    Returns ``ADV_CHUNK`` (k reached k_stop), ``ADV_DONE``, ``ADV_EVENT`` (``y``, ``tt[T_NOW]``
    are the state and time just past the root, ``fired[i] = 1`` for the roots that crossed)
    or a negative failure code: ``ADV_STALL`` after more than ``max_steps`` step attempts
    within one output interval. The state ``y`` must be consistent with the regime on entry.

    ``fresh``: the state was set from outside (start, event switch); its derivatives, modal
    force, margins and armed roots are computed on entry. Otherwise (the previous call
    returned ``ADV_CHUNK``) the loop continues with those of the previous call, exactly as
    if it had not returned: chunk returns, and the checkpoints written at them, leave the
    result bit-identical.

    Buffers (``buf``, ``Buffers``; rows are views): ``Y`` (7, n) states y, ya (one full
    step), ym, yb (the two half steps), yt (root-search trial), ybest (state at the root), wts
    (tolerance weights); ``D`` (6, 8) and ``U`` (6, R) the derivatives (:func:`derivatives`)
    and modal forces (:func:`modal_force`) of the first six; ``G`` (4, K + N_LAW_ROOTS) the
    margins at the step start, half step, end, and of the latest trial; ``armed``, ``fired``
    the roots.
    ``prop``: the ``Propagators`` cache; ``scratch``: ``Scratch``.
    """
    Y, D, U, G, armed, fired = buf
    hslot = prop.hslot
    work = scratch.work
    y, ya, ym, yb, yt, ybest, wts = (Y[B_NOW], Y[B_FULL], Y[B_HALF], Y[B_END], Y[B_TRIAL],
                                     Y[B_BEST], Y[B_WTS])
    d, da, dm, db, dt_, dbest = D[B_NOW], D[B_FULL], D[B_HALF], D[B_END], D[B_TRIAL], D[B_BEST]
    u, ua, um, ub, ut, ubest = U[B_NOW], U[B_FULL], U[B_HALF], U[B_END], U[B_TRIAL], U[B_BEST]
    g0, gm, gb, gt = G[G_START], G[G_HALF], G[G_END], G[G_TRIAL]
    n = grid.size
    M = fp[kn.FP_MMODAL]
    n_ev = g0.size
    t = tt[T_NOW]
    if fresh:
        derivatives(t, y, d, off, fp, cdamp, spos, prof, reg)
        _state_modal_force(y, u, phiT, off, fp, reg, ut)
    if _enter(t, y, g0, armed, fresh, grid, outs, ist, off, fp, omega2, cdamp, phi, phi_obs,
              stiff, cres, spos, prof, reg, rf, work, track_latch):
        return ADV_DONE
    nstate = y.size
    # the cache slots as run-time ints: a literal compiles each callee once more per value
    slot_fly, slot_fly2 = kn.runtime_int(SLOT_FLY), kn.runtime_int(SLOT_FLY2)
    slot_root = kn.runtime_int(SLOT_ROOT)
    while True:
        code = _loop_guard(tt, t, ist, k_stop, n, max_steps)
        if code != ADV_GO:
            return code
        k = ist[I_K]
        lev = ist[I_LEV]
        hl = h_max / 2.0 ** lev
        base = grid[k - 1]
        rel = t - base
        span = grid[k] - base
        target, last = _interval_target(rel, hl, span)
        h = target - rel
        if abs(h - hl) <= 1e-7 * hl:
            s_full = lev
            s_half = lev + 1
            if hslot[s_full] <= 0.0:
                _fill_slot(s_full, hl, omega2, cdamp, phi, cres, M, prop)
                ist[I_MAPS] += 1
            if hslot[s_half] <= 0.0:
                _fill_slot(s_half, 0.5 * hl, omega2, cdamp, phi, cres, M, prop)
                ist[I_MAPS] += 1
            h = hslot[s_full]
        else:
            s_full = slot_fly
            s_half = slot_fly2
            _fill_slot(s_full, h, omega2, cdamp, phi, cres, M, prop)
            _fill_slot(s_half, 0.5 * h, omega2, cdamp, phi, cres, M, prop)
            ist[I_MAPS] += 2
        hh = 0.5 * h
        for i in range(nstate):
            wts[i] = rtol * abs(y[i]) + atol[i]
        # the full step (for the error estimate) and the two half steps (kept)
        model = (prop, wts, off, fp, cdamp, phi, phiT, stiff, spos, prof, reg, scratch, ist)
        ok = implicit_step(t, h, y, d, u, ya, da, ua, s_full, *model)
        ok = ok and implicit_step(t, hh, y, d, u, ym, dm, um, s_half, *model)
        ok = ok and implicit_step(t + hh, h - hh, ym, dm, um, yb, db, ub, s_half, *model)
        ist[I_STEP_EVALS] += 3
        if not ok:
            ist[I_NEWTON_FAIL] += 1
            ist[I_REJECT] += 1
            ist[I_LEV] = lev + 1
            continue
        # plate.q and plate.dq come first in the layout (StateLayout): 2 R modal states
        err = _err_norm(ya, yb, y, atol, rtol, 2 * off[kn.OFF_R], 3.0)
        if err > 1.0:
            ist[I_REJECT] += 1
            fac = SAFETY * err ** (-1.0 / 3.0)
            drop = int(math.ceil(-math.log2(fac))) if fac < 1.0 else 1
            ist[I_LEV] = lev + max(1, drop)
            if err >= ERR_NONFINITE:
                tt[T_NOW] = t
                return ADV_NONFINITE
            continue
        ist[I_STEPS] += 1
        t_new = base + target if not last else grid[k]
        # events: margins at the half step and at the end
        t_mid = t + hh
        kn.events(t_mid, ym, gm, off, fp, phi, cres, spos, prof, reg, rf, work)
        kn.events(t_new, yb, gb, off, fp, phi, cres, spos, prof, reg, rf, work)
        first_half = False
        any_cross = False
        for i in range(n_ev):
            fired[i] = 0
            if armed[i] == 1 and (gm[i] <= 0.0 or gb[i] <= 0.0):
                any_cross = True
                if gm[i] <= 0.0:
                    first_half = True
        if any_cross:
            # the half step holding the earliest crossings, re-taken with variable length
            if first_half:
                tb = t
                yb0, db0, ub0, gb0, ge = y, d, u, g0, gm
            else:
                tb = t_mid
                yb0, db0, ub0, gb0, ge = ym, dm, um, gm, gb
            L = hh if first_half else h - hh
            for i in range(nstate):
                wts[i] = rtol * abs(yb0[i]) + atol[i]
            theta_best = 1.0
            have_best = False
            for i in range(n_ev):
                if armed[i] == 0 or ge[i] > 0.0:
                    continue
                if not (gb0[i] > 0.0):
                    continue
                # is root i before the best so far?
                if have_best:
                    if gt[i] > 0.0:  # still open at the earliest root so far: later
                        continue
                    hi = theta_best
                    ghi = gt[i]
                else:
                    hi = 1.0
                    ghi = ge[i]
                lo = 0.0
                glo = gb0[i]
                side = 0
                for _it in range(ROOT_MAX_TRIALS):
                    if (hi - lo) * L <= ROOT_TOL:
                        break
                    th = _illinois_trial(lo, hi, glo, ghi, L)
                    hs = th * L
                    _fill_slot(slot_root, hs, omega2, cdamp, phi, cres, M, prop)
                    ist[I_MAPS] += 1
                    ist[I_ROOT_EVALS] += 1
                    ist[I_STEP_EVALS] += 1
                    if not implicit_step(tb, hs, yb0, db0, ub0, yt, dt_, ut, slot_root, *model):
                        tt[T_NOW] = tb
                        return ADV_NEWTON
                    kn.events(tb + hs, yt, gt, off, fp, phi, cres, spos, prof, reg, rf, work)
                    lo, hi, glo, ghi, side = _illinois_update(lo, hi, glo, ghi, side, th, gt[i])
                # the state at hi (re-taken so that every margin is evaluated there)
                hs = hi * L
                if hi == 1.0:  # the half step's own end (derivatives are recomputed on entry)
                    src = ym if first_half else yb
                    for j in range(nstate):
                        ybest[j] = src[j]
                else:
                    _fill_slot(slot_root, hs, omega2, cdamp, phi, cres, M, prop)
                    ist[I_MAPS] += 1
                    ist[I_STEP_EVALS] += 1
                    if not implicit_step(tb, hs, yb0, db0, ub0, ybest, dbest, ubest, slot_root,
                                         *model):
                        tt[T_NOW] = tb
                        return ADV_NEWTON
                theta_best = hi
                have_best = True
                kn.events(tb + theta_best * L, ybest, gt, off, fp, phi, cres, spos, prof, reg,
                          rf, work)
            te = tb + theta_best * L
            if theta_best == 1.0 and not first_half:
                te = t_new
            for i in range(n_ev):
                if armed[i] == 1 and gt[i] <= 0.0:
                    fired[i] = 1
            for j in range(nstate):
                y[j] = ybest[j]
            tt[T_NOW] = te
            # an event exactly on the output time: the row is written after the switch
            return ADV_EVENT
        # accept. The energy integrals by Simpson's rule over the two half steps (the midpoint
        # state is at hand): the half steps' trapezoidal sums are second order in h, and on a
        # quiet run the steps are capped by the output grid, so that quadrature error did not
        # shrink with the tolerance (energy audit 1.1e-8 at any rtol on paper without
        # roughness); Simpson's is fourth order (docs/robustness.md, energy audit)
        iE = off[kn.OFF_IE]
        for i in range(kn.N_ENERGY):
            yb[iE + i] = y[iE + i] + h / 6.0 * (d[D_POWER + i] + 4.0 * dm[D_POWER + i]
                                                 + db[D_POWER + i])
        # local extrapolation: the step's end from the two results, third order. The
        # derivatives and modal forces of the kept state by the same combination: exact where
        # they are linear in the state (the modal force of the contact forces, the vertical
        # acceleration), to the square of the correction elsewhere (the friction law, the
        # powers); computing them anew cost 8-10 % of the solve for the same result
        if _extrapolate(t_new, ya, yb, yt, gt, armed, off, fp, phi, cres, spos, prof,
                        reg, rf, work):
            for i in range(n_ev):
                gb[i] = gt[i]
            for j in range(db.size):
                db[j] += (db[j] - da[j]) / 3.0
            for j in range(ub.size):
                ub[j] += (ub[j] - ua[j]) / 3.0
            ist[I_EXTRAP] += 1
        for j in range(nstate):
            y[j] = yb[j]
        for j in range(d.size):
            d[j] = db[j]
        for j in range(u.size):
            u[j] = ub[j]
        for i in range(n_ev):
            g0[i] = gb[i]
            if gb[i] > 0.0:
                armed[i] = 1
        t = t_new
        tt[T_NOW] = t
        if last:
            _latch_and_output(t, y, outs, k, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres,
                              spos, prof, reg, rf, work, track_latch)
            ist[I_K] = k + 1
            ist[I_IVL] = 0
            if track_latch and not kn.set_valued(off):
                # the Feldmann latch's margin depends on the extremum just updated (the
                # other margins, those of a set-valued law included, do not: g0 holds them)
                il = off[kn.OFF_K] + kn.ROOT_LATCH
                g0[il] = kn.latch_margin(y, off, fp, reg, rf)
                if g0[il] > 0.0:
                    armed[il] = 1
        # step size: up one level when the error is small and the time is on that level
        if err * 8.0 <= SAFETY ** 3 and ist[I_LEV] > 0:
            up = h_max / 2.0 ** (ist[I_LEV] - 1)
            if _is_multiple(t - grid[ist[I_K] - 1], up) or last:
                ist[I_LEV] -= 1


# --- the Hermite step's loop (Feldmann law, force-driven block, no friction moment) ---------

#: the Hermite loop's step maps: ``Pm`` and ``Cc`` (N_SLOTS, ...) of
#: :func:`roughvib.solvers.hermite.hermite_slot` per cache slot, ``hslot`` (N_SLOTS,) the
#: step of each slot (0: empty). Slot s holds the step ``h_top / 2^s``: slot 0 is the top
#: level's full step (``PAIR_ROWS`` output intervals)
HermiteMaps = collections.namedtuple("HermiteMaps", ["Pm", "Cc", "hslot"])
#: the Hermite loop's buffers: ``Y`` (N_YBUF, n) states as in ``Buffers`` (and the kept
#: steps inside a block from ``B_CHAIN``), ``DF`` (N_YBUF, K) their contact force rates [N/s]
#: and ``C`` (N_YBUF, n_carry) their carried data (:func:`roughvib.solvers.hermite.carried`),
#: ``G``, ``armed``, ``fired``
HermiteBuffers = collections.namedtuple("HermiteBuffers", ["Y", "DF", "C", "G", "armed", "fired"])
#: the Hermite step's scratch: ``ws`` float, ``iws`` int64 (the Newton matrix it keeps between
#: steps lives there), ``hjac`` the step that matrix was formed for, one row each
#: (``N_NEWTON``) for the kept steps (and root trials) and for the full step of a block, so
#: that each keeps its own matrix; ``jac`` (K, K),
#: ``ipiv`` (K,) and ``rhs`` (2 K,) for :func:`force_rates`
HermiteScratch = collections.namedtuple("HermiteScratch",
                                        ["ws", "iws", "hjac", "jac", "ipiv", "rhs", "work"])
#: order of the Hermite step: the step-doubling estimate is (ya - yb) / (2^4 - 1)
HERMITE_ORDER = 4
HERMITE_FIRST_LEVEL = 10  # the first full step: h_top / 2^10 (4e-5 s / 1024 at 1e-5 s output)
TRAPEZOIDAL_FIRST_LEVEL = 8  # the trapezoidal loop's first step: h_max / 2^8
NEWTON_KEPT = 0  # the scratch row (Newton matrix) of the kept steps and root trials ...
NEWTON_FULL = 1  # ... and of the full step of a block
N_NEWTON = 2
PAIR_ROWS = 8  # output intervals of the top level's block (one kept step each)


def hermite_top_pair(output_step: float, max_step: float) -> float:
    """The Hermite loop's top-level full step [s]: ``PAIR_ROWS`` output steps (a block of
    that many kept steps of one output step) or, when ``max_step`` (0: no limit) is shorter
    than the output step, two of the largest kept step within it (a pair inside an output
    interval)."""
    kept = output_step
    if max_step > 0:
        while kept > max_step * (1 + 1e-12):
            kept *= 0.5
    return PAIR_ROWS * kept if kept == output_step else 2.0 * kept


def hermite_applies(system: System) -> bool:
    """Whether the Hermite step covers the scene: the Feldmann law (not set-valued), a
    force-driven block, no friction moment."""
    off = system.off
    return bool(off[kn.OFF_IX] >= 0 and not kn.set_valued(off) and not kn.moment_on(off))


def new_hermite_maps(R: int, K: int) -> HermiteMaps:
    """An empty Hermite map cache for R modes and K contacts."""
    pm_shape, cc_shape = hm.slot_shapes(R, K)
    return HermiteMaps(np.zeros((N_SLOTS, *pm_shape)), np.zeros((N_SLOTS, *cc_shape)),
                       np.zeros(N_SLOTS))


def new_hermite_scratch(work: np.ndarray, R: int, K: int) -> HermiteScratch:
    """The Hermite step's scratch for R modes and K contacts, with the kernels' ``work``."""
    n_ws, n_iws = hm.scratch_sizes(R, K)
    return HermiteScratch(np.zeros((N_NEWTON, n_ws)), np.zeros((N_NEWTON, n_iws), dtype=np.int64),
                          np.zeros(N_NEWTON),
                          np.zeros((max(K, 1), max(K, 1))), np.zeros(max(K, 1), dtype=np.int64),
                          np.zeros(2 * max(K, 1)), work)


@njit(cache=True)
def force_rates(y, dF, off, fp, phiT, stiff, cres, spos, prof, reg, hs):
    """The contact force rates dF (K,) [N/s] of a consistent state: the contact relation's
    rate on the closed contacts, ``(1/k_c + C) dF = vz - phi^T q' + h'(s + x) vx`` (C the
    residual compliance), 0 on the open ones. ``hs``: ``HermiteScratch``."""
    _iq, idq, _iz, ivz, ix, ivx, _iF, _iE, R, K = kn.state_offsets(off)
    jac, piv, rhs = hs.jac, hs.ipiv, hs.rhs
    idx = rhs[K:2 * K]
    x = y[ix]
    v = y[ivx]
    nc = 0
    for k in range(K):
        dF[k] = 0.0
        if reg[kn.REG_CLOSED + k] == 1:
            idx[nc] = k
            nc += 1
    if nc == 0:
        return
    for a in range(nc):
        k = int(idx[a])
        _, dh, _ = profile_eval(prof, fp[kn.FP_S0], fp[kn.FP_DX], spos[k] + x)
        rhs[a] = y[ivz] - kn.vdot(phiT[k], y[idq:idq + R]) + dh * v
        for c in range(nc):
            jac[a, c] = cres[k, int(idx[c])]
        jac[a, a] += 1.0 / stiff[k]
    lu_factor(jac[:nc, :nc], piv[:nc])
    lu_solve(jac[:nc, :nc], piv[:nc], rhs[:nc])
    for a in range(nc):
        dF[int(idx[a])] = rhs[a]


@njit(cache=True)
def _hermite_fill(slot, h, omega2, cdamp, phi, cres, M, hp, ist):
    """The Hermite maps of step h into cache slot ``slot`` of ``hp``."""
    hm.hermite_slot(h, omega2, cdamp, phi, cres, M, hp.Pm[slot], hp.Cc[slot])
    hp.hslot[slot] = h
    ist[I_MAPS] += 1


@njit(cache=True)
def _hstep(t0, h, y0, dF0, c0, y1, dF1, c1, slot, hp, wts, off, fp, omega2, cdamp, phiT, stiff,
           spos, prof, reg, hs, ist, mat):
    """:func:`roughvib.solvers.hermite.hermite_step` with the maps of ``slot`` and the scratch
    row ``mat`` of ``hs``; the Newton matrix kept there is formed anew when the step length
    changes. ``mat`` is always passed (a default would compile a second specialisation, each
    with its own inlined copy of the step)."""
    if hs.hjac[mat] != h:
        hs.iws[mat, hm.IWS_JAC_VALID] = 0
        hs.hjac[mat] = h
    ist[I_STEP_EVALS] += 1
    ok = hm.hermite_step(t0, h, y0, dF0, c0, y1, dF1, c1, hp.Pm[slot], hp.Cc[slot], off, fp,
                         omega2, cdamp, phiT, stiff, spos, prof, reg, wts, hs.ws[mat],
                         hs.iws[mat])
    ist[I_NEWTON] += hs.iws[mat, hm.IWS_ITERS]
    ist[I_JACS] += hs.iws[mat, hm.IWS_JACS]
    return ok


@njit(cache=True)
def _crossed(armed, g):
    """Whether an armed margin is not positive in g."""
    for i in range(g.size):
        if armed[i] == 1 and not g[i] > 0.0:
            return True
    return False


@njit(cache=True)
def _hermite_root(tb, L, th_lo, th_hi, t_end, yb0, fb0, cb0, glo_at, ghi_at, ye, buf, hp, tt,
                  ist, atol, rtol, off, fp, omega2, cdamp, phi, phiT, stiff, cres, spos, prof,
                  reg, rf, hs):
    """Locate the earliest crossing of an armed margin between the fractions ``th_lo`` and
    ``th_hi`` of the step of length L [s] from (tb, yb0): ``glo_at`` are the margins at
    ``th_lo`` (all armed ones positive), ``ghi_at`` those at ``th_hi`` (the state ``ye``, at
    ``t_end``). The Illinois method on the margin of Hermite steps re-taken from the step's
    start, to ``ROOT_TOL``. Leaves the state at the root in ``buf.Y[B_NOW]`` and its time in
    ``tt``, marks the roots that crossed in ``buf.fired``; returns ``ADV_EVENT`` (or
    ``ADV_NEWTON``)."""
    Y, DF, C, G, armed, fired = buf
    y, yt, ybest, wts = Y[B_NOW], Y[B_TRIAL], Y[B_BEST], Y[B_WTS]
    ft, fbest = DF[B_TRIAL], DF[B_BEST]
    ct, cbest = C[B_TRIAL], C[B_BEST]
    gt = G[G_TRIAL]
    M = fp[kn.FP_MMODAL]
    work = hs.work
    nstate = y.size
    # run-time ints: a literal compiles _hstep (the whole step inlined) once more per value
    slot_root, kept = kn.runtime_int(SLOT_ROOT), kn.runtime_int(NEWTON_KEPT)
    for i in range(nstate):
        wts[i] = rtol * abs(yb0[i]) + atol[i]
    theta_best = th_hi
    have_best = False
    for i in range(ghi_at.size):
        if armed[i] == 0 or ghi_at[i] > 0.0 or not glo_at[i] > 0.0:
            continue
        if have_best:
            if gt[i] > 0.0:  # still open at the earliest root so far: later
                continue
            hi = theta_best
            ghi = gt[i]
        else:
            hi = th_hi
            ghi = ghi_at[i]
        lo = th_lo
        glo = glo_at[i]
        side = 0
        for _it in range(ROOT_MAX_TRIALS):
            if (hi - lo) * L <= ROOT_TOL:
                break
            th = _illinois_trial(lo, hi, glo, ghi, L)
            hs_ = th * L
            _hermite_fill(slot_root, hs_, omega2, cdamp, phi, cres, M, hp, ist)
            ist[I_ROOT_EVALS] += 1
            if not _hstep(tb, hs_, yb0, fb0, cb0, yt, ft, ct, slot_root, hp, wts, off, fp,
                          omega2, cdamp, phiT, stiff, spos, prof, reg, hs, ist, kept):
                tt[T_NOW] = tb
                return ADV_NEWTON
            kn.events(tb + hs_, yt, gt, off, fp, phi, cres, spos, prof, reg, rf, work)
            lo, hi, glo, ghi, side = _illinois_update(lo, hi, glo, ghi, side, th, gt[i])
        if hi == th_hi:
            for j in range(nstate):
                ybest[j] = ye[j]
        else:
            hs_ = hi * L
            _hermite_fill(slot_root, hs_, omega2, cdamp, phi, cres, M, hp, ist)
            if not _hstep(tb, hs_, yb0, fb0, cb0, ybest, fbest, cbest, slot_root, hp, wts, off,
                          fp, omega2, cdamp, phiT, stiff, spos, prof, reg, hs, ist, kept):
                tt[T_NOW] = tb
                return ADV_NEWTON
        theta_best = hi
        have_best = True
        kn.events(tb + theta_best * L, ybest, gt, off, fp, phi, cres, spos, prof, reg, rf, work)
    for i in range(ghi_at.size):
        fired[i] = 1 if armed[i] == 1 and gt[i] <= 0.0 else 0
    for j in range(nstate):
        y[j] = ybest[j]
    tt[T_NOW] = t_end if theta_best == th_hi else tb + theta_best * L
    return ADV_EVENT


@njit(cache=True)
def _accept_point(t, y, g, armed, outs, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres,
                  spos, prof, reg, rf, work, track_latch, ist, output):
    """Arm the margins g (of the state y at time t) that are positive and, at an output time
    (``output``), write the next output row and update the latch and its margin in g."""
    for i in range(g.size):
        if g[i] > 0.0:
            armed[i] = 1
    if not output:
        return
    k = ist[I_K]
    _latch_and_output(t, y, outs, k, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos,
                      prof, reg, rf, work, track_latch)
    ist[I_K] = k + 1
    ist[I_IVL] = 0
    if track_latch:
        # the Feldmann latch's margin depends on the extremum just updated
        il = off[kn.OFF_K] + kn.ROOT_LATCH
        g[il] = kn.latch_margin(y, off, fp, reg, rf)
        if g[il] > 0.0:
            armed[il] = 1


@njit(cache=True, inline="always")
def _chain_row(j, m):
    """The buffer row of the end of kept step j (of m) of a block: the last is ``B_END``."""
    if j == m - 1:
        return B_END
    if j == 0:
        return B_HALF
    return B_CHAIN + j - 1


@njit(cache=True)
def _advance_hermite(tt, ist, k_stop, grid, h_top, buf, hp, atol, rtol, outs, off, fp, omega2,
                     cdamp, phi, phiT, phi_obs, stiff, cres, spos, prof, reg, rf, hs,
                     track_latch, fresh, max_steps):
    """:func:`_hermite_loop` on views of its arrays without memory records
    (:func:`roughvib.model.kernels.unowned`: no reference counting in the loop); the same
    arguments, results and return codes. Called from Python, which holds the arrays."""
    u = kn.unowned
    return _hermite_loop(
        u(tt), u(ist), k_stop, u(grid), h_top,
        HermiteBuffers(u(buf.Y), u(buf.DF), u(buf.C), u(buf.G), u(buf.armed), u(buf.fired)),
        HermiteMaps(u(hp.Pm), u(hp.Cc), u(hp.hslot)),
        u(atol), rtol, u(outs), u(off), u(fp), u(omega2), u(cdamp), u(phi), u(phiT),
        u(phi_obs), u(stiff), u(cres), u(spos), u(prof), u(reg), u(rf),
        HermiteScratch(u(hs.ws), u(hs.iws), u(hs.hjac), u(hs.jac), u(hs.ipiv), u(hs.rhs),
                       u(hs.work)),
        track_latch, fresh, max_steps)


@njit(cache=True)
def _hermite_loop(tt, ist, k_stop, grid, h_top, buf, hp, atol, rtol, outs, off, fp, omega2,
                  cdamp, phi, phiT, phi_obs, stiff, cres, spos, prof, reg, rf, hs,
                  track_latch, fresh, max_steps):
    """``_advance`` with the Hermite step (:mod:`roughvib.solvers.hermite`): the same
    arguments and return codes, with ``h_top`` the top level's full step
    (:func:`hermite_top_pair`) instead of the largest step, ``buf`` a ``HermiteBuffers``,
    ``hp`` a ``HermiteMaps`` and ``hs`` a ``HermiteScratch``.

    Step doubling generalised to a block: m kept Hermite steps of length hk against one step
    of m hk over the same span; the kept ones are kept as they are (fourth order: m local
    errors e against the full step's m^5 e, so the estimate of the kept steps' error is the
    difference / (m^4 - 1)). At the top level a block spans ``PAIR_ROWS`` output intervals,
    one kept step each, and starts on a row divisible by that number; each level down a block
    spans half as many (four, then two); below, a pair (m = 2) lies within one output
    interval, aligned to dyadic fractions of it as in ``_advance``. Every output time is a
    kept step's end. The margins are checked at each kept step's end in turn, each end
    accepted (armed, written, latch updated) before the next is looked at, and a crossing is
    located by Hermite steps re-taken from the start of its kept step (``_hermite_root``).
    """
    Y, DF, C, G, armed, fired = buf
    hslot = hp.hslot
    work = hs.work
    y, ya, wts = Y[B_NOW], Y[B_FULL], Y[B_WTS]
    f, fa = DF[B_NOW], DF[B_FULL]
    c, ca = C[B_NOW], C[B_FULL]
    g0, gm, gl = G[G_START], G[G_HALF], G[G_LOW]
    n = grid.size
    M = fp[kn.FP_MMODAL]
    n_ev = g0.size
    t = tt[T_NOW]
    model = (off, fp, omega2, cdamp, phiT, stiff, spos, prof, reg, hs, ist)
    root_args = (hp, tt, ist, atol, rtol, off, fp, omega2, cdamp, phi, phiT, stiff, cres, spos,
                 prof, reg, rf, hs)
    point_args = (outs, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, reg, rf,
                  work, track_latch, ist)
    if fresh:
        force_rates(y, f, off, fp, phiT, stiff, cres, spos, prof, reg, hs)
        hm.carried(t, y, f, c, off, fp, omega2, cdamp, phiT, spos, prof, reg)
        for mat in range(N_NEWTON):
            hs.iws[mat, hm.IWS_JAC_VALID] = 0
    if _enter(t, y, g0, armed, fresh, grid, outs, ist, off, fp, omega2, cdamp, phi, phi_obs,
              stiff, cres, spos, prof, reg, rf, work, track_latch):
        return ADV_DONE
    nstate = y.size
    # run-time ints: a literal compiles each callee (_hstep: the whole step inlined) once more
    # per value
    slot_fly, slot_fly2 = kn.runtime_int(SLOT_FLY), kn.runtime_int(SLOT_FLY2)
    kept, full = kn.runtime_int(NEWTON_KEPT), kn.runtime_int(NEWTON_FULL)
    while True:
        code = _loop_guard(tt, t, ist, k_stop, n, max_steps)
        if code != ADV_GO:
            return code
        k = ist[I_K]
        lev = ist[I_LEV]
        base = grid[k - 1]
        rel = t - base
        span = grid[k] - base
        hl = h_top / 2.0 ** lev
        # a block over several output intervals starts on a row divisible by their number
        # (so that the rows it steps over do not depend on where the loop stopped: chunks,
        # checkpoints, events) and ends within the grid; otherwise one level down
        rows = 0
        while hl > span * (1.0 + 1e-9):
            r_ = int(round(hl / span))
            if rel <= 1e-9 * span and (k - 1) % r_ == 0 and k - 1 + r_ < n:
                rows = r_
                break
            lev += 1
            hl *= 0.5
        s_full = lev
        if rows > 0:  # m kept steps of one output interval each
            m = rows
            s_kept = lev + int(round(math.log2(rows)))
            last = True
        else:         # a pair within one output interval
            m = 2
            s_kept = lev + 1
            target, last = _interval_target(rel, hl, span)
            if abs(target - rel - hl) > 1e-7 * hl:
                s_full = slot_fly
                s_kept = slot_fly2
                _hermite_fill(s_full, target - rel, omega2, cdamp, phi, cres, M, hp, ist)
                _hermite_fill(s_kept, 0.5 * (target - rel), omega2, cdamp, phi, cres, M, hp,
                              ist)
        if s_full < SLOT_FLY:
            if hslot[s_full] <= 0.0:
                _hermite_fill(s_full, hl, omega2, cdamp, phi, cres, M, hp, ist)
            if hslot[s_kept] <= 0.0:
                _hermite_fill(s_kept, hl / m, omega2, cdamp, phi, cres, M, hp, ist)
        h = hslot[s_full]
        hk = hslot[s_kept]
        for i in range(nstate):
            wts[i] = rtol * abs(y[i]) + atol[i]
        # the m kept steps, then the full step (for the error estimate)
        ok = True
        ts = t
        ys_, fs_, cs_ = y, f, c
        for j in range(m):
            row = _chain_row(j, m)
            ok = _hstep(ts, hk, ys_, fs_, cs_, Y[row], DF[row], C[row], s_kept, hp, wts,
                        *model, kept)
            if not ok:
                break
            ts = grid[k - 1 + j + 1] if rows > 0 else t + (j + 1) * hk
            ys_, fs_, cs_ = Y[row], DF[row], C[row]
        ok = ok and _hstep(t, h, y, f, c, ya, fa, ca, s_full, hp, wts, *model, full)
        if not ok:
            ist[I_NEWTON_FAIL] += 1
            ist[I_REJECT] += 1
            ist[I_LEV] = lev + 1
            continue
        yb = Y[B_END]
        err = _err_norm(ya, yb, y, atol, rtol, 2 * off[kn.OFF_R],
                        float(m) ** HERMITE_ORDER - 1.0)
        if err > 1.0:
            ist[I_REJECT] += 1
            fac = SAFETY * err ** (-1.0 / (HERMITE_ORDER + 1.0))
            drop = int(math.ceil(-math.log2(fac))) if fac < 1.0 else 1
            ist[I_LEV] = lev + max(1, drop)
            # a non-finite estimate within an output interval ends the run; over a block of
            # several intervals it is the long full step's (its Newton can run away where the
            # kept steps do not): one level down
            if err >= ERR_NONFINITE:
                if rows == 0:
                    tt[T_NOW] = t
                    return ADV_NONFINITE
                ist[I_LEV] = lev + 1
            continue
        ist[I_STEPS] += m
        ist[I_BLOCKS] += 1
        ist[I_LEV] = lev
        # the kept steps' ends in time order: each checked for crossings, then accepted
        for i in range(n_ev):
            gl[i] = g0[i]
        ts = t
        ys_, fs_, cs_ = y, f, c
        t_new = t
        for j in range(m):
            row = _chain_row(j, m)
            if rows > 0:
                te = grid[k - 1 + j + 1]
            elif j == m - 1:
                te = base + target if not last else grid[k]
            else:
                te = t + (j + 1) * hk
            ye = Y[row]
            kn.events(te, ye, gm, off, fp, phi, cres, spos, prof, reg, rf, work)
            if _crossed(armed, gm):
                return _hermite_root(ts, hk, 0.0, 1.0, te, ys_, fs_, cs_, gl, gm, ye, buf,
                                     *root_args)
            at_output = rows > 0 or (j == m - 1 and last)
            _accept_point(te, ye, gm, armed, *point_args, at_output)
            for i in range(n_ev):
                gl[i] = gm[i]
            ts = te
            ys_, fs_, cs_ = ye, DF[row], C[row]
            t_new = te
        fb, cb = DF[B_END], C[B_END]
        for j in range(nstate):
            y[j] = yb[j]
        for j in range(f.size):
            f[j] = fb[j]
        for j in range(c.size):
            c[j] = cb[j]
        for i in range(n_ev):
            g0[i] = gl[i]
        t = t_new
        tt[T_NOW] = t
        # step size: up one level when the error is small and the time is on that level
        if err * 2.0 ** (HERMITE_ORDER + 1) <= SAFETY ** (HERMITE_ORDER + 1) and lev > 0:
            up = h_top / 2.0 ** (lev - 1)
            if up > span * (1.0 + 1e-9) or _is_multiple(t - grid[ist[I_K] - 1], up) or last:
                ist[I_LEV] = lev - 1


def _check_scene(system: System) -> None:
    scene = system.scene
    law = scene.friction.law
    if system.tangential and "adaptive-modal" not in LAWS[law].solvers:
        takes = [name for name, fl in LAWS.items() if "adaptive-modal" in fl.solvers]
        raise SceneError(f"solver.method = 'adaptive-modal' supports friction.law = "
                         f"{' or '.join(repr(x) for x in takes)} only (friction.law = {law!r} "
                         f"needs one of {', '.join(repr(x) for x in LAWS[law].solvers)}), got "
                         f"{law!r}")
    if system.n_modes and np.any(system.cdamp**2 >= 4 * system.omega2):
        raise SceneError(f"solver.method = 'adaptive-modal' needs underdamped plate modes: "
                         f"plate.loss_factor must be < 2 (damping ratio loss_factor / 2 < 1), "
                         f"got {scene.plate.loss_factor}")


def solve_adaptive_modal(system: System, *, progress: bool | None = None,
                         checkpoint_dir: str | os.PathLike | None = None,
                         resume: Checkpoint | None = None,
                         hermite: bool | None = None) -> RawSolution:
    """Integrate with the adaptive exact-modal scheme (see the module docstring).

    Parameters
    ----------
    system : System
        From :func:`roughvib.model.system.assemble`.
    progress : bool, optional
        Progress bar on stderr (default: scene.output.progress).
    checkpoint_dir : path, optional
        Where ``checkpoint.pkl`` is written every ``output.checkpoint_interval`` of simulated
        time (nothing is written when the interval is 0 or this is None). A checkpoint holds
        everything the step loop carries, so runs with and without checkpoints, and resumed
        runs, are bit-identical.
    resume : Checkpoint, optional
        Continue from this checkpoint (of the same scene) instead of starting at t = 0.
    hermite : bool, optional
        Step with the fourth-order Hermite step (``_advance_hermite``) or the second-order
        trapezoidal one (``_advance``); default: the Hermite step where it applies
        (:func:`hermite_applies`). True where it does not apply is an error.

    Returns
    -------
    RawSolution
        Grid outputs (the states at the output times, which are step boundaries), event log,
        statistics; ``status`` is ``"success"`` or the failure cause.
    """
    _check_scene(system)
    scene = system.scene
    out_cfg = scene.output
    scfg = scene.solver
    K = system.n_contacts
    R = system.n_modes
    lay = system.layout
    grid, outs = output_grid(system)
    n, n_out = outs.shape
    # largest step: the output step, halved until it is within solver.max_step
    h_max = out_cfg.step
    if scfg.max_step > 0:
        while h_max > scfg.max_step * (1 + 1e-12):
            h_max *= 0.5

    h_top = hermite_top_pair(out_cfg.step, scfg.max_step)
    reg, rf = system.new_regime_arrays()
    regime, y, y_initial = start_state(system, reg, rf, resume, n, n_out)
    check_tolerances(system, y_initial)
    args = system.kernel_args(reg, rf)
    (off, fpa, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, _reg, _rf, work) = args

    nst = lay.size
    n_ev = K + kn.N_LAW_ROOTS
    Y = np.zeros((N_YBUF, nst))
    Y[B_NOW] = y
    y = Y[B_NOW]  # the current state, updated in place by _advance
    D = np.zeros((N_DBUF, N_D))
    U = np.zeros((N_DBUF, R))
    G = np.zeros((N_GBUF, n_ev))
    armed = np.zeros(n_ev, dtype=np.int64)
    fired = np.zeros(n_ev, dtype=np.int64)
    phiT = np.ascontiguousarray(phi.T)
    atol = atol_vector(system)
    ist = np.zeros(N_IST, dtype=np.int64)
    if hermite is None:
        hermite = hermite_applies(system)
    elif hermite and not hermite_applies(system):
        raise ValueError("the Hermite step covers the Feldmann law with a force-driven block "
                         "and no friction moment only")
    if hermite:  # the fourth-order Hermite step (_advance_hermite)
        # a block's kept steps from B_CHAIN: PAIR_ROWS - 2 beyond B_HALF and B_END
        n_ybuf = max(N_YBUF, B_CHAIN + PAIR_ROWS - 2)
        Y = np.zeros((n_ybuf, nst))
        Y[B_NOW] = y
        y = Y[B_NOW]
        DF = np.zeros((n_ybuf, K))
        C = np.zeros((n_ybuf, hm.carry_size(R, K)))
        maps = new_hermite_maps(R, K)
        buf = HermiteBuffers(Y, DF, C, G, armed, fired)
        scratch = new_hermite_scratch(work, R, K)
    else:
        maps = new_propagators(R, K, bool(kn.moment_on(off)))
        buf = Buffers(Y, D, U, G, armed, fired)
        scratch = new_scratch(work, R, K)
    tt = np.zeros(1)
    track_latch = bool(lay.tangential)
    cp_interval = out_cfg.checkpoint_interval
    # checkpoint times are grid indices (a multiple of the interval, rounded to the grid)
    cp_stride = max(1, int(round(cp_interval / out_cfg.step))) if cp_interval > 0 else 0
    if hermite and cp_stride % PAIR_ROWS:  # a checkpoint row ends a block
        cp_stride += PAIR_ROWS - cp_stride % PAIR_ROWS
    scene_toml = scene_to_toml(scene) if cp_stride and checkpoint_dir is not None else ""
    budget = step_budget(out_cfg.step)

    wall_before = cpu_before = 0.0
    if resume is None:
        kn.outputs(0.0, y, outs[FIRST_ROW], *args)
        ist[I_K] = 1
        # the first step h_max / 256 (the Hermite loop: its first full step about as long)
        ist[I_LEV] = HERMITE_FIRST_LEVEL if hermite else TRAPEZOIDAL_FIRST_LEVEL
        book = EventBook(system, regime, reg, rf)
        book.log_initial_phase(0.0, y)
        fresh = True
    else:
        loop = resume.loop
        outs[:resume.k] = resume.outputs
        ist[:] = loop["ist"]
        tt[T_NOW] = resume.t
        if hermite:
            DF[B_NOW] = loop["dF"]
            C[B_NOW] = loop["c"]
            scratch.ws[:] = loop["ws"]
            scratch.iws[:] = loop["iws"]
            scratch.hjac[:] = loop["hjac"]
        else:
            D[B_NOW] = loop["d"]
            U[B_NOW] = loop["u"]
        G[G_START] = loop["g"]
        armed[:] = loop["armed"]
        prev = dict(resume.stats)
        wall_before = float(prev.pop("wall_time", 0.0))
        cpu_before = float(prev.pop("cpu_time", 0.0))
        book = EventBook(system, regime, reg, rf, events=list(resume.events),
                         recent=collections.deque(loop["recent"]),
                         stats=collections.Counter(prev))
        book.stats["resumes"] += 1
        fresh = False  # the loop continues exactly where the checkpointed run was

    status, message = "success", "reached the end of the output grid"
    bar = progress_bar(system, progress, initial=float(tt[T_NOW]))
    chunk = max(1, n // 50)  # returns to Python (progress, checkpoints): ~0.1 ms each
    wall0 = time.perf_counter()
    cpu0 = time.process_time()

    def loop_state() -> dict:
        # everything the step loop carries (and the Hermite step's kept Newton matrix), so
        # that a resumed run is bit-identical
        state = {"recent": list(book.recent), "ist": ist.copy(), "g": G[G_START].copy(),
                 "armed": armed.copy()}
        if hermite:
            state.update(dF=DF[B_NOW].copy(), c=C[B_NOW].copy(), ws=scratch.ws.copy(),
                         iws=scratch.iws.copy(), hjac=scratch.hjac.copy())
        else:
            state.update(d=D[B_NOW].copy(), u=U[B_NOW].copy())
        return state

    def write_cp() -> None:
        k = int(ist[I_K])
        st = dict(book.stats)
        st["wall_time"] = wall_before + time.perf_counter() - wall0
        st["cpu_time"] = cpu_before + time.process_time() - cpu0
        write_checkpoint(checkpoint_dir, Checkpoint(
            scene_toml=scene_toml, t=float(tt[T_NOW]), k=k, y=y.copy(), y_initial=y_initial,
            outputs=outs[:k].copy(), reg=reg.copy(), rf=rf.copy(),
            regime=copy.deepcopy(regime), events=list(book.events), stats=st,
            loop=loop_state(),
            force_amplitude=float(system.force_amplitude),
            base_dir=str(Path(scene.base_dir).resolve()),
            inputs=input_fingerprint(scene_toml, system.profile.stats)))

    try:
        while True:
            k_stop = min(n, int(ist[I_K]) + chunk)
            if cp_stride:  # stop at the next checkpoint row (rows j with j % cp_stride == 0)
                k_stop = min(k_stop, (int(ist[I_K]) - 1) // cp_stride * cp_stride
                             + cp_stride + 1)
            if hermite:
                code = _advance_hermite(tt, ist, k_stop, grid, h_top, buf, maps, atol,
                                        scfg.rtol, outs, off, fpa, omega2, cdamp, phi, phiT,
                                        phi_obs, stiff, cres, spos, prof, reg, rf, scratch,
                                        track_latch, fresh, budget)
            else:
                code = _advance(tt, ist, k_stop, grid, h_max, buf, maps, atol, scfg.rtol, outs,
                                off, fpa, omega2, cdamp, phi, phiT, phi_obs, stiff, cres, spos,
                                prof, reg, rf, scratch, track_latch, fresh, budget)
            fresh = False
            regime.v_ext = float(rf[kn.RF_VEXT])
            bar.n = float(grid[min(int(ist[I_K]), n) - 1])
            bar.refresh()
            if code == ADV_DONE:
                break
            if code == ADV_CHUNK:
                k = int(ist[I_K])
                if cp_stride and (k - 1) % cp_stride == 0 and k < n:
                    book.stats["checkpoints"] += 1
                    if scene_toml:
                        write_cp()
                continue
            te = float(tt[T_NOW])
            if code == ADV_EVENT:
                y_new, _ = book.apply(te, y, set(np.flatnonzero(fired).tolist()))
                y[:] = y_new
                fresh = True
                continue
            where = f"t = {te:.6g} s (regime {regime.describe()})"
            if code == ADV_MIN_STEP:
                raise SolverFailure("step_underflow", f"adaptive-modal: step size underflow "
                                    f"at {where}: the error test keeps failing below "
                                    f"{h_max / 2**(NLEV - 1):.3g} s. Hint: loosen solver.rtol "
                                    f"or check the scene for a discontinuity no event sees",
                                    te)
            if code == ADV_NEWTON:
                raise SolverFailure("newton_failure", f"adaptive-modal: Newton failed while "
                                    f"locating an event at {where}", te)
            if code == ADV_STALL:
                raise stall_failure("adaptive-modal", te, f"more than {budget} step attempts",
                                    regime.describe())
            raise SolverFailure("nonfinite", f"adaptive-modal: the state became non-finite at "
                                f"{where}", te)
    except SolverFailure as exc:
        status, message = exc.status, str(exc)
    finally:
        bar.close()

    stats = dict(book.stats)
    stats.update({
        "steps": int(ist[I_STEPS]), "rejected_steps": int(ist[I_REJECT]),
        "step_evaluations": int(ist[I_STEP_EVALS]), "root_evaluations": int(ist[I_ROOT_EVALS]),
        "propagator_evaluations": int(ist[I_MAPS]), "nonlinear_iterations": int(ist[I_NEWTON]),
        "nonlinear_convergence_failures": int(ist[I_NEWTON_FAIL]),
        "extrapolated_steps": int(ist[I_EXTRAP]),
        "residual_evaluations": None,
        "jacobian_evaluations": int(ist[I_JACS]) if hermite else None,
        "blocks": int(ist[I_BLOCKS]) if hermite else None,
        "restarts": int(book.stats.get("restarts", 0)),
        "wall_time": wall_before + time.perf_counter() - wall0,
        "cpu_time": cpu_before + time.process_time() - cpu0,
        "events_total": len(book.events),
        "largest_step": h_max,  # the largest kept step, of either loop
    })
    k_done = int(ist[I_K])
    return RawSolution(time=grid, outputs=outs, events=book.events, stats=stats, status=status,
                       message=message, y_initial=y_initial, y_final=np.asarray(y, dtype=float),
                       t_final=float(grid[k_done - 1]) if status == "success" else float(tt[T_NOW]),
                       extra={"rows_filled": k_done})
