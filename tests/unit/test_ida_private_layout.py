"""The one private use of scikit-sundae (docs/architecture.md, Conventions): IDA's step
statistics, last step and first step are reached through the SUNDIALS C API on the Cython
solver's ``mem`` pointer. This test fails with a clear assertion when a new scikit-sundae
changes that layout; the solver itself then calls no C function on the pointer and warns."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

sun = pytest.importorskip("sksundae")

from roughvib.solvers.ida import SKSUNDAE_TESTED, _IdaCounters, layout_problem  # noqa: E402


def _decay_solver(rate=3.0):
    """y' = -rate y, y(0) = 1: a DAE of one differential state, exp(-rate t) in closed form."""
    def res(t, y, yp, r):
        r[0] = yp[0] + rate * y[0]

    solver = sun.ida.IDA(res, rtol=1e-8, atol=1e-12)
    solver.init_step(0.0, np.array([1.0]), np.array([-rate]))
    return solver


def test_the_installed_scikit_sundae_has_the_layout_roughvib_reads():
    solver = _decay_solver()
    cy = vars(solver).get("_IDA__IDA")
    problem = layout_problem(cy)
    assert problem is None, (
        f"scikit-sundae {sun.__version__} changed the private layout that "
        f"roughvib.solvers.ida reads IDA's statistics from: {problem}. Check the new "
        f"_cy_ida.pyx, update _CY_IDA_BASICSIZE / the offsets / SKSUNDAE_TESTED and the pin in "
        f"pyproject.toml, or use a public API if the new version has one.")


def test_the_pin_matches_the_tested_versions():
    data = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    pins = [d for d in data["project"]["dependencies"] if d.startswith("scikit-sundae")]
    assert pins == ["scikit-sundae>=1.2,<1.3"] and SKSUNDAE_TESTED == ("1.2.",)
    assert sun.__version__.startswith(SKSUNDAE_TESTED)


def test_the_counters_agree_with_the_public_counts_and_the_closed_form():
    solver = _decay_solver()
    c = _IdaCounters(vars(solver)["_IDA__IDA"])
    r = solver.step(1.0)
    c.validate(int(r.nfev))  # the pointer gives the residual count sksundae reports
    assert c.ok and c.problem is None
    assert r.y[0] == pytest.approx(np.exp(-3.0), rel=1e-6)
    steps = c.steps()
    assert steps is not None and 0 < steps <= r.nfev  # at least one residual per step
    assert 0 < c.last_step() < 1.0


@pytest.mark.parametrize("thing", [object(), "not a solver", None])
def test_another_object_is_refused_without_calling_c(thing):
    c = _IdaCounters(thing)
    assert c.problem and "not sksundae._cy_ida.IDA" in c.problem
    assert not c.ok and c._lib is None and c.steps() is None
    c.validate(0)  # still no C call: nothing loaded
    assert not c.ok


def test_an_unset_pointer_is_refused():
    def res(t, y, yp, r):
        r[0] = yp[0] + y[0]

    solver = sun.ida.IDA(res)  # before init_step, IDA's memory does not exist
    assert layout_problem(vars(solver)["_IDA__IDA"]) == (
        "the IDA memory pointer is not set (init_step not called?)")


def test_an_untested_version_is_refused(monkeypatch):
    monkeypatch.setattr(sun, "__version__", "1.3.0")
    problem = layout_problem(vars(_decay_solver())["_IDA__IDA"])
    assert problem == "scikit-sundae 1.3.0 is not a tested version (1.2.x)"


@pytest.mark.short_run
def test_a_run_on_a_changed_layout_warns_and_reports_no_steps(monkeypatch, tmp_path):
    import roughvib
    import roughvib.solvers.ida as ida_mod
    from roughvib.simulation import simulate

    monkeypatch.chdir(tmp_path)
    scene = roughvib.load_scene("paper-handset", {
        "solver.method": "ida", "output.duration": 0.002, "output.transient": 0.0,
        "plate.max_frequency": 2000.0, "output.progress": False})
    ok = simulate(scene)
    assert ok.summary["solver"]["steps"] > 0
    monkeypatch.setattr(ida_mod, "layout_problem", lambda cy: "a changed layout (test)")
    with pytest.warns(RuntimeWarning, match=r"IDA step statistics unavailable and restarts use "
                                            r"IDA's own first step: a changed layout \(test\)"):
        r = simulate(scene)
    assert r.ok and not r.summary["solver"].get("steps")
    # the public counts stay, and the solution is the same within the tolerances
    assert r.summary["solver"]["residual_evaluations"] > 0
    np.testing.assert_allclose(r.dataset["normal_force"].values,
                               ok.dataset["normal_force"].values, rtol=1e-5)
