"""Accuracy presets: the tolerances are what docs/accuracy.md says, explicit values override
their key only, ``auto`` picks the solver, a run records what it used."""

import math
import re
import tomllib
from pathlib import Path

import pytest

import roughvib
from roughvib.scene import ACCURACY_LEVELS, ACCURACY_PRESETS, SOLVER_METHODS, SceneError
from roughvib.simulation import simulate, verification_scene

DOCS = Path(__file__).resolve().parents[2] / "docs" / "accuracy.md"
COLUMNS = ("rtol", "atol", "atol_acceleration_relative", "atol_acceleration", "step")


def _docs_presets() -> dict:
    """The presets table of docs/accuracy.md: {method: {level: {key: value}}}."""
    text = DOCS.read_text()
    section = text.split("## The presets", 1)[1].split("\n## ", 1)[0]
    out: dict = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        m = re.fullmatch(r"`([a-z-]+)`", cells[0]) if cells else None
        if not m or len(cells) != 2 + len(COLUMNS):
            continue
        level = cells[1].strip("`")
        values = {k: float(v) for k, v in zip(COLUMNS, cells[2:], strict=True)
                  if v not in ("–", "-", "")}
        out.setdefault(m.group(1), {})[level] = values
    return out


def _runs(method: str) -> dict:
    """Overrides of the paper scene that ``method`` runs: a set-valued law for a solver of
    set-valued laws only (moreau), as the solver registry says."""
    from roughvib.solvers import registry

    return {} if registry.get(method).runs_law("single-valued") else {"friction.law": "coulomb"}


def test_each_preset_is_what_the_docs_say():
    docs = _docs_presets()
    assert set(docs) == set(SOLVER_METHODS)
    for method in SOLVER_METHODS:
        assert set(docs[method]) == set(ACCURACY_LEVELS), method
        for level in ACCURACY_LEVELS:
            assert docs[method][level] == ACCURACY_PRESETS[method][level], (method, level)
            # and a scene at that preset runs with exactly these values
            s = roughvib.load_scene("paper", {"solver.method": method, **_runs(method),
                                              "solver.accuracy": level}).resolved_solver()
            for key, value in ACCURACY_PRESETS[method][level].items():
                assert getattr(s, key) == value, (method, level, key)


def test_every_fixed_step_preset_runs_on_the_default_output_grid():
    """A preset step must divide the 1e-5 s output step (a 2e-5 s draft step was refused)."""
    from roughvib.scene import FIXED_STEP_METHODS
    from roughvib.solvers.fixed_step import step_grid

    for method in FIXED_STEP_METHODS:
        for level in ACCURACY_LEVELS:
            scene = roughvib.load_scene("paper", {"solver.method": method, **_runs(method),
                                                  "solver.accuracy": level})
            resolved = scene.with_overrides({"solver.step": scene.resolved_solver().step})
            h, every, _, _ = step_grid(resolved)
            assert every * h == pytest.approx(scene.output.step), (method, level)


def test_explicit_values_override_their_key_only_and_none_restores_the_preset():
    s = roughvib.load_scene("paper", {"solver.method": "ida", "solver.rtol": 1e-9})
    r = s.resolved_solver()
    ref = ACCURACY_PRESETS["ida"]["reference"]
    assert r.rtol == 1e-9 and r.atol == ref["atol"]
    assert r.atol_acceleration_relative == ref["atol_acceleration_relative"]
    assert "rtol" not in s.solver.from_preset() and "atol" in s.solver.from_preset()
    back = s.with_overrides({"solver.rtol": "none"})
    assert back.solver.rtol is None and back.resolved_solver().rtol == ref["rtol"]
    # a method switch takes the new method's preset (nothing explicit was carried over)
    am = back.with_overrides({"solver.method": "adaptive-modal"}).resolved_solver()
    assert am.rtol == ACCURACY_PRESETS["adaptive-modal"]["reference"]["rtol"]
    with pytest.raises(SceneError, match="solver.accuracy must be one of"):
        roughvib.load_scene("paper", {"solver.accuracy": "best"})


def test_auto_runs_adaptive_modal_where_it_can_and_ida_elsewhere():
    assert roughvib.load_scene("paper").resolved_solver().method == "adaptive-modal"
    assert roughvib.load_scene("paper-100mms").resolved_solver().method == "adaptive-modal"
    coulomb = roughvib.load_scene("paper", {"friction.law": "coulomb"})
    assert coulomb.resolved_solver().method == "adaptive-modal"  # every friction law
    overdamped = roughvib.load_scene("paper", {"plate.loss_factor": 2.0})
    assert overdamped.resolved_solver().method == "ida"
    # both event-driven solvers write checkpoints: auto does not need IDA for them
    ckpt = roughvib.load_scene("paper", {"output.checkpoint_interval": 0.05})
    assert ckpt.resolved_solver().method == "adaptive-modal"
    # the second solve of --verify: the other event-driven solver, or IDA 100x tighter
    assert verification_scene(roughvib.load_scene("paper"))[0].solver.method == "ida"
    v, how = verification_scene(roughvib.load_scene("paper", {"solver.method": "ida"}))
    assert v.solver.method == "adaptive-modal" and "reference" in how
    v, how = verification_scene(coulomb)
    assert v.solver.method == "ida" and "reference" in how
    v, how = verification_scene(overdamped)
    run = overdamped.resolved_solver()
    assert v.solver.method == "ida" and "100x tighter" in how
    assert v.solver.rtol == pytest.approx(run.rtol / 100)
    assert v.solver.atol == pytest.approx(run.atol / 100)
    v, _ = verification_scene(roughvib.load_scene("paper", {"solver.method": "exact-modal"}))
    assert v.solver.method == "adaptive-modal" and v.output.checkpoint_interval == 0


@pytest.mark.short_run
def test_a_run_records_its_tolerances_and_the_pilot_scales_atol_acceleration():
    scene = roughvib.load_scene("paper", {"output.duration": 0.01, "output.progress": False,
                                          "plate.max_frequency": 5e3})
    r = simulate(scene)
    s = r.summary["solver"]
    pre = ACCURACY_PRESETS["adaptive-modal"]["reference"]
    assert s["method"] == "adaptive-modal" and s["accuracy"] == "reference"
    assert s["rtol"] == pre["rtol"] and s["atol"] == pre["atol"]
    pilot = s["pilot"]
    assert pilot["duration"] == pytest.approx(0.0025) and pilot["level"] > 0
    assert s["atol_acceleration"] == pytest.approx(pre["atol_acceleration_relative"]
                                                   * pilot["level"])
    assert "atol_acceleration" in s["from_preset"]
    # the saved scene holds the solver section as it ran, as numbers: it repeats the run
    # without a pilot (and a resumed run writes the same file)
    again = roughvib.scene.scene_from_dict(tomllib.loads(r.scene_toml))
    assert again.solver.method == "adaptive-modal" and again.solver.rtol == pre["rtol"]
    assert again.solver.atol_acceleration == s["atol_acceleration"]
    assert again.resolved_solver() == again.solver
    # an explicit absolute value: no pilot
    r2 = simulate(scene.with_overrides({"solver.atol_acceleration": 3e-9}))
    assert "pilot" not in r2.summary["solver"]
    assert r2.summary["solver"]["atol_acceleration"] == 3e-9
    assert math.isfinite(r2.summary["energy_audit"]["relative_residual"])
