"""The compiled parts of the adaptive exact-modal solver (:mod:`roughvib.solvers.adaptive_modal`
is its driver, and the module other code imports).

One responsibility each (docs/architecture.md, "adaptive-modal's two steps"):

* :mod:`.layout`: the step levels, cache slots, return codes, loop-state indices and buffer
  rows both step loops and the driver share;
* :mod:`.propagators`: the plate modes' exact first-order-hold step maps, their cache, and the
  modal forces (contact forces, friction moment);
* :mod:`.trapezoidal`: the trapezoidal step and its Newton solve;
* :mod:`.error`: error control (the step-doubling norm, the level after a rejection) and
  local extrapolation;
* :mod:`.roots`: the Illinois root search's trial and bracket update;
* :mod:`.loop_common`: what both loops do at entry, before each attempt and at output times;
* :mod:`.trapezoidal_loop`: the loop of the trapezoidal step;
* :mod:`.hermite_loop`: the loop of the Hermite step (:mod:`roughvib.solvers.hermite`).
"""
