"""Each friction law's own keys (``friction.parameters``): declared once, checked, completed
with their defaults, refused for another law, and read from the flat form of earlier scene
files."""

import re
from pathlib import Path

import numpy as np
import pytest

import roughvib
from roughvib.scene import (
    FRICTION_LAWS,
    LAW_KEYS,
    Friction,
    SceneError,
    load_scene,
    scene_to_toml,
)

DOCS = Path(__file__).parents[2] / "docs"


def _num(x):
    """A number as the page writes it: 1e8, 5e-5, 0.001."""
    return re.sub(r"e([+-])0*(\d)", lambda m: "e" + m.group(1).replace("+", "") + m.group(2),
                  f"{x:g}")


def _row(law, name, key):
    if key.kind == "file":
        default, rng = "required", "a file name"
    else:
        default = "none" if key.default is None else _num(key.default)
        rng = f"{'(' if key.positive else '['}{_num(key.lowest)}, {_num(key.highest)}]"
    return f"| `{law}` | `{name}` | {default} | {key.unit or '–'} | {rng} | {key.meaning} |"


def test_every_laws_keys_are_documented_as_declared():
    page = (DOCS / "friction.md").read_text()
    rows = [line for line in page.splitlines() if re.match(r"^\| `\w+` \| `\w+` \|", line)]
    want = [_row(law, n, k) for law, d in FRICTION_LAWS.items() for n, k in d.keys.items()]
    assert rows == want


@pytest.mark.parametrize("law", list(FRICTION_LAWS))
def test_a_scene_holds_its_laws_keys_only_completed_with_defaults(law, tmp_path):
    over = {"friction.law": law}
    if law == "table":
        (tmp_path / "c.csv").write_text("velocity,mu\n0,0.35\n0.1,0.3\n")
        over["friction.parameters.table"] = str(tmp_path / "c.csv")
    fr = load_scene("paper", over).friction
    keys = FRICTION_LAWS[law].keys
    assert set(fr.parameters) == set(keys)  # not a union of every law's keys
    for name, key in keys.items():
        if key.kind != "file":
            assert fr.parameters[name] == key.default
    # and nothing a law owns is an attribute of the section
    assert not any(hasattr(fr, k) for k in LAW_KEYS)


def test_the_flat_form_of_earlier_scene_files_is_read_into_parameters(tmp_path):
    """A scene.toml written before the keys moved lists every law's keys flat in [friction]
    (the other laws' at their defaults): it loads to the scene written now."""
    old = tmp_path / "old.toml"
    old.write_text('[friction]\nlaw = "coulomb"\nmu_slip = 0.3\nmu_stick = 0.4\na1 = 500.0\n'
                   'a2 = 20000.0\nhysteresis_velocity = 5e-05\nlatch_velocity = 0.0001\n'
                   'stick_velocity = 0.0005\nstribeck_velocity = 0.002\n'
                   'switching_hysteresis = 0.0\ndwell_time = 1e-4\nchatter_switches = 20\n'
                   'chatter_window = 0.001\n[excitation]\nforce_amplitude = 1.0\n')
    fr = load_scene(old).friction
    assert fr.parameters == {"stribeck_velocity": 0.002, "switching_hysteresis": 0.0,
                             "dwell_time": 1e-4, "chatter_switches": 20,
                             "chatter_window": 0.001}
    new = tmp_path / "new.toml"
    new.write_text(scene_to_toml(load_scene(old)))
    assert "[friction]" in new.read_text() and "\na1 =" not in new.read_text()
    assert load_scene(new) == load_scene(old)
    # --set with the flat name writes the same key
    assert load_scene("paper", {"friction.a1": 600.0}).friction.parameters["a1"] == 600.0


def test_a_key_given_twice_with_different_values_is_refused(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[friction]\na1 = 600.0\n[friction.parameters]\na1 = 700.0\n')
    with pytest.raises(SceneError, match=r"^friction.a1 and friction.parameters.a1 give "
                                         r"different values; .* got 600.0 and 700.0$"):
        load_scene(f)
    f.write_text('[friction]\na1 = 600.0\n[friction.parameters]\na1 = 600.0\n')
    assert load_scene(f).friction.parameters["a1"] == 600.0


def test_another_laws_key_is_refused_unless_it_holds_that_laws_default():
    with pytest.raises(SceneError, match=r"^friction.parameters.a1 is a key of friction.law = "
                                         r"'feldmann', not of friction.law = 'coulomb' \(its "
                                         r"keys: stribeck_velocity, .*\), got 600$"):
        load_scene("paper", {"friction.law": "coulomb", "friction.a1": 600})
    with pytest.raises(SceneError, match=r"^friction.parameters.sigma9 is no law's key"):
        load_scene("paper", {"friction.parameters.sigma9": 1.0})
    # at its default it has no effect on any law: dropped
    fr = Friction(law="coulomb", parameters={"a1": 500.0})
    assert "a1" not in fr.parameters


def test_changing_the_law_starts_from_the_new_laws_defaults():
    """LuGre and coulomb both have a stribeck_velocity, with different defaults: switching the
    law must not carry LuGre's default (2 mm/s) into the Coulomb law (none: constant mu)."""
    lugre = load_scene("paper", {"friction.law": "lugre"})
    assert lugre.friction.parameters["stribeck_velocity"] == 2e-3
    coulomb = lugre.with_overrides({"friction.law": "coulomb"})
    assert coulomb.friction.parameters["stribeck_velocity"] is None
    # a value the user set is kept where the new law has the key
    set3 = lugre.with_overrides({"friction.parameters.stribeck_velocity": 3e-3})
    assert set3.with_overrides({"friction.law": "coulomb"}).friction.parameters[
        "stribeck_velocity"] == 3e-3
    with pytest.raises(SceneError, match=r"^friction.parameters.sigma0 is a key of "
                                         r"friction.law = 'lugre', not of friction.law = "
                                         r"'feldmann'"):
        lugre.with_overrides({"friction.parameters.sigma0": 2e5, "friction.law": "feldmann"})


@pytest.mark.parametrize("key,value,rule", [
    ("a2", 400.0, r"friction.parameters.a2 must be > friction.parameters.a1 \(500.0 s/m\), "
                  r"got 400.0 s/m"),
    ("a2", 0.0, r"friction.parameters.a2 \(.*\) must be in \(0, 1e\+08\] s/m \(the "
                r"physically sane range\), got 0.0"),
    ("latch_velocity", 1e3, r"friction.parameters.latch_velocity \(.*\) must be in \(0, 100\] "
                            r"m/s"),
    ("a1", "x", r"friction.parameters.a1 must be a number s/m, got 'x'"),
])
def test_the_feldmann_keys_rules_are_one_line(key, value, rule):
    with pytest.raises(SceneError, match=f"^{rule}") as info:
        load_scene("paper", {f"friction.parameters.{key}": value})
    assert "\n" not in str(info.value)


def test_the_kinds_of_key_integer_optional_and_file():
    base = {"friction.law": "coulomb"}
    assert load_scene("paper", {**base, "friction.parameters.chatter_switches": 5.0}
                      ).friction.parameters["chatter_switches"] == 5
    with pytest.raises(SceneError, match=r"^friction.parameters.chatter_switches must be an "
                                         r"integer"):
        load_scene("paper", {**base, "friction.parameters.chatter_switches": 2.5})
    assert load_scene("paper", {**base, "friction.parameters.stribeck_velocity": "none"}
                      ).friction.parameters["stribeck_velocity"] is None
    with pytest.raises(SceneError, match=r"^friction.parameters.stribeck_velocity .* must be "
                                         r"in \(0, 100\] m/s"):
        load_scene("paper", {**base, "friction.parameters.stribeck_velocity": 0.0})
    with pytest.raises(SceneError, match=r"^friction.parameters.table must name a CSV file"):
        load_scene("paper", {"friction.law": "table", "friction.parameters.table": 3})


def test_the_coulomb_calibration_is_the_feldmann_model_at_that_laws_defaults():
    """The coulomb law is calibrated in the Feldmann law's tangential model with that law's
    default keys (its own scene holds none of them): the same T0 as a Feldmann scene with
    the same mu_slip and mu_stick."""
    from roughvib.physics.friction import calibrate_force_amplitude

    fe, co = Friction(), Friction(law="coulomb")
    args = (0.01, 0.221, 0.5, 0.221 * 9.81, 2 * np.pi * 7.0)
    assert calibrate_force_amplitude(*args, co) == calibrate_force_amplitude(*args, fe)


def test_a_sweep_varies_a_flat_named_key_of_the_base_law():
    from roughvib.studies import sweep as sw

    spec = sw.load_sweep({"base": "paper", "grid": {"friction.a1": [400.0, 600.0]}})
    assert spec.base_value("friction.a1") == 500.0
    scenes = [spec.base.with_overrides(c.values) for c in spec.cases()]
    assert [s.friction.parameters["a1"] for s in scenes] == [400.0, 600.0]


def test_runs_write_the_parameters_table(tmp_path):
    scene = roughvib.load_scene("paper", {"friction.law": "coulomb",
                                          "friction.parameters.dwell_time": 1e-4})
    text = scene_to_toml(scene)
    friction = text.split("[friction]\n", 1)[1].split("\n[excitation]", 1)[0]
    assert re.search(r"^\[friction.parameters\]\n(\w+ = .*\n)*dwell_time = 0.0001$", friction,
                     re.M)
    assert "stribeck_velocity" not in text  # none: absent, read back as its default
    (tmp_path / "s.toml").write_text(text)
    assert load_scene(tmp_path / "s.toml") == scene
