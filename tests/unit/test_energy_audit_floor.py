"""The energy audit says when it cannot be computed, and its relative residual has a floor.

A block resting on a rigid base stores -(m g)^2 / (2 s) (gravity with its zero at z = 0, the
springs' elastic energy at the static compression m g / s): that energy is the floor of the
relative residual's denominator, so the round-off of a run in which nothing moves reads as
round-off (about 1e-15), not as 1. The paper's convolution scheme keeps no energy integrals:
its audit is null in summary.json, with a note, and the run summary says so."""

from __future__ import annotations

import json
import math

import pytest

import roughvib
from roughvib.cli import main
from roughvib.physics.surface.contact import GRAVITY

AT_REST = {"roughness.kind": "none", "excitation.kind": "prescribed",
           "excitation.velocity": 0.0, "excitation.amplitude": 0.0, "plate.kind": "rigid",
           "output.duration": 0.01, "output.transient": 0.0, "output.progress": False}


def test_a_block_at_rest_closes_to_round_off_relative_to_its_stored_energy(tmp_path,
                                                                          monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = roughvib.simulate(roughvib.load_scene("paper", AT_REST))
    a = r.summary["energy_audit"]
    m = r.summary["model"]
    s_total = m["contact_stiffness_total"]
    mass = roughvib.load_scene("paper").block.mass
    stored = (mass * GRAVITY) ** 2 / (2 * s_total)
    assert a["energy_scale_floor"] == pytest.approx(stored, rel=1e-9)
    # nothing moves: no work, no dissipation to speak of
    terms = sum(abs(a[k]) for k in ("excitation_work", "roughness_work",
                                    "friction_dissipation", "tangential_damping",
                                    "vertical_damping", "plate_damping"))
    assert terms + abs(a["stored_energy_change"]) < 1e-12 * stored
    assert a["energy_scale"] == a["energy_scale_floor"]
    assert abs(a["relative_residual"]) < 1e-12
    assert a["relative_residual"] == a["residual"] / a["energy_scale"]
    assert "energy_audit_note" not in r.summary


@pytest.mark.filterwarnings("ignore:the analysis window:UserWarning")  # 0.02 s of a period
def test_a_moving_block_is_measured_against_its_work_not_the_floor(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    over = {"output.duration": 0.02, "output.transient": 0.0, "plate.max_frequency": 2000.0,
            "output.progress": False}
    a = roughvib.simulate(roughvib.load_scene("paper", over)).summary["energy_audit"]
    work = sum(abs(a[k]) for k in ("excitation_work", "roughness_work", "friction_dissipation",
                                   "tangential_damping", "vertical_damping", "plate_damping"))
    assert a["energy_scale"] == pytest.approx(work + abs(a["stored_energy_change"]))
    assert a["energy_scale"] > a["energy_scale_floor"]


def test_the_paper_scheme_audit_is_not_computed_and_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = main(["run", "paper-handset", "--out", "p", "--set", "solver.method=paper",
                 "--set", "output.duration=0.005", "--set", "output.transient=0",
                 "--set", "plate.max_frequency=2000", "--no-progress"])
    assert code == 0
    text = (tmp_path / "p" / "summary.json").read_text()
    assert "NaN" not in text  # json.dumps wrote NaN for the audit before: not even JSON
    summary = json.loads(text)
    assert summary["status"] == "success"
    assert all(v is None for k, v in summary["energy_audit"].items() if k != "t_end")
    assert summary["energy_audit_note"].startswith("not computed: solver.method = 'paper'")
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("energy audit"))
    assert line == f"energy audit     {summary['energy_audit_note']}"
    assert roughvib.load_result(tmp_path / "p").summary["energy_audit_note"]
    assert math.isclose(summary["energy_audit"]["t_end"], 0.005)
