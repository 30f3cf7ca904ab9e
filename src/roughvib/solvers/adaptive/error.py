"""Error control of adaptive-modal's step loops: the weighted norm of a step-doubling estimate,
the level a rejected step retries at, and local extrapolation (docs/theory.md, "The adaptive
exact-modal scheme").

Every step of length h is also taken as two steps of h/2 (the Hermite loop: m kept steps
against one step over the same span); their difference, divided by ``2^p - 1`` for a method of
order p, estimates the local error of what is kept. The estimate is weighted by IDA's
tolerances (``solver.rtol``, ``solver.atol``, ``solver.atol_acceleration``:
:func:`roughvib.solvers.base.atol_vector`): RMS over the modes as in IDA, max over the block,
contact and energy states (:func:`err_norm`). The trapezoidal loop keeps the two half steps
with that estimate removed (local extrapolation, third order: :func:`extrapolate`).
"""

from __future__ import annotations

import math

from numba import njit

from roughvib.model import kernels as kn

__all__ = ["ERR_NONFINITE", "SAFETY", "err_norm", "extrapolate", "levels_down",
           "modal_err_sq", "tolerance_weights"]

SAFETY = 0.9  # the step-size controller's safety factor on the optimal step
#: what :func:`err_norm` returns for an estimate that is NaN or infinite (and the threshold
#: the loops test it against): the step is rejected as non-finite
ERR_NONFINITE = 1e300


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def tolerance_weights(y, atol, rtol, wts):
    """The error weights ``wts_i = rtol |y_i| + atol_i`` of the state y (the Newton tests'
    units; ``atol`` and ``wts`` shape (n_states,), in each state's unit)."""
    for i in range(y.size):
        wts[i] = rtol * abs(y[i]) + atol[i]


@njit(cache=True, inline="always")  # a step of the loop, as fast as if written there
def levels_down(err, exponent):
    """How many dyadic levels a step rejected with the weighted error ``err`` (> 1) retries
    below its own: ``SAFETY err^exponent`` (``exponent = -1 / (p + 1)`` for an estimate of
    order p + 1) is the step's optimal fraction, rounded down to a power of two, and at least
    one level."""
    fac = SAFETY * err ** exponent
    drop = int(math.ceil(-math.log2(fac))) if fac < 1.0 else 1
    return max(1, drop)


@njit(cache=True)
def err_norm(ya, yb, y0, atol, rtol, n_modal, div):
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
    acc = modal_err_sq(ya, yb, y0, atol, rtol, n_modal, div)
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
def modal_err_sq(ya, yb, y0, atol, rtol, n_modal, div):
    """Sum over the first ``n_modal`` states of ``((ya - yb) / (div w))^2``, with
    ``w = rtol max(abs(y0), abs(yb)) + atol``, summed in whatever order vectorises; NaN or inf
    in any term makes it so.

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
def extrapolate(t1, ya, yb, ye, ge, armed, off, fp, phi, cres, spos, prof, reg, rf, work):
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
        ye[off[kn.OFF_IL]] = kn.set_valued_friction(t1, ye, off, fp, reg)
    kn.events(t1, ye, ge, off, fp, phi, cres, spos, prof, reg, rf, work)
    for i in range(ge.size):
        if armed[i] == 1 and not ge[i] > 0.0:
            return False
    for j in range(yb.size):
        yb[j] = ye[j]
    return True
