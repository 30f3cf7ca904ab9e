"""Event-log inspection: phase table vs the sampled signals, CLI filters, events figure."""

import json

import numpy as np
import pandas as pd
import pytest

from roughvib.analysis.events import lift_off_intervals, phase_table, stick_intervals
from roughvib.cli import main
from roughvib.results import load_result


def test_intervals_recognise_runs_starting_inside_a_phase():
    ev = pd.DataFrame({"time": [0.1, 0.3, 0.5], "kind": ["slip", "stick", "slip"],
                       "contact": pd.array([pd.NA] * 3, dtype="Int64")})
    assert stick_intervals(ev, 1.0) == [(0.0, 0.1), (0.3, 0.5)]
    ev = pd.DataFrame({"time": [0.2, 0.4, 0.6], "kind": ["touch_down", "lift_off", "lift_off"],
                       "contact": pd.array([1, 1, 0], dtype="Int64")})
    assert lift_off_intervals(ev, 1, 1.0) == [(0.0, 0.2), (0.4, 1.0)]
    assert lift_off_intervals(ev, 0, 1.0) == [(0.6, 1.0)]
    table = phase_table(ev, 1.0, 0.5, 2)
    assert list(table["lift_offs_1"]) == [1, 0]
    assert table["lift_off_time_1"].tolist() == pytest.approx([0.3, 0.5])
    # a record of two whole periods ends on the first sample at or after 1.0 s: still two
    # cycles, not a third one of 1e-5 s; a tenth of a period more is a cycle of its own
    table = phase_table(ev, 1.0 + 1e-5, 0.5, 2)
    assert table["end"].tolist() == [0.5, 1.0 + 1e-5]
    assert table["lift_off_time_1"].tolist() == pytest.approx([0.3, 0.5 + 1e-5])
    assert len(phase_table(ev, 1.05, 0.5, 2)) == 3


@pytest.fixture(scope="module")
def coulomb_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("ev") / "run"
    code = main(["run", "--out", str(out), "--quiet",
                 "--set", "plate.kind=rigid", "--set", "friction.law=coulomb",
                 "--set", "contact.points=3", "--set", "roughness.kind=sinusoid",
                 "--set", "roughness.amplitude=1.5e-6", "--set", "roughness.wavelength=0.3e-3",
                 "--set", "output.duration=0.2", "--set", "output.progress=false"])
    assert code == 0
    return out


def test_phase_table_agrees_with_sampled_signals(coulomb_run):
    r = load_result(coulomb_run)
    t = r.dataset["time"].values
    v = r.dataset["block_tangential_velocity"].values
    f = r.dataset["contact_force"].values
    table = phase_table(r.events, float(t[-1]), 1 / 7, 3)
    for _, row in table.iterrows():
        w = (t >= row["start"]) & (t < row["end"])
        # coulomb stick holds v at exactly zero: the sampled fraction matches within 2 samples
        assert row["stick_fraction"] == pytest.approx(np.mean(v[w] == 0.0),
                                                      abs=2 / w.sum())
        for k in range(3):
            open_time = np.sum(f[w, k] == 0.0) * 1e-5
            assert row[f"lift_off_time_{k}"] == pytest.approx(open_time, abs=3e-5 + 2e-5 *
                                                              row[f"lift_offs_{k}"])
    assert table[[f"lift_offs_{k}" for k in range(3)]].to_numpy().sum() == \
        (r.events["kind"] == "lift_off").sum()


def test_events_command_table_json_and_filters(coulomb_run, capsys):
    assert main(["events", str(coulomb_run)]) == 0
    out = capsys.readouterr().out
    assert "stick" in out.splitlines()[0] and "lift-offs per contact" in out
    assert main(["events", str(coulomb_run), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert len(data["phases"]) == 2 and "stick_fraction" in data["phases"][0]
    assert main(["events", str(coulomb_run), "--kind", "stick", "--cycle", "1", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["events"] and all(e["kind"] == "stick" for e in data["events"])
    assert all(1 / 7 <= e["time"] < 2 / 7 for e in data["events"])
    assert main(["events", str(coulomb_run), "--cycle", "9"]) == 2
    assert "--cycle must be in [0, 1]" in capsys.readouterr().err


def test_events_csv_has_both_sides_of_each_switch(coulomb_run):
    ev = pd.read_csv(coulomb_run / "events.csv")
    for col in ("regime_before", "regime_after", "margin_before", "margin_after",
                "friction_before", "friction_after"):
        assert col in ev.columns
    sticks = ev[ev["kind"] == "stick"]
    assert len(sticks) >= 2
    # entering stick: kinetic friction (about mu_slip F_N) jumps to the static balance
    assert np.all(np.abs(sticks["friction_before"]) > 0.25 * 2.168)
    assert (sticks["regime_after"].str.endswith("stick")).all()
    lo = ev[ev["kind"] == "lift_off"]
    assert (lo["contact_force"] == 0.0).all()


def test_plot_events_figure(coulomb_run, capsys):
    assert main(["plot", str(coulomb_run), "--figure", "events"]) == 0
    png = coulomb_run / "figures" / "events.png"
    assert png.exists() and png.stat().st_size > 10_000
    from roughvib.views.figures import plot_events

    axes = plot_events(load_result(coulomb_run))
    assert axes[0].get_ylabel() == "tangential velocity [mm/s]"
    assert axes[1].get_ylabel() == "normal force [N]"
    assert axes[2].get_xlabel() == "time [s]"
    assert main(["plot", str(coulomb_run), "--figure", "nope"]) == 2


def test_stick_series_is_the_coulomb_stick_regime(coulomb_run):
    """result.nc's stick(time): Coulomb stick holds v at exactly zero, so the flag is v == 0
    (except at t = 0, where the block starts at rest in slip+: |T0| exceeds the static bound),
    and it follows the regime strings of the log."""
    ds = load_result(coulomb_run).dataset
    stick, v = ds["stick"].values, ds["block_tangential_velocity"].values
    assert ds["stick"].dtype == np.int8 and ds["stick"].attrs["flag_meanings"] == "slip stick"
    assert np.array_equal(stick[1:] == 1, v[1:] == 0.0)
    assert 0.2 < stick.mean() < 0.8
    ev = pd.read_csv(coulomb_run / "events.csv")
    # the log opens with the initial phase at t = 0, which the series' first sample shows
    assert ev["time"].iloc[0] == 0.0 and ev["kind"].iloc[0] in ("stick", "slip")
    assert (stick[0] == 1) == (ev["kind"].iloc[0] == "stick")
    assert (stick[0] == 1) == ev["regime_after"].iloc[0].endswith(" stick")
    assert np.array_equal(ds["contact_closed"].values, np.ones((v.size, 3), np.int8))
