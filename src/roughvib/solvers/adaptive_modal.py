"""Adaptive exact-modal solver: exact plate propagation, error-controlled steps, located events.

This module is the driver (:func:`solve_adaptive_modal`): it sets up a run, calls a compiled
step loop in chunks, switches the regime at events, writes checkpoints and collects the
statistics. The compiled parts live in :mod:`roughvib.solvers.adaptive` (one responsibility
per module, listed there); the names other code and the tests use are importable from here
too.

Two steps, one loop each (docs/theory.md, "The adaptive exact-modal scheme"):

* the **Hermite step** (:func:`.adaptive.hermite_loop.advance_hermite`;
  :mod:`roughvib.solvers.hermite`), fourth order, where :func:`hermite_applies`: the Feldmann
  law with a force-driven block and no friction moment. The modal force is held as the cubic
  through its values and rates at both ends, the block follows the Hermite-Obreschkoff rule,
  and the error is estimated over blocks of up to ``PAIR_ROWS`` output intervals: one step
  over the block against the kept steps of one interval each (estimate / (m^4 - 1) for m kept
  steps);
* the **trapezoidal step** (:func:`.adaptive.trapezoidal_loop.advance`,
  :func:`.adaptive.trapezoidal.implicit_step`) for every other case, described below.

The plate modes couple to the block only through the K contact forces, and each mode is a
linear oscillator. Over a step of length h with the modal force linear in time (first-order
hold), a mode is propagated exactly, whatever omega h is (docs/theory.md; the fixed-step
``exact-modal`` scheme):

    [q, q']_{n+1} = Phi(h) [q, q']_n + G0(h) u_n + G1(h) u_{n+1},   u = phi^T F / M.

The block's vertical and tangential motion use the trapezoidal rule, so the only implicit
problem per step is the K contact forces and the tangential velocity, solved by Newton on a
(K+1)-square system (no matrix of the plate's size is ever formed). The step is second order;
unlike BDF2 it has no error at all in the modes' own dynamics, only in the force history.

What the scheme adds to the fixed-step one, to make it a reference-grade solver:

* **Error control** by step doubling: every step of length h is also taken as two steps of
  h/2; ``(y_h - y_{h/2,h/2}) / 3`` estimates the local error of the two half steps, and the
  state kept is the two half steps with that estimate removed (local extrapolation, third
  order: :func:`.adaptive.error.extrapolate`). The estimate is weighted by IDA's tolerances
  (``solver.rtol``, ``solver.atol``, ``solver.atol_acceleration``:
  :func:`roughvib.solvers.base.atol_vector`): RMS over the modes as in IDA, max over the
  block, contact and energy states (see :func:`.adaptive.error.err_norm`). Step sizes are
  dyadic fractions of the output step, so the propagators of each size are computed once and
  cached, and every output time is a step boundary (no interpolation of the modes).
* **Events as in IDA**: the regime is fixed within a step (no active set, no max()); the
  margins of :func:`roughvib.model.kernels.events` are checked at every half step, and a
  downward crossing is located by the Illinois method (:mod:`.adaptive.roots`) on the margin
  of a re-taken step of variable length from the last state before it (to ``ROOT_TOL``). The
  regime is then switched and the state made consistent by the same code as IDA's restart
  (:class:`roughvib.solvers.events.EventBook`). A one-step method needs no warm-up after a
  restart: an event costs its root search, not a ramp-up of order and step.

Propagators (:mod:`.adaptive.propagators`): for omega h > 1 the closed form of the damped
oscillator; below, a power series of the same matrix exponential, because the closed form's
``1 - cos`` terms lose all digits for omega h -> 0 (both branches are tested against scipy's
expm).

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
import os
import time
from pathlib import Path

import numpy as np

from roughvib.model import kernels as kn
from roughvib.model.system import System
from roughvib.physics.friction import LAWS
from roughvib.scene import SceneError, scene_to_toml
from roughvib.solvers import hermite as hm
from roughvib.solvers.adaptive.error import err_norm, extrapolate
from roughvib.solvers.adaptive.hermite_loop import (
    HERMITE_FIRST_LEVEL,
    PAIR_ROWS,
    HermiteBuffers,
    advance_hermite,
    hermite_fill,
    hermite_top_pair,
    hstep,
    new_hermite_maps,
    new_hermite_scratch,
)
from roughvib.solvers.adaptive.hermite_loop import NEWTON_KEPT as NEWTON_KEPT
from roughvib.solvers.adaptive.hermite_loop import force_rates as force_rates
from roughvib.solvers.adaptive.layout import (
    ADV_CHUNK,
    ADV_DONE,
    ADV_EVENT,
    ADV_MIN_STEP,
    ADV_NEWTON,
    ADV_STALL,
    B_CHAIN,
    B_NOW,
    G_START,
    I_BLOCKS,
    I_EXTRAP,
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
    N_D,
    N_DBUF,
    N_GBUF,
    N_IST,
    N_YBUF,
    NLEV,
    T_NOW,
)
from roughvib.solvers.adaptive.layout import D_AX as D_AX
from roughvib.solvers.adaptive.layout import D_AZ as D_AZ
from roughvib.solvers.adaptive.layout import D_POWER as D_POWER
from roughvib.solvers.adaptive.loop_common import latch_and_output
from roughvib.solvers.adaptive.propagators import SERIES_LIMIT as SERIES_LIMIT
from roughvib.solvers.adaptive.propagators import (
    fill_slot,
    moment_force,
    new_propagators,
    step_maps,
)
from roughvib.solvers.adaptive.propagators import modal_force as modal_force
from roughvib.solvers.adaptive.trapezoidal import derivatives as derivatives
from roughvib.solvers.adaptive.trapezoidal import forced_response as forced_response
from roughvib.solvers.adaptive.trapezoidal import free_response as free_response
from roughvib.solvers.adaptive.trapezoidal import implicit_step as implicit_step
from roughvib.solvers.adaptive.trapezoidal import new_scratch
from roughvib.solvers.adaptive.trapezoidal_loop import (
    TRAPEZOIDAL_FIRST_LEVEL,
    Buffers,
    advance,
)
from roughvib.solvers.base import (
    FIRST_ROW,
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

# The solver's compiled parts stay importable from here under the names the tests,
# benchmarks and docs use (several were private functions of this module before it was
# split into roughvib.solvers.adaptive). check_tolerances, hermite_applies, step_budget and
# write_checkpoint are called through this module, so that a caller can replace them here
# (the tests and benchmarks/bench_presets.py do).
_err_norm = err_norm
_extrapolate = extrapolate
_fill_slot = fill_slot
_hermite_fill = hermite_fill
_hstep = hstep
_latch_and_output = latch_and_output
_moment_force = moment_force

__all__ = ["hermite_applies", "solve_adaptive_modal", "step_maps"]


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


def hermite_applies(system: System) -> bool:
    """Whether the Hermite step covers the scene: the Feldmann law (not set-valued), a
    force-driven block, no friction moment."""
    off = system.off
    return bool(off[kn.OFF_IX] >= 0 and not kn.set_valued(off) and not kn.moment_on(off))


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
        Step with the fourth-order Hermite step (``advance_hermite``) or the second-order
        trapezoidal one (``advance``); default: the Hermite step where it applies
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
    y = Y[B_NOW]  # the current state, updated in place by advance
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
    if hermite:  # the fourth-order Hermite step (advance_hermite)
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
                code = advance_hermite(tt, ist, k_stop, grid, h_top, buf, maps, atol,
                                        scfg.rtol, outs, off, fpa, omega2, cdamp, phi, phiT,
                                        phi_obs, stiff, cres, spos, prof, reg, rf, scratch,
                                        track_latch, fresh, budget)
            else:
                code = advance(tt, ist, k_stop, grid, h_max, buf, maps, atol, scfg.rtol, outs,
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
