"""The friction laws' registration: ids, what each law declares, and the kernels' one dispatch.

A law is one module of this package (its curve and exact derivatives, its states, its
tangential-only model) plus one entry here:

* its id (``LAW_*``), the value the kernels see in ``off[OFF_LAW]``;
* a :class:`FrictionLaw` in :data:`LAWS`: its kind (``single-valued``, ``set-valued`` or
  ``dynamic`` with internal states), how many states it adds to the state vector, how its
  parameters are packed for the kernels and the tangential model in which T0 is calibrated;
* a branch in the numba dispatch below (:func:`law_kind`, :func:`dynamic_law`,
  :func:`single_valued_mu`, :func:`single_valued_mu_d2`, :func:`single_valued_mu_law`; a
  set-valued law's kinetic curve in
  ``setvalued.kinetic_coefficient``), which raises for an id no law registered: no kernel
  falls through to another law's physics.

The scene's keys of a law and its kind are declared where the scene is validated
(``roughvib.scene.FRICTION_LAWS``); the solvers that run a law follow from its kind and the
solver registry (:attr:`FrictionLaw.solvers`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

from roughvib.physics.friction import coulomb, feldmann, lugre, setvalued, table
from roughvib.physics.friction.feldmann import (
    effective_latch_velocity,
    feldmann_mu,
    feldmann_mu_d2,
    feldmann_mu_law,
    tangential_feldmann,
)
from roughvib.physics.friction.setvalued import kinetic_coefficient, tangential_set_valued
from roughvib.scene import FRICTION_LAWS
from roughvib.solvers import registry

__all__ = ["KIND_DYNAMIC", "KIND_SET_VALUED", "KIND_SINGLE_VALUED", "LAWS", "LAW_COULOMB",
           "LAW_FELDMANN", "LAW_LUGRE", "LAW_TABLE", "FrictionLaw", "dynamic_law",
           "is_set_valued", "kinetic_coefficient", "law_kind", "model_keys",
           "single_valued_mu", "single_valued_mu_d2", "single_valued_mu_law"]

#: ids of the friction laws as the kernels see them (``off[OFF_LAW]``, roughvib.model.layout)
LAW_FELDMANN = feldmann.LAW_ID
LAW_COULOMB = coulomb.LAW_ID
LAW_TABLE = table.LAW_ID
LAW_LUGRE = lugre.LAW_ID

#: the kinds of law as the kernels see them (:func:`law_kind`)
KIND_SINGLE_VALUED = 0  # mu a function of the velocity (and discrete regimes): feldmann
KIND_SET_VALUED = 1     # stick held at v = 0, the friction force algebraic: coulomb, table
KIND_DYNAMIC = 2        # internal states with their own rate equations: lugre
_KIND_IDS = {"single-valued": KIND_SINGLE_VALUED, "set-valued": KIND_SET_VALUED,
             "dynamic": KIND_DYNAMIC}


def _no_parameters(friction, base_dir) -> np.ndarray:
    return np.zeros(0)


def _table_parameters(friction, base_dir) -> np.ndarray:
    return table.law_table(friction, base_dir)


def _lugre_parameters(friction, base_dir) -> np.ndarray:
    return lugre.pack_parameters(friction.parameters)


def model_keys(friction, model: str) -> dict:
    """The own keys the tangential model of law ``model`` reads for this friction section:
    the section's ``parameters`` when it is that law, else that law's defaults (the coulomb
    law is calibrated in the Feldmann law's model, with that law's default keys).

    Parameters
    ----------
    friction : roughvib.scene.Friction
    model : str
        A law's name.

    Returns
    -------
    dict
        ``{key: value}``.
    """
    if friction.law == model:
        return dict(friction.parameters)
    return {k: key.default for k, key in FRICTION_LAWS[model].keys.items()}


# the tangential-only models, tangential(T0, mass, r2, normal_force, omega, friction, dt, n,
# v, x, table): fill v, x (length n + 1) from rest
def _feldmann_tangential(T0, mass, r2, normal_force, omega, friction, dt, n, v, x, table):
    par = model_keys(friction, "feldmann")
    tangential_feldmann(T0, mass, r2, normal_force, omega, float(friction.mu_slip),
                        float(friction.mu_stick), float(par["a1"]), float(par["a2"]),
                        float(par["hysteresis_velocity"]), effective_latch_velocity(par), dt,
                        n, v, x)


def _set_valued_tangential(T0, mass, r2, normal_force, omega, friction, dt, n, v, x, curve):
    tab = np.zeros(0) if curve is None else np.asarray(curve, dtype=float)
    tangential_set_valued(T0, mass, r2, normal_force, omega, LAWS[friction.law].law_id,
                          float(friction.mu_slip), float(friction.mu_stick),
                          float(friction.parameters.get("stribeck_velocity") or 0.0), tab, dt,
                          n, v, x)


def _lugre_tangential(T0, mass, r2, normal_force, omega, friction, dt, n, v, x, table):
    lugre.tangential_lugre(T0, mass, r2, normal_force, omega, float(friction.mu_slip),
                           float(friction.mu_stick), lugre.pack_parameters(friction.parameters),
                           dt, n, v, x)


@dataclass(frozen=True)
class FrictionLaw:
    """What a friction law declares (docs/architecture.md, "A friction law").

    Attributes
    ----------
    name : str
        The value of ``friction.law`` that selects it.
    law_id : int
        Its id in the kernels (``LAW_*``).
    states : int
        Internal states it adds to the state vector (``friction.state``): 0 but for a dynamic
        law. They are displacements [m] (the solvers' absolute tolerance is ``solver.atol``).
    calibration : {"feldmann", "set-valued", "dynamic"}
        Which tangential-only model T0 is calibrated in (to ``excitation.target_rms_velocity``,
        ``roughvib.physics.friction.calibration``): the Feldmann law's, the set-valued laws'
        or a dynamic law's own.
    pack : callable
        ``pack(friction, base_dir) -> ndarray``: its parameters as the kernels read them
        (``fp`` from ``kernels.N_FP``): a tabulated curve, a dynamic law's constants, or
        nothing.
    tangential : callable
        ``tangential(T0, mass, r2, normal_force, omega, friction, dt, n, v, x, table)``: the
        tangential-only model (constant normal force, from rest), filling ``v`` [m/s] and
        ``x`` [m] (length n + 1) on the grid ``k dt``.
    initial : callable
        ``initial(regime, start)``: sets the law's regime at t = 0 (block at rest) in the
        ``roughvib.model.regimes.Regime`` from a ``regime.StartValues``; the law module's
        ``regime_at_start``.
    transition : callable
        ``transition(regime, j, at) -> list[Transition]``: switches the regime in place for
        the law's friction root ``j`` (0, 1, 2) from a ``regime.RootValues`` and returns the
        events to log (none when a guard holds the regime); the law module's
        ``regime_transition``.
    roots : tuple of str
        The meanings of its three friction roots (``kernels.events``' roots ``K + j``), the
        law module's ``ROOTS``.
    notation : callable
        ``notation(regime) -> str``: the friction part of the regime as the event log's
        ``regime_before``/``regime_after`` write it (``b=+1 s=-1 slip``, ``slip+``); the law
        module's ``regime_notation``.
    """

    name: str
    law_id: int
    states: int
    calibration: str
    pack: Callable
    tangential: Callable
    initial: Callable
    transition: Callable
    roots: tuple[str, ...]
    notation: Callable

    @property
    def kind(self) -> str:
        """``"single-valued"``, ``"set-valued"`` or ``"dynamic"``, as the scene declares it."""
        return FRICTION_LAWS[self.name].kind

    @property
    def kind_id(self) -> int:
        """The kind as the kernels see it (``KIND_*``)."""
        return _KIND_IDS[self.kind]

    @property
    def set_valued(self) -> bool:
        """True: stick is a regime with the velocity held at zero and the friction force an
        algebraic state (break-away at ``mu_stick F_N``, the kinetic curve of
        ``setvalued.kinetic_coefficient`` in slip)."""
        return self.kind == "set-valued"

    @property
    def solvers(self) -> tuple[str, ...]:
        """The solver methods that integrate it with a force-driven block, as the solver
        registry says (:meth:`roughvib.solvers.registry.Method.runs_law`)."""
        return tuple(m.name for m in registry.methods() if m.runs_law(self.kind))


#: the friction laws by the name a scene uses (``friction.law``)
LAWS = {
    "feldmann": FrictionLaw("feldmann", LAW_FELDMANN, 0, "feldmann", _no_parameters,
                            _feldmann_tangential, feldmann.regime_at_start,
                            feldmann.regime_transition, feldmann.ROOTS,
                            feldmann.regime_notation),
    # the Coulomb law keeps the calibration it always had (the Feldmann model with the same
    # mu_slip / mu_stick and that law's default keys), so that its runs stay bit-identical
    "coulomb": FrictionLaw("coulomb", LAW_COULOMB, 0, "feldmann", _no_parameters,
                           _feldmann_tangential, setvalued.regime_at_start,
                           setvalued.regime_transition, setvalued.ROOTS,
                           setvalued.regime_notation),
    "table": FrictionLaw("table", LAW_TABLE, 0, "set-valued", _table_parameters,
                         _set_valued_tangential, setvalued.regime_at_start,
                         setvalued.regime_transition, setvalued.ROOTS,
                         setvalued.regime_notation),
    "lugre": FrictionLaw("lugre", LAW_LUGRE, 1, "dynamic", _lugre_parameters,
                         _lugre_tangential, lugre.regime_at_start, lugre.regime_transition,
                         lugre.ROOTS, lugre.regime_notation),
}
if len({law.law_id for law in LAWS.values()}) != len(LAWS):  # pragma: no cover
    raise ImportError("two friction laws have the same LAW_ID")
if tuple(LAWS) != tuple(FRICTION_LAWS):  # pragma: no cover - a registration error
    raise ImportError(f"the friction laws registered ({', '.join(LAWS)}) are not the scene's "
                      f"({', '.join(FRICTION_LAWS)})")


# --------------------------------------------------------------------------------------------
# the kernels' dispatch: every branch on a law id is here
# --------------------------------------------------------------------------------------------

#: the Feldmann law's second-derivative form and its own-branch form inlined (numba IR) into
#: their dispatch, so that a caller that inlines the dispatch (the Hermite step's residual,
#: ``njit(inline="always")`` on its ``py_func``) has the law's expressions in place, as it had
#: when it inlined the law itself (with the law called from the dispatch instead, a default
#: solve took about 2 % more CPU). Same Python functions, same results to the bit.
#: (``py_func``: the Python function of a dispatcher; with NUMBA_DISABLE_JIT it is the
#: function)
_feldmann_mu_d2 = njit(inline="always")(getattr(feldmann_mu_d2, "py_func", feldmann_mu_d2))
_feldmann_mu_law = njit(inline="always")(getattr(feldmann_mu_law, "py_func", feldmann_mu_law))


@njit(cache=True)
def law_kind(law):
    """The kind (``KIND_*``) of the law with id ``law``; raises for an unregistered id."""
    if law == LAW_FELDMANN:
        return KIND_SINGLE_VALUED
    if law == LAW_COULOMB or law == LAW_TABLE:
        return KIND_SET_VALUED
    if law == LAW_LUGRE:
        return KIND_DYNAMIC
    raise ValueError("friction law: no law is registered with this id")


@njit(cache=True)
def is_set_valued(law):
    """Whether the law with id ``law`` has a stick regime with an algebraic friction force."""
    return law_kind(law) == KIND_SET_VALUED


@njit(cache=True)
def single_valued_mu(law, x, b, mu_slip, mu_stick, a1, a2):
    """A single-valued law's coefficient on its branch ``b`` and its slope.

    Parameters
    ----------
    law : int
        ``LAW_FELDMANN`` (any other id raises).
    x : float
        The law's argument [m/s] (the Feldmann law: ``v + s v_h``).
    b : float
        The branch, +1.0 or -1.0.
    mu_slip, mu_stick, a1, a2 : float
        The Feldmann law's constants ([-], [-], [s/m], [s/m]).

    Returns
    -------
    mu : float
        [-].
    dmu_dx : float
        [s/m].
    """
    if law == LAW_FELDMANN:
        return feldmann_mu(x, b, mu_slip, mu_stick, a1, a2)
    raise ValueError("friction law: single_valued_mu of a law that is not single-valued")


@njit(cache=True)
def single_valued_mu_d2(law, x, b, mu_slip, mu_stick, a1, a2):
    """:func:`single_valued_mu` and the branch's second derivative (for the Newton matrices
    of fourth-order steps, whose rate equations hold ``dmu/dx``).

    Parameters
    ----------
    law : int
        ``LAW_FELDMANN`` (any other id raises).
    x, b, mu_slip, mu_stick, a1, a2
        As :func:`single_valued_mu`.

    Returns
    -------
    mu : float
        [-].
    dmu_dx : float
        [s/m].
    d2mu_dx2 : float
        [s^2/m^2].
    """
    if law == LAW_FELDMANN:
        return _feldmann_mu_d2(x, b, mu_slip, mu_stick, a1, a2)
    raise ValueError("friction law: single_valued_mu_d2 of a law that is not single-valued")


@njit(cache=True)
def single_valued_mu_law(law, x, mu_slip, mu_stick, a1, a2):
    """A single-valued law's coefficient and its slope on the branch the law itself takes at
    ``x`` (the Feldmann law: ``b = sign(x)``, +1 at x = 0), for the schemes that keep no
    branch as a discrete state (the fixed-step schemes).

    Parameters
    ----------
    law : int
        ``LAW_FELDMANN`` (any other id raises).
    x : float
        The law's argument [m/s] (the Feldmann law: ``v + s v_h``).
    mu_slip, mu_stick, a1, a2 : float
        As :func:`single_valued_mu`.

    Returns
    -------
    mu : float
        [-].
    dmu_dx : float
        [s/m].
    """
    if law == LAW_FELDMANN:
        return _feldmann_mu_law(x, mu_slip, mu_stick, a1, a2)
    raise ValueError("friction law: single_valued_mu_law of a law that is not single-valued")


@njit(cache=True)
def dynamic_law(law, v, z, b, mu_slip, mu_stick, p):
    """A dynamic law's coefficient, its state's rate and their partial derivatives.

    Parameters
    ----------
    law : int
        A dynamic law's id (``LAW_LUGRE``; any other id raises).
    v : float
        Sliding velocity [m/s].
    z : float
        The law's state (LuGre: the bristle deflection [m]).
    b : float
        The velocity's sign in the current regime (+1.0 or -1.0).
    mu_slip, mu_stick : float
        ``friction.mu_slip``, ``friction.mu_stick`` [-].
    p : ndarray
        The law's packed parameters (``fp`` from ``kernels.N_FP``).

    Returns
    -------
    mu, zdot, dmu_dv, dmu_dz, dzdot_dv, dzdot_dz : float
        As ``roughvib.physics.friction.lugre.bristle_law``.
    """
    if law == LAW_LUGRE:
        return lugre.bristle_law(v, z, b, mu_slip, mu_stick, p)
    raise ValueError("friction law: dynamic_law of a law without internal states")
