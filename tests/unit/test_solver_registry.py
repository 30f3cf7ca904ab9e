"""The solver registry (roughvib.solvers.registry) is the one place that says what each solver
runs: scene validation refuses what a solver cannot run when the scene is loaded, in one line
naming ``solver.method``, the key that rules it out and what would run the scene; ``simulate``
and ``roughvib compare`` take their solvers from it; the docs' tables say what it says."""

import ast
import os
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

import roughvib
from roughvib.scene import ACCURACY_PRESETS, FIXED_STEP_METHODS, SOLVER_METHODS, SceneError
from roughvib.solvers import registry

DOCS = Path(__file__).resolve().parents[2] / "docs"


def _scene(tmp_path: Path, overrides: dict | None = None):
    """The paper scene from a file in ``tmp_path`` (files it names are looked for there), with
    ``overrides``; a table law finds its curve there."""
    (tmp_path / "curve.csv").write_text("velocity,mu\n0.0,0.3\n1.0,0.3\n")
    path = tmp_path / "scene.toml"
    path.write_text("")  # an empty file is the paper scene
    return roughvib.load_scene(path, overrides)


def _first_table(text: str) -> list[list[str]]:
    """The rows (cells stripped) of the first Markdown table in ``text``, header and rule
    left out."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.lstrip().startswith("|"))
    rows = []
    for line in lines[start:]:
        if not line.lstrip().startswith("|"):
            break
        rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows[2:]


# --------------------------------------------------------------------------------------------
# the registry and the docs
# --------------------------------------------------------------------------------------------


def test_the_solver_table_of_the_docs_lists_the_registered_solvers():
    rows = _first_table((DOCS / "solvers.md").read_text())
    listed = [re.fullmatch(r"`([a-z-]+)`", r[0]).group(1) for r in rows]
    assert listed == list(registry.names())


def test_the_scene_module_and_the_registry_agree():
    assert SOLVER_METHODS == registry.names()
    assert FIXED_STEP_METHODS == registry.names(registry.STEP)
    assert set(registry.names(registry.TOLERANCE)) | set(FIXED_STEP_METHODS) == set(SOLVER_METHODS)
    for m in registry.methods():
        assert ACCURACY_PRESETS[m.name] == m.presets


def test_the_friction_laws_name_the_solvers_the_registry_gives_them():
    from roughvib.physics.friction import LAWS
    from roughvib.scene import SET_VALUED_LAWS

    assert [n for n, law in LAWS.items() if law.set_valued] == list(SET_VALUED_LAWS)
    for name, law in LAWS.items():
        kind = ("set-valued" if name in SET_VALUED_LAWS
                else "dynamic" if law.states else "single-valued")
        assert law.solvers == tuple(m.name for m in registry.methods()
                                    if kind in m.friction), name
    # and docs/friction.md's table says the same
    for row in _first_table((DOCS / "friction.md").read_text()):
        law = re.match(r"`([a-z]+)`", row[0]).group(1)
        assert set(re.findall(r"`([a-z-]+)`", row[-1])) == set(LAWS[law].solvers), law


#: the rows of docs/architecture.md's table "which solver takes which component": the scenes
#: that show each row (every one must agree with the row)
COMPONENT_SCENES = {
    "plate, imported modes": [{"plate.kind": "imported", "plate.modes_file": "modes.npz"}],
    "rigid base": [{"plate.kind": "rigid"}],
    "critically damped modes (`plate.loss_factor = 2`)": [{"plate.loss_factor": 2.0}],
    "Feldmann law": [{"friction.law": "feldmann"}],
    "coulomb, table": [{"friction.law": "coulomb"},
                       {"friction.law": "table", "friction.table": "curve.csv"}],
    "LuGre law": [{"friction.law": "lugre"}],
    "prescribed motion, any law": [
        {"excitation.kind": "prescribed", "excitation.velocity": 0.01,
         "excitation.force_amplitude": "none", "friction.law": law}
        for law in ("feldmann", "coulomb")],
    "point or area patch": [{"contact.patch": "point"}, {"contact.patch": "area"}],
    "friction moment": [{"contact.friction_moment": True}],
    "checkpoints": [{"output.checkpoint_interval": 0.01}],
}


def _architecture_table() -> tuple[list[str], dict[str, list[str]]]:
    text = (DOCS / "architecture.md").read_text()
    part = text.split("| component |", 1)[1]
    header = [c.strip() for c in ("component |" + part.split("\n", 1)[0]).strip("|").split("|")]
    rows = {}
    for line in part.split("\n")[2:]:
        if not line.strip().startswith("|"):
            break
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        rows[cells[0]] = cells[1:]
    return header[1:], rows


def test_the_architecture_table_of_components_is_what_the_registry_says(tmp_path):
    methods, rows = _architecture_table()
    assert sorted(methods) == sorted(registry.names())
    assert set(rows) == set(COMPONENT_SCENES)
    for component, cells in rows.items():
        for method, cell in zip(methods, cells, strict=True):
            m = registry.get(method)
            for over in COMPONENT_SCENES[component]:
                # the rest of the scene is one the solver runs (moreau: a set-valued law)
                base = {} if m.runs_law("single-valued") else {"friction.law": "coulomb"}
                scene = _scene(tmp_path, {**base, **over})
                assert (m.supports(scene) is None) == cell.startswith("yes"), (
                    component, method, over, m.supports(scene))


# --------------------------------------------------------------------------------------------
# refused when the scene is loaded
# --------------------------------------------------------------------------------------------

REFUSED = [
    # (overrides, method, the key that rules it out, what runs the scene instead)
    ({"friction.law": "coulomb"}, "newmark", "friction.law = 'coulomb'",
     "ida, adaptive-modal or moreau"),
    ({"friction.law": "coulomb"}, "exact-modal", "friction.law = 'coulomb'",
     "ida, adaptive-modal or moreau"),
    ({"friction.law": "feldmann"}, "moreau", "friction.law = 'feldmann'",
     "ida, adaptive-modal, exact-modal, newmark or paper"),
    ({"friction.law": "table", "friction.table": "curve.csv"}, "paper",
     "friction.law = 'table'", "ida, adaptive-modal or moreau"),
    ({"contact.friction_moment": True}, "exact-modal", "contact.friction_moment = true",
     "ida or adaptive-modal"),
    ({"contact.friction_moment": True}, "newmark", "contact.friction_moment = true",
     "ida or adaptive-modal"),
    ({"contact.friction_moment": True}, "paper", "contact.friction_moment = true",
     "ida or adaptive-modal"),
    ({"contact.friction_moment": True, "friction.law": "coulomb"}, "moreau",
     "contact.friction_moment = true", "ida or adaptive-modal"),
    ({"output.checkpoint_interval": 0.01}, "newmark", "output.checkpoint_interval = 0.01 s",
     "ida or adaptive-modal"),
    ({"plate.kind": "rigid"}, "paper", "plate.kind = 'rigid'",
     "ida, adaptive-modal, exact-modal or newmark"),
    ({"plate.max_frequency": 100.0}, "paper", "plate.max_frequency = 100 Hz",
     "ida, adaptive-modal, exact-modal or newmark"),
    ({"plate.loss_factor": 2.0}, "paper", "plate.loss_factor = 2",
     "ida, exact-modal or newmark"),
    ({"plate.loss_factor": 2.0}, "adaptive-modal", "plate.loss_factor = 2",
     "ida, exact-modal or newmark"),
]


@pytest.mark.parametrize("over,method,key,others", REFUSED,
                         ids=[f"{m}-{k.split(' ')[0]}" for _, m, k, _ in REFUSED])
def test_a_scene_the_solver_cannot_run_is_refused_at_load_in_one_line(tmp_path, over, method,
                                                                        key, others):
    with pytest.raises(SceneError) as info:
        _scene(tmp_path, {**over, "solver.method": method})
    msg = str(info.value)
    assert "\n" not in msg
    assert re.fullmatch(rf"solver\.method = '{method}' cannot run this scene: "
                        rf"{re.escape(key)}( .*)?, and {method} .*; use {re.escape(others)}",
                        msg), msg
    # supports() says the same, without the solver.method prefix
    scene = _scene(tmp_path, over)
    assert msg.endswith(registry.get(method).supports(scene))


def test_the_issue_example_is_refused_by_roughvib_load_scene(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a built-in scene's files would be looked for here
    with pytest.raises(SceneError, match=r"^solver.method = 'newmark' cannot run this scene: "
                                         r"friction.law = 'coulomb' is set-valued"):
        roughvib.load_scene("paper", {"friction.law": "coulomb", "solver.method": "newmark"})
    assert list(tmp_path.iterdir()) == []


def test_a_prescribed_motion_runs_on_every_solver_with_any_law(tmp_path):
    """A prescribed motion has no friction model: no solver refuses its law."""
    for law in ("feldmann", "coulomb"):
        scene = _scene(tmp_path, {"excitation.kind": "prescribed", "excitation.velocity": 0.01,
                                  "excitation.force_amplitude": "none", "friction.law": law})
        assert registry.supporting(scene) == registry.names()


def test_auto_takes_the_first_solver_of_auto_that_runs_the_scene(tmp_path):
    assert registry.AUTO == ("adaptive-modal", "ida")
    assert _scene(tmp_path).resolved_solver().method == "adaptive-modal"
    for law in ("coulomb", "feldmann"):
        over = {"friction.law": law, "contact.friction_moment": True}
        assert _scene(tmp_path, over).resolved_solver().method == "adaptive-modal"
    assert _scene(tmp_path, {"plate.loss_factor": 2.0}).resolved_solver().method == "ida"
    assert _scene(tmp_path, {"plate.kind": "rigid", "plate.loss_factor": 2.0}
                  ).resolved_solver().method == "adaptive-modal"  # no modes to damp


def test_a_scene_auto_cannot_run_is_refused_naming_each_reason(tmp_path, monkeypatch):
    scene = _scene(tmp_path, {"plate.loss_factor": 2.0})
    monkeypatch.setitem(registry._METHODS, "ida",
                        replace(registry.get("ida"), friction="single-valued"))
    with pytest.raises(SceneError, match=r"^solver.method = 'auto' finds no solver for this "
                                         r"scene \(adaptive-modal: plate.loss_factor = 2 .*; "
                                         r"ida: friction.law = 'coulomb' is set-valued .*\); "
                                         r"use moreau$"):
        scene.with_overrides({"friction.law": "coulomb"})


# --------------------------------------------------------------------------------------------
# calling the solvers
# --------------------------------------------------------------------------------------------


def test_the_registry_names_its_solvers_and_imports_none_of_them():
    tree = ast.parse(Path(registry.__file__).read_text())
    imported = [n.module if isinstance(n, ast.ImportFrom) else a.name
                for n in ast.walk(tree) if isinstance(n, ast.Import | ast.ImportFrom)
                for a in n.names]
    assert not [m for m in imported if m and m.startswith("roughvib")], imported
    for m in registry.methods():
        module, function = m.solve.split(":")
        assert module.startswith("roughvib.solvers.") and callable(m.solve_function()), m.name
    # validating a scene imports no solver and no numerical library
    code = ("import sys, roughvib\n"
            "roughvib.load_scene('paper', {'solver.method': 'newmark'})\n"
            "print(' '.join(sorted(sys.modules)))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    loaded = p.stdout.split()
    assert [m for m in loaded if m.startswith("roughvib.solvers")] == [
        "roughvib.solvers", "roughvib.solvers.registry"]
    assert not [m for m in loaded if m.split(".")[0] in ("numpy", "numba", "scipy")]


def test_registering_a_solver_is_all_a_new_solver_needs(monkeypatch):
    """A solver registered under a new name is a choice of solver.method, resolves its own
    presets and is what simulate runs (here IDA's solve function under another name)."""
    ida = registry.get("ida")
    copy = replace(ida, name="ida-copy", presets={
        level: {**values, "rtol": 1e-5} for level, values in ida.presets.items()})
    monkeypatch.setitem(registry._METHODS, "ida-copy", copy)
    with pytest.raises(ValueError, match="already registered"):
        registry.register(copy)
    scene = roughvib.load_scene("paper", {"solver.method": "ida-copy", "output.duration": 0.002,
                                          "output.transient": 0.0, "output.progress": False,
                                          "plate.max_frequency": 2e3,
                                          "excitation.force_amplitude": 0.915,
                                          "excitation.target_rms_velocity": "none"})
    assert scene.resolved_solver().rtol == 1e-5
    with pytest.warns(roughvib.scene.ModelValidityWarning, match="analysis window"):
        r = roughvib.simulate(scene)
    assert r.ok, r.summary["message"]
    assert r.summary["solver"]["method"] == "ida-copy" and r.summary["solver"]["rtol"] == 1e-5
    assert r.summary["solver"]["steps"] > 0


def test_compare_runs_the_solvers_that_run_the_scene(tmp_path):
    from roughvib.studies.compare import study_methods

    assert study_methods(_scene(tmp_path)) == ("ida", "adaptive-modal", "exact-modal",
                                                "newmark", "paper")
    coulomb = _scene(tmp_path, {"friction.law": "coulomb"})
    assert study_methods(coulomb) == ("ida", "adaptive-modal", "moreau")
    assert study_methods(coulomb, ["moreau", "ida"]) == ("moreau", "ida")
    with pytest.raises(SceneError, match=r"^solver.method = 'newmark' cannot run this scene: "
                                         r"friction.law = 'coulomb' is set-valued.*; use ida, "
                                         r"adaptive-modal or moreau$"):
        study_methods(coulomb, ["ida", "newmark"])
