"""What both adaptive-modal step loops do at entry, before each step attempt and at output
times: the output rows and the latch's running extremum, the stall and step-size guards, and
the step targets within an output interval. Every output time is a step boundary (no
interpolation of the modes).
"""

from __future__ import annotations

import math

from numba import njit

from roughvib.model import kernels as kn
from roughvib.solvers.adaptive.layout import (
    ADV_CHUNK,
    ADV_DONE,
    ADV_GO,
    ADV_MIN_STEP,
    ADV_STALL,
    I_IVL,
    I_K,
    I_LEV,
    NLEV,
    T_NOW,
)

__all__ = ["enter_loop", "interval_target", "is_multiple", "latch_and_output", "loop_guard",
           "write_row"]


@njit(cache=True)
def is_multiple(rel, h):
    """Whether ``rel`` is (to 1e-7 of h) a whole multiple of h."""
    f = rel / h
    return abs(f - round(f)) <= 1e-7


@njit(cache=True)
def latch_and_output(t, y, outs, k, args_off, fp, omega2, cdamp, phi, phi_obs, stiff, cres,
                      spos, prof, reg, rf, work, track_latch):
    """Output row k and the latch's running extremum, as solve_ida does at grid points."""
    kn.outputs(t, y, outs[k], args_off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos,
               prof, reg, rf, work)
    if track_latch:
        kn.follow_latch_extremum(y[args_off[kn.OFF_IVX]], reg, rf)


@njit(cache=True)
def enter_loop(t, y, g0, armed, fresh, grid, outs, ist, off, fp, omega2, cdamp, phi, phi_obs, stiff,
           cres, spos, prof, reg, rf, work, track_latch):
    """A step loop's entry: the outputs at grid points the state at t landed on (after an
    event's switch, as IDA does) and, for a state set from outside (``fresh``), its margins
    in g0 and the roots armed. Returns whether the grid is done."""
    n = grid.size
    k = ist[I_K]
    while k < n and grid[k] - t <= 1e-12 * max(1.0, t):
        latch_and_output(grid[k], y, outs, k, off, fp, omega2, cdamp, phi, phi_obs, stiff,
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
def loop_guard(tt, t, ist, k_stop, n, max_steps):
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
def interval_target(rel, hl, span):
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


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def write_row(t, y, g, armed, outs, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos,
              prof, reg, rf, work, track_latch, ist):
    """Write the next output row (``ist[I_K]``) of the accepted state y at the output time t
    [s], update the latch's running extremum, and move on to the next row (the stall count
    starts anew). The Feldmann latch's margin depends on the extremum just updated: it is
    recomputed in the margins g and armed when positive (the other margins, those of a
    set-valued law included, do not)."""
    k = ist[I_K]
    latch_and_output(t, y, outs, k, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos,
                     prof, reg, rf, work, track_latch)
    ist[I_K] = k + 1
    ist[I_IVL] = 0
    if track_latch and not kn.set_valued(off):
        il = off[kn.OFF_K] + kn.ROOT_LATCH
        g[il] = kn.latch_margin(y, off, fp, reg, rf)
        if g[il] > 0.0:
            armed[il] = 1
