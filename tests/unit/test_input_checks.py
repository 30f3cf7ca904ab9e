"""Inputs that make no physical sense are refused, legal ones outside the model's validity are
warned about (summary and stderr), and every input check runs before the expensive work."""

from __future__ import annotations

import json
import math
import re
import warnings

import numpy as np
import pytest

import roughvib.model.system as system_mod
from roughvib.cli import main
from roughvib.model.system import (
    MAX_RMS_SLOPE,
    MAX_RMS_TO_BLOCK,
    WARN_RMS_SLOPE,
    WARN_RMS_TO_BLOCK,
    assemble,
    check_profile,
)
from roughvib.physics.surface.roughness import build_profile
from roughvib.scene import ModelValidityWarning, SceneError, load_scene, validity_warnings

TINY = ["--set", "output.duration=0.005", "--set", "plate.max_frequency=2000", "--no-progress",
        "--quiet"]


@pytest.fixture
def nothing_expensive(monkeypatch):
    """Fail the test if assembly gets to the structure (plate modes) or the T0 calibration."""
    def expensive(*a, **k):
        raise AssertionError("expensive work started before every input check")

    monkeypatch.setattr(system_mod, "build_structure", expensive)
    monkeypatch.setattr(system_mod, "calibrated_force_amplitude", expensive)


def _profile_file(tmp_path, scale: float):
    """The paper scene's profile written in units of 1/scale metres (1e6: micrometres)."""
    s = load_scene("paper")
    path = tmp_path / "profile.txt"
    np.savetxt(path, build_profile(s.roughness, s.block).z * scale)
    return path


def test_a_micrometre_profile_declared_as_metres_is_refused(tmp_path, nothing_expensive,
                                                            capsys):
    path = _profile_file(tmp_path, 1e6)
    scene = load_scene("paper", {"roughness.kind": "file", "roughness.path": str(path),
                                 "roughness.units": "m"})
    with pytest.raises(SceneError) as info:
        assemble(scene)
    msg = str(info.value)
    assert msg.startswith(f"roughness.path {path} (units = 'm'): the rms height about the mean "
                          f"line must be at most 0.01 m for a roughness profile, got 0.3")
    assert float(msg.split(", got ")[1].split(" m")[0]) == pytest.approx(0.35, rel=0.01)
    assert msg.endswith("are the file's x and heights in um (roughness.units = 'um')?")
    assert "\n" not in msg
    assert main(["run", "--set", "roughness.kind='file'", "--set",
                 f"roughness.path='{path}'", *TINY]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    # declared correctly it is the paper's 0.35 um profile, and it passes without a warning
    ok = load_scene("paper", {"roughness.kind": "file", "roughness.path": str(path),
                              "roughness.units": "um"})
    prof = build_profile(ok.roughness, ok.block)
    assert prof.stats["rms"] == pytest.approx(0.35e-6, rel=0.02)
    assert check_profile(ok, prof) == []


def test_rms_slope_far_beyond_small_slopes_is_refused(nothing_expensive):
    # roughness.rms = 1 mm on the paper's band (50 um .. 40 mm, no contact filter) gives an
    # rms slope of 20
    with pytest.raises(SceneError, match=r"^roughness.rms 0.001 m gives an input profile with "
                                         r"rms slope 20\.\d, the model needs at most 1 "):
        assemble(load_scene("paper", {"roughness.rms": 1e-3, "contact.filter": "none",
                                      "roughness.shortest_wavelength": 50e-6}))


def _sinusoid(amplitude: float, wavelength: float):
    return load_scene("paper", {"roughness.kind": "sinusoid", "roughness.amplitude": amplitude,
                                "roughness.wavelength": wavelength})


def test_roughness_comparable_to_the_block_is_refused(nothing_expensive):
    # A cos(2 pi s / L) over whole periods (4 on the 0.16 m trace): rms A / sqrt(2), rms slope
    # 2 pi A / (L sqrt(2)) (closed forms)
    a, lam = 1e-3, 0.04
    slope = 2 * math.pi * a / (lam * math.sqrt(2))
    assert slope < MAX_RMS_SLOPE and a / math.sqrt(2) > MAX_RMS_TO_BLOCK * 0.04
    with pytest.raises(SceneError, match=r"gives an input profile of 0.000707 m rms, the model "
                                         r"needs at most 0.01 x the block's smaller side "
                                         r"\(0.04 m\)"):
        assemble(_sinusoid(a, lam))


@pytest.mark.parametrize("amplitude,wavelength,warned", [
    (1e-5, 2e-4, "rms slope 0.22"),      # slope 0.222 > 0.1, height 7 um
    (1e-4, 0.04, "of 7.07e-05 m rms"),   # height 71 um > 40 um, slope 0.011
    (1e-6, 1e-3, None),
])
def test_profiles_outside_the_model_validity_warn(amplitude, wavelength, warned):
    scene = _sinusoid(amplitude, wavelength)
    notes = check_profile(scene, build_profile(scene.roughness, scene.block))
    if warned is None:
        assert notes == []
    else:
        assert len(notes) == 1 and warned in notes[0]
    assert WARN_RMS_SLOPE < MAX_RMS_SLOPE and WARN_RMS_TO_BLOCK < MAX_RMS_TO_BLOCK


def test_validity_warnings_of_the_scene():
    assert validity_warnings(load_scene("paper")) == []
    thick = validity_warnings(load_scene("paper", {"plate.thickness": 10.0}))
    assert len(thick) == 1 and "Kirchhoff (thin-plate) theory does not hold" in thick[0]
    # modes above f6: there the bending wavelength 2 pi / k, k^4 = w^2 m'' / B', is < 6 h
    scene = load_scene("paper", {"plate.thickness": 0.01})
    (note,) = validity_warnings(scene)
    f6 = float(re.search(r"modes above (\S+) Hz", note).group(1))
    p = scene.plate
    k = ((2 * math.pi * f6) ** 2 * p.mass_per_area / p.bending_stiffness) ** 0.25
    assert 2 * math.pi / k == pytest.approx(6 * p.thickness, rel=1e-3)
    assert validity_warnings(load_scene("paper", {"plate.max_frequency": 0.9 * f6,
                                                  "plate.thickness": 0.01})) == []
    # the metrics window: a run shorter than its run-in, a window shorter than a period
    short = validity_warnings(load_scene("paper", {"output.duration": 0.02}))
    assert "output.transient (0.142857 s) is not shorter than output.duration" in short[0]
    assert "the analysis window (0.02 s) is shorter than one excitation period" in short[1]
    assert "miss excitation.target_rms_velocity" in short[1]
    part = validity_warnings(load_scene("paper", {"output.duration": 0.25}))
    assert len(part) == 1 and "window (0.107143 s)" in part[0]
    # two periods at 7 Hz as the docs write them (0.2857142857 s): the window falls 1e-10 of
    # a period short by rounding, and the metrics' window holds one whole period
    assert validity_warnings(load_scene("paper", {"output.duration": 0.2857142857})) == []
    from roughvib.analysis.levels import whole_period_window

    t = np.arange(0.0, 0.2857142857 + 0.5e-5, 1e-5)
    win = whole_period_window(t, 1 / 7, 1 / 7)
    assert (win.stop - win.start) * 1e-5 == pytest.approx(1 / 7, abs=1e-5)
    # four digits are no rounding: 0.2857 s leaves a window 1e-4 of a period short
    (four,) = validity_warnings(load_scene("paper", {"output.duration": 0.2857}))
    assert "shorter than one excitation period" in four
    # uniform sliding (prescribed, no oscillation) has no period to cover
    assert validity_warnings(load_scene("paper", {
        "output.duration": 0.25, "output.transient": 0.0, "excitation.kind": "prescribed",
        "excitation.velocity": 0.01, "excitation.amplitude": 0.0})) == []


def test_a_run_reports_its_warnings_in_the_summary_and_on_stderr(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "--out", str(out), "--set", "plate.thickness=0.05", *TINY]) == 0
    err = capsys.readouterr().err.splitlines()
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["warnings"]) == 3
    assert summary["warnings"][0].startswith("plate.thickness 0.05 m is more than 0.1 x")
    assert err == [f"roughvib: warning: {w}" for w in summary["warnings"]]
    with warnings.catch_warnings(record=True) as caught:  # Python users get them as warnings
        warnings.simplefilter("always")
        assemble(load_scene("paper", {"plate.thickness": 0.05, "plate.max_frequency": 2000.0,
                                      "output.duration": 0.005}))
    assert [str(w.message) for w in caught if w.category is ModelValidityWarning] == \
        summary["warnings"]


def test_every_input_check_runs_before_the_expensive_work(nothing_expensive, capsys):
    # 0.1 Hz: the calibrated stroke (+-68 mm) leaves the 0.16 m trace; this used to be found
    # after 158 s of calibration
    with pytest.raises(SceneError, match=r"roughness.trace_length must cover the contacts' "
                                         r"travel of about ±0.0675 m"):
        assemble(load_scene("paper", {"excitation.frequency": 0.1}), travel=0.0675)
    assert main(["run", "--set", "excitation.frequency=0.1", *TINY]) == 2
    assert "roughness.trace_length must cover" in capsys.readouterr().err


def test_overflowing_numbers_on_the_command_line_are_one_line(capsys):
    assert main(["run", "--set", "block.mass=1" + "0" * 400, *TINY]) == 2
    assert capsys.readouterr().err == ("roughvib: error: block.mass must be a finite number kg, "
                                       "got 1.000e+400\n")


def test_a_scene_spacing_has_the_upper_bound_of_a_profile_files_step(tmp_path):
    """roughness.spacing (the step of a profile file without an x column, or of a synthetic
    profile) is refused above 1 mm, as the step a profile file's own x column gives; it
    allowed 10 mm."""
    from roughvib.physics.surface.measured import FILE_SPACING
    from roughvib.scene import SANE_BOUNDS

    assert SANE_BOUNDS["roughness.spacing"][:2] == FILE_SPACING
    path = tmp_path / "profile.txt"
    path.write_text("\n".join(f"{1e-6 * math.sin(k):.6g}" for k in range(400)) + "\n")
    file = {"roughness.kind": "file", "roughness.path": str(path), "roughness.units": "m",
            "roughness.filter": "none"}
    with pytest.raises(SceneError, match=r"^roughness.spacing must be in \[1e-09, 0.001\] m "
                                         r"\(the physically sane range, docs/scenes.md\), "
                                         r"got 0.002$"):
        load_scene("paper", {**file, "roughness.spacing": 2e-3})
    assert load_scene("paper", {**file, "roughness.spacing": 1e-3}).roughness.spacing == 1e-3
