"""Benchmark: cost of one ``hermite_step`` (roughvib.solvers.hermite) in a compiled loop.

Run on demand, not by the tests:

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=src python benchmarks/bench_hermite_step.py \
        [--scene paper] [--calls 5000] [--repeats 30]

The ``paper`` scene (R = 393 modes, K = 1 contact; ``paper-handset``: K = 10) at its start
state (contacts closed, block breaking away from stick; the force rates consistent with the
contact relation), one step of the output interval (1e-5 s). Calling a many-argument numba
function from Python costs several times the step itself, so the calls are made inside an
``@njit`` loop (``hermite_step`` is inlined into it, as into the solver's ``_hstep``). Two
loops, each timed as the best of ``--repeats`` (CPU time per call, the machine may be
shared):

* ``fixed``: the same step from the same state ``--calls`` times (the Newton matrix kept
  from call to call, as between the steps of one slot and regime);
* ``march``: ``--calls`` steps, marching from the start state ``MARCH_STEPS`` at a time (the
  state changes, so Newton's iteration counts are those of a run: break-away, then sliding).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import describe  # this folder's (the script's own directory is on sys.path)
from numba import njit

from roughvib.model import kernels as kn
from roughvib.model.system import assemble
from roughvib.physics.surface.interp import profile_eval
from roughvib.scene import load_scene
from roughvib.solvers import hermite as hm
from roughvib.solvers.base import atol_vector
from roughvib.solvers.checkpoint import start_state

FORCE_AMPLITUDE = 0.9153599563724701   # the paper scene's calibrated T0 [N]
MARCH_STEPS = 1000                      # steps of a march (10 ms), then from the start again


@njit
def _fixed(calls, t0, h, y, dF, c, y1, dF1, c1, Pm, Cc, off, fp, om, cd, phiT, stiff, spos,
           prof, reg, wts, ws, iws):
    ok = True
    for _ in range(calls):
        ok = hm.hermite_step(t0, h, y, dF, c, y1, dF1, c1, Pm, Cc, off, fp, om, cd, phiT,
                             stiff, spos, prof, reg, wts, ws, iws) and ok
    return ok


@njit
def _march(calls, t0, h, y, dF, c, y1, dF1, c1, Pm, Cc, off, fp, om, cd, phiT, stiff, spos,
           prof, reg, wts, ws, iws):
    ok = True
    ys, dFs, cs = y.copy(), dF.copy(), c.copy()
    for i in range(calls):
        if i % MARCH_STEPS == 0:      # back to the start
            y[:] = ys
            dF[:] = dFs
            c[:] = cs
        t = t0 + (i % MARCH_STEPS) * h
        if i % 2 == 0:
            ok = hm.hermite_step(t, h, y, dF, c, y1, dF1, c1, Pm, Cc, off, fp, om, cd,
                                 phiT, stiff, spos, prof, reg, wts, ws, iws) and ok
        else:
            ok = hm.hermite_step(t, h, y1, dF1, c1, y, dF, c, Pm, Cc, off, fp, om, cd,
                                 phiT, stiff, spos, prof, reg, wts, ws, iws) and ok
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="paper")
    ap.add_argument("--calls", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=30)
    args = ap.parse_args()
    system = assemble(load_scene(args.scene), force_amplitude=FORCE_AMPLITUDE)
    reg, rf = system.new_regime_arrays()
    _, y0, _ = start_state(system, reg, rf, None, 0, 0)
    R, K = system.n_modes, system.n_contacts
    fp = system.fp
    h = load_scene(args.scene).output.step
    pm_shape, cc_shape = hm.slot_shapes(R, K)
    Pm, Cc = np.zeros(pm_shape), np.zeros(cc_shape)
    hm.hermite_slot(h, system.omega2, system.cdamp, system.phi, system.cres,
                    fp[kn.FP_MMODAL], Pm, Cc)
    phiT = np.ascontiguousarray(system.phi.T)
    x, v = y0[system.layout.index("block.x")], y0[system.layout.index("block.vx")]
    rate = np.array([y0[system.layout.index("block.vz")]
                     - system.phi[:, k] @ y0[system.layout.slice("plate.dq")]
                     + profile_eval(system.prof, fp[kn.FP_S0], fp[kn.FP_DX],
                                    system.input_s[k] + x)[1] * v for k in range(K)])
    dF0 = np.linalg.solve(np.diag(1 / system.stiff) + system.cres, rate)
    wts = atol_vector(system) + 1e-5 * np.abs(y0)
    n_ws, n_iws = hm.scratch_sizes(R, K)
    c0 = np.zeros(hm.carry_size(R, K))
    rest = (system.off, fp, system.omega2, system.cdamp, phiT)
    hm.carried(0.0, y0, dF0, c0, *rest, system.input_s, system.prof, reg)
    print(describe())
    print(f"{args.scene}: R = {R}, K = {K}, h = {h:g} s, {args.calls} calls, "
          f"best of {args.repeats}")
    for name, loop in (("fixed", _fixed), ("march", _march)):
        best = np.inf
        for rep in range(args.repeats + 1):       # the first compiles
            y, dF, c = y0.copy(), dF0.copy(), c0.copy()
            ws, iws = np.zeros(n_ws), np.zeros(n_iws, dtype=np.int64)
            call = (0.0, h, y, dF, c, y.copy(), dF.copy(), c.copy(), Pm, Cc, *rest,
                    system.stiff, system.input_s, system.prof, reg, wts, ws, iws)
            calls = args.calls if rep else 2
            w0 = time.process_time()
            assert loop(calls, *call)
            if rep:
                best = min(best, time.process_time() - w0)
        print(f"{name}: {best / args.calls * 1e6:.2f} us per call")


if __name__ == "__main__":
    main()
