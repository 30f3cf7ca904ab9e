"""The Illinois root search of adaptive-modal's events: the trial point and the bracket update
both step loops use (docs/theory.md, "The adaptive exact-modal scheme").

The regime is fixed within a step; the margins of :func:`roughvib.model.kernels.events` are
checked at the step's points, and a downward crossing is located by the Illinois method on
the margin of a re-taken step of variable length from the last state before it, to
``ROOT_TOL``. The loops own the searches themselves (:func:`.trapezoidal_loop.advance`,
:func:`.hermite_loop.hermite_root`): they re-take the steps.
"""

from __future__ import annotations

from numba import njit

__all__ = ["ROOT_MAX_TRIALS", "ROOT_TOL", "illinois_trial", "illinois_update"]

ROOT_TOL = 1e-13     # s, width of the bracket that locates an event
#: trials of one root search at most (a search that converges takes a few: 25 were a sign of
#: bisection, see illinois_trial; 200 bisections halve any step below ROOT_TOL)
ROOT_MAX_TRIALS = 200


@njit(cache=True)
def illinois_trial(lo, hi, glo, ghi, L):
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
def illinois_update(lo, hi, glo, ghi, side, th, g):
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
