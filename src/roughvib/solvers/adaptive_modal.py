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

Friction: every law of ``roughvib.physics.friction.LAWS`` (or prescribed motion). The
Feldmann law is a smooth function of the velocity in each branch. A set-valued law
(``coulomb``, ``table``) slides with its kinetic curve and its exact slope in the Newton row
of the velocity; in its stick regime the block is held (v = 0, x fixed, no tangential unknown)
and the friction force is the algebraic ``friction.force`` that holds it. Break-away, velocity
zero and the guards' timers are the roots of :func:`roughvib.model.kernels.events`, switched by
the same :class:`~roughvib.solvers.events.EventBook` as IDA's.

Limits: underdamped modes (plate loss factor < 2).
"""

from __future__ import annotations

import os

import numpy as np

from roughvib.model import kernels as kn
from roughvib.model.system import System
from roughvib.physics.friction import LAWS
from roughvib.scene import SceneError
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
    EventRun,
    RawSolution,
    RunProgress,
    atol_vector,
    check_tolerances,
    make_checkpoint,
)
from roughvib.solvers.checkpoint import Checkpoint, write_checkpoint
from roughvib.solvers.events import SolverFailure, stall_failure, step_budget

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
    """Whether the Hermite step covers the scene: a single-valued law (the Feldmann law; not
    set-valued, not dynamic), a force-driven block, no friction moment."""
    off = system.off
    return bool(off[kn.OFF_IX] >= 0 and not kn.set_valued(off) and not kn.dynamic(off)
                and not kn.moment_on(off))


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
        Step with the fourth-order Hermite step (:func:`.adaptive.hermite_loop.advance_hermite`)
        or the second-order trapezoidal one (:func:`.adaptive.trapezoidal_loop.advance`);
        default: the Hermite step where it applies (:func:`hermite_applies`). True where it
        does not apply is an error.

    Returns
    -------
    RawSolution
        Grid outputs (the states at the output times, which are step boundaries), event log,
        statistics; ``status`` is ``"success"`` or the failure cause.
    """
    _check_scene(system)
    return _AdaptiveRun(system, progress, checkpoint_dir, resume, hermite).run()


def _largest_step(output_step: float, max_step: float) -> float:
    """The trapezoidal loop's largest step [s]: the output step, halved until it is within
    ``solver.max_step`` (0: no limit)."""
    h_max = output_step
    if max_step > 0:
        while h_max > max_step * (1 + 1e-12):
            h_max *= 0.5
    return h_max


class _AdaptiveRun(EventRun):
    """One run of :func:`solve_adaptive_modal`: the loop's arrays and the Python side of it.

    The compiled loop (:func:`.adaptive.hermite_loop.advance_hermite` or
    :func:`.adaptive.trapezoidal_loop.advance`) returns every ``chunk`` output rows, at a
    checkpoint row, at an event and at the end (:meth:`run`); this switches the regime at
    events, writes checkpoints, shows the progress and turns a failure code into a
    :class:`SolverFailure` (:meth:`_fail`).
    """

    def __init__(self, system: System, progress: bool | None,
                 checkpoint_dir: str | os.PathLike | None, resume: Checkpoint | None,
                 hermite: bool | None) -> None:
        if hermite is None:
            hermite = hermite_applies(system)
        elif hermite and not hermite_applies(system):
            raise ValueError("the Hermite step covers the Feldmann law with a force-driven "
                             "block and no friction moment only")
        self.hermite = hermite
        # a checkpoint row ends a block of the Hermite loop
        super().__init__(system, checkpoint_dir, resume, PAIR_ROWS if hermite else 1)
        scene = system.scene
        out_cfg = scene.output
        self.h_max = _largest_step(out_cfg.step, scene.solver.max_step)
        self.h_top = hermite_top_pair(out_cfg.step, scene.solver.max_step)
        check_tolerances(system, self.y_initial)
        self._allocate(self.y_start)
        self.atol = atol_vector(system)
        self.tt = np.zeros(1)
        self.track_latch = bool(system.layout.tangential)
        self.budget = step_budget(out_cfg.step)
        self._start(resume)
        self.progress = RunProgress(system, progress, self.t_start, 0)
        self.chunk = max(1, self.n // 50)  # returns to Python (progress, checkpoints): ~0.1 ms
        self.clock.start()

    def _allocate(self, y0: np.ndarray) -> None:
        """The loop's buffers, map cache and scratch, the current state y0 in ``Y[B_NOW]``
        (``self.y``, updated in place by the loop)."""
        system = self.system
        K, R, nst = system.n_contacts, system.n_modes, system.layout.size
        n_ev = K + kn.N_LAW_ROOTS
        work = self.args[-1]
        # a block's kept steps from B_CHAIN: PAIR_ROWS - 2 beyond B_HALF and B_END
        Y = np.zeros((max(N_YBUF, B_CHAIN + PAIR_ROWS - 2) if self.hermite else N_YBUF, nst))
        Y[B_NOW] = y0
        self.y = Y[B_NOW]
        G = np.zeros((N_GBUF, n_ev))
        armed = np.zeros(n_ev, dtype=np.int64)
        fired = np.zeros(n_ev, dtype=np.int64)
        if self.hermite:  # the fourth-order Hermite step (advance_hermite)
            DF = np.zeros((Y.shape[0], K))
            C = np.zeros((Y.shape[0], hm.carry_size(R, K)))
            self.maps = new_hermite_maps(R, K)
            self.buf = HermiteBuffers(Y, DF, C, G, armed, fired)
            self.scratch = new_hermite_scratch(work, R, K)
        else:
            D = np.zeros((N_DBUF, N_D))
            U = np.zeros((N_DBUF, R))
            self.maps = new_propagators(R, K, bool(kn.moment_on(system.off)))
            self.buf = Buffers(Y, D, U, G, armed, fired)
            self.scratch = new_scratch(work, R, K)
        self.phiT = np.ascontiguousarray(system.phi.T)
        self.ist = np.zeros(N_IST, dtype=np.int64)

    def _start(self, resume: Checkpoint | None) -> None:
        """The loop state at the start, or the checkpoint's; the event book and the clock."""
        self._event_book(resume)
        ist, buf = self.ist, self.buf
        if resume is None:
            kn.outputs(0.0, self.y, self.outs[FIRST_ROW], *self.args)
            ist[I_K] = 1
            # the first step h_max / 256 (the Hermite loop: its first full step about as long)
            ist[I_LEV] = HERMITE_FIRST_LEVEL if self.hermite else TRAPEZOIDAL_FIRST_LEVEL
            self.book.log_initial_phase(0.0, self.y)
            self.fresh = True
            return
        loop = resume.loop
        ist[:] = loop["ist"]
        self.tt[T_NOW] = resume.t
        if self.hermite:
            buf.DF[B_NOW] = loop["dF"]
            buf.C[B_NOW] = loop["c"]
            self.scratch.ws[:] = loop["ws"]
            self.scratch.iws[:] = loop["iws"]
            self.scratch.hjac[:] = loop["hjac"]
        else:
            buf.D[B_NOW] = loop["d"]
            buf.U[B_NOW] = loop["u"]
        buf.G[G_START] = loop["g"]
        buf.armed[:] = loop["armed"]
        self.fresh = False  # the loop continues exactly where the checkpointed run was

    def run(self) -> RawSolution:
        """Integrate to the end of the grid (or a failure) and return the solution."""
        ist, n, cp_stride = self.ist, self.n, self.cp_stride
        status, message = "success", "reached the end of the output grid"
        try:
            while True:
                k_stop = min(n, int(ist[I_K]) + self.chunk)
                if cp_stride:  # stop at the next checkpoint row (rows j, j % cp_stride == 0)
                    k_stop = min(k_stop, (int(ist[I_K]) - 1) // cp_stride * cp_stride
                                 + cp_stride + 1)
                code = self._advance(k_stop)
                self.fresh = False
                self.regime.v_ext = float(self.rf[kn.RF_VEXT])
                self.progress.show(int(ist[I_K]), self.grid[min(int(ist[I_K]), n) - 1])
                if code == ADV_DONE:
                    break
                if code == ADV_CHUNK:
                    k = int(ist[I_K])
                    if cp_stride and (k - 1) % cp_stride == 0 and k < n:
                        self.book.stats["checkpoints"] += 1
                        if self.scene_toml:
                            self._write_checkpoint()
                    continue
                if code == ADV_EVENT:
                    te = float(self.tt[T_NOW])
                    fired = set(np.flatnonzero(self.buf.fired).tolist())
                    y_new, _ = self.book.apply(te, self.y, fired)
                    self.y[:] = y_new
                    self.fresh = True
                    continue
                self._fail(code)
        except SolverFailure as exc:
            status, message = exc.status, str(exc)
        finally:
            self.progress.close()
        return self._solution(status, message)

    def _advance(self, k_stop: int) -> int:
        """The compiled loop until output row ``k_stop``; its return code."""
        scfg = self.system.scene.solver
        (off, fpa, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, _reg, _rf,
         _work) = self.args
        reg, rf = self.reg, self.rf
        if self.hermite:
            return advance_hermite(self.tt, self.ist, k_stop, self.grid, self.h_top, self.buf,
                                   self.maps, self.atol, scfg.rtol, self.outs, off, fpa,
                                   omega2, cdamp, phi, self.phiT, phi_obs, stiff, cres, spos,
                                   prof, reg, rf, self.scratch, self.track_latch, self.fresh,
                                   self.budget)
        return advance(self.tt, self.ist, k_stop, self.grid, self.h_max, self.buf, self.maps,
                       self.atol, scfg.rtol, self.outs, off, fpa, omega2, cdamp, phi, self.phiT,
                       phi_obs, stiff, cres, spos, prof, reg, rf, self.scratch,
                       self.track_latch, self.fresh, self.budget)

    def _fail(self, code: int) -> None:
        """Raise the :class:`SolverFailure` of a failure code of the loop."""
        te = float(self.tt[T_NOW])
        where = f"t = {te:.6g} s (regime {self.regime.describe()})"
        if code == ADV_MIN_STEP:
            raise SolverFailure("step_underflow", f"adaptive-modal: step size underflow "
                                f"at {where}: the error test keeps failing below "
                                f"{self.h_max / 2**(NLEV - 1):.3g} s. Hint: loosen solver.rtol "
                                f"or check the scene for a discontinuity no event sees", te)
        if code == ADV_NEWTON:
            raise SolverFailure("newton_failure", f"adaptive-modal: Newton failed while "
                                f"locating an event at {where}", te)
        if code == ADV_STALL:
            raise stall_failure("adaptive-modal", te, f"more than {self.budget} step attempts",
                                self.regime.describe())
        raise SolverFailure("nonfinite", f"adaptive-modal: the state became non-finite at "
                            f"{where}", te)

    def _loop_state(self) -> dict:
        """Everything the step loop carries (and the Hermite step's kept Newton matrix), so
        that a resumed run is bit-identical."""
        buf, scratch = self.buf, self.scratch
        state = {"recent": list(self.book.recent), "ist": self.ist.copy(),
                 "g": buf.G[G_START].copy(), "armed": buf.armed.copy()}
        if self.hermite:
            state.update(dF=buf.DF[B_NOW].copy(), c=buf.C[B_NOW].copy(), ws=scratch.ws.copy(),
                         iws=scratch.iws.copy(), hjac=scratch.hjac.copy())
        else:
            state.update(d=buf.D[B_NOW].copy(), u=buf.U[B_NOW].copy())
        return state

    def _write_checkpoint(self) -> None:
        st = dict(self.book.stats)
        st.update(self.clock.times())
        write_checkpoint(self.checkpoint_dir, make_checkpoint(
            self.system, self.scene_toml, t=float(self.tt[T_NOW]), k=int(self.ist[I_K]),
            y=self.y, y_initial=self.y_initial, outputs=self.outs, reg=self.reg, rf=self.rf,
            regime=self.regime, events=self.book.events, stats=st, loop=self._loop_state()))

    def _solution(self, status: str, message: str) -> RawSolution:
        ist, book, hermite = self.ist, self.book, self.hermite
        stats = dict(book.stats)
        stats.update({
            "steps": int(ist[I_STEPS]), "rejected_steps": int(ist[I_REJECT]),
            "step_evaluations": int(ist[I_STEP_EVALS]),
            "root_evaluations": int(ist[I_ROOT_EVALS]),
            "propagator_evaluations": int(ist[I_MAPS]),
            "nonlinear_iterations": int(ist[I_NEWTON]),
            "nonlinear_convergence_failures": int(ist[I_NEWTON_FAIL]),
            "extrapolated_steps": int(ist[I_EXTRAP]),
            "residual_evaluations": None,
            "jacobian_evaluations": int(ist[I_JACS]) if hermite else None,
            "blocks": int(ist[I_BLOCKS]) if hermite else None,
            "restarts": int(book.stats.get("restarts", 0)),
            **self.clock.times(),
            "events_total": len(book.events),
            "largest_step": self.h_max,  # the largest kept step, of either loop
        })
        k_done = int(ist[I_K])
        t_final = float(self.grid[k_done - 1]) if status == "success" else float(self.tt[T_NOW])
        return RawSolution(time=self.grid, outputs=self.outs, events=book.events, stats=stats,
                           status=status, message=message, y_initial=self.y_initial,
                           y_final=np.asarray(self.y, dtype=float), t_final=t_final,
                           extra={"rows_filled": k_done})
