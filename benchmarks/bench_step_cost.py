"""Benchmark: where the default solver's time per accepted step goes.

Run on demand, not by the tests:

    python benchmarks/bench_step_cost.py                    # paper and paper-100mms
    python benchmarks/bench_step_cost.py paper --reps 20000

numba has no profiler, so the cost is split as counts times per-call costs. For each scene
(the default run: adaptive-modal at the ``reference`` preset, plate tolerance from the pilot):

1. the whole solve is timed warm (best CPU time of three) and its counters read: steps,
   implicit steps (three per attempt plus the root-search trials), Newton iterations,
   propagator computations, grid points;
2. a checkpoint written half-way through the run gives a state in mid-run (its regime, state,
   derivatives and modal force);
3. from that state each part of a step is called ``--reps`` times in a compiled loop and timed
   (per call, best of three): the implicit step (full and half slot) and, inside it, its
   propagation of the R modes (the same loop, copied here) and its assembly of the new state
   (modal force, state, :func:`derivatives`); ``kernels.events``; ``kernels.outputs`` with
   the latch update; ``_err_norm``; the tolerance weights and the copies of an accepted step;
4. per accepted step: count per step times cost per call; what the counts do not explain
   (the loop's control, the events' Python side, cache misses of the real sequence) is the
   rest.

OpenBLAS is held to one thread (the fixed-step floor's ``numpy.linalg.solve`` would otherwise
spin extra threads, whose CPU time counts in the process's); the adaptive solver calls no BLAS.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

from roughvib import simulation  # noqa: E402
from roughvib.model import kernels as kn  # noqa: E402
from roughvib.model.system import assemble  # noqa: E402
from roughvib.scene import load_scene  # noqa: E402
from roughvib.solvers import adaptive_modal as am  # noqa: E402
from roughvib.solvers.base import atol_vector  # noqa: E402
from roughvib.solvers.checkpoint import read_checkpoint  # noqa: E402


@njit
def _loop_implicit(reps, t0, h, y0, d0, u0, y1, d1, u1, slot, prop, wts, off, fp, cdamp, phi,
                   phiT, stiff, spos, prof, reg, scratch, ist):
    ok = True
    for _ in range(reps):
        ok = am.implicit_step(t0, h, y0, d0, u0, y1, d1, u1, slot, prop, wts, off, fp, cdamp,
                              phi, phiT, stiff, spos, prof, reg, scratch, ist) and ok
    return ok


@njit
def _loop_propagate(reps, y0, u0, slot, prop, off, phiT, ws):
    """implicit_step's free response of the modes (its first loop), alone."""
    iq, idq, R, K = off[kn.OFF_IQ], off[kn.OFF_IDQ], off[kn.OFF_R], off[kn.OFF_K]
    sq = ws[0:R]
    sdq = ws[R:2 * R]
    wfree = ws[2 * R:2 * R + K]
    for _ in range(reps):
        am.free_response(prop.P[slot], y0[iq:iq + R], y0[idq:idq + R], u0, phiT, sq, sdq,
                         wfree)


@njit
def _loop_assemble(reps, t1, y1, d1, u1, slot, prop, off, fp, cdamp, phiT, spos, prof, reg,
                   ws):
    """implicit_step's assembly of the new state (modal force, q, q', derivatives), alone."""
    iq, idq, iF, R, K = off[kn.OFF_IQ], off[kn.OFF_IDQ], off[kn.OFF_IF], off[kn.OFF_R], \
        off[kn.OFF_K]
    M = fp[kn.FP_MMODAL]
    sq = ws[0:R]
    sdq = ws[R:2 * R]
    F = y1[iF:iF + K].copy()
    for _ in range(reps):
        am.modal_force(F, u1, phiT, M)
        am.forced_response(prop.P[slot], sq, sdq, u1, y1[iq:iq + R], y1[idq:idq + R])
        am.derivatives(t1, y1, d1, off, fp, cdamp, spos, prof, reg)


@njit
def _loop_events(reps, t, y, g, off, fp, phi, cres, spos, prof, reg, rf, work):
    for _ in range(reps):
        kn.events(t, y, g, off, fp, phi, cres, spos, prof, reg, rf, work)


@njit
def _loop_outputs(reps, t, y, outs, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos,
                  prof, reg, rf, work):
    for i in range(reps):
        am._latch_and_output(t, y, outs, i % outs.shape[0], off, fp, omega2, cdamp, phi,
                             phi_obs, stiff, cres, spos, prof, reg, rf, work, True)


@njit
def _loop_err(reps, ya, yb, y, atol, rtol, n_modal):
    acc = 0.0
    for _ in range(reps):
        acc += am._err_norm(ya, yb, y, atol, rtol, n_modal)
    return acc


@njit
def _loop_copies(reps, y, yb, d, db, u, ub, wts, atol, rtol):
    """The tolerance weights of a step and the copies of an accepted one (state, derivatives,
    modal force)."""
    for _ in range(reps):
        for i in range(y.size):
            wts[i] = rtol * abs(y[i]) + atol[i]
        for j in range(y.size):
            y[j] = yb[j]
        for j in range(d.size):
            d[j] = db[j]
        for j in range(u.size):
            u[j] = ub[j]


def _per_call(fn, reps, *args):
    """Best CPU time per call [us] of three timed batches (after one compiling call)."""
    fn(1, *args)
    best = float("inf")
    for _ in range(3):
        t0 = time.process_time()
        fn(reps, *args)
        best = min(best, (time.process_time() - t0) / reps)
    return best * 1e6


def measure(name: str, reps: int) -> dict:
    """Counts of the default solve of scene ``name`` and the per-call cost of each part."""
    scene = load_scene(name, {"output.progress": False})
    scene = replace(scene, solver=scene.resolved_solver())
    system, _ = simulation._scale_atol_acceleration(assemble(scene))
    best = float("inf")
    raw = None
    for _ in range(4):  # the first compiles / loads
        t0 = time.process_time()
        raw = am.solve_adaptive_modal(system, progress=False)
        best = min(best, time.process_time() - t0)
    st = raw.stats
    n_grid = raw.time.size
    # a state in mid-run: the checkpoint at half the duration
    half = 0.5 * scene.output.duration
    cp_scene = replace(scene, output=replace(scene.output, checkpoint_interval=half))
    with tempfile.TemporaryDirectory() as tmp:
        am.solve_adaptive_modal(replace(system, scene=cp_scene), progress=False,
                                checkpoint_dir=tmp)
        cp = read_checkpoint(tmp)
    reg, rf = cp.reg.copy(), cp.rf.copy()
    (off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, _r, _f, work) = \
        system.kernel_args(reg, rf)
    R, K = system.n_modes, system.n_contacts
    n = system.layout.size
    lev = int(cp.loop["ist"][am.I_LEV])
    h_max = scene.output.step
    prop = am.new_propagators(R, K, bool(kn.moment_on(off)))
    M = fp[kn.FP_MMODAL]
    for s in (lev, lev + 1):
        am._fill_slot(s, h_max / 2.0 ** s, omega2, cdamp, phi, cres, M, prop)
    phiT = np.ascontiguousarray(phi.T)
    scratch = am.new_scratch(work, R, K)
    atol = atol_vector(system)
    rtol = scene.solver.rtol
    y = np.array(cp.y)
    d = np.array(cp.loop["d"])
    u = np.array(cp.loop["u"])
    wts = rtol * np.abs(y) + atol
    y1, d1, u1 = np.zeros(n), np.zeros(am.N_D), np.zeros(R)
    ist = np.zeros(am.N_IST, dtype=np.int64)
    t = cp.t
    h = h_max / 2.0 ** lev
    model = (prop, wts, off, fp, cdamp, phi, phiT, stiff, spos, prof, reg, scratch, ist)
    c = {}
    before = int(ist[am.I_NEWTON])
    c["implicit_full"] = _per_call(_loop_implicit, reps, t, h, y, d, u, y1, d1, u1, lev, *model)
    newton_isolated = (int(ist[am.I_NEWTON]) - before) / (1 + 3 * reps)
    c["implicit_half"] = _per_call(_loop_implicit, reps, t, 0.5 * h, y, d, u, y1, d1, u1,
                                   lev + 1, *model)
    yb, db, ub = y1.copy(), d1.copy(), u1.copy()
    c["propagate"] = _per_call(_loop_propagate, reps, y, u, lev, prop, off, phiT,
                               np.zeros(2 * R + 5 * K + 3))
    c["assemble"] = _per_call(_loop_assemble, reps, t + h, y1.copy(), d1.copy(), u1.copy(),
                              lev, prop, off, fp, cdamp, phiT, spos, prof, reg,
                              np.zeros(2 * R + 5 * K + 3))
    g = np.zeros(K + kn.N_LAW_ROOTS)
    c["events"] = _per_call(_loop_events, reps, t + h, yb, g, off, fp, phi, cres, spos, prof,
                            reg, rf, work)
    outs = np.zeros((64, raw.outputs.shape[1]))
    c["outputs"] = _per_call(_loop_outputs, reps, t + h, yb, outs, off, fp, omega2, cdamp, phi,
                             phi_obs, stiff, cres, spos, prof, reg, rf.copy(), work)
    c["err_norm"] = _per_call(_loop_err, reps, y1, yb * (1 + 1e-9), y, atol, rtol, 2 * R)
    c["copies"] = _per_call(_loop_copies, reps, y.copy(), yb, d.copy(), db, u.copy(), ub,
                            wts.copy(), atol, rtol)
    steps = st["steps"]
    attempts = steps + st["rejected_steps"]
    per_step = {
        "implicit steps": (st["step_evaluations"] / steps,
                           (c["implicit_full"] + 2 * c["implicit_half"]) / 3),
        "  of which propagation": (st["step_evaluations"] / steps, c["propagate"]),
        "  of which assembly (modal force, q, q', derivatives)":
            (st["step_evaluations"] / steps, c["assemble"]),
        "_err_norm": (attempts / steps, c["err_norm"]),
        "kernels.events": (2.0 + st["root_evaluations"] / steps, c["events"]),
        "outputs (kernels.outputs, latch)": (n_grid / steps, c["outputs"]),
        "weights and copies": (1.0, c["copies"]),
    }
    return {"scene": name, "R": R, "K": K, "cpu": best, "steps": steps, "attempts": attempts,
            "evals": st["step_evaluations"], "newton": st["nonlinear_iterations"],
            "maps": st["propagator_evaluations"], "grid": n_grid, "per_call": c,
            "per_step": per_step, "newton_isolated": newton_isolated}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=["paper", "paper-100mms"])
    ap.add_argument("--reps", type=int, default=20000, help="calls per timed batch")
    args = ap.parse_args()
    for name in args.scenes:
        r = measure(name, args.reps)
        us_step = r["cpu"] / r["steps"] * 1e6
        print(f"\n`{name}`: R = {r['R']} modes, K = {r['K']} contacts; {r['steps']:,} steps "
              f"({r['attempts']:,} attempts), {r['evals']:,} implicit steps, "
              f"{r['newton']:,} Newton iterations ({r['newton'] / r['evals']:.2f} per implicit "
              f"step; {r['newton_isolated']:.2f} in the isolated calls), {r['maps']} "
              f"propagator computations, {r['grid']:,} grid points; solve {r['cpu']:.3f} s CPU "
              f"= {us_step:.1f} us per step")
        print("| part | calls per step | us per call | us per step | share |")
        print("|---|---|---|---|---|")
        explained = 0.0
        for part, (calls, us) in r["per_step"].items():
            tot = calls * us
            if not part.startswith("  "):
                explained += tot
            print(f"| {part} | {calls:.3f} | {us:.2f} | {tot:.2f} | {tot / us_step:.0%} |")
        rest = us_step - explained
        print(f"| rest (loop control, events' Python side, ...) | | | {rest:.2f} | "
              f"{rest / us_step:.0%} |")
        print(f"| **whole step** | | | **{us_step:.2f}** | 100% |", flush=True)


if __name__ == "__main__":
    main()
