"""The set-valued friction laws (``coulomb``, ``table``) with the adaptive exact-modal solver:
closed-form stick/slip times, agreement with IDA within the accuracy contract, and the energy
audit across stick phases."""

from dataclasses import replace

import numpy as np
import pytest
from test_coulomb import W, _phases
from test_friction_table import _write, flat_table_run

import roughvib
from roughvib.analysis.accuracy import measure_accuracy
from roughvib.api import simulate
from roughvib.physics.friction import coulomb_kinetic
from roughvib.scene import ModelValidityWarning


def _stick_windows(result, margin=1e-5):
    """Output-time masks of the stick phases, ``margin`` [s] inside each phase."""
    ev = result.events
    kinds = [(k, t) for k, t in zip(ev["kind"], ev["time"], strict=True)
             if k in ("stick", "slip")]
    t = result.dataset["time"].values
    ends = [x for _, x in kinds[1:]] + [t[-1]]
    return [(t > t0 + margin) & (t < t1 - margin)
            for (k, t0), t1 in zip(kinds, ends, strict=True) if k == "stick"]


@pytest.mark.parametrize("T0,mu_st,mu_sl,r2", [
    (0.95, 0.40, 0.30, 0.5),
    (1.10, 0.50, 0.25, 0.5),
])
def test_flat_table_with_adaptive_modal_is_the_coulomb_closed_form(tmp_path, monkeypatch, T0,
                                                                    mu_st, mu_sl, r2):
    """A flat curve on a rigid plate: every stick and slip start within 1e-7 s of the closed
    form (the contract allows 1e-6 s), the block held at exactly v = 0 with the friction force
    equal to the drive in stick, and the energy audit closed across the stick phases."""
    monkeypatch.chdir(tmp_path)
    r, err = flat_table_run(tmp_path, "adaptive-modal", T0, mu_st, mu_sl, r2)
    assert err < 1e-7, err
    ds = r.dataset
    t = ds["time"].values
    x = ds["block_tangential_displacement"].values
    windows = _stick_windows(r)
    assert len(windows) >= 2
    for w in windows:
        assert np.all(ds["block_tangential_velocity"].values[w] == 0.0)
        assert np.ptp(x[w]) == 0.0  # held where it stopped
        # the friction force is what holds the block: the drive (v = 0, no damper force)
        np.testing.assert_allclose(ds["friction_force"].values[w], T0 * np.cos(W * t[w]),
                                   rtol=1e-12, atol=1e-15)
    audit = r.summary["energy_audit"]
    assert abs(audit["relative_residual"]) < 1e-6, audit


def _stribeck_table(folder, mu_st, mu_sl, vs):
    """The Coulomb law's Stribeck curve sampled every v_s / 20 to 12 v_s, as a CSV file."""
    v = np.linspace(0.0, 12 * vs, 241)
    mu = [coulomb_kinetic(x, mu_sl, mu_st, vs)[0] for x in v]
    return _write(folder / "stribeck.csv", v, mu)


@pytest.mark.filterwarnings("ignore", category=ModelValidityWarning)  # window < a period
@pytest.mark.parametrize("law", ["coulomb", "table"])
def test_adaptive_modal_matches_ida_with_the_set_valued_laws(tmp_path, monkeypatch, law):
    """Plate modes to 3 kHz, the paper's roughness and drive, a Stribeck law (analytic, or
    sampled into a table): slip, stick and break-away within 0.08 s. adaptive-modal at its
    reference preset against IDA at its own: every item of the accuracy contract (band
    levels, event times, tangential velocity, energy audit) holds, and both runs stick."""
    monkeypatch.chdir(tmp_path)
    mu_st, mu_sl, vs = 0.3856, 0.30, 2e-3
    over = {"plate.max_frequency": 3e3, "output.duration": 0.08,
            "excitation.force_amplitude": 0.91536, "excitation.target_rms_velocity": "none",
            "contact.velocity_factor": False, "output.progress": False,
            "friction.law": law, "friction.mu_stick": mu_st, "friction.mu_slip": mu_sl}
    if law == "table":
        _stribeck_table(tmp_path, mu_st, mu_sl, vs)
        over["friction.table"] = "stribeck.csv"
    else:
        over["friction.stribeck_velocity"] = vs
    base = replace(roughvib.load_scene("paper", over), base_dir=str(tmp_path))
    runs = {m: simulate(base.with_overrides({"solver.method": m})) for m in ("adaptive-modal",
                                                                            "ida")}
    for r in runs.values():
        assert r.ok, r.summary["message"]
    am = runs["adaptive-modal"]
    kinds = [k for k, _ in _phases(am)]
    assert kinds == [k for k, _ in _phases(runs["ida"])]
    assert "stick" in kinds and kinds.count("slip") >= 2  # a stick phase and a break-away
    for w in _stick_windows(am):
        assert np.all(am.dataset["block_tangential_velocity"].values[w] == 0.0)
    acc = measure_accuracy(am, runs["ida"], period=base.period,
                           transient=base.output.transient)
    assert acc["verdict"] == "pass", acc["failures"]
    assert acc["events"]["matched"] >= 3 and acc["events"]["unmatched"] == 0
