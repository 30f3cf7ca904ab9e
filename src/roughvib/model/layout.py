"""Named state layout: state names <-> slices of the solver's state vector.

Only the states a scene requires exist: a rigid plate has no ``plate.q``/``plate.dq``, a
prescribed tangential motion has no ``block.x``/``block.vx``. The order is

    plate.q (R), plate.dq (R), block.z, block.vz, [block.x, block.vx], contact.force (K),
    [friction.force], [friction.state (n)], energy.* (6 running integrals for the energy
    audit)

``contact.force`` and ``friction.force`` (set-valued laws only) are algebraic (DAE);
``friction.state`` holds a dynamic law's internal states (e.g. a bristle deflection),
as many as the law declares (``FrictionLaw.states``); everything else is differential. Outside this
module no code indexes the state with bare integers: use :meth:`StateLayout.slice` or the
``index`` attributes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ENERGY_TERMS", "N_OFF", "OFF_IDQ", "OFF_IE", "OFF_IF", "OFF_IL", "OFF_IPSI", "OFF_IQ",
           "OFF_IS", "OFF_IVX", "OFF_IVZ", "OFF_IX", "OFF_IZ", "OFF_K", "OFF_LAW", "OFF_R",
           "StateLayout"]

# Positions in the int64 header ``off`` that every kernel receives (:meth:`StateLayout.offsets`).
# numba reads module-level integers as compile-time constants, so ``off[OFF_IZ]`` compiles to
# the same code as a literal index.
OFF_IQ = 0    #: first plate.q
OFF_IDQ = 1   #: first plate.dq
OFF_IZ = 2    #: block.z
OFF_IVZ = 3   #: block.vz
OFF_IX = 4    #: block.x, -1 for prescribed tangential motion
OFF_IVX = 5   #: block.vx, -1 for prescribed tangential motion
OFF_IF = 6    #: first contact.force
OFF_IE = 7    #: first energy integral
OFF_R = 8     #: number of plate modes R
OFF_K = 9     #: number of contacts K
OFF_IL = 10   #: friction.force (set-valued laws), -1 otherwise
OFF_LAW = 11  #: friction-law id (roughvib.physics.friction.LAW_*)
#: first position in ``fp`` of the friction moment's lever-scaled slopes (K x R, contact-major:
#: ``fp[off[OFF_IPSI] + k R + r]`` = hp/2 dphi_r/dx at contact k [1/sqrt(kg)]), -1 when
#: ``contact.friction_moment`` is off
OFF_IPSI = 12
OFF_IS = 13   #: first friction.state (a dynamic law's internal states), -1 without one
N_OFF = 14

#: running integrals appended to the state (all in J): their time derivatives are powers
ENERGY_TERMS = (
    "excitation_work",          # int T_exc * vx dt
    "friction_dissipation",     # int mu * F_N * vx dt
    "tangential_damping",       # int r2 * vx^2 dt
    "vertical_damping",         # int r1 * vz^2 dt
    "plate_damping",            # int sum_r 2 zeta_r w_r M dq_r^2 dt
    "roughness_work",           # int sum_k F_k z'(s_k + x) vx dt  (kinematic input power)
)
#: positions of the energy integrals, relative to the first (``off[OFF_IE]``), in the order
#: of ENERGY_TERMS
E_EXCITATION = 0
E_FRICTION = 1
E_TANGENTIAL_DAMPING = 2
E_VERTICAL_DAMPING = 3
E_PLATE_DAMPING = 4
E_ROUGHNESS = 5
N_ENERGY = len(ENERGY_TERMS)


@dataclass(frozen=True)
class StateLayout:
    """Positions of the named states in the state vector.

    Parameters
    ----------
    n_modes : int
        R, number of plate modes (0 for a rigid plate).
    n_contacts : int
        K, number of contact springs.
    tangential : bool
        Whether the block's tangential position and velocity are states.
    friction_state : bool
        Whether the friction force is an algebraic state (set-valued laws).
    law_states : int
        Internal states of a dynamic friction law (``friction.state``), 0 without one.
    """

    n_modes: int
    n_contacts: int
    tangential: bool
    friction_state: bool = False
    law_states: int = 0
    _slices: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        r, k = self.n_modes, self.n_contacts
        sizes = [("plate.q", r), ("plate.dq", r), ("block.z", 1), ("block.vz", 1)]
        if self.tangential:
            sizes += [("block.x", 1), ("block.vx", 1)]
        sizes += [("contact.force", k)]
        if self.friction_state:
            sizes += [("friction.force", 1)]
        if self.law_states:
            sizes += [("friction.state", self.law_states)]
        sizes += [(f"energy.{name}", 1) for name in ENERGY_TERMS]
        slices = {}
        pos = 0
        for name, size in sizes:
            slices[name] = slice(pos, pos + size)
            pos += size
        object.__setattr__(self, "_slices", slices)

    @property
    def size(self) -> int:
        """Length of the state vector."""
        return max(s.stop for s in self._slices.values())

    @property
    def names(self) -> tuple[str, ...]:
        """State names in order."""
        return tuple(self._slices)

    def slice(self, name: str) -> slice:
        """Slice of a named state (KeyError naming the known states otherwise)."""
        try:
            return self._slices[name]
        except KeyError:
            raise KeyError(f"no state {name!r} in this layout (known: "
                           f"{', '.join(self._slices)})") from None

    def index(self, name: str) -> int:
        """Index of a scalar state, or -1 if the state does not exist in this layout."""
        s = self._slices.get(name)
        if s is None:
            return -1
        if s.stop - s.start != 1:
            raise ValueError(f"state {name!r} is not scalar (size {s.stop - s.start})")
        return s.start

    def has(self, name: str) -> bool:
        """Whether a named state exists in this layout."""
        return name in self._slices

    @property
    def algebraic_indices(self) -> np.ndarray:
        """Indices of algebraic unknowns (contact forces, and the friction force if present)."""
        s = self._slices["contact.force"]
        idx = list(range(s.start, s.stop))
        if self.friction_state:
            idx.append(self.index("friction.force"))
        return np.array(idx, dtype=np.int64)

    def offsets(self, law: int = 0) -> np.ndarray:
        """Integer header handed to the kernels, positions ``OFF_*`` of this module.

        ``off[OFF_IX]``/``off[OFF_IVX]`` are -1 for prescribed tangential motion,
        ``off[OFF_IL]`` (friction force) is -1 unless the friction force is a state,
        ``off[OFF_IS]`` (first friction.state) -1 unless the law has internal states;
        ``off[OFF_LAW]`` is the friction-law id ``law`` (``roughvib.physics.friction``).
        """
        off = np.empty(N_OFF, dtype=np.int64)
        off[OFF_IQ] = self._slices["plate.q"].start
        off[OFF_IDQ] = self._slices["plate.dq"].start
        off[OFF_IZ] = self.index("block.z")
        off[OFF_IVZ] = self.index("block.vz")
        off[OFF_IX] = self.index("block.x")
        off[OFF_IVX] = self.index("block.vx")
        off[OFF_IF] = self._slices["contact.force"].start
        off[OFF_IE] = self._slices["energy." + next(iter(ENERGY_TERMS))].start
        off[OFF_R] = self.n_modes
        off[OFF_K] = self.n_contacts
        off[OFF_IL] = self.index("friction.force")
        off[OFF_LAW] = law
        off[OFF_IPSI] = -1  # no friction moment; roughvib.model.system.assemble sets it
        off[OFF_IS] = self._slices["friction.state"].start if self.law_states else -1
        return off
