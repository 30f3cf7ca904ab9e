"""Contacts that reach their margins at the same instant switch together.

On a sinusoidal surface the contact points sit on maxima whole wavelengths apart, so three
contacts on a rigid plate under prescribed sliding see identical roughness input: by symmetry
their compressions, forces and regimes must be identical at every instant, whatever the solver.
Before the fix, IDA reported only some of the simultaneous touch-down roots; the restart left one
contact open with its margin already below zero, a downward crossing that never came, and the
contact stayed open while penetrating (closed fractions 0.78 / 0.21 / 0.78).
"""

import numpy as np
import pytest

import roughvib

#: the scenes here are shorter than the run-in plus one excitation period on purpose
#: (the marker is in tests/conftest.py)
pytestmark = pytest.mark.short_run

IN_PHASE = {"plate.kind": "rigid", "roughness.kind": "sinusoid", "roughness.amplitude": 10e-6,
            "roughness.wavelength": 0.73e-3, "excitation.kind": "prescribed",
            "excitation.velocity": 0.1, "excitation.amplitude": 0.0,
            "excitation.target_rms_velocity": "none", "output.progress": False,
            "contact.points": 3, "output.duration": 0.01}


@pytest.fixture(scope="module")
def runs():
    out = {}
    for method in ("ida", "adaptive-modal"):
        scene = roughvib.load_scene("paper-handset", {**IN_PHASE, "solver.method": method})
        out[method] = roughvib.simulate(scene, progress=False)
    return out


def test_contact_points_are_in_phase(runs):
    # the premise: identical roughness input at the three points
    r = runs["ida"].dataset["roughness_input"].values
    assert np.ptp(r, axis=1).max() <= 1e-12 * np.abs(r).max()


@pytest.mark.parametrize("method", ["ida", "adaptive-modal"])
def test_in_phase_contacts_switch_together(runs, method):
    ds = runs[method].dataset
    closed = ds["contact_closed"].values
    force = ds["contact_force"].values
    assert runs[method].ok
    assert 0 < closed.mean() < 1  # the contacts do lift off
    assert (closed == closed[:, :1]).all(), "a contact left its in-phase partners"
    assert np.abs(force - force[:, :1]).max() <= 1e-9 * np.abs(force).max()
    ev = runs[method].events
    td = ev[ev["kind"] == "touch_down"].sort_values("time")
    # every touch-down instant switches all three contacts (IDA locates the three roots within
    # round-off of each other, ~1e-16 s apart: one instant is a cluster closer than 1e-9 s)
    instant = np.cumsum(np.diff(td["time"].values, prepend=-1.0) > 1e-9)
    assert len(set(instant)) >= 2
    assert (td.groupby(instant)["contact"].nunique() == 3).all()
    # and switches each contact once per instant: no contact switches back within round-off
    # of its switch (before the fix of the refire rule IDA logged touch_down, lift_off,
    # touch_down of one contact within 3e-16 s, its margin read -6e-19 m after closing)
    sw = ev[ev["kind"].isin(["touch_down", "lift_off"])]
    for c, g in sw.groupby("contact"):
        t = g["time"].values
        assert (np.diff(t) > 1e-9).all(), (c, g[["time", "kind"]])
        assert (g["kind"].values[1:] != g["kind"].values[:-1]).all(), c
    t_all = np.sort(sw["time"].values)
    n_instants = int((np.diff(t_all, prepend=-1.0) > 1e-9).sum())
    assert len(sw) == 3 * n_instants


def test_ida_matches_adaptive_modal_on_in_phase_contacts(runs):
    a, b = runs["ida"].dataset, runs["adaptive-modal"].dataset
    x, y = a["normal_force"].values, b["normal_force"].values
    assert np.sqrt(np.mean((x - y) ** 2)) <= 1e-3 * np.sqrt(np.mean(y ** 2))
