"""Named state layout: state names <-> slices of the solver's state vector.

Only the states a scene requires exist: a rigid plate has no ``plate.q``/``plate.dq``, a
prescribed tangential motion has no ``block.x``/``block.vx``. The order is

    plate.q (R), plate.dq (R), block.z, block.vz, [block.x, block.vx], contact.force (K),
    [friction.force], energy.* (6 running integrals for the energy audit)

``contact.force`` and ``friction.force`` (set-valued Coulomb law only) are algebraic (DAE);
everything else is differential. Outside this
module no code indexes the state with bare integers: use :meth:`StateLayout.slice` or the
``index`` attributes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ENERGY_TERMS", "StateLayout"]

#: running integrals appended to the state (all in J): their time derivatives are powers
ENERGY_TERMS = (
    "excitation_work",          # int T_exc * vx dt
    "friction_dissipation",     # int mu * F_N * vx dt
    "tangential_damping",       # int r2 * vx^2 dt
    "vertical_damping",         # int r1 * vz^2 dt
    "plate_damping",            # int sum_r 2 zeta_r w_r M dq_r^2 dt
    "roughness_work",           # int sum_k F_k z'(s_k + x) vx dt  (kinematic input power)
)


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
        Whether the friction force is an algebraic state (set-valued Coulomb law).
    """

    n_modes: int
    n_contacts: int
    tangential: bool
    friction_state: bool = False
    _slices: dict = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        r, k = self.n_modes, self.n_contacts
        sizes = [("plate.q", r), ("plate.dq", r), ("block.z", 1), ("block.vz", 1)]
        if self.tangential:
            sizes += [("block.x", 1), ("block.vx", 1)]
        sizes += [("contact.force", k)]
        if self.friction_state:
            sizes += [("friction.force", 1)]
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

    def offsets(self) -> np.ndarray:
        """Integer array handed to the kernels: [iq, idq, iz, ivz, ix, ivx, iF, iE, R, K, iL].

        ``ix``/``ivx`` are -1 for prescribed tangential motion, ``iL`` (friction force) is -1
        unless the friction force is a state.
        """
        return np.array([
            self._slices["plate.q"].start, self._slices["plate.dq"].start,
            self.index("block.z"), self.index("block.vz"),
            self.index("block.x"), self.index("block.vx"),
            self._slices["contact.force"].start,
            self._slices[f"energy.{ENERGY_TERMS[0]}"].start,
            self.n_modes, self.n_contacts, self.index("friction.force"),
        ], dtype=np.int64)
