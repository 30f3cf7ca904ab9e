"""Scene sections of the run: the solver (method, accuracy preset, tolerances) and the output.

What each solver runs and its presets are asked of the solver registry
(:mod:`roughvib.solvers.registry`, which imports nothing from roughvib).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from roughvib.scene.checks import (
    SceneError,
    _boolean,
    _check_bounds,
    _choice,
    _fmt,
    _integer,
    _nonneg,
    _number,
    _positive,
    _range,
    _set,
)
from roughvib.solvers import registry as _registry

#: :mod:`roughvib.solvers.registry`, which says what each one runs
SOLVER_METHODS = _registry.names()
#: the methods driven by a fixed step (``solver.step``); the others by tolerances
FIXED_STEP_METHODS = _registry.names(_registry.STEP)

#: the accuracy presets, from the most accurate to the cheapest (docs/accuracy.md)
ACCURACY_LEVELS = ("reference", "standard", "draft")

#: tolerances of each accuracy preset per method (``{method: {level: {key: value}}}``): what
#: ``solver.accuracy`` stands for when ``solver.rtol``, ``solver.atol``,
#: ``solver.atol_acceleration`` and ``solver.step`` are not given. Each solver's entry in
#: :mod:`roughvib.solvers.registry` holds its presets (and says how they were measured);
#: docs/accuracy.md lists them with their measured cost and error.
ACCURACY_PRESETS: dict[str, dict[str, dict[str, float]]] = {
    m.name: {level: dict(values) for level, values in m.presets.items()}
    for m in _registry.methods()}
_TOLERANCE_KEYS = ("rtol", "atol", "atol_acceleration", "atol_acceleration_relative", "step")


@dataclass(frozen=True)
class Solver:
    """Time integration.

    Attributes
    ----------
    method : {"auto", "ida", "adaptive-modal", "exact-modal", "newmark", "paper", "moreau"}
        ``auto`` (default): ``adaptive-modal`` where it can run (underdamped plate modes),
        otherwise ``ida`` (``plate.loss_factor >= 2``); :meth:`Scene.resolved_solver` makes
        the choice.
        ``ida``: event-driven adaptive DAE solver (SUNDIALS IDA). ``adaptive-modal``: exact
        per-mode propagation with error-controlled dyadic steps (step doubling, IDA's
        tolerances) and located events (every friction law, or prescribed motion). Fixed-step
        baselines (step ``solver.step``): ``exact-modal`` exact per-mode propagation with
        piecewise-linear force and an implicit contact/block step; ``newmark``
        average-acceleration Newmark on the modal model; ``paper`` the paper's scheme:
        backward Euler, Newton-Raphson with the Heaviside inside, plate by discrete
        convolution of its impulse response (explicit in the plate, O(N^2) cost); ``moreau``
        Moreau-Jean time-stepping of the set-valued laws (``friction.law = "coulomb"`` or
        ``"table"``) with the exact-modal plate. What each method runs is the solver
        registry's (:mod:`roughvib.solvers.registry`): a method that cannot run the scene is
        refused when the scene is built.
    accuracy : {"reference", "standard", "draft"}
        Accuracy preset: the tolerances (``rtol``, ``atol``, ``atol_acceleration``) or the step
        each method uses unless they are given explicitly (``ACCURACY_PRESETS``).
        ``reference`` (default) meets the accuracy contract of docs/accuracy.md with the
        event-driven methods (the fixed-step ones locate events only to about a step).
    step : float or None
        Time step of the fixed-step methods [s]; ``None``: from the preset.
    rtol : float or None
        Relative tolerance; ``None``: from the preset.
    atol : float or None
        Absolute tolerance of the block's displacements [m]; block velocities and contact
        forces get tolerances scaled from it (docs/theory.md); ``None``: from the preset.
    atol_acceleration : float or None
        Absolute tolerance of the plate modes expressed as an acceleration [m/s^2]: mode r
        gets atol_q = a / w_r^2 and atol_dq = a / w_r, so high modes stay error-controlled
        down to this acceleration (what spectra to 50 kHz need); ``None``: from the preset,
        scaled with the run's acceleration level (``atol_acceleration_relative``).
    atol_acceleration_relative : float or None
        Plate-mode tolerance relative to the run's vertical acceleration level [-]: unless
        ``atol_acceleration`` is given, a pilot solve (the first 0.02 s, or a quarter of a
        shorter run, at draft tolerances) measures the larger rms vertical acceleration of
        block and plate, L, and the run uses ``atol_acceleration`` = this x max(L, 1e-6
        m/s^2). Quiet scenes get a tight tolerance, loud ones a loose one, so that the bands
        the accuracy contract checks (within 80 dB of the strongest) are resolved alike.
        ``None``: from the preset. The event-driven solvers refuse ``atol`` and
        ``atol_acceleration`` below the round-off floors of the scene (docs/robustness.md;
        they grow with the static load m g).
    max_order : int
        Highest BDF order (1..5). Default 2: orders >= 3 are not A-stable and were measured
        to excite the lightly damped top plate modes spuriously (docs/theory.md).
    max_step : float
        Largest internal step [s]; 0 means unbounded.
    linear_solver : {"sparse", "gmres"}
        IDA's linear solver for the Newton systems. ``sparse``: SuperLU_MT on the analytic
        arrow-shaped CSC Jacobian. ``gmres``: matrix-free GMRES (Krylov dimension 1) with the
        exact block-elimination preconditioner and analytic Jacobian-vector products of
        :mod:`roughvib.model.krylov` (docs/performance.md compares both).
    max_events : int
        Event-storm guard: at most this many events within ``event_window``.
    event_window : float
        Window of the event-storm guard [s].

    Notes
    -----
    An explicit value is one that is not ``None``: a scene file or ``--set`` that names
    ``solver.rtol`` (or ``atol``, ``atol_acceleration``, ``step``) overrides the preset for
    that key only; the other keys still come from the preset. :meth:`resolved` fills them in.
    """

    method: str = "auto"
    accuracy: str = "reference"
    step: float | None = None
    rtol: float | None = None
    atol: float | None = None
    atol_acceleration: float | None = None
    atol_acceleration_relative: float | None = None
    max_order: int = 2
    max_step: float = 0.0
    linear_solver: str = "sparse"
    max_events: int = 500
    event_window: float = 1e-3

    def __post_init__(self) -> None:
        p = "solver"
        _set(self, "method", _choice(f"{p}.method", self.method,
                                     ("auto",) + _registry.names()))
        _set(self, "accuracy", _choice(f"{p}.accuracy", self.accuracy, ACCURACY_LEVELS))
        if self.step is not None:
            _set(self, "step", _positive(f"{p}.step", self.step, "s"))
        if self.rtol is not None:
            _set(self, "rtol", _range(f"{p}.rtol", self.rtol, 1e-14, 1e-2, ""))
        if self.atol is not None:
            _set(self, "atol", _positive(f"{p}.atol", self.atol, "m"))
        if self.atol_acceleration is not None:
            _set(self, "atol_acceleration",
                 _positive(f"{p}.atol_acceleration", self.atol_acceleration, "m/s^2"))
        if self.atol_acceleration_relative is not None:
            _set(self, "atol_acceleration_relative",
                 _range(f"{p}.atol_acceleration_relative", self.atol_acceleration_relative,
                        0.0, 1.0, "", lo_open=True))
        _set(self, "max_order", _integer(f"{p}.max_order", self.max_order, 1, 5))
        _set(self, "max_step", _nonneg(f"{p}.max_step", self.max_step, "s"))
        _set(self, "linear_solver", _choice(f"{p}.linear_solver", self.linear_solver,
                                            ("sparse", "gmres")))
        _set(self, "max_events", _integer(f"{p}.max_events", self.max_events, 1))
        _set(self, "event_window", _positive(f"{p}.event_window", self.event_window, "s"))
        _check_bounds(self, "solver")

    def resolved(self, method: str | None = None) -> Solver:
        """This section with a concrete method and every tolerance and step filled in.

        Parameters
        ----------
        method : str, optional
            The method to resolve ``"auto"`` to (:meth:`Scene.resolved_solver` knows the
            scene); required when ``self.method == "auto"``.

        Returns
        -------
        Solver
            ``method`` concrete; ``rtol``, ``atol``, ``atol_acceleration`` and ``step`` the
            explicit values where given, else those of ``ACCURACY_PRESETS[method][accuracy]``,
            else those of the IDA preset of the same accuracy (tolerances) or 1e-5 s (step), so
            that every key holds a number whatever the method uses.
            ``atol_acceleration_relative`` is None for the fixed-step methods. Where
            ``atol_acceleration`` was not given, the run replaces it by
            ``atol_acceleration_relative`` times the level a pilot solve measures
            (:func:`roughvib.simulation.simulate`).
        """
        m = self.method if self.method != "auto" else method
        if m not in _registry.names():
            raise ValueError(f"Solver.resolved needs a concrete method, got {m!r}")
        solver = _registry.get(m)
        preset = {"step": 1e-5, **_registry.get("ida").presets[self.accuracy],
                  **solver.presets[self.accuracy]}
        values = {k: getattr(self, k) if getattr(self, k) is not None else preset[k]
                  for k in _TOLERANCE_KEYS}
        if solver.kind == _registry.STEP:
            values["atol_acceleration_relative"] = None
        return replace(self, method=m, **values)

    def from_preset(self) -> tuple[str, ...]:
        """Names of the tolerance keys (rtol, atol, atol_acceleration,
        atol_acceleration_relative, step) not given explicitly, i.e. taken from the accuracy
        preset."""
        return tuple(k for k in _TOLERANCE_KEYS if getattr(self, k) is None)


@dataclass(frozen=True)
class Output:
    """What is simulated and stored.

    Attributes
    ----------
    duration : float
        Simulated time [s].
    step : float
        Uniform output grid spacing [s] (1e-5 s: spectra to 50 kHz).
    transient : float
        Run-in excluded from the summary metrics [s]; metrics use whole excitation periods
        after it where possible.
    progress : bool
        Show a progress bar on stderr.
    checkpoint_interval : float
        Simulated time between checkpoints [s]; 0 (default) writes none. With ``roughvib run``
        each checkpoint is ``OUT/checkpoint.pkl`` (replaced atomically); ``roughvib run
        --resume OUT`` continues from it with results identical to an uninterrupted run of
        the same scene. IDA is restarted at every checkpoint (about 20 extra steps), so a run
        with checkpoints differs from one without them within the solver tolerance;
        adaptive-modal runs with and without checkpoints are identical. The interval is
        rounded to whole output steps, and with adaptive-modal's Hermite step (the Feldmann
        law with a force-driven block) up to a multiple of eight of them (its error estimate
        spans blocks of eight output intervals). ``solver.method = "ida"`` or ``"adaptive-modal"``.
    radiation : bool
        Compute the plate's radiated sound (docs/radiation.md): third-octave levels of the
        sound power, of the plate's mean-square velocity and of the radiation efficiency, in
        ``radiation.csv`` of the run directory and a figure in the run report. Needs the
        simply supported plate (``plate.kind = "modal"``).
    radiating_sides : int
        1 (a plate in an infinite baffle radiating into one half space) or 2 (both sides
        radiate, each as into a baffled half space: twice the power).
    air_density : float
        rho0 of the air [kg/m^3] (20 °C: 1.204).
    sound_speed : float
        c0 of the air [m/s] (20 °C: 343).
    microphones : tuple of (float, float, float)
        With ``radiation``: points [x, y, z] [m] in the plate's frame (z > 0 above the plate,
        on the radiating side) where the sound pressure is computed (third-octave levels to
        5 kHz in ``microphones.csv``, dB re 20 uPa); empty by default.
    """

    duration: float = 3.0 / 7.0
    step: float = 1e-5
    transient: float = 1.0 / 7.0
    progress: bool = True
    checkpoint_interval: float = 0.0
    radiation: bool = False
    radiating_sides: int = 1
    air_density: float = 1.204
    sound_speed: float = 343.0
    microphones: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self) -> None:
        p = "output"
        _set(self, "duration", _positive(f"{p}.duration", self.duration, "s"))
        _set(self, "step", _positive(f"{p}.step", self.step, "s"))
        _set(self, "transient", _nonneg(f"{p}.transient", self.transient, "s"))
        _set(self, "progress", _boolean(f"{p}.progress", self.progress))
        _set(self, "checkpoint_interval",
             _nonneg(f"{p}.checkpoint_interval", self.checkpoint_interval, "s"))
        _check_bounds(self, "output")
        if 0 < self.checkpoint_interval < self.step:
            raise SceneError(f"{p}.checkpoint_interval must be 0 (off) or >= output.step "
                             f"({self.step} s), got {self.checkpoint_interval} s")
        if self.step > self.duration:
            raise SceneError(f"{p}.step must be <= output.duration ({self.duration} s), "
                             f"got {self.step} s")
        if self.duration / self.step > 2e7:
            raise SceneError(f"{p}.step gives more than 2e7 output samples, got {self.step} s")
        _set(self, "radiation", _boolean(f"{p}.radiation", self.radiation))
        _set(self, "radiating_sides", _integer(f"{p}.radiating_sides", self.radiating_sides,
                                               1, 2))
        _set(self, "air_density", _positive(f"{p}.air_density", self.air_density, "kg/m^3"))
        _set(self, "sound_speed", _positive(f"{p}.sound_speed", self.sound_speed, "m/s"))
        mics = self.microphones
        if not isinstance(mics, list | tuple) or len(mics) > 64:
            raise SceneError(f"{p}.microphones must be a list of at most 64 points [x, y, z] m, "
                             f"got {_fmt(mics)}")
        points = []
        for i, m in enumerate(mics):
            if not isinstance(m, list | tuple) or len(m) != 3:
                raise SceneError(f"{p}.microphones[{i}] must be a point [x, y, z] m, "
                                 f"got {_fmt(m)}")
            x, y, z = (_number(f"{p}.microphones[{i}][{j}]", v, "m") for j, v in enumerate(m))
            if not z > 0:
                raise SceneError(f"{p}.microphones[{i}][2] must be > 0 m (above the plate), "
                                 f"got {_fmt(m[2])}")
            points.append((x, y, z))
        _set(self, "microphones", tuple(points))
