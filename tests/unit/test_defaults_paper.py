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
