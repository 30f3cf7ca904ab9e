"""Extreme numbers that pass a key's own rule but overflow later (issue 25) are refused in one
line naming the key, the rule, the unit and the value: each key has a physically sane range,
and the quantities a run derives from several keys are checked with the keys they come from.
Every refusal here happens before any solve."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from roughvib.cli import main
from roughvib.physics.surface.roughness import build_profile
from roughvib.scene import (
    MAX_FIXED_STEPS,
    MAX_MODES,
    MAX_PROFILE_SAMPLES,
    SANE_BOUNDS,
    Plate,
    SceneError,
    bounds_rule,
    load_scene,
)

TINY = ["--set", "output.duration=0.005", "--set", "plate.max_frequency=2000", "--no-progress",
        "--quiet"]


@pytest.fixture
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


# the cases of issue 25, each a different defect class before: OverflowError,
# ZeroDivisionError, a scipy ValueError on infinite spline input, a 150-digit mode count, an
# accepted all-zero profile, numpy overflow warnings, and a calibration message naming neither
# key nor cause
@pytest.mark.parametrize("setting,unit", [
    ("plate.thickness=1e308", "m"), ("plate.thickness=1e-300", "m"),
    ("roughness.rms=1e308", "m"), ("plate.density=1e308", "kg/m^3"),
    ("block.length=1e-300", "m"), ("solver.atol=1e308", "m"),
    ("excitation.frequency=1e308", "Hz"),
])
@pytest.mark.parametrize("scene", ["paper", "paper-handset"])
def test_the_extreme_numbers_of_issue_25_are_refused_in_one_line(setting, unit, scene, in_tmp,
                                                                 capsys):
    key, value = setting.split("=")
    with _no_warning():
        code = main(["run", scene, "--out", str(in_tmp / "run"), "--set", setting, *TINY])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err, err
    lo, hi, _ = SANE_BOUNDS[key]
    rule = f"at most {hi:g} {unit}" if lo == 0 else f"in [{lo:g}, {hi:g}] {unit}"
    assert err == (f"roughvib: error: {key} must be {rule} (the physically sane range, "
                   f"docs/scenes.md), got {float(value)!r}\n")
    assert not (in_tmp / "run").exists()


class _no_warning:
    """Fail on any warning (numpy overflow warnings used to leak)."""

    def __enter__(self):
        import warnings
        self._cm = warnings.catch_warnings()
        self._cm.__enter__()
        warnings.simplefilter("error")

    def __exit__(self, *exc):
        return self._cm.__exit__(*exc)


@pytest.mark.parametrize("key", sorted(SANE_BOUNDS))
def test_every_bounded_key_refuses_the_float_extremes_by_name(key):
    lo, hi, unit = SANE_BOUNDS[key]
    assert 0 <= lo < hi < 1e300 or (lo < 0 and hi < 1e300)
    extremes = [1e308, -1e308 if lo < 0 else None, 1e-300 if lo > 0 else None]
    for v in (x for x in extremes if x is not None):
        with pytest.raises(SceneError) as info:
            load_scene("paper", {key: v})
        msg = str(info.value)
        assert "\n" not in msg
        assert msg.startswith(f"{key} must be {bounds_rule(key)} (the physically"), msg
        assert msg.endswith(f"got {v!r}") and (unit in msg)


def test_the_bounds_are_documented_as_in_the_code():
    page = (Path(__file__).parents[2] / "docs" / "scenes.md").read_text()
    for key, (lo, hi, unit) in SANE_BOUNDS.items():
        row = re.search(rf"^\| `{re.escape(key)}` \| ([^|]+) \| ([^|]+) \| ([^|]+) \|$", page,
                        re.M)
        assert row, key
        assert row.group(1).startswith(f"{lo:g}" if lo else "its own rule"), key
        assert row.group(2).strip() == f"{hi:g}" and row.group(3).strip() == (unit or "–"), key


def test_the_mode_count_names_its_keys_and_stays_short():
    # E = 1e3 Pa (the lowest sane value): c = sqrt(B'/m'') = sqrt(E h^2 / (12 (1 - nu^2) rho))
    # and N ~ a b omega_max / (4 pi c) (the asymptotic mode count of a plate)
    p = dict(youngs_modulus=1e3)
    b = 1e3 * 0.003**3 / (12 * (1 - 0.3**2))
    c = math.sqrt(b / (7850.0 * 0.003))
    n = 0.30 * 0.26 * 2 * math.pi * 50e3 / c / (4 * math.pi)
    assert n > MAX_MODES
    with pytest.raises(SceneError) as info:
        Plate(**p)
    msg = str(info.value)
    assert f"about {n:.3g} modes" in msg and len(msg) < 250
    for name in ("length", "width", "thickness", "youngs_modulus", "density", "poisson_ratio"):
        assert name in msg


def test_profile_samples_and_fixed_steps_are_bounded_by_name():
    spacing = 0.16 / (2 * MAX_PROFILE_SAMPLES)
    with pytest.raises(SceneError, match=r"^roughness.trace_length / roughness.spacing must be "
                                         r"at most 1e\+07 profile samples, got 0.16 m / "):
        load_scene("paper", {"roughness.spacing": spacing, "roughness.shortest_wavelength": 1e-6})
    duration = 2 * MAX_FIXED_STEPS * 1e-9
    with pytest.raises(SceneError, match=r"^output.duration / solver.step must be at most "
                                         r"1e\+10 steps of solver.method = 'newmark', got "):
        load_scene("paper", {"solver.method": "newmark", "solver.step": 1e-9,
                             "output.duration": duration, "output.step": 1.0})
    # an event-driven method ignores solver.step: no refusal
    load_scene("paper", {"solver.step": 1e-9, "output.duration": duration, "output.step": 1.0})


def _bypass(obj, **values):
    """Values that passed no range check (the derived checks guard what the ranges miss)."""
    for k, v in values.items():
        object.__setattr__(obj, k, v)
    return obj


def test_a_profile_with_infinite_heights_is_refused_before_the_interpolant(in_tmp):
    s = load_scene("paper-handset")
    rough = _bypass(s.roughness, kind="sinusoid", amplitude=math.inf)
    with pytest.raises(SceneError, match=r"^roughness.kind = 'sinusoid' gives a profile with "
                                         r"non-finite heights .*, got \d+ of \d+ samples$"):
        build_profile(rough, s.block)


def test_a_filter_that_removes_the_whole_profile_is_refused(in_tmp):
    s = load_scene("paper-handset")
    block = _bypass(s.block, length=1e-300)  # H = 1 - sinc(k L / 2) = 0 for every k
    with pytest.raises(SceneError, match=r"^roughness.filter = 'highpass' over block.length = "
                                         r"1e-300 m removes the whole profile"):
        build_profile(s.roughness, block)
    # the same block with the filter off keeps the profile: the check is the filter's
    prof = build_profile(_bypass(s.roughness, filter="none"), block)
    assert np.std(prof.z) > 0


@pytest.mark.short_run
def test_values_derived_for_the_run_are_checked_before_the_solve(monkeypatch, in_tmp):
    """The calibrated force, the contact module's count, stiffness and r1 and the pilot's
    tolerance are written into the saved scene; they are validated before the solve, so a bad
    one never costs a run (it used to be checked after it). Shown with a bound lowered below
    the contact module's r1 of the paper scene (about 83 N s/m)."""
    import roughvib.scene as scene_mod
    import roughvib.simulation as sim

    monkeypatch.setitem(scene_mod.SANE_BOUNDS, "block.vertical_damping", (0.0, 1.0, "N s/m"))

    def no_solve(*a, **k):
        raise AssertionError("the solve started before the derived values were checked")

    monkeypatch.setattr(sim, "_solve", no_solve)
    scene = load_scene("paper", {"output.duration": 0.002, "plate.max_frequency": 2000.0,
                                 "output.progress": False})
    with pytest.raises(SceneError, match=r"^a value derived for this run .* out of range: "
                                         r"block.vertical_damping must be at most 1 N s/m "
                                         r".*got \d+\.\d+$"):
        sim.simulate(scene)


@pytest.mark.parametrize("summits", [
    {}, {"contact.summit_std": 1e-6}, {"contact.summit_std": 1e-6, "contact.summit_radius": 1e-4},
])
@pytest.mark.parametrize("raw_rms", [1e-300, 1e-100, 1e-15])
def test_a_tiny_raw_rms_is_refused_by_its_own_name(raw_rms, summits):
    """A raw_rms the contact module cannot use was blamed on the roughness band (or raised a
    ZeroDivisionError): the refusal names roughness.raw_rms, the key set, and its value."""
    from roughvib.physics.surface.contact import contact_stiffness

    scene = load_scene("paper", {"roughness.raw_rms": raw_rms, **summits})
    if len(summits) == 2 and raw_rms == 1e-15:
        # only the density is derived, which does not depend on the rms: a usable contact
        assert contact_stiffness(scene).summit_density > 0
        return
    with pytest.raises(SceneError) as info:
        contact_stiffness(scene)
    msg = str(info.value)
    assert msg.startswith("roughness.raw_rms must be ") and msg.endswith(f"got {raw_rms!r} m")
    assert "wavelength" not in msg and "\n" not in msg


def test_the_lowest_raw_rms_named_is_the_lowest_that_works():
    """The bound the refusal states is the lowest raw_rms the contact module can use: just
    above it the derived summits carry the block within the summit keys' ranges, just below
    it the refusal names raw_rms again. (At the scale of the contact spots the limit is where
    the block can no longer be carried, not an edge of the ranges: the spots grow as the
    surface smooths, so no range edge need bind there.)"""
    from roughvib.physics.surface.contact import contact_stiffness

    with pytest.raises(SceneError) as info:
        contact_stiffness(load_scene("paper", {"roughness.raw_rms": 1e-15}))
    need = float(re.search(r"must be >= (\S+) m", str(info.value)).group(1))
    cs = contact_stiffness(load_scene("paper", {"roughness.raw_rms": need * 1.01,
                                                "contact.points": 10}))
    lo_std, rad_hi = SANE_BOUNDS["contact.summit_std"][0], SANE_BOUNDS["contact.summit_radius"][1]
    assert cs.summit_std >= lo_std and cs.summit_radius <= rad_hi
    with pytest.raises(SceneError, match=r"^roughness.raw_rms must be >= "):
        contact_stiffness(load_scene("paper", {"roughness.raw_rms": need * 0.99}))


def test_a_relative_acceleration_tolerance_is_refused_by_its_own_name(in_tmp, capsys):
    """solver.atol_acceleration_relative times the pilot's level is the atol_acceleration of the
    run; below the scene's round-off floor the refusal names the key the user set, the
    derived tolerance and the lowest relative value, and that value runs."""
    code = main(["run", "paper", "--out", "r", "--set",
                 "solver.atol_acceleration_relative=1e-300", *TINY])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2
    m = re.fullmatch(r"roughvib: error: solver.atol_acceleration_relative must be >= (\S+) for "
                     r"this scene: times the pilot's acceleration level (\S+) m/s\^2 it gives "
                     r"atol_acceleration = (\S+) m/s\^2, below the round-off floor (\S+) m/s\^2 "
                     r".*, got 1e-300", err)
    assert m, err
    need, level, atol, floor = (float(g) for g in m.groups())
    assert atol == pytest.approx(1e-300 * level, rel=1e-2) and atol < floor
    assert need == pytest.approx(floor / level, rel=1e-2)
    assert not (in_tmp / "r").exists()
    assert main(["run", "paper", "--out", "r", "--set",
                 f"solver.atol_acceleration_relative={need!r}", *TINY]) == 0
