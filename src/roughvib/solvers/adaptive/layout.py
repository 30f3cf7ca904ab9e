"""The adaptive-modal loops' shared layout: step levels and cache slots, return codes, the
integer loop state ``ist`` and the rows of the state, derivative and margin buffers.

These are plain module constants: numba freezes them into the compiled loops. Pass them to a
compiled (not inlined) function through :func:`roughvib.model.kernels.runtime_int`, never as
they are (a constant argument compiles the callee once more per value).
"""

from __future__ import annotations

NLEV = 40            # dyadic levels below the largest step (h_min = h_max / 2^39)
SLOT_FLY = NLEV      # cache slots for steps that are not dyadic (after an event) ...
SLOT_FLY2 = NLEV + 1  # ... their half step
SLOT_ROOT = NLEV + 2  # ... and the trial steps of the root search
N_SLOTS = NLEV + 3

# return codes of the step loops (trapezoidal_loop.advance, hermite_loop.advance_hermite)
ADV_CHUNK = 0
ADV_EVENT = 1
ADV_DONE = 2
ADV_MIN_STEP = -1
ADV_NEWTON = -2
ADV_NONFINITE = -3
ADV_STALL = -4
ADV_GO = 9     # (loop_guard: attempt a step)

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
I_EXTRAP = 10    # accepted steps whose end was extrapolated (error.extrapolate)
I_JACS = 11      # Newton matrices formed (the Hermite step; the trapezoidal step forms one per
#                  iteration)
I_BLOCKS = 12    # the Hermite loop's accepted blocks (m kept steps against one long step)
N_IST = 13

# rows of the derivative vector d of trapezoidal.derivatives(): z'', x'', then the N_ENERGY
# powers
D_AZ = 0
D_AX = 1
D_POWER = 2
N_D = D_POWER + 6  # == D_POWER + N_ENERGY (roughvib.model.layout)
# rows of the state buffers Y (B_* all), D and U (the first six) of the loops
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
