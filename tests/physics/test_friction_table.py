"""The tabulated friction law (``friction.law = "table"``): closed forms, the Stribeck law it
samples, its interpolant, its calibration and its one-line refusals."""

import math

import numpy as np
import pytest
from test_coulomb import _closed_form_phases, _phases, _scene

import roughvib
from roughvib.api import simulate
from roughvib.physics.friction import (
    LAW_TABLE,
    LAWS,
    coulomb_kinetic,
    kinetic_coefficient,
    law_table,
    load_friction_table,
    pchip_slopes,
    table_kinetic,
)
from roughvib.scene import FRICTION_LAWS, SceneError


def _write(path, velocity, mu):
    rows = zip(velocity, mu, strict=True)
    lines = ["velocity,mu"] + [f"{float(v)!r},{float(m)!r}" for v, m in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _table_scene(tmp_path, velocity, mu, **over):
    _write(tmp_path / "curve.csv", velocity, mu)
    sc = _scene(**{"friction.law": "table", "friction.table": "curve.csv", **over})
    return _rebase(sc, tmp_path)


def _rebase(scene, folder):
    """The scene as if its file lay in ``folder`` (the table path is relative to it)."""
    from dataclasses import replace

    return replace(scene, base_dir=str(folder))


def test_every_registered_law_is_a_scene_choice():
    assert tuple(LAWS) == tuple(FRICTION_LAWS)
    assert [law.law_id for law in LAWS.values()] == sorted({law.law_id for law in LAWS.values()})


def flat_table_run(tmp_path, method, T0, mu_st, mu_sl, r2):
    """Two periods of a rigid plate with a flat kinetic table mu(v) = mu_slip under ``method``;
    checks that its stick and slip phases are those of the Coulomb closed form (at least five)
    and returns the result and the largest event-time error [s]."""
    t_end = 2.0 / 7.0
    sc = _table_scene(tmp_path, [0.0, 1.0], [mu_sl, mu_sl], **{
        "excitation.force_amplitude": T0, "friction.mu_stick": mu_st,
        "friction.mu_slip": mu_sl, "block.tangential_damping": r2, "output.duration": t_end,
        "solver.method": method})
    r = simulate(sc)
    assert r.ok, r.summary["message"]
    assert r.summary["solver"]["method"] == method
    ref = _closed_form_phases(T0, mu_st, mu_sl, r2, t_end)
    got = _phases(r)
    assert [k for k, _ in got] == [k for k, _ in ref]
    assert len(ref) >= 5
    return r, max(abs(a[1] - b[1]) for a, b in zip(got, ref, strict=True))


@pytest.mark.parametrize("T0,mu_st,mu_sl,r2", [
    (0.95, 0.40, 0.30, 0.5),
    (1.10, 0.50, 0.25, 0.5),
])
def test_flat_table_is_the_coulomb_law(tmp_path, monkeypatch, T0, mu_st, mu_sl, r2):
    """A flat curve mu(v) = mu_slip: every stick and slip start within 1e-6 s of the closed
    form of the Coulomb law (the limit of the accuracy contract), stick exactly at v = 0, with
    IDA (adaptive-modal, the default: tests/physics/test_adaptive_modal_setvalued.py)."""
    monkeypatch.chdir(tmp_path)
    r, err = flat_table_run(tmp_path, "ida", T0, mu_st, mu_sl, r2)
    assert err < 1e-6, err
    v = r.dataset["block_tangential_velocity"].values
    assert np.mean(v == 0.0) > 0.2


def test_flat_table_with_moreau_matches_closed_form(tmp_path, monkeypatch):
    """Moreau-Jean time-stepping runs the table law too (phase starts within 3 steps)."""
    monkeypatch.chdir(tmp_path)
    T0, mu_st, mu_sl, r2, h = 0.95, 0.40, 0.30, 0.5, 1e-5
    t_end = 2.0 / 7.0
    sc = _table_scene(tmp_path, [0.0, 0.5, 1.0], [mu_sl] * 3, **{
        "excitation.force_amplitude": T0, "friction.mu_stick": mu_st,
        "friction.mu_slip": mu_sl, "block.tangential_damping": r2, "output.duration": t_end,
        "solver.method": "moreau", "solver.step": h})
    r = simulate(sc)
    assert r.ok, r.summary["message"]
    ref = _closed_form_phases(T0, mu_st, mu_sl, r2, t_end)
    got = _phases(r)
    assert [k for k, _ in got] == [k for k, _ in ref]
    assert max(abs(a[1] - b[1]) for a, b in zip(got, ref, strict=True)) < 3 * h


def test_table_sampled_from_stribeck_reproduces_the_stribeck_law(tmp_path, monkeypatch):
    """The Coulomb law's Stribeck curve, sampled every v_s / 20 to 12 v_s (then flat): the
    table run matches the analytic law within the accuracy contract (event times 1e-6 s,
    relative rms velocity error 1e-4)."""
    monkeypatch.chdir(tmp_path)
    mu_st, mu_sl, vs = 0.40, 0.30, 2e-3
    v = np.linspace(0.0, 12 * vs, 241)
    mu = np.array([coulomb_kinetic(x, mu_sl, mu_st, vs)[0] for x in v])
    over = {"excitation.force_amplitude": 1.0, "friction.mu_stick": mu_st,
            "friction.mu_slip": mu_sl, "block.tangential_damping": 0.5,
            "output.duration": 2.0 / 7.0}
    r_tab = simulate(_table_scene(tmp_path, v, mu, **over))
    r_ana = simulate(_scene(**over, **{"friction.stribeck_velocity": vs}))
    assert r_tab.ok and r_ana.ok
    a, b = _phases(r_tab), _phases(r_ana)
    assert [k for k, _ in a] == [k for k, _ in b]
    assert len(a) >= 5
    assert max(abs(x[1] - y[1]) for x, y in zip(a, b, strict=True)) < 1e-6
    va = r_tab.dataset["block_tangential_velocity"].values
    vb = r_ana.dataset["block_tangential_velocity"].values
    assert np.sqrt(np.mean((va - vb) ** 2) / np.mean(vb**2)) < 1e-4


def test_interpolant_is_monotone_exact_at_nodes_and_has_its_derivative():
    v = np.array([0.0, 0.01, 0.02, 0.05, 0.1, 0.2])
    mu = np.array([0.4, 0.39, 0.30, 0.30, 0.31, 0.45])  # a step and a flat stretch
    tab = np.concatenate([[v.size], v, mu, pchip_slopes(v, mu)])
    for kernel in (table_kinetic, table_kinetic.py_func):  # compiled and plain Python
        for x, m in zip(v[:-1], mu[:-1], strict=True):
            assert kernel(x, tab)[0] == pytest.approx(m, abs=1e-15)
        xs = np.linspace(0.0, 0.25, 2001)
        ys = np.array([kernel(x, tab)[0] for x in xs])
        # no overshoot: within the data's range on every interval, flat where the data are
        for i in range(v.size - 1):
            w = (xs >= v[i]) & (xs <= v[i + 1])
            lo, hi = min(mu[i], mu[i + 1]), max(mu[i], mu[i + 1])
            assert np.all((ys[w] >= lo - 1e-15) & (ys[w] <= hi + 1e-15))
        assert np.all(ys[(xs >= 0.02) & (xs <= 0.05)] == pytest.approx(0.30, abs=1e-15))
        assert np.all(ys[xs >= 0.2] == 0.45)  # beyond the table: the last value
        for x in (0.003, 0.015, 0.07, 0.15):
            h = 1e-7
            fd = (kernel(x + h, tab)[0] - kernel(x - h, tab)[0]) / (2 * h)
            assert kernel(x, tab)[1] == pytest.approx(fd, rel=1e-6, abs=1e-9)
    assert kinetic_coefficient(LAW_TABLE, 0.015, 0.0, 0.0, 0.0, tab) == table_kinetic(0.015, tab)


def test_table_law_calibrates_t0_to_the_target(tmp_path, monkeypatch):
    """On a rigid plate without roughness the model is the calibration's tangential model, so
    the run reaches the target rms velocity (calibration rtol 1e-3, first-order steps)."""
    monkeypatch.chdir(tmp_path)
    v = [0.0, 0.005, 0.02, 0.1]
    mu = [0.38, 0.33, 0.30, 0.30]
    sc = _table_scene(tmp_path, v, mu, **{"excitation.target_rms_velocity": 0.01,
                                          "output.duration": 5.0 / 7.0,
                                          "output.transient": 3.0 / 7.0})
    r = simulate(sc)
    assert r.ok, r.summary["message"]
    cal = r.summary["calibration"]
    assert cal["method"].startswith("set-valued")
    assert abs(cal["relative_deviation"]) < 5e-3, cal


@pytest.mark.parametrize("text,needle", [
    ("velocity,mu\n0,0.3\n", "at least 2 data rows, got 1"),
    ("speed,mu\n0,0.3\n1,0.3\n", "columns 'velocity' [m/s] and 'mu'"),
    ("velocity,mu\n0,0.3\n0.2,0.3\n0.1,0.3\n", "row 3 (line 4): velocity must increase"),
    ("velocity,mu\n0,0.3\n-0.1,0.3\n", "row 2 (line 3): velocity must be in [0, 100] m/s"),
    ("velocity,mu\n0,0.3\n150,0.3\n", "row 2 (line 3): velocity must be in [0, 100] m/s (the "
                                       "physically sane range of a sliding speed), got 150"),
    ("velocity,mu\n0,0.3\n1,1e300\n", "row 2 (line 3): mu must be in [0, 10] (the physically "
                                       "sane range of a friction coefficient, as "
                                       "friction.mu_stick), got 1e+300"),
    ("velocity,mu\n0,0.3\n1,-0.1\n", "row 2 (line 3): mu must be in [0, 10]"),
    # a step of 0.05 within 1e-200 m/s made the adaptive-modal solver divide by zero
    ("velocity,mu\n0,0.35\n1e-200,0.3\n1,0.3\n", "row 2 (line 3): mu may change by at most "
                                                   "1e+09 s/m x the velocity step"),
    ("velocity;mu\n0;0,3\n1;0,3\n", "must separate its columns with commas (a CSV file, "
                                     "decimals with a point), got ';' between 'velocity' and "
                                     "'mu' in the header row"),
    ("velocity\tmu\n0\t0.3\n1\t0.3\n", "got '\\t' between 'velocity' and 'mu'"),
    ("mu velocity\n0.3 0\n0.3 1\n", "got ' ' between 'velocity' and 'mu'"),
    ("velocity [m/s] | mu [-]\n0|0.3\n1|0.3\n", "got '|' between 'velocity' and 'mu'"),
    ("velocity,mu\n0,0.3\n0.1,nan\n", "row 2 (line 3): mu must be a finite number"),
    ("velocity,mu\n0,0.5\n0.1,0.3\n", "row 1 (line 2): mu at velocity 0 must be <= "
                                      "friction.mu_stick (0.4), got 0.5"),
    ("velocity,mu\n0.01,0.3\n0.1,0.3\n", "row 1 (line 2): velocity must start at 0 m/s"),
])
def test_bad_tables_are_refused_in_one_line(tmp_path, text, needle):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        load_friction_table(path, 0.4)
    msg = str(info.value)
    assert "\n" not in msg
    assert str(path) in msg and needle in msg, msg


def test_a_table_that_is_not_utf8_is_refused_naming_the_byte(tmp_path):
    path = tmp_path / "latin1.csv"
    path.write_bytes("velocity,mu\n0,0.3\n1,0.3 \u00e9\n".encode("latin-1"))
    with pytest.raises(SceneError) as info:
        load_friction_table(path, 0.4)
    assert str(info.value) == (f"friction.parameters.table {str(path)!r} must be UTF-8 text "
                               f"(save it as "
                               f"UTF-8 CSV), got byte 0xe9 at byte 24 on line 3")


def test_a_byte_order_mark_is_not_part_of_the_header(tmp_path):
    """Spreadsheets write UTF-8 CSV with a byte-order mark; scene, sweep and roughness files
    accept one, and so does a friction table (it is not read into the first column name)."""
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbfvelocity,mu\r\n0,0.35\r\n0.5,0.3\r\n")
    v, mu = load_friction_table(path, 0.4)
    np.testing.assert_array_equal(v, [0.0, 0.5])
    np.testing.assert_array_equal(mu, [0.35, 0.3])


def test_scene_and_solvers_refuse_what_they_cannot_do(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SceneError, match=r"^friction.parameters.table must name a CSV file of "
                                         r"the kinetic curve, .* when friction.law = 'table', "
                                         r"got none$"):
        roughvib.load_scene("paper", {"friction.law": "table"})
    with pytest.raises(SceneError, match=r"^friction.parameters.table is a key of friction.law "
                                         r"= 'table', not of friction.law = 'feldmann'"):
        roughvib.load_scene("paper", {"friction.table": "x.csv"})
    with pytest.raises(SceneError, match="friction.parameters.table 'missing.csv' must be a "
                                         "readable"):
        law_table(roughvib.load_scene("paper", {"friction.law": "table",
                                                "friction.table": "missing.csv"}).friction)
    sc = _table_scene(tmp_path, [0.0, 1.0], [0.3, 0.3], **{
        "excitation.force_amplitude": 1.0, "output.duration": 0.15})
    for method in ("exact-modal", "paper"):
        # refused when the scene is made, before anything runs
        with pytest.raises(SceneError, match=rf"^solver.method = '{method}' cannot run this "
                                             rf"scene: friction.law = 'table' is set-valued "
                                             rf".*, and {method} runs single-valued laws only; "
                                             rf"use ida, adaptive-modal or moreau$") as info:
            sc.with_overrides({"solver.method": method, "solver.step": 1e-5})
        assert "\n" not in str(info.value)


def test_law_table_packs_the_checked_curve(tmp_path):
    path = _write(tmp_path / "c.csv", [0.0, 0.1, 0.3], [0.35, 0.3, 0.32])
    v, mu = load_friction_table(path, 0.4)
    np.testing.assert_array_equal(v, [0.0, 0.1, 0.3])
    sc = roughvib.load_scene("paper", {"friction.law": "table", "friction.table": "c.csv",
                                       "friction.mu_stick": 0.4})
    tab = law_table(sc.friction, tmp_path)
    assert tab.size == 1 + 3 * 3 and int(tab[0]) == 3
    assert math.isclose(table_kinetic(0.1, tab)[0], 0.3)
