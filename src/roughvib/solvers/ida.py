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

import collections
import copy
import ctypes
import glob
import os
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from roughvib.model import kernels as kn
from roughvib.model import krylov
from roughvib.model.krylov import krylov_workspace
from roughvib.model.system import System
from roughvib.scene import scene_to_toml
from roughvib.solvers.base import (
    FIRST_ROW,
    RawSolution,
    atol_vector,
    check_tolerances,
    output_grid,
    progress_bar,
    tolerance_floors,
)
from roughvib.solvers.checkpoint import (
    Checkpoint,
    input_fingerprint,
    start_state,
    write_checkpoint,
)
from roughvib.solvers.events import (
    EventBook,
    EventRecord,
    SolverFailure,
    stall_failure,
    step_budget,
)

if TYPE_CHECKING:
    import scipy.sparse as sp

# scikit-sundae and scipy.sparse are imported where IDA runs. RawSolution, EventRecord and
# tolerance_floors live in solvers/base.py and solvers/events.py; this module still answers
# for them (simulation.py imports them from here). check_tolerances is called through this
# module's name, so that a caller can replace it here (the tests do).

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

    rows, cols = kn.jacobian_pattern(system.off)
    n = system.layout.size
    nnz = rows.size
    if len(set(zip(rows.tolist(), cols.tolist(), strict=True))) != nnz:
        raise AssertionError("duplicate Jacobian entries in the pattern")
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
    import sksundae as sun

    scene = system.scene
    out_cfg = scene.output
    scfg = scene.solver
    K = system.n_contacts
    lay = system.layout
    grid, outs = output_grid(system)
    n, n_out = outs.shape

    reg, rf = system.new_regime_arrays()
    regime, y, y_initial = start_state(system, reg, rf, resume, n, n_out)
    t_start, k_start = (0.0, 1) if resume is None else (float(resume.t), int(resume.k))
    if resume is not None:
        outs[:k_start] = resume.outputs
    y, yp = system.consistent(t_start, y, reg, rf)
    check_tolerances(system, y_initial)
    cp_interval = scene.output.checkpoint_interval
    # checkpoint times are grid indices (a multiple of the interval, rounded to the grid)
    cp_stride = max(1, int(round(cp_interval / out_cfg.step))) if cp_interval > 0 else 0
    scene_toml = scene_to_toml(scene) if cp_stride and checkpoint_dir is not None else ""

    args = system.kernel_args(reg, rf)
    ev_args = system.event_args(reg, rf)
    (off, fpa, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, _reg, _rf, work) = args
    pattern, perm = _sparsity(system)
    vals = np.zeros(perm.size)
    residual = kn.residual
    jacobian_values = kn.jacobian_values
    scatter = kn.scatter
    events_k = kn.events

    def resfn(t, yy, yyp, res):
        residual(t, yy, yyp, res, off, fpa, omega2, cdamp, phi, phi_obs, stiff, cres, spos,
                 prof, reg, rf, work)

    budget = step_budget(out_cfg.step)
    jac_budget = budget // JACOBIANS_PER_STEP_BUDGET
    jac_count = [0]  # Jacobians within the current step() call

    def jacfn(t, yy, yyp, res, cj, jj):
        jac_count[JAC_COUNT] += 1
        if jac_count[JAC_COUNT] > jac_budget:  # aborts this IDASolve call (stall guard)
            raise _JacobianBudget
        jacobian_values(t, yy, yyp, cj, vals, off, fpa, omega2, cdamp, phi, phi_obs, stiff,
                        cres, spos, prof, reg, rf, work)
        scatter(vals, perm, jj)

    def eventsfn(t, yy, yyp, ev):
        events_k(t, yy, ev, *ev_args)

    n_ev = K + kn.N_LAW_ROOTS
    eventsfn.direction = [-1] * n_ev
    eventsfn.terminal = [True] * n_ev

    options = dict(
        rtol=scfg.rtol, atol=atol_vector(system), algebraic_idx=lay.algebraic_indices,
        eventsfn=eventsfn, num_events=n_ev, max_num_steps=budget, max_step=scfg.max_step,
        max_order=scfg.max_order,
    )
    if scfg.linear_solver == "gmres":
        options.update(_krylov_options(system, args))
    else:
        options.update(linsolver="sparse", sparsity=pattern, jacfn=jacfn)
    with warnings.catch_warnings():
        # sksundae warns that its own sparse FD Jacobian is unused: we pass an analytic one
        warnings.filterwarnings("ignore", message="Custom sparse Jacobian approximation")
        solver = sun.ida.IDA(resfn, **options)
    solver.init_step(t_start, y, yp)
    # the Cython object behind the public solver, only to read IDA's statistics through the C
    # API (docs/architecture.md, Conventions); _IdaCounters checks its layout first
    counters = _IdaCounters(vars(solver).get("_IDA__IDA"))
    if counters.problem is not None:
        warnings.warn(f"IDA step statistics unavailable and restarts use IDA's own first step: "
                      f"{counters.problem}", RuntimeWarning, stacklevel=2)
    h_restart = 0.0  # first step after the latest restart [s] (0: IDA's own estimate)
    h_restart_cap = RESTART_STEP_FRACTION * out_cfg.step
    # validated before the first step too, so that a failure inside the first IDA call (the
    # Jacobian guard) still reports IDA's counts
    counters.validate_time(t_start)
    if resume is not None and resume.loop.get("h_restart", 0.0) > 0:
        h_restart = float(resume.loop["h_restart"])
        counters.set_init_step(h_restart)

    stats = collections.Counter()
    events: list[EventRecord] = []
    recent: collections.deque[float] = collections.deque()
    status, message = "success", "reached the end of the output grid"
    t_last_restart = 0.0
    last_fired: set[int] = set()
    refire_ignored = 0
    wall_before = cpu_before = 0.0
    if resume is not None:
        prev = dict(resume.stats)
        wall_before = float(prev.pop("wall_time", 0.0))
        cpu_before = float(prev.pop("cpu_time", 0.0))
        stats.update(prev)
        stats["resumes"] += 1
        events = list(resume.events)
        recent = collections.deque(resume.loop["recent"])
        t_last_restart = float(resume.loop["t_last_restart"])
        last_fired = set(resume.loop["last_fired"])
        refire_ignored = int(resume.loop["refire_ignored"])
    wall0 = time.perf_counter()
    cpu0 = time.process_time()

    if resume is None:
        kn.outputs(0.0, y, outs[FIRST_ROW], *args)
    bar = progress_bar(system, progress, initial=t_start)
    bar_next = k_start
    bar_stride = max(1, n // 200)
    vx_i = lay.index("block.vx")
    first_result = True

    def close_segment(r) -> None:
        """Add the counts of the IDA segment since the latest (re)initialisation; ``r`` is its
        latest result, or None when the segment failed inside its first call (then IDA's own
        counters give the evaluations, where they are validated)."""
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
            if scfg.linear_solver == "gmres":
                stats["linear_iterations"] += counters.count("IDAGetNumLinIters") or 0
                stats["linear_convergence_failures"] += \
                    counters.count("IDAGetNumLinConvFails") or 0

    def write_cp(k_next: int, t_cp: float, y_cp: np.ndarray) -> None:
        st = dict(stats)
        st["wall_time"] = wall_before + time.perf_counter() - wall0
        st["cpu_time"] = cpu_before + time.process_time() - cpu0
        st["refires_ignored"] = refire_ignored
        write_checkpoint(checkpoint_dir, Checkpoint(
            scene_toml=scene_toml, t=t_cp, k=k_next, y=y_cp.copy(), y_initial=y_initial,
            outputs=outs[:k_next].copy(), reg=reg.copy(), rf=rf.copy(),
            regime=copy.deepcopy(regime), events=list(events), stats=st,
            loop={"recent": list(recent), "t_last_restart": t_last_restart,
                  "last_fired": sorted(last_fired), "refire_ignored": refire_ignored,
                  "h_restart": h_restart},
            force_amplitude=float(system.force_amplitude),
            base_dir=str(Path(scene.base_dir).resolve()),
            inputs=input_fingerprint(scene_toml, system.profile.stats, ida=True)))

    book = EventBook(system, regime, reg, rf, events=events, recent=recent, stats=stats)
    if resume is None:
        book.log_initial_phase(0.0, y)
    k = k_start
    r = None
    try:
        while k < n:
            jac_count[JAC_COUNT] = 0
            try:
                r = solver.step(grid[k], "normal", None)
            except KeyError as exc:  # unknown IDA return code (scikit-sundae has no name for it)
                raise SolverFailure("ida_error", f"IDA returned unknown flag {exc} near "
                                    f"t = {grid[k - 1]:.6g} s", grid[k - 1]) from None
            except _JacobianBudget:
                raise stall_failure("ida", grid[k - 1], f"more than {jac_budget} Jacobians",
                                    regime.describe()) from None
            if first_result:
                counters.validate(int(r.nfev))
                first_result = False
            if r.status == 2:
                te = float(r.t)
                row = np.asarray(r.i_events)[-1]
                fired = {int(i) for i in np.flatnonzero(row)}
                for a in ("_i", "_t", "_y", "_yp"):
                    getattr(eventsfn, a).clear()
                eventsfn._i_cnt[:] = 0
                if te - t_last_restart <= REFIRE_DT * max(1.0, te) and fired <= last_fired:
                    refire_ignored += 1
                    last_fired = set()
                    continue
                close_segment(r)
                r_event, r = r, None  # closed; a later failure adds what follows
                y, yp = book.apply(te, np.asarray(r_event.y, dtype=float), fired)
                # first step after the restart: RESTART_STEP_FRACTION of the last step
                h_restart = min(RESTART_STEP_FRACTION * counters.last_step(), h_restart_cap)
                solver.init_step(te, y, yp)
                counters.set_init_step(h_restart)
                # one instant may take several restarts (IDA reports simultaneous roots up to
                # ~1e-16 s apart): the functions switched at any of them count as just switched
                if te - t_last_restart <= REFIRE_DT * max(1.0, te):
                    last_fired = last_fired | book.switched
                else:
                    last_fired = set(book.switched)
                t_last_restart = te
                while k < n and grid[k] - te <= 1e-12 * max(1.0, te):
                    kn.outputs(grid[k], y, outs[k], *args)
                    k += 1
                continue
            if r.status == -1:  # max_num_steps within this output interval
                raise stall_failure("ida", grid[k - 1], f"more than {budget} steps",
                                    regime.describe())
            if r.status < 0:
                # r.y keeps IDA's last accepted state
                near = _closest_contact(grid[k - 1], r.y, K, ev_args)
                raise SolverFailure(
                    "ida_error", f"IDA failed at t = {grid[k - 1]:.6g} s with flag {r.status}: "
                    f"{r.message} (regime {regime.describe()}{near}). "
                    f"Hint: {_IDA_HINTS.get(r.status, _IDA_HINTS[0])}", grid[k - 1])
            yk = r.y
            kn.outputs(grid[k], yk, outs[k], *args)
            if vx_i >= 0 and not system.coulomb:
                v = yk[vx_i]
                if regime.latch < 0:
                    if v > rf[kn.RF_VEXT]:
                        rf[kn.RF_VEXT] = v
                        regime.v_ext = v
                elif v < rf[kn.RF_VEXT]:
                    rf[kn.RF_VEXT] = v
                    regime.v_ext = v
            if k >= bar_next:
                bar.n = float(grid[k])
                bar.refresh()
                bar_next = k + bar_stride
            k += 1
            if cp_stride and (k - 1) % cp_stride == 0 and k < n:
                # restart IDA at the checkpoint time from a consistent state, exactly as a
                # resumed run does, so that both continue bit-identically
                close_segment(r)
                t_cp = float(grid[k - 1])
                y_cp = np.array(yk, dtype=float)
                t_last_restart = t_cp
                last_fired = set()
                h_restart = min(RESTART_STEP_FRACTION * counters.last_step(), h_restart_cap)
                stats["checkpoints"] += 1
                if scene_toml:
                    write_cp(k, t_cp, y_cp)
                y, yp = system.consistent(t_cp, y_cp, reg, rf)
                solver.init_step(t_cp, y, yp)
                counters.set_init_step(h_restart)
                r = None
        if r is not None:
            close_segment(r)
            y = np.array(r.y, dtype=float) if r.status != 2 else y
    except SolverFailure as exc:
        status, message = exc.status, str(exc)
        close_segment(r)  # r None: the failure came inside the segment's first call
    finally:
        bar.close()

    stats["wall_time"] = wall_before + time.perf_counter() - wall0
    stats["cpu_time"] = cpu_before + time.process_time() - cpu0
    stats["refires_ignored"] = refire_ignored
    stats["events_total"] = len(events)
    stats_d = dict(stats)
    if not counters.ok:
        stats_d["steps"] = None
        why = counters.problem or "IDA's counters could not be validated"
        stats_d["note"] = f"step counts unavailable ({why})"
    t_final = float(grid[k - 1]) if k > 0 else 0.0
    return RawSolution(time=grid, outputs=outs, events=events, stats=stats_d, status=status,
                       message=message, y_initial=y_initial, y_final=np.asarray(y, dtype=float),
                       t_final=t_final, extra={"rows_filled": k})
