"""The energy audit on a quiet run (issue 25): no roughness, so nothing but the block's
tangential stick-slip moves and the solvers take long steps. The audit's energy integrals are
quadratures over those steps; their error test weighs them by their running totals, so on
long steps their quadrature error, not the tolerance, set the residual (docs/robustness.md,
"Energy audit"). Measured on one period of `paper` without roughness (relative residuals):
adaptive-modal 1.16e-8 at rtol 1e-6 and 1e-10 alike with trapezoidal integrals, 4.0e-9 with
Simpson's rule, 4.4e-10 with solver.max_step = 5e-6 s; IDA at rtol 1e-7 1.3e-5, 9.1e-8 with
solver.max_step = 1e-5 s."""

import pytest

import roughvib
from roughvib.api import simulate

PERIOD = 1.0 / 7.0


def _audit(method, **over):
    scene = roughvib.load_scene("paper", {
        "roughness.kind": "none", "output.duration": PERIOD, "output.transient": 0.0,
        "output.progress": False, "solver.method": method, **over})
    r = simulate(scene)
    assert r.ok, r.summary["message"]
    return r.summary["energy_audit"]["relative_residual"]


def test_adaptive_modal_meets_50_rtol_at_rtol_1e_10_and_its_floor_is_the_step():
    rtol = 1e-10
    capped = _audit("adaptive-modal", **{"solver.rtol": rtol})
    # the documented bound (was 1.16e-8 with the trapezoidal energy integrals)
    assert abs(capped) < 50 * rtol
    # the rest is set by the largest step (the output step), not by the tolerance: halving
    # the step lowers it about 9x (a fourth-order quadrature of a second-order scheme)
    finer = _audit("adaptive-modal", **{"solver.rtol": rtol, "solver.max_step": 5e-6})
    assert abs(finer) < abs(capped) / 4


@pytest.mark.slow
def test_ida_quiet_run_audit_is_limited_by_its_steps_not_by_rtol():
    rtol = 1e-7  # the reference preset
    long_steps = _audit("ida", **{"solver.rtol": rtol})
    short_steps = _audit("ida", **{"solver.rtol": rtol, "solver.max_step": 1e-5})
    # the documented bound for IDA on quiet runs: 200 rtol on IDA's own steps ...
    assert abs(long_steps) < 200 * rtol
    # ... and 50 rtol once the steps are bounded: the integrals' quadrature error was the cause
    assert abs(short_steps) < 50 * rtol and abs(short_steps) < abs(long_steps) / 20
