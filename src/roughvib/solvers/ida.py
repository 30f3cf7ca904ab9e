"""Event-driven SUNDIALS IDA solver (scikit-sundae): smooth segments + stop/switch/restart.

The DAE of :mod:`roughvib.model.kernels` is integrated with IDA (variable-order BDF) using a
sparse direct linear solver (SuperLU_MT) with an analytic CSC Jacobian. Every non-smooth
change is a root of a regime-dependent *margin* function (positive while the regime holds):
contact lift-off/touch-down, friction-law branch, hysteresis-latch flip, and stick/slip phase
starts. At a root the solver stops, the regime is switched, consistent (y, yp) are computed
(algebraic forces re-solved, yp = f(y)) and IDA is re-initialised at the event time. Output on
the uniform grid comes from IDA's own interpolation (``step(t_k)`` in normal mode).

Guards (docs/theory.md): a root that fires again within ``REFIRE_DT`` of the restart for the
same function is ignored once; more than ``solver.max_events`` events within
``solver.event_window`` stop the run with status ``event_storm``.

scikit-sundae pitfalls handled here: the eventsfn's event history is
cleared after every event; step counts are read through SUNDIALS' ``IDAGetNumSteps`` (not
exposed by sksundae; see ``_IdaCounters``, which checks the private layout before calling C,
:func:`layout_problem`); unknown return codes are caught.
"""

from __future__ import annotations

import ctypes
import glob
import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from roughvib.model import jacobian, krylov
from roughvib.model import kernels as kn
from roughvib.model.krylov import krylov_workspace
from roughvib.model.system import System
from roughvib.scene import SceneError
from roughvib.solvers.base import (
    FIRST_ROW,
    EventRun,
    RawSolution,
    RunProgress,
    atol_vector,
    check_tolerances,
    make_checkpoint,
    tolerance_floors,
)
from roughvib.solvers.checkpoint import Checkpoint, write_checkpoint
from roughvib.solvers.events import (
    EventRecord,
    SolverFailure,
    stall_failure,
    step_budget,
)

if TYPE_CHECKING:
    import scipy.sparse as sp

# scikit-sundae and scipy.sparse are imported where IDA runs. RawSolution, EventRecord and
# tolerance_floors live in solvers/base.py and solvers/events.py; this module still answers
# for them (simulation.py imports them from here). write_checkpoint and check_tolerances are
# called through this module's names, so that a caller can replace them here (the tests do).

__all__ = ["EventRecord", "RawSolution", "SolverFailure", "solve_ida", "tolerance_floors"]

# A root that fires within REFIRE_DT of the latest restart, for functions switched at that
# instant, is round-off: contacts in phase reach their margins together, IDA places their roots
# up to ~1e-16 s apart, and over such times a margin is of the size of its own round-off
# (~1e-19 m), so a contact just closed can read as penetrating by -1e-19 m and fire back. A
# physical reversal takes a good part of the model's fastest period, that of a mode at
# plate.max_frequency (2e-5 s at 50 kHz), far beyond 1e-12 s, so such a refire is ignored once.
REFIRE_DT = 1e-12  # s
JAC_COUNT = 0  # the one entry of the Jacobian counter box
# IDA restarts at order 1; its default first step (~1e-3 of the distance to the next output
# time, 1e-8 s here) takes ~10 step doublings and as many Jacobian factorizations to grow back.
# Starting at 1e-2 of the last step cut that by a third at unchanged accuracy on the paper
# scene (499 forced restarts in 0.05 s: 5036 -> 3379 Jacobians, 7.5 -> 5.2 s, energy audit and
# band errors unchanged); 5e-2 was faster still but doubled the energy-audit residual, and the
# last step itself (fraction 1) degraded the plate bands by 1 dB (benchmarks/bench_restart.py).
# It is capped at the same fraction of the output step: after a free flight (an exact parabola)
# BDF's last step is huge, and restarting a touch-down with it failed the error test 10 times.
RESTART_STEP_FRACTION = 0.01
# Stall guard on the Jacobians of one step() call: at most step_budget / this many. A healthy
# interval needs a few (restarts add ~10 each); the stalled runs (a huge block mass)
# refactorised at every step, at ~5 ms per factorisation.
JACOBIANS_PER_STEP_BUDGET = 40


class _JacobianBudget(Exception):
    """Raised inside the Jacobian callback to abort a stalled IDASolve call."""


#: the scikit-sundae versions whose private layout ``_IdaCounters`` was checked against (the
#: dependency is pinned to this range in pyproject.toml)
SKSUNDAE_TESTED = ("1.2.",)
#: ``tp_basicsize`` of ``sksundae._cy_ida.IDA`` in those versions [bytes]
_CY_IDA_BASICSIZE = 144
#: byte offsets in that object: Cython's vtable pointer right after the object header, then
#: the first attribute of the class, ``cdef void* mem`` (the IDA memory)
_VTAB_OFFSET = 16
_MEM_OFFSET = 24


def layout_problem(cy_solver) -> str | None:
    """Why the IDA memory pointer cannot be read from scikit-sundae's Cython solver object
    (None: it can).

    scikit-sundae exposes only the residual and Jacobian counts (``IDAResult.nfev``,
    ``njev``); the step statistics, the last step size and ``IDASetInitStep`` are reached
    through the SUNDIALS C API on the object's private ``mem`` pointer. Before anything calls
    C on it, this checks, without calling C: the installed version is in
    :data:`SKSUNDAE_TESTED`; the object is a ``sksundae._cy_ida.IDA`` of the known size; the
    shipped Cython source declares ``mem`` as the class's first attribute; the word at the
    vtable offset is the class's own vtable (so the header and offsets are as expected); and
    the pointer is set.

    Parameters
    ----------
    cy_solver : object
        The Cython solver held by ``sksundae.ida.IDA``, after ``init_step``.

    Returns
    -------
    str or None
        One line naming the first check that failed.
    """
    try:
        import sksundae as sun
        from sksundae import _cy_ida
    except ImportError as exc:  # pragma: no cover - IDA runs only with sksundae
        return f"scikit-sundae cannot be imported ({exc})"
    version = getattr(sun, "__version__", "?")
    if not version.startswith(SKSUNDAE_TESTED):
        return (f"scikit-sundae {version} is not a tested version "
                f"({', '.join(v + 'x' for v in SKSUNDAE_TESTED)})")
    if type(cy_solver) is not _cy_ida.IDA:
        return f"the solver object is a {type(cy_solver).__name__}, not sksundae._cy_ida.IDA"
    size = type(cy_solver).__basicsize__
    if size != _CY_IDA_BASICSIZE:
        return f"sksundae._cy_ida.IDA has {size} bytes, not {_CY_IDA_BASICSIZE}"
    pyx = Path(_cy_ida.__file__).with_name("_cy_ida.pyx")
    try:
        _, found, body = pyx.read_text().partition("cdef class IDA:")
    except OSError:
        found = ""
    if not found:
        return f"{pyx.name} (the source that fixes the layout) is not installed"
    first = next((ln.split("#")[0].split() for ln in body.splitlines()
                  if ln.strip().startswith("cdef ")), [])
    if first != ["cdef", "void*", "mem"]:
        return f"the first attribute of IDA in {pyx.name} is {' '.join(first)!r}, not mem"
    capsule = type(cy_solver).__dict__.get("__pyx_vtable__")
    if capsule is None:
        return "sksundae._cy_ida.IDA has no Cython vtable"
    get = ctypes.pythonapi.PyCapsule_GetPointer
    get.restype = ctypes.c_void_p
    get.argtypes = [ctypes.py_object, ctypes.c_char_p]
    vtab = get(capsule, None)
    if ctypes.c_void_p.from_address(id(cy_solver) + _VTAB_OFFSET).value != vtab:
        return "the object's vtable pointer is not at the expected offset"
    if not ctypes.c_void_p.from_address(id(cy_solver) + _MEM_OFFSET).value:
        return "the IDA memory pointer is not set (init_step not called?)"
    return None


class _IdaCounters:
    """Read IDA's step statistics and last step, and set the first step, through the
    SUNDIALS C API.

    scikit-sundae (1.2) exposes neither (only ``nfev`` and ``njev``). The IDA memory pointer
    is read from the Cython object at a fixed offset once :func:`layout_problem` finds the
    layout as tested, and is further validated by comparing ``IDAGetNumResEvals`` through it
    with sksundae's own ``nfev`` (or IDA's current time with t0). If a check fails, no C
    function is called on the pointer: the statistics are reported as unavailable rather than
    wrong, restarts use IDA's own first step, and ``problem`` says why (the run warns once).
    """

    OFFSET = _MEM_OFFSET

    def __init__(self, cy_solver) -> None:
        self.ok = False
        self._mem = None
        self._lib = None
        self.problem = layout_problem(cy_solver)
        if self.problem is not None:
            return
        try:
            import sksundae as sun

            libdir = os.path.join(os.path.dirname(os.path.dirname(sun.__file__)),
                                  "scikit_sundae.libs")
            cands = glob.glob(os.path.join(libdir, "libsundials_ida*.so*"))
            if not cands:
                self.problem = f"no libsundials_ida in {libdir}"
                return
            self._lib = ctypes.CDLL(cands[0])
            self._mem = ctypes.c_void_p.from_address(id(cy_solver) + self.OFFSET).value
        except Exception as exc:  # noqa: BLE001 - diagnostics only, never fatal
            self._lib = None
            self.problem = f"the SUNDIALS library cannot be loaded ({exc})"

    def validate(self, nfev: int) -> None:
        if self._lib is None or not self._mem:
            return
        self.ok = self._get("IDAGetNumResEvals") == nfev

    def _get(self, name: str) -> int:
        val = ctypes.c_long(0)
        fn = getattr(self._lib, name)
        fn.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_long)]
        fn.restype = ctypes.c_int
        if fn(self._mem, ctypes.byref(val)) != 0:
            return -1
        return int(val.value)

    def steps(self) -> int | None:
        return self._get("IDAGetNumSteps") if self.ok else None

    def validate_time(self, t0: float) -> None:
        """Validate the pointer right after ``init_step(t0)`` (before any step): IDA's current
        time must be t0 exactly and no residual evaluated yet."""
        if self._lib is None or not self._mem:
            return
        val = ctypes.c_double(float("nan"))
        fn = self._lib.IDAGetCurrentTime
        fn.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_double)]
        fn.restype = ctypes.c_int
        self.ok = (fn(self._mem, ctypes.byref(val)) == 0 and val.value == t0
                   and self._get("IDAGetNumResEvals") == 0)

    def last_step(self) -> float:
        """Size of the last successful step [s] (0 when unknown)."""
        if not self.ok:
            return 0.0
        val = ctypes.c_double(0.0)
        fn = self._lib.IDAGetLastStep
        fn.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_double)]
        fn.restype = ctypes.c_int
        return float(val.value) if fn(self._mem, ctypes.byref(val)) == 0 else 0.0

    def set_init_step(self, h: float) -> None:
        """First step after the next (re)initialisation [s] (``IDASetInitStep``)."""
        if self.ok and h > 0:
            fn = self._lib.IDASetInitStep
            fn.argtypes = [ctypes.c_void_p, ctypes.c_double]
            fn.restype = ctypes.c_int
            fn(self._mem, h)

    def error_test_failures(self) -> int | None:
        return self._get("IDAGetNumErrTestFails") if self.ok else None

    def nonlinear_conv_failures(self) -> int | None:
        return self._get("IDAGetNumNonlinSolvConvFails") if self.ok else None

    def count(self, name: str) -> int | None:
        """Any ``IDAGetNum*`` counter by its C name (None when unavailable)."""
        return self._get(name) if self.ok else None


def _sparsity(system: System) -> tuple[sp.csc_matrix, np.ndarray]:
    import scipy.sparse as sp

    rows, cols = system.jacobian_pattern()  # refuses duplicate entries
    n = system.layout.size
    nnz = rows.size
    order = sp.coo_matrix((np.arange(1, nnz + 1, dtype=float), (rows, cols)), shape=(n, n))
    csc = order.tocsc()
    csc.sort_indices()
    perm = (csc.data.astype(np.int64) - 1)
    pattern = sp.csc_matrix((np.ones(nnz), csc.indices.copy(), csc.indptr.copy()), shape=(n, n))
    return pattern, perm


_IDA_HINTS = {
    -3: "the error test failed down to the minimum step: a discontinuity the event functions "
        "do not see, or a grazing contact; try a tighter solver.rtol or a smaller "
        "solver.max_step, and check the event log's last entries",
    -4: "Newton failed to converge: the contact or friction regime may be inconsistent with "
        "the state (look at the last events), or contact.stiffness is extreme; try a smaller "
        "solver.max_step",
    0: "tighten solver.rtol, limit solver.max_step, or run the fixed-step 'exact-modal' "
       "scheme to see whether the scene itself is ill-posed",
}


def _closest_contact(t: float, y: np.ndarray, n_contacts: int, ev_args: tuple) -> str:
    """'; contact k closest to switching' from the contact margins at the failure."""
    if n_contacts == 0:
        return ""
    buf = np.empty(n_contacts + kn.N_LAW_ROOTS)
    try:
        kn.events(t, np.asarray(y, dtype=float), buf, *ev_args)
    except Exception:  # noqa: BLE001 - diagnostics only, never mask the failure itself
        return ""
    k = int(np.argmin(np.abs(buf[:n_contacts])))
    return f"; contact {k} is closest to switching (margin {buf[k]:.3g})"


def _krylov_options(system: System, args: tuple) -> dict:
    """IDA options of the matrix-free path: GMRES(1) + exact preconditioner + analytic Jv.

    Both callbacks evaluate the Newton matrix at IDA's current iterate, so the preconditioned
    system is the identity and one Krylov iteration solves it.
    """
    import sksundae as sun

    (off, fpa, omega2, cdamp, phi, _phi_obs, stiff, cres, spos, prof, reg, _rf, work) = args
    ws = krylov_workspace(system.layout.size, system.n_modes, system.n_contacts)
    pwork = np.zeros_like(work)  # keeps the factorised iterate's compressions between calls
    jac_vec = krylov.jac_vec
    precond_solve = krylov.precond_solve

    def psolve(t, yy, yyp, res, rv, zv, cj, delta):
        precond_solve(t, yy, cj, rv, zv, off, fpa, omega2, cdamp, phi, stiff, cres, spos, prof,
                      reg, pwork, *ws)

    def jv(t, yy, yyp, res, v, out, cj):
        jac_vec(t, yy, cj, v, out, off, fpa, omega2, cdamp, phi, stiff, cres, spos, prof, reg,
                work)

    return dict(linsolver="gmres", krylov_dim=1, precond=sun.ida.IDAPrecond(None, psolve),
                jactimes=sun.ida.IDAJacTimes(None, jv))


def solve_ida(system: System, *, progress: bool | None = None,
              checkpoint_dir: str | os.PathLike | None = None,
              resume: Checkpoint | None = None) -> RawSolution:
    """Integrate a system over ``scene.output.duration`` with event-driven IDA.

    Parameters
    ----------
    system : System
        From :func:`roughvib.model.system.assemble`.
    progress : bool, optional
        Progress bar on stderr (default: scene.output.progress).
    checkpoint_dir : path, optional
        Where ``checkpoint.pkl`` is written every ``output.checkpoint_interval`` of simulated
        time (nothing is written when the interval is 0 or this is None; IDA is restarted at
        each checkpoint time either way, so runs with and without a directory agree).
    resume : Checkpoint, optional
        Continue from this checkpoint (of the same scene) instead of starting at t = 0.

    Returns
    -------
    RawSolution
        Grid outputs, event log, statistics; ``status`` is ``"success"`` or the failure cause
        (then the outputs end where the integration stopped).
    """
    return _IdaRun(system, progress, checkpoint_dir, resume).run()


class _Callbacks(NamedTuple):
    resfn: Callable
    jacfn: Callable
    eventsfn: Callable
    pattern: sp.csc_matrix  # the Jacobian's sparsity


def _callbacks(system: System, args: tuple, ev_args: tuple, jac_budget: int,
               jac_count: list[int]) -> _Callbacks:
    """IDA's residual, sparse Jacobian and event callbacks on the kernels' arrays ``args``
    and ``ev_args``, and the Jacobian's sparsity pattern.

    The Jacobian callback counts its calls in ``jac_count[JAC_COUNT]`` and raises
    :class:`_JacobianBudget` beyond ``jac_budget`` (the caller resets the count before each
    IDA call).
    """
    (off, fpa, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, reg, rf, work) = args
    pattern, perm = _sparsity(system)
    vals = np.zeros(perm.size)
    residual = kn.residual
    jacobian_values = jacobian.jacobian_values
    scatter = kn.scatter
    events_k = kn.events

    def resfn(t, yy, yyp, res):
        residual(t, yy, yyp, res, off, fpa, omega2, cdamp, phi, phi_obs, stiff, cres, spos,
                 prof, reg, rf, work)

    def jacfn(t, yy, yyp, res, cj, jj):
        jac_count[JAC_COUNT] += 1
        if jac_count[JAC_COUNT] > jac_budget:  # aborts this IDASolve call (stall guard)
            raise _JacobianBudget
        jacobian_values(t, yy, yyp, cj, vals, off, fpa, omega2, cdamp, phi, phi_obs, stiff,
                        cres, spos, prof, reg, rf, work)
        scatter(vals, perm, jj)

    def eventsfn(t, yy, yyp, ev):
        events_k(t, yy, ev, *ev_args)

    n_ev = system.n_contacts + kn.N_LAW_ROOTS
    eventsfn.direction = [-1] * n_ev
    eventsfn.terminal = [True] * n_ev
    return _Callbacks(resfn, jacfn, eventsfn, pattern)


def _new_solver(system: System, args: tuple, callbacks: _Callbacks, budget: int):
    """scikit-sundae's IDA on the callbacks of :func:`_callbacks`, with the scene's
    tolerances, limits and linear solver (``budget``: steps per output interval)."""
    import sksundae as sun

    resfn, jacfn, eventsfn, pattern = callbacks
    scfg = system.scene.solver
    options = dict(
        rtol=scfg.rtol, atol=atol_vector(system), algebraic_idx=system.layout.algebraic_indices,
        eventsfn=eventsfn, num_events=len(eventsfn.direction), max_num_steps=budget,
        max_step=scfg.max_step, max_order=scfg.max_order,
    )
    if scfg.linear_solver == "gmres":
        if system.tangential and kn.dynamic(system.off):  # the registry refuses it at load
            raise SceneError("solver.linear_solver = 'gmres': the Krylov preconditioner does "
                             "not eliminate a dynamic friction law's state; use 'sparse'")
        options.update(_krylov_options(system, args))
    else:
        options.update(linsolver="sparse", sparsity=pattern, jacfn=jacfn)
    with warnings.catch_warnings():
        # sksundae warns that its own sparse FD Jacobian is unused: we pass an analytic one
        warnings.filterwarnings("ignore", message="Custom sparse Jacobian approximation")
        return sun.ida.IDA(resfn, **options)


class _IdaRun(EventRun):
    """One run of :func:`solve_ida`: the IDA solver, its callbacks and the event loop's state.

    The loop asks IDA for the next output time, one call at a time (:meth:`_next_row`); a
    root stops it at an event (:meth:`_event`: switch, consistent restart), an output time
    writes its row (:meth:`_row`) and, at a checkpoint row, restarts IDA there
    (:meth:`_checkpoint_restart`). The counts of each IDA segment (from one
    (re)initialisation to the next) are added when it closes (:meth:`_close_segment`).
    """

    def __init__(self, system: System, progress: bool | None,
                 checkpoint_dir: str | os.PathLike | None, resume: Checkpoint | None) -> None:
        super().__init__(system, checkpoint_dir, resume)
        out_cfg = system.scene.output
        t_start, k_start = self.t_start, self.k_start
        self.y, self.yp = system.consistent(t_start, self.y_start, self.reg, self.rf)
        check_tolerances(system, self.y_initial)

        self.ev_args = system.event_args(self.reg, self.rf)
        self.budget = step_budget(out_cfg.step)
        self.jac_budget = self.budget // JACOBIANS_PER_STEP_BUDGET
        self.jac_count = [0]  # Jacobians within the current step() call
        callbacks = _callbacks(system, self.args, self.ev_args, self.jac_budget, self.jac_count)
        self.eventsfn = callbacks.eventsfn
        self.solver = _new_solver(system, self.args, callbacks, self.budget)
        self.solver.init_step(t_start, self.y, self.yp)
        # the Cython object behind the public solver, only to read IDA's statistics through
        # the C API (docs/architecture.md, Conventions); _IdaCounters checks its layout first
        self.counters = _IdaCounters(vars(self.solver).get("_IDA__IDA"))
        if self.counters.problem is not None:
            warnings.warn(f"IDA step statistics unavailable and restarts use IDA's own first "
                          f"step: {self.counters.problem}", RuntimeWarning, stacklevel=3)
        self.h_restart = 0.0  # first step after the latest restart [s] (0: IDA's own estimate)
        self.h_restart_cap = RESTART_STEP_FRACTION * out_cfg.step
        # validated before the first step too, so that a failure inside the first IDA call
        # (the Jacobian guard) still reports IDA's counts
        self.counters.validate_time(t_start)
        if resume is not None and resume.loop.get("h_restart", 0.0) > 0:
            self.h_restart = float(resume.loop["h_restart"])
            self.counters.set_init_step(self.h_restart)

        self._start_loop(resume)
        if resume is None:
            kn.outputs(0.0, self.y, self.outs[FIRST_ROW], *self.args)
        self.progress = RunProgress(system, progress, t_start, k_start, max(1, self.n // 200))
        self.vx_i = system.layout.index("block.vx")
        self.first_result = True
        if resume is None:
            self.book.log_initial_phase(0.0, self.y)
        self.k = k_start
        self.r = None  # IDA's latest result in the open segment (None: none yet)

    def _start_loop(self, resume: Checkpoint | None) -> None:
        """The event loop's bookkeeping, new or from the checkpoint, and the run's clock."""
        self.t_last_restart = 0.0
        self.last_fired: set[int] = set()
        self.refire_ignored = 0
        if resume is not None:
            self.t_last_restart = float(resume.loop["t_last_restart"])
            self.last_fired = set(resume.loop["last_fired"])
            self.refire_ignored = int(resume.loop["refire_ignored"])
        self._event_book(resume)
        self.clock.start()

    def run(self) -> RawSolution:
        """Integrate to the end of the grid (or a failure) and return the solution."""
        status, message = "success", "reached the end of the output grid"
        try:
            while self.k < self.n:
                self._next_row()
            if self.r is not None:
                self._close_segment(self.r)
                if self.r.status != 2:
                    self.y = np.array(self.r.y, dtype=float)
        except SolverFailure as exc:
            status, message = exc.status, str(exc)
            self._close_segment(self.r)  # r None: the failure came inside the segment's first call
        finally:
            self.progress.close()
        return self._solution(status, message)

    def _next_row(self) -> None:
        """One IDA call towards the next output time, and what its result asks for."""
        k, grid = self.k, self.grid
        self.jac_count[JAC_COUNT] = 0
        try:
            r = self.solver.step(grid[k], "normal", None)
        except KeyError as exc:  # unknown IDA return code (scikit-sundae has no name for it)
            raise SolverFailure("ida_error", f"IDA returned unknown flag {exc} near "
                                f"t = {grid[k - 1]:.6g} s", grid[k - 1]) from None
        except _JacobianBudget:
            raise stall_failure("ida", grid[k - 1], f"more than {self.jac_budget} Jacobians",
                                self.regime.describe()) from None
        self.r = r
        if self.first_result:
            self.counters.validate(int(r.nfev))
            self.first_result = False
        if r.status == 2:
            self._event(r)
            return
        if r.status == -1:  # max_num_steps within this output interval
            raise stall_failure("ida", grid[k - 1], f"more than {self.budget} steps",
                                self.regime.describe())
        if r.status < 0:
            # r.y keeps IDA's last accepted state
            near = _closest_contact(grid[k - 1], r.y, self.system.n_contacts, self.ev_args)
            raise SolverFailure(
                "ida_error", f"IDA failed at t = {grid[k - 1]:.6g} s with flag {r.status}: "
                f"{r.message} (regime {self.regime.describe()}{near}). "
                f"Hint: {_IDA_HINTS.get(r.status, _IDA_HINTS[0])}", grid[k - 1])
        self._row(r)

    def _event(self, r) -> None:
        """A root stopped IDA: switch the regime and restart there (unless it is the refire
        of a root just switched, which is ignored once)."""
        te = float(r.t)
        row = np.asarray(r.i_events)[-1]
        fired = {int(i) for i in np.flatnonzero(row)}
        eventsfn = self.eventsfn
        for a in ("_i", "_t", "_y", "_yp"):
            getattr(eventsfn, a).clear()
        eventsfn._i_cnt[:] = 0
        same_instant = te - self.t_last_restart <= REFIRE_DT * max(1.0, te)
        if same_instant and fired <= self.last_fired:
            self.refire_ignored += 1
            self.last_fired = set()
            return
        self._close_segment(r)
        self.r = None  # closed; a later failure adds what follows
        y, yp = self.y, self.yp = self.book.apply(te, np.asarray(r.y, dtype=float), fired)
        # first step after the restart: RESTART_STEP_FRACTION of the last step
        self.h_restart = min(RESTART_STEP_FRACTION * self.counters.last_step(),
                             self.h_restart_cap)
        self.solver.init_step(te, y, yp)
        self.counters.set_init_step(self.h_restart)
        # one instant may take several restarts (IDA reports simultaneous roots up to
        # ~1e-16 s apart): the functions switched at any of them count as just switched
        if same_instant:
            self.last_fired = self.last_fired | self.book.switched
        else:
            self.last_fired = set(self.book.switched)
        self.t_last_restart = te
        grid, k = self.grid, self.k
        while k < self.n and grid[k] - te <= 1e-12 * max(1.0, te):
            kn.outputs(grid[k], y, self.outs[k], *self.args)
            k += 1
        self.k = k

    def _row(self, r) -> None:
        """IDA reached the next output time: write its row, follow the latch's velocity
        extremum, show the progress and, at a checkpoint row, restart there."""
        k, grid, rf, regime = self.k, self.grid, self.rf, self.regime
        yk = r.y
        kn.outputs(grid[k], yk, self.outs[k], *self.args)
        if self.vx_i >= 0 and not self.system.set_valued:
            regime.v_ext = float(kn.follow_latch_extremum(yk[self.vx_i], self.reg, rf))
        self.progress.show(k, grid[k])
        self.k = k = k + 1
        if self.cp_stride and (k - 1) % self.cp_stride == 0 and k < self.n:
            self._checkpoint_restart(r, yk)

    def _checkpoint_restart(self, r, yk) -> None:
        """Restart IDA at the checkpoint time from a consistent state, exactly as a resumed run
        does, so that both continue bit-identically (and write the checkpoint when a
        directory is given)."""
        self._close_segment(r)
        k = self.k
        t_cp = float(self.grid[k - 1])
        y_cp = np.array(yk, dtype=float)
        self.t_last_restart = t_cp
        self.last_fired = set()
        self.h_restart = min(RESTART_STEP_FRACTION * self.counters.last_step(),
                             self.h_restart_cap)
        self.book.stats["checkpoints"] += 1
        if self.scene_toml:
            self._write_checkpoint(k, t_cp, y_cp)
        self.y, self.yp = self.system.consistent(t_cp, y_cp, self.reg, self.rf)
        self.solver.init_step(t_cp, self.y, self.yp)
        self.counters.set_init_step(self.h_restart)
        self.r = None

    def _write_checkpoint(self, k_next: int, t_cp: float, y_cp: np.ndarray) -> None:
        st = dict(self.book.stats)
        st.update(self.clock.times())
        st["refires_ignored"] = self.refire_ignored
        loop = {"recent": list(self.book.recent), "t_last_restart": self.t_last_restart,
                "last_fired": sorted(self.last_fired), "refire_ignored": self.refire_ignored,
                "h_restart": self.h_restart}
        write_checkpoint(self.checkpoint_dir, make_checkpoint(
            self.system, self.scene_toml, t=t_cp, k=k_next, y=y_cp, y_initial=self.y_initial,
            outputs=self.outs, reg=self.reg, rf=self.rf, regime=self.regime,
            events=self.book.events, stats=st, loop=loop, ida=True))

    def _close_segment(self, r) -> None:
        """Add the counts of the IDA segment since the latest (re)initialisation; ``r`` is its
        latest result, or None when the segment failed inside its first call (then IDA's own
        counters give the evaluations, where they are validated)."""
        stats, counters = self.book.stats, self.counters
        if r is not None:
            stats["residual_evaluations"] += int(r.nfev)
            stats["jacobian_evaluations"] += int(r.njev)
        elif counters.ok:
            stats["residual_evaluations"] += counters.count("IDAGetNumResEvals") or 0
            stats["jacobian_evaluations"] += counters.count("IDAGetNumJacEvals") or 0
        s = counters.steps()
        if s is not None:
            stats["steps"] += s
            stats["error_test_failures"] += counters.error_test_failures() or 0
            stats["nonlinear_convergence_failures"] += counters.nonlinear_conv_failures() or 0
            stats["nonlinear_iterations"] += counters.count("IDAGetNumNonlinSolvIters") or 0
            if self.system.scene.solver.linear_solver == "gmres":
                stats["linear_iterations"] += counters.count("IDAGetNumLinIters") or 0
                stats["linear_convergence_failures"] += \
                    counters.count("IDAGetNumLinConvFails") or 0

    def _solution(self, status: str, message: str) -> RawSolution:
        stats = dict(self.book.stats)
        stats.update(self.clock.times())
        stats["refires_ignored"] = self.refire_ignored
        stats["events_total"] = len(self.book.events)
        if not self.counters.ok:
            stats["steps"] = None
            why = self.counters.problem or "IDA's counters could not be validated"
            stats["note"] = f"step counts unavailable ({why})"
        k = self.k
        t_final = float(self.grid[k - 1]) if k > 0 else 0.0
        return RawSolution(time=self.grid, outputs=self.outs, events=self.book.events,
                           stats=stats, status=status, message=message,
                           y_initial=self.y_initial, y_final=np.asarray(self.y, dtype=float),
                           t_final=t_final, extra={"rows_filled": k})
