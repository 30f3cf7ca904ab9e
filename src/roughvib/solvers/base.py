"""What every solver shares: the result contract, the output grid, the tolerances, the
progress bar, checkpoint and statistics bookkeeping.

The solvers (:mod:`.ida`, :mod:`.adaptive_modal`, :mod:`.fixed_step`,
:mod:`.paper_scheme`) import these from here and not from each other:

* :class:`RawSolution`, what a solver hands to :class:`roughvib.results.Result`;
* :func:`output_grid`, the uniform output grid and its rows, and :data:`FIRST_ROW`;
* :func:`atol_vector`, the per-state absolute tolerances, and :func:`tolerance_floors` /
  :func:`check_tolerances`, their round-off floors;
* :class:`RunProgress` (on :func:`progress_bar`), the progress bar in simulated seconds;
* :func:`checkpoint_stride`, :func:`checkpoint_scene` and :func:`make_checkpoint`, the
  event-driven solvers' checkpoint glue (the file itself: :mod:`.checkpoint`);
* :func:`resumed_statistics` and :class:`RunClock`, the statistics a run starts from and its
  wall and CPU time across resumed processes;
* :class:`EventRun`, the set-up the event-driven runs (IDA's and adaptive-modal's) share;
* :data:`MODE_Q`, :data:`MODE_DQ`, a mode's components in the per-mode step maps of the
  modal solvers.

The drivers call :func:`.checkpoint.write_checkpoint` and :func:`check_tolerances` through
their own module (``ida.write_checkpoint``, ``adaptive_modal.check_tolerances``), so that a
caller can replace them there (the tests stop a run after its first checkpoint that way).
"""

from __future__ import annotations

import collections
import copy
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from roughvib.model import kernels as kn
from roughvib.scene import SceneError, scene_to_toml
from roughvib.solvers.checkpoint import Checkpoint, input_fingerprint, start_state
from roughvib.solvers.events import EventBook, EventRecord

if TYPE_CHECKING:
    from roughvib.model.regimes import Regime
    from roughvib.model.system import System
    from roughvib.scene import Output, Scene

__all__ = ["ATOL_FLOOR_ULPS", "FIRST_ROW", "MODE_DQ", "MODE_Q", "EventRun", "RawSolution",
           "RunClock", "RunProgress", "atol_vector", "check_tolerances", "checkpoint_scene",
           "checkpoint_stride", "make_checkpoint", "output_grid", "progress_bar",
           "resumed_statistics", "tolerance_floors"]

FIRST_ROW = 0  #: the output row of t = 0
#: a mode's state [q, q'] in the per-mode step maps of the modal solvers: ``Phi[r, i, j]``
#: (R, 2, 2) and ``G0[r, i]``, ``G1[r, i]`` (R, 2) of adaptive-modal and the fixed-step
#: schemes, the last axis of the Hermite step's maps
MODE_Q = 0   #: the modal coordinate q [m sqrt(kg)]
MODE_DQ = 1  #: its rate q' [m sqrt(kg) / s]


@dataclass
class RawSolution:
    """What a solver hands to :class:`roughvib.results.Result` (one contract for all).

    Attributes
    ----------
    time : ndarray, shape (n,)
        The output grid [s] (:func:`output_grid`).
    outputs : ndarray, shape (n, kernels.n_output_columns(K))
        The output rows (:func:`roughvib.model.kernels.outputs`); rows not reached are NaN.
    events : list of EventRecord
        The event log.
    stats : dict
        Solver statistics (counts, ``wall_time`` and ``cpu_time`` [s], ...).
    status : str
        ``"success"`` or the failure cause.
    message : str
        One line on how the run ended.
    y_initial : ndarray, shape (n_states,)
        The state at t = 0 (energy audit).
    y_final : ndarray, shape (n_states,)
        The last state reached.
    t_final : float
        Its time [s].
    extra : dict
        Anything solver-specific (``rows_filled``: output rows written).
    """

    time: np.ndarray                 # (n,) [s]
    outputs: np.ndarray              # (n, kernels.n_output_columns(K))
    events: list[EventRecord]
    stats: dict
    status: str
    message: str
    y_initial: np.ndarray
    y_final: np.ndarray
    t_final: float
    extra: dict = field(default_factory=dict)


def output_grid(system: System) -> tuple[np.ndarray, np.ndarray]:
    """The uniform output grid of a run and its output rows, NaN until written.

    Parameters
    ----------
    system : System
        The assembled model; its scene's ``output.duration`` and ``output.step`` [s] set the
        grid.

    Returns
    -------
    grid : ndarray, shape (n,)
        0, output.step, ..., output.duration [s].
    outs : ndarray, shape (n, kernels.n_output_columns(K))
        All NaN.
    """
    out_cfg = system.scene.output
    n = int(round(out_cfg.duration / out_cfg.step)) + 1
    return np.arange(n) * out_cfg.step, np.full((n, kn.n_output_columns(system.n_contacts)),
                                                  np.nan)


# --- tolerances ------------------------------------------------------------------------------

def atol_vector(system: System) -> np.ndarray:
    """Per-component absolute tolerances scaled from solver.atol (a displacement, m).

    A mode's tolerances are those of the structure's largest displacement in it, converted to
    the modal coordinate by ``system.mode_scale`` (mass-normalised shapes: q in m sqrt(kg)),
    and capped by ``solver.atol_acceleration`` [m/s^2] divided by w^2 (q) or w (q').

    Parameters
    ----------
    system : System
        The assembled model (its layout, modes, stiffnesses and ``scene.solver``).

    Returns
    -------
    ndarray, shape (n_states,)
        In each state's unit: m sqrt(kg) (plate.q), m sqrt(kg)/s (plate.dq), m (block.z,
        block.x, friction.state), m/s (block.vz, block.vx), N (contact.force, friction.force),
        J (energy.*).

    Raises
    ------
    AssertionError
        When a state of the layout has no tolerance (a layout change not followed here).
    """
    lay = system.layout
    a = system.scene.solver.atol
    atol = np.full(lay.size, np.nan)
    if system.n_modes:
        omega = np.sqrt(system.omega2)
        acc = system.scene.solver.atol_acceleration
        atol[lay.slice("plate.q")] = np.minimum(a, acc / system.omega2) / system.mode_scale
        atol[lay.slice("plate.dq")] = np.minimum(a * omega, acc / omega) / system.mode_scale
    atol[lay.index("block.z")] = a
    atol[lay.index("block.vz")] = a * 2 * np.pi * 1e3
    if lay.tangential:
        atol[lay.index("block.x")] = a
        atol[lay.index("block.vx")] = a * 1e3
    atol[lay.slice("contact.force")] = a * system.stiff
    if lay.has("friction.force"):
        atol[lay.index("friction.force")] = a * float(np.mean(system.stiff))
    if lay.has("friction.state"):  # a dynamic law's states are displacements (FrictionLaw)
        atol[lay.slice("friction.state")] = a
    for name in lay.names:
        if name.startswith("energy."):
            atol[lay.index(name)] = a * 1e-2
    if np.isnan(atol).any():  # every state needs a tolerance: never leave one undefined
        missing = [n for n in lay.names if np.isnan(atol[lay.slice(n)]).any()]
        raise AssertionError(f"no absolute tolerance for states {missing}")
    return atol


#: solver.atol must be at least this many unit round-offs of the contact compression's terms
#: (docs/robustness.md): near a lift-off or touch-down a contact force is known only to
#: s_k eps L. Measured on the one-contact lift-off scene of docs/robustness.md (rtol 1e-10,
#: 0.02 s): IDA ran through at 100, 10 and 2.3 eps L and stalled at 1 eps L and below, so
#: the floor keeps a margin of 40 over the lowest atol that ran (adaptive-modal ran far lower).
ATOL_FLOOR_ULPS = 100.0


def tolerance_floors(system: System, y: np.ndarray) -> dict[str, tuple[float, float]]:
    """Round-off floors of the absolute tolerances at state ``y`` (the static equilibrium).

    * ``atol``: the contact compression z - w_k + h is a difference of terms as large as
      ``L = |z| + max |w_k| + max |h|`` [m] (block position, plate displacement at the contacts,
      roughness height), so it is known to eps L, and a closing contact's force only to
      s_k eps L, while its tolerance weight tends to atol s_k. The floor is
      ``ATOL_FLOOR_ULPS`` eps L.
    * ``atol_acceleration``: each mode balances w_r^2 q_r against its modal force per unit
      modal mass u_r = sum_k phi_rk F_k / M, so its acceleration is known to ``eps max |u_r|``.
      Below that floor both event-driven solvers slow down (1.6x at the floor, 4x at 4x the
      floor, 100x and more for block.mass >= 1e9 kg) and finally stall.

    Parameters
    ----------
    system : System
        The assembled model.
    y : ndarray, shape (n_states,)
        The state the floors are taken at.

    Returns
    -------
    dict
        ``{field: (floor, scale)}`` for ``atol`` [m] and, with plate modes,
        ``atol_acceleration`` [m/s^2]; ``scale`` is the magnitude whose round-off sets the
        floor (in the floor's unit).
    """
    eps = float(np.finfo(float).eps)
    lay = system.layout
    F = np.asarray(y[lay.slice("contact.force")], dtype=float)
    w = system.cres @ F
    if system.n_modes:
        w = w + system.phi.T @ np.asarray(y[lay.slice("plate.q")], dtype=float)
    L = (abs(float(y[lay.index("block.z")])) + float(np.max(np.abs(w), initial=0.0))
         + float(np.max(np.abs(system.profile.z), initial=0.0)))
    floors = {"atol": (ATOL_FLOOR_ULPS * eps * L, L)}
    if system.n_modes:
        # modal force per unit modal mass, as the structure's largest acceleration [m/s^2]
        u = float(np.max(np.abs((system.phi @ F) * system.mode_scale)))
        floors["atol_acceleration"] = (eps * u, u)
    return floors


def check_tolerances(system: System, y: np.ndarray) -> None:
    """Refuse absolute tolerances below their round-off floors (:func:`tolerance_floors`).

    Parameters
    ----------
    system : System
        The assembled model (``scene.solver.atol`` [m], ``atol_acceleration`` [m/s^2]).
    y : ndarray, shape (n_states,)
        The state at t = 0.

    Raises
    ------
    SceneError
        One line naming each field below its floor, the rule, the unit and the value.
    """
    scfg = system.scene.solver
    floors = tolerance_floors(system, y)
    bad = []
    floor, L = floors["atol"]
    if scfg.atol < floor:
        bad.append(f"solver.atol must be >= {floor:.2g} m for this scene ({ATOL_FLOOR_ULPS:g} "
                   f"round-offs of the contact compression, whose terms reach {L:.3g} m), "
                   f"got {scfg.atol:g} m")
    if "atol_acceleration" in floors:
        floor, u = floors["atol_acceleration"]
        if scfg.atol_acceleration < floor:
            bad.append(f"solver.atol_acceleration must be >= {floor:.2g} m/s^2 for this scene "
                       f"(the round-off of the plate modes' force balance, whose modal forces "
                       f"per modal mass reach {u:.3g} m/s^2 under block.mass = "
                       f"{system.scene.block.mass:g} kg), got {scfg.atol_acceleration:g} m/s^2")
    if bad:
        raise SceneError("; ".join(bad))


# --- progress --------------------------------------------------------------------------------

def progress_bar(system: System, progress: bool | None, initial: float = 0.0):
    """The run's progress bar on stderr, in simulated seconds (shared by the solvers).

    Parameters
    ----------
    system : System
        The assembled model (its scene's name, ``output.duration`` [s], ``output.progress``).
    progress : bool or None
        Show it; None means the scene's ``output.progress``. When stderr is not a terminal (a
        log file), a few whole lines instead (``roughvib._progress``).
    initial : float
        The simulated time it starts at [s] (a resumed run's checkpoint time).

    Returns
    -------
    object
        A tqdm-like bar (``n``, ``refresh()``, ``close()``).
    """
    from roughvib._progress import progress_bar as bar

    scene = system.scene
    if progress is None:
        progress = scene.output.progress
    return bar(float(scene.output.duration), initial=initial, unit="s sim",
               disable=not progress, file=sys.stderr, desc=f"roughvib {scene.name}",
               value_format=".4f", unit_scale=False, leave=False,
               bar_format="{l_bar}{bar}| {n:.4f}/{total:.4f} s sim [{elapsed}<{remaining}]")


class RunProgress:
    """The progress bar of an event-driven run, shown at output rows at most every
    ``stride`` rows.

    Parameters
    ----------
    system : System
        As for :func:`progress_bar`.
    progress : bool or None
        As for :func:`progress_bar`.
    initial : float
        The simulated time the run starts at [s].
    first_row : int
        The first output row the run fills.
    stride : int
        Output rows between two updates (0: at every :meth:`show`).
    """

    def __init__(self, system: System, progress: bool | None, initial: float, first_row: int,
                 stride: int = 0) -> None:
        self.bar = progress_bar(system, progress, initial=initial)
        self.stride = stride
        self._next = first_row

    def show(self, k: int, t: float) -> None:
        """The run has reached output row ``k`` (never less than before) at time ``t`` [s]:
        update the bar when ``k`` is at least ``stride`` rows past the previous update."""
        if k >= self._next:
            self.bar.n = float(t)
            self.bar.refresh()
            self._next = k + self.stride

    def close(self) -> None:
        self.bar.close()


# --- checkpoints and statistics --------------------------------------------------------------

def checkpoint_stride(output: Output, multiple: int = 1) -> int:
    """Output rows between checkpoints (0: none).

    Parameters
    ----------
    output : Output
        The scene's ``output`` (``checkpoint_interval`` and ``step`` [s]).
    multiple : int
        The stride is rounded up to a multiple of this (adaptive-modal's Hermite loop: a
        checkpoint row ends a block of that many rows).

    Returns
    -------
    int
        A checkpoint is taken at the grid rows j with ``j % stride == 0``: the interval
        rounded to the grid (at least one row), or 0 when ``checkpoint_interval`` is 0.
    """
    interval = output.checkpoint_interval
    stride = max(1, int(round(interval / output.step))) if interval > 0 else 0
    if stride % multiple:
        stride += multiple - stride % multiple
    return stride


def checkpoint_scene(scene: Scene, stride: int, directory) -> str:
    """The scene's TOML text that checkpoints store, or ``""`` when none are written (no
    stride or no directory). ``directory`` is the checkpoint directory (path or None)."""
    return scene_to_toml(scene) if stride and directory is not None else ""


def make_checkpoint(system: System, scene_toml: str, *, t: float, k: int, y: np.ndarray,
                    y_initial: np.ndarray, outputs: np.ndarray, reg: np.ndarray,
                    rf: np.ndarray, regime: Regime, events: list, stats: dict, loop: dict,
                    ida: bool = False) -> Checkpoint:
    """A :class:`~.checkpoint.Checkpoint` of an event-driven run; every array is copied.

    Parameters
    ----------
    system : System
        The assembled model (T0, the scene's base directory, the profile's statistics).
    scene_toml : str
        From :func:`checkpoint_scene`.
    t : float
        The checkpoint time [s], a grid time.
    k : int
        The next output row (``grid[k - 1] == t``).
    y, y_initial : ndarray, shape (n_states,)
        The state at ``t`` and at 0.
    outputs : ndarray, shape (>= k, n_out)
        The output rows; rows 0 .. k-1 are stored.
    reg, rf : ndarray
        The kernels' regime arrays.
    regime : Regime
        Deep-copied.
    events : list of EventRecord
    stats : dict
        The statistics so far, with ``wall_time`` and ``cpu_time`` [s] (:class:`RunClock`).
    loop : dict
        What the solver's loop carries (see :class:`~.checkpoint.Checkpoint`).
    ida : bool
        The run is IDA's (its fingerprint names the SUNDIALS version).

    Returns
    -------
    Checkpoint
    """
    return Checkpoint(
        scene_toml=scene_toml, t=t, k=k, y=y.copy(), y_initial=y_initial,
        outputs=outputs[:k].copy(), reg=reg.copy(), rf=rf.copy(),
        regime=copy.deepcopy(regime), events=list(events), stats=stats, loop=loop,
        force_amplitude=float(system.force_amplitude),
        base_dir=str(Path(system.scene.base_dir).resolve()),
        inputs=input_fingerprint(scene_toml, system.profile.stats, ida=ida))


class RunClock:
    """Wall and CPU time of a run, including those of the processes it was resumed from.

    Parameters
    ----------
    wall_before, cpu_before : float
        The times of the earlier processes [s] (:func:`resumed_statistics`).
    """

    def __init__(self, wall_before: float = 0.0, cpu_before: float = 0.0) -> None:
        self.wall_before = wall_before
        self.cpu_before = cpu_before
        self.start()

    def start(self) -> None:
        """Count from now."""
        self._wall0 = time.perf_counter()
        self._cpu0 = time.process_time()

    def times(self) -> dict[str, float]:
        """``{"wall_time": ..., "cpu_time": ...}`` so far [s]."""
        return {"wall_time": self.wall_before + time.perf_counter() - self._wall0,
                "cpu_time": self.cpu_before + time.process_time() - self._cpu0}


def resumed_statistics(resume: Checkpoint | None) -> tuple[collections.Counter, RunClock]:
    """The statistics an event-driven run starts from, and its clock.

    Parameters
    ----------
    resume : Checkpoint or None
        The checkpoint the run continues from.

    Returns
    -------
    stats : collections.Counter
        Empty for a new run; the checkpoint's counts with ``resumes`` one up otherwise.
    clock : RunClock
        Started now, carrying the checkpoint's ``wall_time`` and ``cpu_time`` [s].
    """
    if resume is None:
        return collections.Counter(), RunClock()
    prev = dict(resume.stats)
    wall_before = float(prev.pop("wall_time", 0.0))
    cpu_before = float(prev.pop("cpu_time", 0.0))
    stats = collections.Counter(prev)
    stats["resumes"] += 1
    return stats, RunClock(wall_before, cpu_before)


# --- the event-driven runs ---------------------------------------------------------------------

class EventRun:
    """The set-up that the event-driven runs (IDA's and adaptive-modal's) share.

    A run's class calls this first. The tolerance check and the step budget stay in each
    solver's module (``check_tolerances``, ``step_budget`` called through its names, so that
    a caller can replace them there), as do the progress bar (opened last, once nothing else
    can fail: ``RunProgress(system, progress, self.t_start, self.k_start, stride)``) and
    the event book (``_event_book``, when the run has its state).

    Parameters
    ----------
    system : System
        The assembled model.
    checkpoint_dir : path or None
        Where checkpoints are written (None: nowhere).
    resume : Checkpoint or None
        The checkpoint the run continues from (checked against the scene and the grid).
    checkpoint_multiple : int
        The checkpoint stride is a multiple of this (see :func:`checkpoint_stride`).

    Attributes
    ----------
    grid, outs : ndarray
        From :func:`output_grid`; on a resume, the checkpoint's rows already in ``outs``.
    n : int
        The grid's rows.
    reg, rf : ndarray
        The kernels' regime arrays, holding the start regime.
    regime : Regime
        The start regime.
    y_start, y_initial : ndarray, shape (n_states,)
        The state the run starts from and the state at t = 0
        (:func:`.checkpoint.start_state`).
    t_start : float
        The time the run starts at [s] (0, or the checkpoint's).
    k_start : int
        The first output row it fills (1, or the checkpoint's next row).
    args : tuple
        The kernels' argument tail (:meth:`.System.kernel_args` of ``reg``, ``rf``).
    cp_stride : int
        Output rows between checkpoints (:func:`checkpoint_stride`; 0: none).
    scene_toml : str
        What the checkpoints store of the scene (:func:`checkpoint_scene`; "": none written).
    """

    def __init__(self, system: System, checkpoint_dir, resume: Checkpoint | None,
                 checkpoint_multiple: int = 1) -> None:
        self.system = system
        self.checkpoint_dir = checkpoint_dir
        self.grid, self.outs = output_grid(system)
        self.n, n_out = self.outs.shape
        self.reg, self.rf = system.new_regime_arrays()
        self.regime, self.y_start, self.y_initial = start_state(system, self.reg, self.rf,
                                                                resume, self.n, n_out)
        self.t_start, self.k_start = (0.0, 1) if resume is None else (float(resume.t),
                                                                       int(resume.k))
        if resume is not None:
            self.outs[:self.k_start] = resume.outputs
        self.args = system.kernel_args(self.reg, self.rf)
        self.cp_stride = checkpoint_stride(system.scene.output, checkpoint_multiple)
        self.scene_toml = checkpoint_scene(system.scene, self.cp_stride, checkpoint_dir)

    def _event_book(self, resume: Checkpoint | None) -> None:
        """The run's statistics and clock (:func:`resumed_statistics`) and its event book
        (``self.book``, ``self.clock``), new or with the checkpoint's events and recent
        event times."""
        stats, self.clock = resumed_statistics(resume)
        events: list[EventRecord] = []
        recent: collections.deque[float] = collections.deque()
        if resume is not None:
            events = list(resume.events)
            recent = collections.deque(resume.loop["recent"])
        self.book = EventBook(self.system, self.regime, self.reg, self.rf, events=events,
                              recent=recent, stats=stats)
