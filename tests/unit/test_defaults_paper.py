"""One source of defaults (issue 25): the dataclass defaults of the scene are the built-in
`paper` scene, so an empty scene file is `paper`, and a file that changes one key keeps the
contact module of `paper` for every other key."""

from __future__ import annotations

import dataclasses

from roughvib.scene import _SECTIONS, Scene, load_scene, scene_to_dict


def _without_names(scene: Scene) -> dict:
    d = scene_to_dict(scene)
    d.pop("name")
    d.pop("description")
    return d


def test_an_empty_scene_file_is_the_paper_scene(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "empty.toml").write_text("")
    empty, paper = load_scene(tmp_path / "empty.toml"), load_scene("paper")
    assert empty.name == paper.name == "paper"
    # every key of every section, with None values kept (scene_to_dict drops them)
    for sec in _SECTIONS:
        a, b = getattr(empty, sec), getattr(paper, sec)
        for f in dataclasses.fields(a):
            assert getattr(a, f.name) == getattr(b, f.name), f"{sec}.{f.name}"
    assert _without_names(empty) == _without_names(paper)
    assert _without_names(Scene()) == _without_names(paper)


def test_the_paper_scene_file_sets_nothing_but_its_name(tmp_path, monkeypatch):
    import tomllib
    from importlib import resources

    monkeypatch.chdir(tmp_path)
    data = tomllib.loads(resources.files("roughvib.scenes").joinpath("paper.toml").read_text())
    assert set(data) == {"name", "description"}


def test_a_file_that_changes_only_the_mass_keeps_the_contact_module(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "heavy.toml").write_text('name = "heavy"\n\n[block]\nmass = 0.543\n')
    scene = load_scene(tmp_path / "heavy.toml")
    assert scene.block.mass == 0.543
    assert scene.contact.points == "auto" and scene.contact.stiffness == "auto"
    assert scene.contact.velocity_factor is True and scene.block.vertical_damping == "auto"
    # and it is the built-in heavy scene apart from its name
    assert _without_names(scene) == _without_names(load_scene("paper-heavy"))


def test_the_hand_set_scene_keeps_the_hand_set_contact(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    s = load_scene("paper-handset")
    assert (s.contact.points, s.contact.stiffness, s.block.vertical_damping,
            s.contact.velocity_factor) == (10, 3.1e6, 83.0, False)
    # it differs from paper in exactly those four keys
    a, b = _without_names(s), _without_names(load_scene("paper"))
    diff = {f"{sec}.{k}" for sec in a for k in a[sec] if a[sec][k] != b[sec].get(k)}
    assert diff == {"contact.points", "contact.stiffness", "block.vertical_damping",
                    "contact.velocity_factor"}


SHORT = ["--set", "output.duration=0.005", "--set", "plate.max_frequency=2000", "--no-progress",
         "--quiet"]


def test_a_block_at_rest_runs_with_the_default_velocity_factor(tmp_path, monkeypatch):
    """A default never makes a valid scene invalid: the static check of a block resting on the
    plate (no roughness, prescribed motion of zero rms) runs with contact.velocity_factor =
    true left at its default; the factor is 1 there, and the saved scene says why."""
    import json
    import math

    from roughvib.cli import main
    from roughvib.physics.surface.contact import GRAVITY, contact_stiffness

    monkeypatch.chdir(tmp_path)
    rest = ["--set", "roughness.kind=none", "--set", "excitation.kind=prescribed",
            "--set", "excitation.velocity=0", "--set", "excitation.amplitude=0"]
    assert main(["run", "paper", "--out", "rest", *rest, *SHORT]) == 0
    summary = json.loads((tmp_path / "rest" / "summary.json").read_text())
    assert summary["status"] == "success"
    stat = summary["calibration"]["contact_stiffness"]
    assert stat["velocity_factor"] == 1.0
    assert stat["velocity_factor_note"].startswith("contact.velocity_factor not applied: the "
                                                   "block does not slide")
    # at rest the contacts carry the weight, m g, and nothing else
    m = load_scene("paper").block.mass
    assert math.isclose(summary["metrics"]["normal_force_mean"], m * GRAVITY, rel_tol=1e-3)
    # the saved scene repeats the run: the static stiffness, the factor off, the reason given
    text = (tmp_path / "rest" / "scene.toml").read_text()
    line = next(x for x in text.splitlines() if x.startswith("velocity_factor"))
    assert line.startswith("velocity_factor = false  # contact.velocity_factor not applied")
    static = contact_stiffness(load_scene("paper", {"roughness.kind": "none",
                                                    "contact.velocity_factor": False}))
    assert load_scene(tmp_path / "rest" / "scene.toml").contact.stiffness == static.s_total


def test_the_saved_paper_scene_says_where_its_velocity_factor_went(tmp_path, monkeypatch):
    """paper uses the velocity factor; its saved scene.toml holds the stiffness with the factor
    applied and the factor off (so that it is not applied twice), and says so on both keys."""
    from roughvib.cli import main
    from roughvib.physics.surface.contact import contact_stiffness

    monkeypatch.chdir(tmp_path)
    assert main(["run", "paper", "--out", "p", *SHORT]) == 0
    lines = (tmp_path / "p" / "scene.toml").read_text().splitlines()
    stiff = next(x for x in lines if x.startswith("stiffness = "))
    vf = next(x for x in lines if x.startswith("velocity_factor = "))
    cs = contact_stiffness(load_scene("paper"))
    assert cs.velocity_factor_note == ""  # applied: paper states 0.01 m/s rms
    assert stiff.endswith(f"# contact module (gw), velocity factor {cs.velocity_factor:.4g} "
                          f"applied")
    assert vf == (f"velocity_factor = false  # the scene's velocity factor "
                  f"({cs.velocity_factor:.4g}) is already in contact.stiffness")
    assert load_scene(tmp_path / "p" / "scene.toml").contact.stiffness == cs.s_total
