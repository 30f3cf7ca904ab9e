"""The step loop of adaptive-modal's Hermite step (:mod:`roughvib.solvers.hermite`), where it
applies: the Feldmann law, a force-driven block, no friction moment
(:func:`roughvib.solvers.adaptive_modal.hermite_applies`).

The modal force is held as the cubic through its values and rates at both ends, the block
follows the Hermite-Obreschkoff rule (fourth order), and the error is estimated over blocks of
up to ``PAIR_ROWS`` output intervals: one step over the block against the kept steps of one
interval each (estimate / (m^4 - 1) for m kept steps). The margins are checked at each kept
step's end in turn, and a crossing is located by Hermite steps re-taken from the start of its
kept step (:func:`hermite_root`).
"""

from __future__ import annotations

import collections
import math

import numpy as np
from numba import njit

from roughvib.model import kernels as kn
from roughvib.model.krylov import lu_factor, lu_solve
from roughvib.physics.surface.interp import profile_eval
from roughvib.solvers import hermite as hm
from roughvib.solvers.adaptive.error import (
    ERR_NONFINITE,
    SAFETY,
    err_norm,
    levels_down,
    tolerance_weights,
)
from roughvib.solvers.adaptive.layout import (
    ADV_DONE,
    ADV_EVENT,
    ADV_GO,
    ADV_NEWTON,
    ADV_NONFINITE,
    B_BEST,
    B_CHAIN,
    B_END,
    B_FULL,
    B_HALF,
    B_NOW,
    B_TRIAL,
    B_WTS,
    G_HALF,
    G_LOW,
    G_START,
    G_TRIAL,
    I_BLOCKS,
    I_JACS,
    I_K,
    I_LEV,
    I_MAPS,
    I_NEWTON,
    I_NEWTON_FAIL,
    I_REJECT,
    I_ROOT_EVALS,
    I_STEP_EVALS,
    I_STEPS,
    N_SLOTS,
    SLOT_FLY,
    SLOT_FLY2,
    SLOT_ROOT,
    T_NOW,
)
from roughvib.solvers.adaptive.loop_common import (
    enter_loop,
    interval_target,
    is_multiple,
    loop_guard,
    write_row,
)
from roughvib.solvers.adaptive.roots import (
    ROOT_MAX_TRIALS,
    ROOT_TOL,
    illinois_trial,
    illinois_update,
)

__all__ = ["HERMITE_FIRST_LEVEL", "HERMITE_ORDER", "PAIR_ROWS", "HermiteBuffers", "HermiteMaps",
           "HermiteScratch", "advance_hermite", "force_rates", "hermite_loop", "hermite_top_pair",
           "hstep", "new_hermite_maps", "new_hermite_scratch"]

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
def hermite_fill(slot, h, omega2, cdamp, phi, cres, M, hp, ist):
    """The Hermite maps of step h into cache slot ``slot`` of ``hp``."""
    hm.hermite_slot(h, omega2, cdamp, phi, cres, M, hp.Pm[slot], hp.Cc[slot])
    hp.hslot[slot] = h
    ist[I_MAPS] += 1


@njit(cache=True)
def hstep(t0, h, y0, dF0, c0, y1, dF1, c1, slot, hp, wts, off, fp, omega2, cdamp, phiT, stiff,
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
def crossed(armed, g):
    """Whether an armed margin is not positive in g."""
    for i in range(g.size):
        if armed[i] == 1 and not g[i] > 0.0:
            return True
    return False


@njit(cache=True)
def hermite_root(tb, L, th_lo, th_hi, t_end, yb0, fb0, cb0, glo_at, ghi_at, ye, buf, hp, tt,
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
    # run-time ints: a literal compiles hstep (the whole step inlined) once more per value
    slot_root, kept = kn.runtime_int(SLOT_ROOT), kn.runtime_int(NEWTON_KEPT)
    tolerance_weights(yb0, atol, rtol, wts)
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
            th = illinois_trial(lo, hi, glo, ghi, L)
            hs_ = th * L
            hermite_fill(slot_root, hs_, omega2, cdamp, phi, cres, M, hp, ist)
            ist[I_ROOT_EVALS] += 1
            if not hstep(tb, hs_, yb0, fb0, cb0, yt, ft, ct, slot_root, hp, wts, off, fp,
                          omega2, cdamp, phiT, stiff, spos, prof, reg, hs, ist, kept):
                tt[T_NOW] = tb
                return ADV_NEWTON
            kn.events(tb + hs_, yt, gt, off, fp, phi, cres, spos, prof, reg, rf, work)
            lo, hi, glo, ghi, side = illinois_update(lo, hi, glo, ghi, side, th, gt[i])
        if hi == th_hi:
            for j in range(nstate):
                ybest[j] = ye[j]
        else:
            hs_ = hi * L
            hermite_fill(slot_root, hs_, omega2, cdamp, phi, cres, M, hp, ist)
            if not hstep(tb, hs_, yb0, fb0, cb0, ybest, fbest, cbest, slot_root, hp, wts, off,
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
def accept_point(t, y, g, armed, outs, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres,
                 spos, prof, reg, rf, work, track_latch, ist, output):
    """Arm the margins g (of the state y at time t) that are positive and, at an output time
    (``output``), write the next output row and update the latch and its margin in g
    (:func:`.loop_common.write_row`)."""
    for i in range(g.size):
        if g[i] > 0.0:
            armed[i] = 1
    if not output:
        return
    write_row(t, y, g, armed, outs, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos,
              prof, reg, rf, work, track_latch, ist)


@njit(cache=True, inline="always")
def chain_row(j, m):
    """The buffer row of the end of kept step j (of m) of a block: the last is ``B_END``."""
    if j == m - 1:
        return B_END
    if j == 0:
        return B_HALF
    return B_CHAIN + j - 1


@njit(cache=True)
def advance_hermite(tt, ist, k_stop, grid, h_top, buf, hp, atol, rtol, outs, off, fp, omega2,
                     cdamp, phi, phiT, phi_obs, stiff, cres, spos, prof, reg, rf, hs,
                     track_latch, fresh, max_steps):
    """:func:`hermite_loop` on views of its arrays without memory records
    (:func:`roughvib.model.kernels.unowned`: no reference counting in the loop); the same
    arguments, results and return codes. Called from Python, which holds the arrays."""
    u = kn.unowned
    return hermite_loop(
        u(tt), u(ist), k_stop, u(grid), h_top,
        HermiteBuffers(u(buf.Y), u(buf.DF), u(buf.C), u(buf.G), u(buf.armed), u(buf.fired)),
        HermiteMaps(u(hp.Pm), u(hp.Cc), u(hp.hslot)),
        u(atol), rtol, u(outs), u(off), u(fp), u(omega2), u(cdamp), u(phi), u(phiT),
        u(phi_obs), u(stiff), u(cres), u(spos), u(prof), u(reg), u(rf),
        HermiteScratch(u(hs.ws), u(hs.iws), u(hs.hjac), u(hs.jac), u(hs.ipiv), u(hs.rhs),
                       u(hs.work)),
        track_latch, fresh, max_steps)


@njit(cache=True)
def hermite_loop(tt, ist, k_stop, grid, h_top, buf, hp, atol, rtol, outs, off, fp, omega2,
                 cdamp, phi, phiT, phi_obs, stiff, cres, spos, prof, reg, rf, hs,
                 track_latch, fresh, max_steps):
    """:func:`.trapezoidal_loop.trapezoidal_loop` with the Hermite step
    (:mod:`roughvib.solvers.hermite`): the same arguments and return codes, with ``h_top``
    the top level's full step (:func:`hermite_top_pair`) instead of the largest step, ``buf``
    a ``HermiteBuffers``, ``hp`` a ``HermiteMaps`` and ``hs`` a ``HermiteScratch``.

    Step doubling generalised to a block: m kept Hermite steps of length hk against one step
    of m hk over the same span; the kept ones are kept as they are (fourth order: m local
    errors e against the full step's m^5 e, so the estimate of the kept steps' error is the
    difference / (m^4 - 1)). At the top level a block spans ``PAIR_ROWS`` output intervals,
    one kept step each, and starts on a row divisible by that number; each level down a block
    spans half as many (four, then two); below, a pair (m = 2) lies within one output
    interval, aligned to dyadic fractions of it as in the trapezoidal loop
    (``_block_rows``, ``_block_slots``). Every output time is a kept step's end. The
    kept steps and the full step are taken by ``_take_block``; the margins are checked at
    each kept step's end in turn, each end accepted (armed, written, latch updated) before the
    next is looked at (``_accept_block``), and a crossing is located by Hermite steps
    re-taken from the start of its kept step (:func:`hermite_root`).
    """
    Y, DF, C, G, armed, fired = buf
    work = hs.work
    y, ya, wts = Y[B_NOW], Y[B_FULL], Y[B_WTS]
    f = DF[B_NOW]
    c = C[B_NOW]
    g0, gl = G[G_START], G[G_LOW]
    n = grid.size
    n_ev = g0.size
    t = tt[T_NOW]
    model = (off, fp, omega2, cdamp, phiT, stiff, spos, prof, reg, hs, ist)
    root_args = (hp, tt, ist, atol, rtol, off, fp, omega2, cdamp, phi, phiT, stiff, cres, spos,
                 prof, reg, rf, hs)
    point_args = (outs, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, reg, rf,
                  work, track_latch, ist)
    events = (off, fp, phi, cres, spos, prof, reg, rf, work)
    if fresh:
        force_rates(y, f, off, fp, phiT, stiff, cres, spos, prof, reg, hs)
        hm.carried(t, y, f, c, off, fp, omega2, cdamp, phiT, spos, prof, reg)
        for mat in range(N_NEWTON):
            hs.iws[mat, hm.IWS_JAC_VALID] = 0
    if enter_loop(t, y, g0, armed, fresh, grid, outs, ist, off, fp, omega2, cdamp, phi, phi_obs,
                  stiff, cres, spos, prof, reg, rf, work, track_latch):
        return ADV_DONE
    nstate = y.size
    # run-time ints: a literal compiles each callee (hstep: the whole step inlined) once more
    # per value
    slot_fly, slot_fly2 = kn.runtime_int(SLOT_FLY), kn.runtime_int(SLOT_FLY2)
    kept, full = kn.runtime_int(NEWTON_KEPT), kn.runtime_int(NEWTON_FULL)
    while True:
        code = loop_guard(tt, t, ist, k_stop, n, max_steps)
        if code != ADV_GO:
            return code
        k = ist[I_K]
        base = grid[k - 1]
        rel = t - base
        span = grid[k] - base
        rows, lev, hl = _block_rows(rel, span, h_top, ist[I_LEV], k, n)
        m, s_full, s_kept, target, last = _block_slots(rows, lev, rel, hl, span, slot_fly,
                                                       slot_fly2, hp, omega2, cdamp, phi, cres,
                                                       fp, ist)
        h = hp.hslot[s_full]
        hk = hp.hslot[s_kept]
        tolerance_weights(y, atol, rtol, wts)
        if not _take_block(t, k, rows, m, h, hk, s_full, s_kept, grid, buf, hp, wts, model,
                           kept, full):
            ist[I_NEWTON_FAIL] += 1
            ist[I_REJECT] += 1
            ist[I_LEV] = lev + 1
            continue
        yb = Y[B_END]
        err = err_norm(ya, yb, y, atol, rtol, 2 * off[kn.OFF_R],
                       float(m) ** HERMITE_ORDER - 1.0)
        if err > 1.0:
            ist[I_REJECT] += 1
            ist[I_LEV] = lev + levels_down(err, -1.0 / (HERMITE_ORDER + 1.0))
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
        code, t_new = _accept_block(t, k, rows, m, hk, base, target, last, grid, buf,
                                    root_args, point_args, events)
        if code != ADV_GO:
            return code
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
            if up > span * (1.0 + 1e-9) or is_multiple(t - grid[ist[I_K] - 1], up) or last:
                ist[I_LEV] = lev - 1


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _block_rows(rel, span, h_top, lev, k, n):
    """The level of the next block from level ``lev`` and its output rows: ``(rows, lev,
    hl)`` with hl [s] the level's full step. A block over several output intervals (``rows``
    of them) starts on a row divisible by their number (so that the rows it steps over do not
    depend on where the loop stopped: chunks, checkpoints, events) and ends within the grid;
    otherwise one level down, until the full step fits in the output interval of length
    ``span`` [s] (``rows`` 0: a pair within it, ``rel`` [s] into it). ``k``: the next output
    row, ``n`` the grid's size."""
    hl = h_top / 2.0 ** lev
    rows = 0
    while hl > span * (1.0 + 1e-9):
        r_ = int(round(hl / span))
        if rel <= 1e-9 * span and (k - 1) % r_ == 0 and k - 1 + r_ < n:
            rows = r_
            break
        lev += 1
        hl *= 0.5
    return rows, lev, hl


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _block_slots(rows, lev, rel, hl, span, slot_fly, slot_fly2, hp, omega2, cdamp, phi, cres,
                 fp, ist):
    """The block's kept steps and the cache slots of its full and kept steps, filled when
    empty: ``(m, s_full, s_kept, target, last)``. With ``rows`` output intervals, m = rows
    kept steps of one interval each (``last``: the block ends on an output time); with none, a
    pair (m = 2) to ``target`` [s] into the interval (:func:`.loop_common.interval_target`),
    in ``slot_fly`` and ``slot_fly2`` when it is not the level's full step."""
    M = fp[kn.FP_MMODAL]
    hslot = hp.hslot
    s_full = lev
    target = 0.0  # (only a pair's end is a target within the interval)
    if rows > 0:  # m kept steps of one output interval each
        m = rows
        s_kept = lev + int(round(math.log2(rows)))
        last = True
    else:         # a pair within one output interval
        m = 2
        s_kept = lev + 1
        target, last = interval_target(rel, hl, span)
        if abs(target - rel - hl) > 1e-7 * hl:
            s_full = slot_fly
            s_kept = slot_fly2
            hermite_fill(s_full, target - rel, omega2, cdamp, phi, cres, M, hp, ist)
            hermite_fill(s_kept, 0.5 * (target - rel), omega2, cdamp, phi, cres, M, hp, ist)
    if s_full < SLOT_FLY:
        if hslot[s_full] <= 0.0:
            hermite_fill(s_full, hl, omega2, cdamp, phi, cres, M, hp, ist)
        if hslot[s_kept] <= 0.0:
            hermite_fill(s_kept, hl / m, omega2, cdamp, phi, cres, M, hp, ist)
    return m, s_full, s_kept, target, last


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _take_block(t, k, rows, m, h, hk, s_full, s_kept, grid, buf, hp, wts, model, kept, full):
    """The block's m kept steps of length hk [s] (each from the end of the one before, into
    the buffer rows of :func:`chain_row`), then its full step of length h [s] from t (into
    ``B_FULL``), with the maps of the slots ``s_kept`` and ``s_full`` and the Newton matrices
    of the scratch rows ``kept`` and ``full``. Returns False when a step's Newton fails.
    ``model``: the argument tail of :func:`hstep` before its scratch row."""
    Y, DF, C = buf.Y, buf.DF, buf.C
    y, f, c = Y[B_NOW], DF[B_NOW], C[B_NOW]
    ok = True
    ts = t
    ys_, fs_, cs_ = y, f, c
    for j in range(m):
        row = chain_row(j, m)
        ok = hstep(ts, hk, ys_, fs_, cs_, Y[row], DF[row], C[row], s_kept, hp, wts, *model, kept)
        if not ok:
            break
        ts = grid[k - 1 + j + 1] if rows > 0 else t + (j + 1) * hk
        ys_, fs_, cs_ = Y[row], DF[row], C[row]
    return ok and hstep(t, h, y, f, c, Y[B_FULL], DF[B_FULL], C[B_FULL], s_full, hp, wts,
                        *model, full)


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _accept_block(t, k, rows, m, hk, base, target, last, grid, buf, root_args, point_args,
                  events):
    """The ends of an accepted block's m kept steps (of length hk [s]) in time order: each
    checked for crossings of the armed margins and, if none, accepted (:func:`accept_point`).
    Returns ``(code, t_new)``: ``ADV_GO`` and the block's end time [s] (the margins there in
    ``G[G_LOW]``), or the code of :func:`hermite_root` at the first crossing. ``root_args``,
    ``point_args`` and ``events``: the argument tails of :func:`hermite_root`,
    :func:`accept_point` and :func:`roughvib.model.kernels.events`."""
    Y, DF, C, G, armed, _fired = buf
    g0, gm, gl = G[G_START], G[G_HALF], G[G_LOW]
    for i in range(gl.size):
        gl[i] = g0[i]
    ts = t
    ys_, fs_, cs_ = Y[B_NOW], DF[B_NOW], C[B_NOW]
    t_new = t
    for j in range(m):
        row = chain_row(j, m)
        if rows > 0:
            te = grid[k - 1 + j + 1]
        elif j == m - 1:
            te = base + target if not last else grid[k]
        else:
            te = t + (j + 1) * hk
        ye = Y[row]
        kn.events(te, ye, gm, *events)
        if crossed(armed, gm):
            return hermite_root(ts, hk, 0.0, 1.0, te, ys_, fs_, cs_, gl, gm, ye, buf,
                                *root_args), t_new
        at_output = rows > 0 or (j == m - 1 and last)
        accept_point(te, ye, gm, armed, *point_args, at_output)
        for i in range(gl.size):
            gl[i] = gm[i]
        ts = te
        ys_, fs_, cs_ = ye, DF[row], C[row]
        t_new = te
    return ADV_GO, t_new
