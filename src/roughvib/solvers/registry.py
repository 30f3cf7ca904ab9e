"""The solver registry: every value of ``solver.method``, what each solver runs and how to call it.

One :class:`Method` per solver holds

* its ``name`` (the value of ``solver.method``) and ``kind``: :data:`TOLERANCE` (adaptive
  steps driven by ``solver.rtol``/``atol``/``atol_acceleration``) or :data:`STEP` (a fixed
  step, ``solver.step``);
* its accuracy presets (what ``solver.accuracy`` sets for it: ``{level: {key: value}}``);
* the function that solves, named ``"module:function"`` and imported only when a run calls
  :meth:`Method.run`, so that importing this registry (and validating a scene) stays cheap;
* what it offers and what it runs: checkpoints, the energy audit, which friction laws (with a
  force-driven block), the friction force's moment, and any further rule of its own.

:meth:`Method.supports` answers for a scene: None if the solver runs it, else one line that
names the key and value that rule the solver out and the solvers that would run the scene.
Scene validation (:class:`roughvib.scene.Scene`) asks it for the scene's method, so a scene a
solver cannot run is refused when it is loaded; :func:`resolve_auto` is what
``solver.method = "auto"`` becomes. ``simulate`` calls :meth:`Method.run`, and
``roughvib compare`` builds its ladders from :func:`supporting`.

This module is read by scene validation (stage 0 of the pipeline, docs/architecture.md), so it
imports nothing from roughvib and reads a scene only through its attributes; the solver modules
are named, not imported. A new solver is its module in ``solvers/`` plus one :func:`register`
call at the end of this file.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["AUTO", "STEP", "TOLERANCE", "Method", "get", "methods", "names", "refusal_line",
           "register", "resolve_auto", "supporting"]

#: kind of a solver driven by tolerances (adaptive steps)
TOLERANCE = "tolerance"
#: kind of a solver driven by a fixed step (``solver.step``)
STEP = "step"
_KINDS = (TOLERANCE, STEP)
#: the kinds of friction law (``roughvib.scene.FRICTION_LAWS``), each of which a solver may run
#: with a force-driven block
LAW_KINDS = ("single-valued", "set-valued", "dynamic")

#: ``solver.method = "auto"``: the first of these that runs the scene
AUTO = ("adaptive-modal", "ida")

#: a rule of one solver: ``rule(scene, method)`` is None, or the reason it cannot run the scene
Rule = Callable[[Any, "Method"], "str | None"]


@dataclass(frozen=True, eq=False)
class Method:
    """One solver (a value of ``solver.method``).

    Attributes
    ----------
    name : str
        The value of ``solver.method``.
    kind : {"tolerance", "step"}
        :data:`TOLERANCE`: adaptive steps under ``solver.rtol``, ``atol`` and
        ``atol_acceleration``; :data:`STEP`: a fixed step ``solver.step``.
    summary : str
        What it is, in a few words.
    presets : mapping
        ``{accuracy level: {key: value}}``: the tolerances or the step each
        ``solver.accuracy`` sets (``roughvib.scene.ACCURACY_PRESETS``, docs/accuracy.md).
    solve : str
        ``"module:function"``: the solve function, ``function(system, *, progress)`` (with
        ``checkpoint_dir`` and ``resume`` too where ``checkpoints``), returning a
        ``RawSolution``.
    checkpoints : bool
        Writes checkpoints (``output.checkpoint_interval``) and resumes from them.
    energy_audit : bool
        Keeps the energy integrals, so a run has an energy audit (and can be verified).
    friction : tuple of {"single-valued", "set-valued", "dynamic"}
        The kinds of friction law it runs with a force-driven block (a prescribed motion has
        no friction model, so every solver runs it with any law).
    friction_moment : bool
        Integrates the friction force's moment on the plate (``contact.friction_moment``).
    rules : tuple of callables
        Further rules of its own, ``rule(scene, method) -> str | None``.
    """

    name: str
    kind: str
    summary: str
    presets: Mapping[str, Mapping[str, float]]
    solve: str
    checkpoints: bool = False
    energy_audit: bool = True
    friction: tuple[str, ...] = LAW_KINDS
    friction_moment: bool = False
    rules: tuple[Rule, ...] = field(default=())

    def runs_law(self, kind: str) -> bool:
        """Whether it runs a friction law of this kind (``"single-valued"``, ``"set-valued"``
        or ``"dynamic"``) with a force-driven block."""
        return kind in self.friction

    def refusal(self, scene) -> str | None:
        """The first rule that rules the solver out for ``scene`` (key, value and why), or
        None. :meth:`supports` adds what would run the scene instead."""
        for rule in _COMMON_RULES + self.rules:
            reason = rule(scene, self)
            if reason is not None:
                return reason
        return None

    def supports(self, scene) -> str | None:
        """None if the solver runs ``scene``, else one line: the key and value that rule it
        out, why, and the solvers that would run the scene.

        Parameters
        ----------
        scene : roughvib.scene.Scene
            Read through its sections only (the solver section is not looked at).

        Returns
        -------
        str or None
            e.g. ``"friction.law = 'coulomb' is set-valued, and newmark runs single-valued
            laws only; use ida, adaptive-modal or moreau"``.
        """
        reason = self.refusal(scene)
        if reason is None:
            return None
        others = [m.name for m in methods() if m.name != self.name and m.refusal(scene) is None]
        return f"{reason}; " + (f"use {_either(others)}" if others
                                else "no registered solver runs this scene")

    def solve_function(self) -> Callable:
        """The solve function, its module imported now."""
        module, _, function = self.solve.partition(":")
        return getattr(importlib.import_module(module), function)

    def run(self, system, *, progress: bool | None = None, checkpoint_dir=None, resume=None):
        """Solve ``system`` (assembled from a scene this solver supports) and return its
        ``RawSolution``; ``checkpoint_dir`` and ``resume`` reach a solver that writes
        checkpoints, the others do without them."""
        solve = self.solve_function()
        if self.checkpoints:
            return solve(system, progress=progress, checkpoint_dir=checkpoint_dir,
                         resume=resume)
        return solve(system, progress=progress)


_METHODS: dict[str, Method] = {}


def register(method: Method) -> Method:
    """Add a solver to the registry (once per name); returns it."""
    if method.name in _METHODS or method.name == "auto":
        raise ValueError(f"solver {method.name!r} is already registered")
    if method.kind not in _KINDS:
        raise ValueError(f"solver {method.name!r}: kind must be one of {_KINDS}, "
                         f"got {method.kind!r}")
    if not method.friction or not set(method.friction) <= set(LAW_KINDS):
        raise ValueError(f"solver {method.name!r}: friction must be kinds of {LAW_KINDS}, "
                         f"got {method.friction!r}")
    if ":" not in method.solve:
        raise ValueError(f"solver {method.name!r}: solve must be 'module:function', "
                         f"got {method.solve!r}")
    _METHODS[method.name] = method
    return method


def methods(kind: str | None = None) -> tuple[Method, ...]:
    """Every registered solver in registration order, or those of one ``kind``."""
    return tuple(m for m in _METHODS.values() if kind is None or m.kind == kind)


def names(kind: str | None = None) -> tuple[str, ...]:
    """The names of :func:`methods`."""
    return tuple(m.name for m in methods(kind))


def get(name: str) -> Method:
    """The solver registered as ``name`` (a concrete method, not ``"auto"``).

    Raises
    ------
    ValueError
        No solver of that name.
    """
    try:
        return _METHODS[name]
    except (KeyError, TypeError):
        raise ValueError(f"no solver {name!r} is registered (solvers: "
                         f"{', '.join(_METHODS)})") from None


def supporting(scene, kind: str | None = None) -> tuple[str, ...]:
    """The names of the solvers (of one ``kind``) that run ``scene``, in registration order."""
    return tuple(m.name for m in methods(kind) if m.refusal(scene) is None)


def resolve_auto(scene) -> str | None:
    """What ``solver.method = "auto"`` runs for ``scene``: the first of :data:`AUTO` that
    supports it (``adaptive-modal`` unless the plate modes are overdamped, then ``ida``), or
    None if none does."""
    for name in AUTO:
        if name in _METHODS and _METHODS[name].refusal(scene) is None:
            return name
    return None


def refusal_line(scene) -> str | None:
    """None if the scene's ``solver.method`` runs the scene, else the one-line refusal that
    scene validation raises: it names ``solver.method``, the solver, the rule and what would
    run the scene."""
    method = scene.solver.method
    if method == "auto":
        if resolve_auto(scene) is not None:
            return None
        why = "; ".join(f"{n}: {get(n).refusal(scene)}" for n in AUTO if n in _METHODS)
        others = supporting(scene)
        return (f"solver.method = 'auto' finds no solver for this scene ({why}); " +
                (f"use {_either(others)}" if others else "no registered solver runs it"))
    reason = get(method).supports(scene)
    return None if reason is None else f"solver.method = {method!r} cannot run this scene: {reason}"


def _either(items) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} or {items[-1]}"


# --------------------------------------------------------------------------------------------
# the rules
# --------------------------------------------------------------------------------------------


def _friction_law(scene, m: Method) -> str | None:
    if scene.excitation.kind != "force":  # prescribed motion: no friction model
        return None
    law = scene.friction.law
    kind = scene.friction.kind
    if m.runs_law(kind):
        return None
    what = {"set-valued": "set-valued (stick held at v = 0)",
            "dynamic": "dynamic (internal states)"}.get(kind, kind)
    return (f"friction.law = {law!r} is {what}, and {m.name} runs "
            f"{_either(m.friction)} laws only")


def _dynamic_law_moment(scene, m: Method) -> str | None:
    if (scene.contact.friction_moment and scene.excitation.kind == "force"
            and scene.friction.kind == "dynamic"):
        return (f"contact.friction_moment = true, and the moment of a dynamic law's force "
                f"(friction.law = {scene.friction.law!r}) is not integrated by any solver yet")
    return None


def _krylov_law(scene, m: Method) -> str | None:
    if (scene.solver.linear_solver == "gmres" and scene.excitation.kind == "force"
            and scene.friction.kind == "dynamic"):
        return (f"solver.linear_solver = 'gmres', and IDA's Krylov preconditioner does not "
                f"eliminate a dynamic law's states (friction.law = {scene.friction.law!r}); "
                f"use solver.linear_solver = 'sparse'")
    return None


def _friction_moment(scene, m: Method) -> str | None:
    if scene.contact.friction_moment and not m.friction_moment:
        return (f"contact.friction_moment = true, and {m.name} does not integrate the friction "
                f"force's moment on the plate")
    return None


def _checkpoints(scene, m: Method) -> str | None:
    interval = scene.output.checkpoint_interval
    if interval > 0 and not m.checkpoints:
        return f"output.checkpoint_interval = {interval:g} s, and {m.name} writes no checkpoints"
    return None


def _underdamped_modes(scene, m: Method) -> str | None:
    """adaptive-modal propagates each mode as a damped oscillator, the paper's scheme convolves
    with exp(-zeta w t) sin(w_d t) / w_d, w_d = w sqrt(1 - zeta^2): underdamped modes only."""
    plate = scene.plate
    # the modal plate's damping ratio is loss_factor / 2 for every mode; imported modes are
    # refused >= 1 when they are read, a rigid base has none
    if plate.kind == "modal" and plate.loss_factor >= 2.0:
        return (f"plate.loss_factor = {plate.loss_factor:g} makes the plate modes critically "
                f"damped (damping ratio loss_factor / 2 >= 1), and {m.name} runs "
                f"underdamped modes only")
    return None


def _plate_modes(scene, m: Method) -> str | None:
    plate = scene.plate
    if plate.kind == "rigid":
        return (f"plate.kind = 'rigid' has no modes, and {m.name} needs a structure with modes "
                f"(the plate is its impulse response)")
    if plate.kind == "modal":
        # mode (1, 1) by the plate's own rule, the one plate_modes keeps its modes by
        w1 = plate.mode_omega(1, 1)
        if not plate.keeps_mode(w1):
            return (f"plate.max_frequency = {plate.max_frequency:g} Hz is below the plate's "
                    f"first mode ({w1 / (2.0 * math.pi):.4g} Hz), and {m.name} needs at "
                    f"least one plate mode (the plate is its impulse response)")
    # imported modes: the solver counts them after reading the file
    return None


_COMMON_RULES: tuple[Rule, ...] = (_friction_law, _friction_moment, _dynamic_law_moment,
                                   _checkpoints)


# --------------------------------------------------------------------------------------------
# the solvers
# --------------------------------------------------------------------------------------------
# The presets: tolerances of each accuracy preset per method, what ``solver.accuracy`` stands
# for when ``solver.rtol``, ``solver.atol``, ``solver.atol_acceleration`` and ``solver.step``
# are not given. ``atol_acceleration_relative`` scales the plate modes' tolerance with the
# run's own acceleration level, measured by a short pilot solve (docs/accuracy.md);
# ``atol_acceleration`` is the absolute value used when no level can be measured. The measured
# cost and error of every entry are in docs/accuracy.md. ``reference`` meets the accuracy
# contract on both built-in paper scenes for ``ida``, ``adaptive-modal`` and ``newmark``, and
# on ``paper-100mms`` for ``exact-modal``; on ``paper`` exact-modal's stick/slip events, found
# from sign changes between steps, miss the event-time limit (about half a step). The paper's
# scheme keeps no energy audit, so it never meets the contract.

register(Method(
    "ida", TOLERANCE,
    "SUNDIALS IDA: variable-step BDF on the DAE, events by root finding",
    {"reference": {"rtol": 1e-7, "atol": 1e-12, "atol_acceleration": 1e-10,
                   "atol_acceleration_relative": 1e-8},
     "standard": {"rtol": 1e-6, "atol": 1e-12, "atol_acceleration": 1e-8,
                  "atol_acceleration_relative": 1e-6},
     "draft": {"rtol": 1e-4, "atol": 1e-11, "atol_acceleration": 1e-6,
               "atol_acceleration_relative": 1e-4}},
    "roughvib.solvers.ida:solve_ida",
    checkpoints=True, friction_moment=True, rules=(_krylov_law,)))

# adaptive-modal: the Hermite step is fourth order and the trapezoidal step's kept states are
# extrapolated to third order, so the reference's plate-mode tolerance is a decade looser than
# the rtol. Measured over the default length against tight runs (docs/accuracy.md): Hermite
# step (the built-in scenes) worst plate band -0.30 dB (paper) and -0.25 dB (paper-100mms), at
# 40 kHz, events <= 1.1e-9 s; trapezoidal step -0.19 and -0.019 dB, events <= 1.1e-9 s
register(Method(
    "adaptive-modal", TOLERANCE,
    "exact per-mode propagation, error-controlled dyadic steps, located events",
    {"reference": {"rtol": 1e-5, "atol": 1e-12, "atol_acceleration": 1e-6,
                   "atol_acceleration_relative": 1e-4},
     "standard": {"rtol": 1e-4, "atol": 1e-11, "atol_acceleration": 1e-6,
                  "atol_acceleration_relative": 1e-4},
     "draft": {"rtol": 1e-3, "atol": 1e-11, "atol_acceleration": 1e-5,
               "atol_acceleration_relative": 1e-3}},
    "roughvib.solvers.adaptive_modal:solve_adaptive_modal",
    checkpoints=True, friction_moment=True, friction=("single-valued", "set-valued"),
    rules=(_underdamped_modes,)))

# fixed steps divide the default 1e-5 s output step: 1e-5 s is the coarsest that runs
register(Method(
    "exact-modal", STEP,
    "fixed step: exact per-mode propagation, piecewise-linear modal force",
    {"reference": {"step": 2.5e-6}, "standard": {"step": 5e-6}, "draft": {"step": 1e-5}},
    "roughvib.solvers.fixed_step:solve_fixed_step",
    friction=("single-valued",)))

register(Method(
    "newmark", STEP,
    "fixed step: average-acceleration Newmark on the modal model",
    {"reference": {"step": 1e-6}, "standard": {"step": 5e-6}, "draft": {"step": 1e-5}},
    "roughvib.solvers.fixed_step:solve_fixed_step",
    friction=("single-valued",)))

# the paper's scheme is defined by its 1e-5 s step; no preset changes it
register(Method(
    "paper", STEP,
    "the paper's scheme: backward Euler, plate by convolution of its impulse response",
    {"reference": {"step": 1e-5}, "standard": {"step": 1e-5}, "draft": {"step": 1e-5}},
    "roughvib.solvers.paper_scheme:solve_paper_scheme",
    energy_audit=False, friction=("single-valued",), rules=(_plate_modes, _underdamped_modes)))

register(Method(
    "moreau", STEP,
    "fixed step: Moreau-Jean time-stepping of the set-valued laws, exact-modal plate",
    {"reference": {"step": 1e-6}, "standard": {"step": 5e-6}, "draft": {"step": 1e-5}},
    "roughvib.solvers.fixed_step:solve_fixed_step",
    friction=("set-valued",)))
