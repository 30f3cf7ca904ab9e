"""Scene contract: defaults, validation messages, TOML round trip, overrides."""

import math

import numpy as np
import pytest

from roughvib.scene import SceneError, builtin_scenes, load_scene, scene_from_dict, scene_to_toml


def test_empty_file_is_the_paper_scene_and_handset_sets_the_hand_set_contact(tmp_path):
    f = tmp_path / "empty.toml"
    f.write_text("")
    empty = load_scene(f)
    paper = load_scene("paper")
    for sec in ("block", "plate", "contact", "roughness", "friction", "excitation", "solver",
                "output"):
        assert getattr(empty, sec) == getattr(paper, sec)
    # the built-in hand-set scene differs only in the contact module's keys
    handset = load_scene("paper-handset")
    module = {"block.vertical_damping": "auto", "contact.points": "auto",
              "contact.stiffness": "auto", "contact.velocity_factor": True}
    assert paper.with_overrides({"name": "paper-handset",
                                 "description": handset.description}) != handset
    assert load_scene("paper-handset", module).contact == paper.contact
    assert load_scene("paper-handset", module).block == paper.block
    for sec in ("plate", "roughness", "friction", "excitation", "solver", "output"):
        assert getattr(paper, sec) == getattr(handset, sec)


def test_builtin_scenes_listed_with_descriptions():
    names = builtin_scenes()
    assert {"paper", "paper-100mms", "paper-heavy", "paper-heavy-100mms"} <= set(names)
    assert all(names.values())
    heavy = load_scene("paper-heavy-100mms")
    assert heavy.block.mass == 0.543
    assert heavy.excitation.target_rms_velocity == 0.1


@pytest.mark.filterwarnings("ignore:the analysis window:UserWarning")
def test_paper_100mms_sticks_briefly_at_the_reversals_as_its_description_says(tmp_path,
                                                                               monkeypatch):
    """`roughvib scenes` said "(no stick)"; a run sticks at every velocity reversal, briefly."""
    import roughvib

    monkeypatch.chdir(tmp_path)
    assert "brief sticks at the reversals only" in builtin_scenes()["paper-100mms"]
    scene = load_scene("paper-100mms", {"output.duration": 2 / 7, "output.transient": 1 / 7,
                                        "plate.max_frequency": 2000.0, "output.progress": False})
    res = roughvib.simulate(scene)
    ev = res.events
    v = res.dataset["block_tangential_velocity"].values
    t = res.dataset["time"].values
    window = t >= 1 / 7
    reversals = int(np.sum(np.diff(np.sign(v[window][np.abs(v[window]) > 1e-4])) != 0))
    sticks = ev[(ev["kind"] == "stick") & (ev["time"] >= 1 / 7)]
    assert reversals == 2 and len(sticks) == reversals  # one stick per reversal
    assert 0 < res.summary["metrics"]["stick_fraction"] < 0.05  # and a brief one


def test_paper_defaults_follow_physics_brief():
    s = load_scene("paper")
    assert s.block.mass == 0.221
    assert s.plate.length == 0.30 and s.plate.width == 0.26 and s.plate.thickness == 0.003
    assert s.contact.points == "auto" and s.contact.stiffness == "auto"
    assert load_scene("paper-handset").contact.points == 10
    assert s.excitation.frequency == 7.0
    assert s.excitation.target_rms_velocity == 0.01
    assert s.output.step == 1e-5
    # B' = E h^3 / (12 (1 - nu^2)) = 519.2 N m, m'' = 23.55 kg/m^2 (docs/theory.md, The plate)
    assert math.isclose(s.plate.bending_stiffness, 519.2, rel_tol=1e-3)
    assert math.isclose(s.plate.mass_per_area, 23.55, rel_tol=1e-12)


@pytest.mark.parametrize("key,value,fragment", [
    ("plate.thickness", -0.003, "plate.thickness must be > 0 m, got -0.003"),
    ("block.mass", "heavy", "block.mass must be a number kg, got 'heavy'"),
    ("contact.points", 2.5, "contact.points must be an integer, got 2.5"),
    ("plate.kind", "elastic",
     "plate.kind must be one of 'modal', 'rigid', 'imported', got 'elastic'"),
    ("plate.poisson_ratio", 0.7, "plate.poisson_ratio must be in [0.0, 0.5)"),
    ("plate.observation_position", [0.5, 0.1], "plate.observation_position[0] must be inside"),
    ("output.step", 1.0, "output.step must be <= output.duration"),
    ("block.sizes", 1, "block.sizes is not a known key of [block]"),
    ("blocks.mass", 1, "blocks.mass is not a scene key"),
    ("friction.mu_stick", 0.1, "friction.mu_stick must be >= friction.mu_slip"),
    ("solver.rtol", 0.5, "solver.rtol must be in"),
])
def test_bad_values_name_field_rule_unit_value(key, value, fragment):
    with pytest.raises(SceneError) as info:
        load_scene("paper", {key: value})
    msg = str(info.value)
    assert fragment in msg
    assert "\n" not in msg


def test_excitation_needs_exactly_one_of_force_or_target():
    with pytest.raises(SceneError, match="exactly one of force_amplitude"):
        load_scene("paper", {"excitation.force_amplitude": 1.0})
    s = load_scene("paper", {"excitation.force_amplitude": 1.0,
                             "excitation.target_rms_velocity": "none"})
    assert s.excitation.force_amplitude == 1.0 and s.excitation.target_rms_velocity is None


def test_toml_round_trip_and_overrides(tmp_path):
    s = load_scene("paper-heavy", **{"output.duration": 0.2}, block__tangential_damping=0.7)
    assert s.output.duration == 0.2 and s.block.tangential_damping == 0.7
    f = tmp_path / "s.toml"
    f.write_text(scene_to_toml(s))
    back = load_scene(f)
    assert back == s


def test_unknown_section_and_type_errors():
    with pytest.raises(SceneError, match="not a scene section"):
        scene_from_dict({"plates": {}})
    with pytest.raises(SceneError, match=r"block must be a table \[block\]"):
        scene_from_dict({"block": 3})


def test_unknown_scene_name():
    with pytest.raises(SceneError, match="neither a built-in scene"):
        load_scene("no-such-scene")


@pytest.mark.parametrize("name,fragment", [
    ("/some/abs/path", "got '/some/abs/path'"),
    ("../../x", "got '../../x'"),
    ("", "got ''"),
    (".", "got '.'"),
    ("..", "got '..'"),
    ("a\\b", "got 'a\\\\b'"),
    ("a\nb", "got 'a\\nb'"),
    ("x" * 300, "got 300 characters"),
    (" padded", "got ' padded'"),
    (7, "name must be a string, got 7"),
])
def test_scene_name_must_be_a_plain_file_name(name, fragment):
    # the name decides the output directory runs/<name>: it must not leave runs/ (or be runs/)
    with pytest.raises(SceneError) as info:
        load_scene("paper", {"name": name})
    msg = str(info.value)
    assert fragment in msg and "\n" not in msg
    assert msg.startswith("name must be")


def test_plain_names_pass():
    for name in ("paper", "light block, 50 mm per s", "v=0.02,seed=3-7725088a3a",
                 "x" * 100, "Stahlplatte-ü"):
        assert load_scene("paper", {"name": name}).name == name


def test_scene_files_must_be_utf8_and_may_carry_a_bom(tmp_path):
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbfname = \"bom\"\n[block]\nmass = 0.3\n")
    s = load_scene(bom)
    assert s.name == "bom" and s.block.mass == 0.3
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b"name = \"x\"\ndescription = \"caf\xe9\"\n")
    with pytest.raises(SceneError) as info:
        load_scene(latin)
    assert str(info.value) == (f"scene file {latin} must be UTF-8 text (save it as UTF-8), "
                               f"got byte 0xe9 on line 2")


@pytest.mark.parametrize("key", ["block.mass", "plate.thickness", "roughness.seed",
                                 "solver.max_events", "contact.points"])
def test_numbers_beyond_float_or_int64_range_are_one_line_errors(key, tmp_path):
    huge = int("1" + "0" * 400)
    with pytest.raises(SceneError) as info:
        load_scene("paper", {key: huge})
    msg = str(info.value)
    assert msg.startswith(key) and msg.endswith("got 1.000e+400") and len(msg) < 200
    # the same number written in a scene file
    section, field = key.split(".")
    f = tmp_path / "huge.toml"
    f.write_text(f"[{section}]\n{field} = 1{'0' * 400}\n")
    with pytest.raises(SceneError, match=r"got 1\.000e\+400$"):
        load_scene(f)


@pytest.mark.skipif(not hasattr(__import__("os"), "mkfifo"), reason="named pipes are POSIX")
def test_a_scene_file_that_is_not_a_regular_file_is_refused_at_once(tmp_path):
    """A named pipe as scene file blocked `roughvib run` forever (waiting for a writer); a
    directory or a device is no scene file either. In a subprocess with a timeout, so that a
    regression fails instead of hanging the suite."""
    import os
    import subprocess
    import sys

    os.mkfifo(tmp_path / "fifo.toml")
    (tmp_path / "dir.toml").mkdir()
    for name, kind in (("fifo.toml", "a named pipe (FIFO)"), ("dir.toml", "a directory"),
                       (os.devnull, "a character device")):
        done = subprocess.run([sys.executable, "-m", "roughvib", "run", name], cwd=tmp_path,
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 2
        assert done.stderr == (f"roughvib: error: scene file {name} must be a regular file, "
                               f"got {kind}\n")
    with pytest.raises(SceneError, match=r"^sweep file .*fifo.toml must be a regular file, "
                                         r"got a named pipe \(FIFO\)$"):
        from roughvib.scene import read_toml_file

        read_toml_file(tmp_path / "fifo.toml", "sweep file")
    assert not (tmp_path / "runs").exists()
