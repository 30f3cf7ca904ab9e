"""The step loop of adaptive-modal's trapezoidal step (:mod:`.trapezoidal`), for every scene
the Hermite loop does not cover (docs/theory.md, "The adaptive exact-modal scheme").

Each attempt takes one step of length h and two of h/2 (:func:`.trapezoidal.implicit_step`);
their difference is the error estimate (:func:`.error.err_norm`), and an accepted step keeps
the two half steps, extrapolated (:func:`.error.extrapolate`). Step sizes are dyadic fractions
of the largest step, so their propagators are cached (:func:`.propagators.fill_slot`). The
margins are checked at the half step and at the end; a crossing is located on the half step
that holds it by re-taken steps of variable length (``_trapezoidal_root``).
"""

from __future__ import annotations

import collections

from numba import njit

from roughvib.model import kernels as kn
from roughvib.solvers.adaptive.error import (
    ERR_NONFINITE,
    SAFETY,
    err_norm,
    extrapolate,
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
    B_END,
    B_FULL,
    B_HALF,
    B_NOW,
    B_TRIAL,
    B_WTS,
    D_POWER,
    G_END,
    G_HALF,
    G_START,
    G_TRIAL,
    I_EXTRAP,
    I_K,
    I_LEV,
    I_MAPS,
    I_NEWTON_FAIL,
    I_REJECT,
    I_ROOT_EVALS,
    I_STEP_EVALS,
    I_STEPS,
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
from roughvib.solvers.adaptive.propagators import Propagators, fill_slot, state_modal_force
from roughvib.solvers.adaptive.roots import (
    ROOT_MAX_TRIALS,
    ROOT_TOL,
    illinois_trial,
    illinois_update,
)
from roughvib.solvers.adaptive.trapezoidal import Scratch, derivatives, implicit_step

__all__ = ["TRAPEZOIDAL_FIRST_LEVEL", "Buffers", "advance", "trapezoidal_loop"]

#: the step loop's buffers: ``Y`` (N_YBUF, n) states, ``D`` (N_DBUF, N_D) derivatives, ``U``
#: (N_DBUF, R) modal forces, ``G`` (N_GBUF, K + N_LAW_ROOTS) margins, ``armed`` / ``fired``
#: (K + N_LAW_ROOTS,) int64
Buffers = collections.namedtuple("Buffers", ["Y", "D", "U", "G", "armed", "fired"])
#: the level of a run's first step: h_max / 2^8
TRAPEZOIDAL_FIRST_LEVEL = 8


@njit(cache=True)
def advance(tt, ist, k_stop, grid, h_max, buf, prop, atol, rtol, outs, off, fp, omega2, cdamp,
            phi, phiT, phi_obs, stiff, cres, spos, prof, reg, rf, scratch, track_latch, fresh,
            max_steps):
    """:func:`trapezoidal_loop` on views of its arrays without memory records
    (:func:`roughvib.model.kernels.unowned`: no reference counting in the loop); the same
    arguments, results and return codes. Called from Python, which holds the arrays."""
    u = kn.unowned
    return trapezoidal_loop(
        u(tt), u(ist), k_stop, u(grid), h_max,
        Buffers(u(buf.Y), u(buf.D), u(buf.U), u(buf.G), u(buf.armed), u(buf.fired)),
        Propagators(u(prop.Phi), u(prop.G0), u(prop.G1), u(prop.G1c), u(prop.hslot),
                    u(prop.Hm), u(prop.hmslot), u(prop.P)),
        u(atol), rtol, u(outs), u(off), u(fp), u(omega2), u(cdamp), u(phi), u(phiT),
        u(phi_obs), u(stiff), u(cres), u(spos), u(prof), u(reg), u(rf),
        Scratch(u(scratch.work), u(scratch.ws), u(scratch.jac), u(scratch.ipiv)),
        track_latch, fresh, max_steps)


@njit(cache=True)
def trapezoidal_loop(tt, ist, k_stop, grid, h_max, buf, prop, atol, rtol, outs, off, fp,
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
    (tolerance weights); ``D`` (6, 8) and ``U`` (6, R) the derivatives
    (:func:`.trapezoidal.derivatives`) and modal forces (:func:`.propagators.modal_force`) of
    the first six; ``G`` (4, K + N_LAW_ROOTS) the margins at the step start, half step, end,
    and of the latest trial; ``armed``, ``fired`` the roots. ``prop``: the ``Propagators``
    cache; ``scratch``: ``Scratch``.

    Each pass: the guards (:func:`.loop_common.loop_guard`), the step's slots
    (``_step_slots``), the full and the two half steps, the error test, the crossings
    (``_crossings``, then ``_trapezoidal_root``), the acceptance (``_accept``), the
    output row at an output time and the next step size.
    """
    Y, D, U, G, armed, fired = buf
    work = scratch.work
    y, ya, ym, yb, wts = Y[B_NOW], Y[B_FULL], Y[B_HALF], Y[B_END], Y[B_WTS]
    d, da, dm, db = D[B_NOW], D[B_FULL], D[B_HALF], D[B_END]
    u, ua, um, ub, ut = U[B_NOW], U[B_FULL], U[B_HALF], U[B_END], U[B_TRIAL]
    g0, gm, gb = G[G_START], G[G_HALF], G[G_END]
    n = grid.size
    t = tt[T_NOW]
    if fresh:
        derivatives(t, y, d, off, fp, cdamp, spos, prof, reg)
        state_modal_force(y, u, phiT, off, fp, reg, ut)
    if enter_loop(t, y, g0, armed, fresh, grid, outs, ist, off, fp, omega2, cdamp, phi, phi_obs,
                  stiff, cres, spos, prof, reg, rf, work, track_latch):
        return ADV_DONE
    # the cache slots as run-time ints: a literal compiles each callee once more per value
    slot_fly, slot_fly2 = kn.runtime_int(SLOT_FLY), kn.runtime_int(SLOT_FLY2)
    slot_root = kn.runtime_int(SLOT_ROOT)
    model = (prop, wts, off, fp, cdamp, phi, phiT, stiff, spos, prof, reg, scratch, ist)
    events = (off, fp, phi, cres, spos, prof, reg, rf, work)
    while True:
        code = loop_guard(tt, t, ist, k_stop, n, max_steps)
        if code != ADV_GO:
            return code
        k = ist[I_K]
        lev = ist[I_LEV]
        hl = h_max / 2.0 ** lev
        base = grid[k - 1]
        rel = t - base
        span = grid[k] - base
        target, last = interval_target(rel, hl, span)
        h, s_full, s_half = _step_slots(target - rel, hl, lev, slot_fly, slot_fly2, prop, omega2,
                                        cdamp, phi, cres, fp, ist)
        hh = 0.5 * h
        tolerance_weights(y, atol, rtol, wts)
        # the full step (for the error estimate) and the two half steps (kept)
        ok = implicit_step(t, h, y, d, u, ya, da, ua, s_full, *model)
        ok = ok and implicit_step(t, hh, y, d, u, ym, dm, um, s_half, *model)
        ok = ok and implicit_step(t + hh, h - hh, ym, dm, um, yb, db, ub, s_half, *model)
        ist[I_STEP_EVALS] += 3
        if not ok:
            ist[I_NEWTON_FAIL] += 1
            ist[I_REJECT] += 1
            ist[I_LEV] = lev + 1
            continue
        # plate.q and plate.dq come first in the layout (StateLayout): 2 R modal states; the
        # estimate of a second-order method is the difference / (2^2 - 1)
        err = err_norm(ya, yb, y, atol, rtol, 2 * off[kn.OFF_R], 3.0)
        if err > 1.0:
            ist[I_REJECT] += 1
            ist[I_LEV] = lev + levels_down(err, -1.0 / 3.0)
            if err >= ERR_NONFINITE:
                tt[T_NOW] = t
                return ADV_NONFINITE
            continue
        ist[I_STEPS] += 1
        t_new = base + target if not last else grid[k]
        # events: margins at the half step and at the end
        kn.events(t + hh, ym, gm, *events)
        kn.events(t_new, yb, gb, *events)
        any_cross, first_half = _crossings(armed, fired, gm, gb)
        if any_cross:
            return _trapezoidal_root(t, h, t_new, first_half, buf, prop, atol, rtol, tt, ist,
                                     model, omega2, cdamp, phi, cres, fp, events, slot_root)
        _accept(t_new, h, buf, ist, events)
        t = t_new
        tt[T_NOW] = t
        if last:
            write_row(t, y, g0, armed, outs, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres,
                      spos, prof, reg, rf, work, track_latch, ist)
        # step size: up one level when the error is small and the time is on that level
        if err * 8.0 <= SAFETY ** 3 and ist[I_LEV] > 0:
            up = h_max / 2.0 ** (ist[I_LEV] - 1)
            if is_multiple(t - grid[ist[I_K] - 1], up) or last:
                ist[I_LEV] -= 1


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _step_slots(h, hl, lev, slot_fly, slot_fly2, prop, omega2, cdamp, phi, cres, fp, ist):
    """The cache slots of a step of length h [s] on level ``lev`` (of length hl [s]) and of
    its half: ``(h, s_full, s_half)``. A step of the level's length uses the level's slots
    (``lev``, ``lev + 1``), filled once, and is the slot's length exactly; a shorter one (to
    an output time, after an event) fills ``slot_fly`` and ``slot_fly2`` anew."""
    M = fp[kn.FP_MMODAL]
    hslot = prop.hslot
    if abs(h - hl) <= 1e-7 * hl:
        s_full = lev
        s_half = lev + 1
        if hslot[s_full] <= 0.0:
            fill_slot(s_full, hl, omega2, cdamp, phi, cres, M, prop)
            ist[I_MAPS] += 1
        if hslot[s_half] <= 0.0:
            fill_slot(s_half, 0.5 * hl, omega2, cdamp, phi, cres, M, prop)
            ist[I_MAPS] += 1
        h = hslot[s_full]
    else:
        s_full = slot_fly
        s_half = slot_fly2
        fill_slot(s_full, h, omega2, cdamp, phi, cres, M, prop)
        fill_slot(s_half, 0.5 * h, omega2, cdamp, phi, cres, M, prop)
        ist[I_MAPS] += 2
    return h, s_full, s_half


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _crossings(armed, fired, gm, gb):
    """Whether an armed margin is not positive at the half step (gm) or the end (gb), and
    whether one is at the half step: ``(any_cross, first_half)``. Clears ``fired``."""
    first_half = False
    any_cross = False
    for i in range(gm.size):
        fired[i] = 0
        if armed[i] == 1 and (gm[i] <= 0.0 or gb[i] <= 0.0):
            any_cross = True
            if gm[i] <= 0.0:
                first_half = True
    return any_cross, first_half


@njit(cache=True)
def _trapezoidal_root(t, h, t_new, first_half, buf, prop, atol, rtol, tt, ist, model, omega2,
                      cdamp, phi, cres, fp, events, slot_root):
    """Locate the earliest crossing in the half step that holds it (the first when
    ``first_half``) of the step [t, t_new] of length h: for each armed margin that crossed, in
    turn, the Illinois method (:mod:`.roots`) on the margin of steps re-taken from the half
    step's start, to ``ROOT_TOL``, within the bracket left by the earlier roots. Leaves the
    state at the root in ``Y[B_NOW]`` and its time in ``tt``, marks the roots that crossed
    there in ``fired``; returns ``ADV_EVENT`` (or ``ADV_NEWTON``). ``model`` and ``events``:
    the argument tails of :func:`.trapezoidal.implicit_step` and
    :func:`roughvib.model.kernels.events`."""
    Y, D, U, G, armed, fired = buf
    y, ym, yb, yt, ybest, wts = Y[B_NOW], Y[B_HALF], Y[B_END], Y[B_TRIAL], Y[B_BEST], Y[B_WTS]
    dt_, dbest = D[B_TRIAL], D[B_BEST]
    ut, ubest = U[B_TRIAL], U[B_BEST]
    gt = G[G_TRIAL]
    M = fp[kn.FP_MMODAL]
    n_ev = gt.size
    nstate = y.size
    hh = 0.5 * h
    # the half step holding the earliest crossings, re-taken with variable length
    if first_half:
        tb = t
        yb0, db0, ub0, gb0, ge = y, D[B_NOW], U[B_NOW], G[G_START], G[G_HALF]
    else:
        tb = t + hh
        yb0, db0, ub0, gb0, ge = ym, D[B_HALF], U[B_HALF], G[G_HALF], G[G_END]
    L = hh if first_half else h - hh
    tolerance_weights(yb0, atol, rtol, wts)
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
            th = illinois_trial(lo, hi, glo, ghi, L)
            hs = th * L
            fill_slot(slot_root, hs, omega2, cdamp, phi, cres, M, prop)
            ist[I_MAPS] += 1
            ist[I_ROOT_EVALS] += 1
            ist[I_STEP_EVALS] += 1
            if not implicit_step(tb, hs, yb0, db0, ub0, yt, dt_, ut, slot_root, *model):
                tt[T_NOW] = tb
                return ADV_NEWTON
            kn.events(tb + hs, yt, gt, *events)
            lo, hi, glo, ghi, side = illinois_update(lo, hi, glo, ghi, side, th, gt[i])
        # the state at hi (re-taken so that every margin is evaluated there)
        hs = hi * L
        if hi == 1.0:  # the half step's own end (derivatives are recomputed on entry)
            src = ym if first_half else yb
            for j in range(nstate):
                ybest[j] = src[j]
        else:
            fill_slot(slot_root, hs, omega2, cdamp, phi, cres, M, prop)
            ist[I_MAPS] += 1
            ist[I_STEP_EVALS] += 1
            if not implicit_step(tb, hs, yb0, db0, ub0, ybest, dbest, ubest, slot_root, *model):
                tt[T_NOW] = tb
                return ADV_NEWTON
        theta_best = hi
        have_best = True
        kn.events(tb + theta_best * L, ybest, gt, *events)
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


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def _accept(t_new, h, buf, ist, events):
    """Accept the step of length h [s] that ends at t_new [s]: its end (the two half steps,
    with Simpson's energy integrals, extrapolated where no armed margin objects) becomes the
    current state with its derivatives, modal force and margins, and the margins that are
    positive there are armed. ``events``: the argument tail of
    :func:`roughvib.model.kernels.events`."""
    off, fp, phi, cres, spos, prof, reg, rf, work = events
    Y, D, U, G, armed, _fired = buf
    y, ya, yb, yt = Y[B_NOW], Y[B_FULL], Y[B_END], Y[B_TRIAL]
    d, da, dm, db = D[B_NOW], D[B_FULL], D[B_HALF], D[B_END]
    u, ua, ub = U[B_NOW], U[B_FULL], U[B_END]
    g0, gb, gt = G[G_START], G[G_END], G[G_TRIAL]
    n_ev = g0.size
    nstate = y.size
    # the energy integrals by Simpson's rule over the two half steps (the midpoint state is at
    # hand): the half steps' trapezoidal sums are second order in h, and on a quiet run the
    # steps are capped by the output grid, so that quadrature error did not shrink with the
    # tolerance (energy audit 1.1e-8 at any rtol on paper without roughness); Simpson's is
    # fourth order (docs/robustness.md, energy audit)
    iE = off[kn.OFF_IE]
    for i in range(kn.N_ENERGY):
        yb[iE + i] = y[iE + i] + h / 6.0 * (d[D_POWER + i] + 4.0 * dm[D_POWER + i]
                                             + db[D_POWER + i])
    # local extrapolation: the step's end from the two results, third order. The
    # derivatives and modal forces of the kept state by the same combination: exact where
    # they are linear in the state (the modal force of the contact forces, the vertical
    # acceleration), to the square of the correction elsewhere (the friction law, the
    # powers); computing them anew cost 8-10 % of the solve for the same result
    if extrapolate(t_new, ya, yb, yt, gt, armed, off, fp, phi, cres, spos, prof, reg, rf, work):
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
