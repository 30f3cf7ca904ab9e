"""The friction-law component: one module per law, their registration and the calibration of T0.

* :mod:`~roughvib.physics.friction.feldmann`: the paper's law (Eq. 10) with its latched
  hysteresis, the default;
* :mod:`~roughvib.physics.friction.coulomb` and :mod:`~roughvib.physics.friction.table`: the
  set-valued laws' kinetic curves (stick held at v = 0), and
  :mod:`~roughvib.physics.friction.setvalued` what they share;
* a dynamic law with internal states (its module named in ``LAWS``' registration);
* :mod:`~roughvib.physics.friction.laws`: the registration (ids, ``LAWS``, what each law
  declares) and the kernels' one dispatch on the law id;
* :mod:`~roughvib.physics.friction.calibration`: the tangential-only model each law declares
  and the calibration of the force amplitude T0 to a target rms velocity.

docs/architecture.md ("A friction law") gives the contract and what a new law takes. Every
name below is importable from ``roughvib.physics.friction``.
"""

from __future__ import annotations

from roughvib.physics.friction.calibration import (
    calibrate_force_amplitude,
    calibrated_force_amplitude,
    law_parameters,
    rms_over_periods,
    simulate_tangential,
)
from roughvib.physics.friction.coulomb import coulomb_kinetic
from roughvib.physics.friction.feldmann import (
    EXP_ZERO_BELOW,
    exp_or_zero,
    feldmann_mu,
    feldmann_mu_d2,
    feldmann_mu_law,
    latch_margin,
    latch_update,
    mu_reference,
)
from roughvib.physics.friction.laws import (
    KIND_DYNAMIC,
    KIND_SET_VALUED,
    KIND_SINGLE_VALUED,
    LAW_COULOMB,
    LAW_FELDMANN,
    LAW_TABLE,
    LAWS,
    FrictionLaw,
    dynamic_law,
    is_set_valued,
    law_kind,
    single_valued_mu,
    single_valued_mu_d2,
    single_valued_mu_law,
)
from roughvib.physics.friction.setvalued import kinetic_coefficient
from roughvib.physics.friction.table import (
    TAB_HEAD,
    TAB_N,
    law_table,
    load_friction_table,
    pchip_slopes,
    table_kinetic,
)

__all__ = [
    "EXP_ZERO_BELOW",
    "KIND_DYNAMIC",
    "KIND_SET_VALUED",
    "KIND_SINGLE_VALUED",
    "LAWS",
    "LAW_COULOMB",
    "LAW_FELDMANN",
    "LAW_TABLE",
    "TAB_HEAD",
    "TAB_N",
    "FrictionLaw",
    "calibrate_force_amplitude",
    "calibrated_force_amplitude",
    "coulomb_kinetic",
    "dynamic_law",
    "exp_or_zero",
    "feldmann_mu",
    "feldmann_mu_d2",
    "feldmann_mu_law",
    "is_set_valued",
    "kinetic_coefficient",
    "latch_margin",
    "latch_update",
    "law_kind",
    "law_parameters",
    "law_table",
    "load_friction_table",
    "mu_reference",
    "pchip_slopes",
    "rms_over_periods",
    "simulate_tangential",
    "single_valued_mu",
    "single_valued_mu_d2",
    "single_valued_mu_law",
    "table_kinetic",
]
