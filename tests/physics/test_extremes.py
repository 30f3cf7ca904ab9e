"""Extreme scenes (docs/robustness.md): every run is either right, checked by invariants, or stops
with a status that names the cause and gives a hint.

Invariants (``_invariants``): no NaN; contact forces never negative; the energy audit closes
within a multiple of rtol; event counts bounded. Where a case runs whole excitation periods,
the mean normal force equals m g (the block has no mean vertical acceleration). Case-specific
checks compare against closed forms (static equilibrium, linear scaling with the roughness)
or against the same run at a tighter tolerance. docs/robustness.md tabulates the outcomes.
"""

import math
import re

import numpy as np
import pytest

import roughvib
from roughvib.analysis.compare import band_level_errors, max_abs_db
from roughvib.analysis.spectra import band_powers, third_octave_bands
from roughvib.api import simulate
from roughvib.cli import main
from roughvib.model.system import GRAVITY
from roughvib.scene import SceneError

RTOL = 1e-6
EVENT_DRIVEN = ["ida", "adaptive-modal"]


def _run(name="paper-handset", **over):
    base = {"output.progress": False, "solver.rtol": RTOL}
    base.update(over)
    return simulate(roughvib.load_scene(name, base))


def _invariants(r, *, energy_factor=50.0, max_events=None):
    assert r.ok, r.summary["message"]
    ds = r.dataset
    for name in ds.data_vars:
        if "no friction model" in ds[name].attrs.get("comment", ""):
            continue  # prescribed tangential motion: NaN by the result contract
        assert np.all(np.isfinite(ds[name].values)), f"NaN/inf in {name}"
    F = ds["contact_force"].values
    assert F.min() >= -1e-9 * max(1.0, np.abs(F).max()), f"negative contact force {F.min()}"
    audit = r.summary["energy_audit"]
    rtol = r.summary["solver"]["rtol"]
    # a run where nothing moves has no energy scale: then the residual itself must vanish
    assert (abs(audit["relative_residual"]) < energy_factor * rtol
            or abs(audit["residual"]) < 1e-15), audit
    if max_events is not None:
        assert len(r.events) <= max_events
    return ds


def _mean_force_over_periods(r, mass, periods):
    t = r.dataset["time"].values
    n = int(round(periods / 7.0 / (t[1] - t[0])))
    fn = r.dataset["normal_force"].values[:n]
    return float(np.mean(fn)), mass * GRAVITY


# ---- stiffness, damping, modes --------------------------------------------------------------

@pytest.mark.short_run
@pytest.mark.parametrize("method", EVENT_DRIVEN)
@pytest.mark.parametrize("stiffness", [1e8, 1e10])
def test_very_stiff_contact(stiffness, method):
    r = _run(**{"solver.method": method, "contact.stiffness": stiffness, "output.duration": 0.005,
                "plate.max_frequency": 3000.0})
    ds = _invariants(r, max_events=2000)
    # statics: the initial contact forces carry the block exactly
    assert ds["contact_force"].values[0].sum() == pytest.approx(0.221 * GRAVITY, rel=1e-9)


@pytest.mark.short_run
def test_tiny_damping_keeps_the_energy_balance():
    """Loss factor 1e-5 and no dampers: almost nothing dissipates vertically, so the energy
    stored in the plate and block must match the work of the roughness input. Band levels
    converge with the tolerance: against rtol 1e-10, rtol 1e-8 is within 0.2 dB in every band
    200 Hz - 5 kHz, and the default rtol keeps the promise of docs/theory.md (bands above
    30 dB re 1e-6 m/s^2 within 1 dB; the quiet 4-5 kHz bands, 40-50 dB below the peak, read up
    to 2.3 dB low at rtol 1e-6, which a rectangular window's leakage used to hide)."""
    base = {"plate.loss_factor": 1e-5, "block.vertical_damping": 0.0,
            "block.tangential_damping": 0.0, "output.duration": 0.01,
            "plate.max_frequency": 5000.0}
    r = _run(**base)
    _invariants(r)
    tight = _run(**base, **{"solver.rtol": 1e-8, "solver.atol_acceleration": 1e-10})
    ref = _run(**base, **{"solver.rtol": 1e-10, "solver.atol_acceleration": 1e-12})
    fc, lo, hi = third_octave_bands(100.0, 50e3)
    keep = hi <= 5e4 * (1 + 1e-12)
    for v in ("plate_vertical_acceleration", "block_vertical_acceleration"):
        x_ref = ref.dataset[v].values
        fc_, d_tight = band_level_errors(tight.dataset[v].values, x_ref, 1e5)
        assert max_abs_db(fc_, d_tight, 200.0, 5000.0) < 0.2, v
        _, d = band_level_errors(r.dataset[v].values, x_ref, 1e5)
        level = 10 * np.log10(band_powers(x_ref, 1e5, lo[keep], hi[keep], window="hann")
                              / 1e-12 + 1e-300)
        loud = (fc_ >= 200.0) & (fc_ <= 5000.0) & (level > 30.0)
        assert loud.sum() >= 3 and np.nanmax(np.abs(d[loud])) < 1.0, v


@pytest.mark.slow
@pytest.mark.short_run
@pytest.mark.filterwarnings("ignore:plate modes above:roughvib.scene.ModelValidityWarning")
def test_many_modes_to_100_khz():
    """All modes to 100 kHz. Their number follows the lattice-point count of a simply
    supported a x b plate: N = a b k^2 / (4 pi) - (a + b) k / (2 pi), k^4 = omega^2 rho h / D
    (798 for the default plate)."""
    r = _run(**{"plate.max_frequency": 1e5, "output.duration": 0.003})
    _invariants(r)
    p = roughvib.load_scene("paper").plate
    d = p.youngs_modulus * p.thickness**3 / (12 * (1 - p.poisson_ratio**2))
    k = math.sqrt(2 * math.pi * 1e5) * (p.density * p.thickness / d) ** 0.25
    n_weyl = p.length * p.width * k**2 / (4 * math.pi) - (p.length + p.width) * k / (2 * math.pi)
    assert r.summary["model"]["modes"] == pytest.approx(n_weyl, rel=0.02)


# ---- velocity ------------------------------------------------------------------------------

def _sliding(velocity, method, **extra):
    """Constant sliding at ``velocity`` [m/s] (prescribed), plate modes to 5 kHz, 4 ms."""
    return _run(**{"solver.method": method, "excitation.kind": "prescribed",
                   "excitation.velocity": velocity,
                   "excitation.amplitude": 0.0, "excitation.target_rms_velocity": "none",
                   "output.duration": 0.004, "plate.max_frequency": 5000.0, **extra})


@pytest.fixture(scope="module")
def tight_sliding():
    """The runs of :func:`_sliding` at rtol 1e-8 by adaptive-modal, one per velocity, made
    once for both methods.

    Each method's default run is compared with it: for adaptive-modal that is the same
    solver at a tighter tolerance (as before), for IDA an independent integrator of the same
    DAE (exact modal propagation with step doubling) at a tighter tolerance, where it used to
    be IDA's own run at rtol 1e-8: the check is now agreement with a converged solution by
    another method, not only with the same method's tighter run. The two tight runs agree to
    1e-5 dB in every band checked here (measured), and adaptive-modal's costs 0.3 s (0.3 m/s)
    and 0.5 s (1 m/s) against IDA's 4.2 s and 9.6 s."""
    runs = {}

    def get(velocity):
        if velocity not in runs:
            runs[velocity] = _sliding(velocity, "adaptive-modal", **{
                "solver.rtol": 1e-8, "solver.atol_acceleration": 1e-10})
        return runs[velocity]

    return get


@pytest.mark.short_run
@pytest.mark.parametrize("method", EVENT_DRIVEN)
@pytest.mark.parametrize("velocity", [0.3, 1.0])
def test_high_sliding_velocity(velocity, method, tight_sliding):
    """Constant sliding at 0.3 and 1 m/s (prescribed): lift-offs and touch-downs alternate per
    contact, and the run agrees with a run at a tighter tolerance (:func:`tight_sliding`)."""
    r = _sliding(velocity, method)
    _invariants(r, max_events=20_000)
    for k in range(r.summary["model"]["contacts"]):
        kinds = r.events[r.events["contact"] == k].sort_values("time")["kind"].tolist()
        kinds = [x for x in kinds if x in ("lift_off", "touch_down")]
        assert all(a != b for a, b in zip(kinds, kinds[1:], strict=False)), k
    tight = tight_sliding(velocity)
    for v in ("plate_vertical_acceleration", "block_vertical_acceleration"):
        fc, d = band_level_errors(r.dataset[v].values, tight.dataset[v].values, 1e5)
        assert max_abs_db(fc, d, 1000.0, 5000.0) < 1.0, v


# ---- contact regimes -------------------------------------------------------------------------

def _bounce(amplitude, **extra):
    over = {"plate.kind": "rigid", "contact.points": 1, "roughness.kind": "sinusoid",
            "roughness.amplitude": amplitude, "roughness.wavelength": 0.5e-3,
            "excitation.kind": "prescribed", "excitation.velocity": 0.1,
            "excitation.amplitude": 0.0, "excitation.target_rms_velocity": "none",
            "output.duration": 0.02}
    over.update(extra)
    return _run(**over)


@pytest.mark.short_run
@pytest.mark.parametrize("method", EVENT_DRIVEN)
def test_lift_off_chatter_is_resolved_event_by_event(method):
    """A sinusoid whose kinematic acceleration A w^2 is 80 g: the block flies over the crests;
    every lift-off is followed by a touch-down and the energy audit closes. With impacts the
    audit residual converges only like sqrt(rtol) (measured 7e-5, 2e-5, 8e-6, 2.3e-6 at rtol
    1e-6 ... 1e-9; docs/robustness.md), so the bound is 0.1 sqrt(rtol) and it must shrink."""
    r = _bounce(10e-6, **{"solver.method": method})
    _invariants(r, max_events=500, energy_factor=0.1 / math.sqrt(RTOL))
    tight = _bounce(10e-6, **{"solver.method": method, "solver.rtol": 1e-9})
    assert (abs(tight.summary["energy_audit"]["relative_residual"])
            < abs(r.summary["energy_audit"]["relative_residual"]) / 5)
    n_lift = int((r.events["kind"] == "lift_off").sum())
    assert n_lift >= 3
    assert abs(n_lift - int((r.events["kind"] == "touch_down").sum())) <= 1


@pytest.mark.short_run
@pytest.mark.parametrize("method", EVENT_DRIVEN)
def test_grazing_contact_either_holds_or_names_the_storm(method):
    """Roughness acceleration A w^2 = g exactly: the contact force grazes zero at every crest.
    The run must stay right (no negative force, audit closed) or stop as an event storm."""
    w = 2 * math.pi * 0.1 / 0.5e-3
    # base-excited oscillator below its contact resonance wn^2 = s / m: block acceleration
    # amplitude A w^2 / (1 - w^2 / wn^2) reaches g at this A
    r = _bounce(GRAVITY * (1 - w**2 * 0.221 / 3.1e6) / w**2, **{"solver.method": method})
    if r.ok:
        _invariants(r, max_events=500, energy_factor=0.1 / math.sqrt(RTOL))
    else:
        assert r.status == "event_storm" and "Hint" in r.summary["message"]


@pytest.mark.short_run
@pytest.mark.parametrize("method", EVENT_DRIVEN)
def test_event_storm_stops_with_time_regime_and_hint(method):
    r = _bounce(10e-6, **{"solver.method": method, "solver.max_events": 2,
                          "solver.event_window": 0.1})
    assert r.status == "event_storm"
    msg = r.summary["message"]
    assert "more than 2 events within 0.1 s at t = " in msg
    assert "contact 0" in msg and "regime closed=" in msg and "Hint:" in msg


@pytest.mark.short_run
def test_zero_roughness_leaves_the_vertical_static():
    """No roughness: friction acts tangentially only, so the normal force stays m g exactly
    while the block slides back and forth."""
    r = _run(**{"roughness.kind": "none", "output.duration": 0.02,
                "plate.max_frequency": 3000.0})
    ds = _invariants(r)
    np.testing.assert_allclose(ds["normal_force"].values, 0.221 * GRAVITY, rtol=1e-9)
    assert np.max(np.abs(ds["block_tangential_velocity"].values)) > 1e-3
    assert np.max(np.abs(ds["plate_vertical_acceleration"].values)) < 1e-9


def _impulse_defect(r, mass, r1):
    """Vertical momentum balance of the block over the run, relative to m g T. With vertical
    positive down, m v' = m g - F - r1 v, so integral F dt = m g T - m dv - r1 dz exactly;
    the integral is taken by trapezoids on the output grid."""
    ds = r.dataset
    t = ds["time"].values
    f = ds["normal_force"].values
    v = ds["block_vertical_velocity"].values
    z = ds["block_vertical_displacement"].values
    T = t[-1] - t[0]
    impulse = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t)))
    expected = mass * GRAVITY * T - mass * (v[-1] - v[0]) - r1 * (z[-1] - z[0])
    return (impulse - expected) / (mass * GRAVITY * T)


def test_very_light_load_over_a_whole_period():
    """0.01 kg: the contact opens often. Over a whole period the contact impulse equals the
    weight's impulse minus the block's momentum change and the damper's impulse r1 dz (the
    mean normal force is m g up to these, 0.4 % here)."""
    r = _run(**{"block.mass": 0.01, "output.duration": 1 / 7, "output.transient": 0.0,
                "plate.max_frequency": 3000.0})
    _invariants(r, max_events=50_000)
    assert abs(_impulse_defect(r, 0.01, 83.0)) < 1e-4
    mean, mg = _mean_force_over_periods(r, 0.01, 1)
    assert mean == pytest.approx(mg, rel=1e-2)


@pytest.mark.short_run
def test_heavy_load_tiny_roughness_is_linear():
    """Heavy block on tiny roughness never lifts off: the response is linear in the roughness,
    so doubling the rms raises every level by 20 log10(2) = 6.02 dB."""
    lev = []
    for rms in (1e-9, 2e-9):
        r = _run(**{"block.mass": 2.0, "roughness.rms": rms, "excitation.kind": "prescribed",
                    "excitation.velocity": 0.01, "excitation.amplitude": 0.0,
                    "excitation.target_rms_velocity": "none", "output.duration": 0.02,
                    "plate.max_frequency": 5000.0, "solver.atol_acceleration": 1e-12})
        _invariants(r, max_events=0)
        lev.append({v: 20 * np.log10(np.std(r.dataset[v].values[500:]))
                    for v in ("plate_vertical_acceleration", "block_vertical_acceleration")})
    for v in lev[0]:
        assert lev[1][v] - lev[0][v] == pytest.approx(20 * math.log10(2), abs=0.02), v


@pytest.mark.short_run
def test_stick_only_excitation_never_slips():
    """Coulomb friction with a drive below mu_stick m g: the block sticks for ever, its
    tangential velocity is exactly zero and friction balances the drive."""
    r = _run(**{"friction.law": "coulomb", "excitation.force_amplitude": 0.5,
                "excitation.target_rms_velocity": "none", "output.duration": 0.05,
                "plate.max_frequency": 3000.0, "roughness.kind": "none"})
    ds = _invariants(r)
    assert np.max(np.abs(ds["block_tangential_velocity"].values)) < 1e-12
    assert not (r.events["kind"] == "slip").any()


@pytest.mark.short_run
@pytest.mark.parametrize("points", [1, 10])
def test_one_contact_versus_ten(points):
    """The same total stiffness on 1 or 10 contacts: statics carry m g either way."""
    r = _run(**{"contact.points": points, "output.duration": 0.01,
                "plate.max_frequency": 3000.0})
    ds = _invariants(r)
    assert ds["contact_force"].values[0].sum() == pytest.approx(0.221 * GRAVITY, rel=1e-9)


@pytest.mark.short_run
def test_cubic_and_quintic_interpolation_agree_to_20_khz():
    """On the default input (the surface to 0.2 um through the contact filter, four samples
    per shortest wavelength) the interpolant no longer matters: solved tightly (rtol 1e-8),
    cubic and quintic agree within 0.5 dB in every band above 20 dB re 1e-6 m/s^2 from 200 Hz
    to 20 kHz. (On the paper's 50 um band and 10 um grid they differ by tens of dB above the
    band: there the interpolant's images are the input.)"""
    res = {}
    for interp in ("cubic", "quintic"):
        res[interp] = _run(**{"roughness.interpolation": interp, "output.duration": 0.02,
                              "plate.max_frequency": 2e4, "solver.rtol": 1e-8,
                              "solver.atol_acceleration": 1e-10})
        _invariants(res[interp])
    for v in ("plate_vertical_acceleration", "block_vertical_acceleration"):
        fc, d = band_level_errors(res["cubic"].dataset[v].values,
                                  res["quintic"].dataset[v].values, 1e5, floor_db=20.0)
        assert np.isfinite(d).sum() >= 4, v
        assert max_abs_db(fc, d, 200.0, 20e3) < 0.5, v


@pytest.mark.slow
def test_long_run_of_20_periods_does_not_drift():
    periods = 20
    r = _run(**{"output.duration": periods / 7, "plate.max_frequency": 2000.0,
                "output.transient": 0.0})
    _invariants(r)
    t = r.dataset["time"].values
    n = int(round(1 / 7 / (t[1] - t[0])))
    fn = r.dataset["normal_force"].values
    x = r.dataset["block_tangential_displacement"].values
    assert abs(_impulse_defect(r, 0.221, 83.0)) < 1e-5
    for p in range(periods):
        assert np.mean(fn[p * n:(p + 1) * n]) == pytest.approx(0.221 * GRAVITY, rel=1e-3), p
    # the stroke's centre does not wander: the mean position of the last period is that of
    # the second (the first holds the start transient) within 5 % of the stroke
    stroke = np.ptp(x[n:2 * n])
    assert abs(np.mean(x[-n:]) - np.mean(x[n:2 * n])) < 0.05 * stroke


def test_ida_failure_message_names_the_contact_closest_to_switching():
    """The diagnostic behind an ``ida_error``: the contact whose margin is nearest zero. At the
    static equilibrium of one contact on a crest its margin is the static force."""
    from roughvib.model.system import assemble
    from roughvib.solvers.ida import _IDA_HINTS, _closest_contact

    scene = roughvib.load_scene("paper", {"contact.points": 3, "plate.max_frequency": 3000.0,
                                          "output.progress": False})
    system = assemble(scene)
    reg, rf = system.new_regime_arrays()
    y0, closed = system.static_equilibrium()
    from roughvib.model.regimes import initial_regime

    initial_regime(closed, system.fp, True, scene.friction.law).pack(reg, rf)
    text = _closest_contact(0.0, y0, 3, system.event_args(reg, rf))
    forces = y0[system.layout.slice("contact.force")]
    k = int(np.argmin(np.abs(forces)))
    assert f"contact {k} is closest to switching" in text
    assert all("solver." in h for h in _IDA_HINTS.values())


# ---- tolerances at the edges, and runs that always end (issue 17) ---------------------------

TIGHT = {"solver.rtol": 1e-10, "solver.atol": 1e-16, "solver.atol_acceleration": 1e-12}


def _events_agree(a, b, dt):
    assert list(a.events["kind"]) == list(b.events["kind"])
    assert np.max(np.abs(a.events["time"].to_numpy() - b.events["time"].to_numpy())) < dt


@pytest.mark.short_run
def test_tight_tolerances_through_lift_off_and_touch_down():
    """rtol 1e-10, atol 1e-16 m, atol_acceleration 1e-12 m/s^2 on the one-contact lift-off
    scene (lift-off, touch-down, lift-off in 4 ms). Both used to fail: adaptive-modal's Newton
    demanded updates below the round-off of its equations (step_underflow at the touch-down),
    IDA restarted the touch-down with zero force rates and failed its error test down to the
    minimum step. The two solvers, different discretisations, must agree on the event times
    far below their 1e-5 s output step, and the audit closes like sqrt(rtol) with impacts."""
    runs = [_bounce(10e-6, **{"solver.method": m, "output.duration": 0.004, **TIGHT})
            for m in EVENT_DRIVEN]
    for r in runs:
        _invariants(r, max_events=10, energy_factor=0.1 / math.sqrt(TIGHT["solver.rtol"]))
    assert len(runs[0].events) >= 3
    _events_agree(*runs, 1e-9)


@pytest.mark.short_run
def test_tight_tolerances_on_an_elastic_plate():
    """The same tolerances with plate modes to 2 kHz up to the first lift-off (adaptive-modal
    stopped there with newton_failure)."""
    over = {"plate.kind": "modal", "plate.max_frequency": 2000.0, "output.duration": 6e-4,
            **TIGHT}
    runs = [_bounce(10e-6, **{"solver.method": m, **over}) for m in EVENT_DRIVEN]
    for r in runs:
        _invariants(r, max_events=10, energy_factor=0.1 / math.sqrt(TIGHT["solver.rtol"]))
    assert list(runs[0].events["kind"]) == ["lift_off"]
    _events_agree(*runs, 1e-9)


@pytest.mark.short_run
@pytest.mark.parametrize("method", EVENT_DRIVEN)
def test_tolerances_below_their_round_off_floor_are_refused_in_one_line(method):
    """Below the floors of docs/robustness.md a run cannot meet its tolerance (IDA stalled at
    a tenth of the atol floor): refused before the run, naming field, rule, unit and value.
    Here the compression's terms reach 1.9e-5 m (the 10 um sinusoid, the static compression),
    so solver.atol >= 100 eps x 1.9e-5 m = 4.3e-19 m."""
    over = {"solver.method": method, "plate.kind": "modal", "plate.max_frequency": 2000.0,
            "output.duration": 2e-4}
    with pytest.raises(SceneError) as exc:
        _bounce(10e-6, **over, **{"solver.atol": 1e-20})
    msg = str(exc.value)
    assert "\n" not in msg
    assert re.fullmatch(r"solver\.atol must be >= 4\.3e-19 m for this scene \(.*\), "
                        r"got 1e-20 m", msg), msg
    with pytest.raises(SceneError, match=r"^solver\.atol_acceleration must be >= \S+ m/s\^2 "
                                         r"for this scene \(.*\), got 1e-17 m/s\^2$"):
        _bounce(10e-6, **over, **{"solver.atol_acceleration": 1e-17})
    # just above both floors the run goes through
    _invariants(_bounce(10e-6, **over, **{"solver.atol": 5e-19,
                                          "solver.atol_acceleration": 1e-15}))


def _error_lines(stderr: str) -> str:
    return "\n".join(ln for ln in stderr.strip().splitlines()
                     if not ln.startswith("roughvib: warning: "))


@pytest.mark.parametrize("method,mass", [("ida", 1e15), ("ida", 1e12), ("adaptive-modal", 1e9)])
def test_huge_masses_are_refused_in_one_line(method, mass, tmp_path, capsys):
    """The runs of issue 17 that never ended (`roughvib run --set block.mass=1e15 --set
    output.duration=0.005` sat in one IDA step for 150 s; 1e9 kg needed 93,000 Jacobians for
    5 ms). Cause: each mode balances w^2 q against its modal force phi F / M, which grows with
    m g, so round-off in that balance (eps m g / M: 4e-6 m/s^2 at 1e9 kg) exceeds the default
    acceleration tolerance 1e-8 m/s^2 from about 2e6 kg on; the block's position (3e4 m of
    static compression at 1e9 kg) likewise swamps the displacement tolerance."""
    # the hand-set contact (paper-handset): with the contact module (paper) such a mass is
    # refused even earlier, because no summit statistics carry it (checked below)
    code = main(["run", "paper-handset", "--out", str(tmp_path / "run"), "--no-progress",
                 "--quiet", "--set", f"block.mass={mass:g}", "--set", "output.duration=0.005",
                 "--set", f"solver.method={method}"])
    # the short run draws validity warnings (one line each) before the one-line error
    err = _error_lines(capsys.readouterr().err)
    assert code == 2 and "\n" not in err, err
    assert "solver.atol_acceleration must be >= " in err and f"block.mass = {mass:g} kg" in err
    code = main(["run", "paper", "--out", str(tmp_path / "auto"), "--no-progress", "--quiet",
                 "--set", f"block.mass={mass:g}", "--set", "output.duration=0.005",
                 "--set", f"solver.method={method}"])
    err = _error_lines(capsys.readouterr().err)
    assert code == 2 and "\n" not in err, err
    assert "cannot carry block.mass" in err and "pressed flat" in err


@pytest.mark.short_run
@pytest.mark.parametrize("method", EVENT_DRIVEN)
def test_huge_mass_runs_at_tolerances_above_the_floors(method):
    """1e9 kg with both tolerances above their floors: an ordinary run (20 steps per output
    interval at most, against up to 20,000 before), and the block, 2e9 times the plate's modal
    mass, is not moved by the roughness: the normal force stays m g."""
    r = _run(**{"solver.method": method, "block.mass": 1e9, "solver.atol": 1e-8,
                "solver.atol_acceleration": 1e-4, "output.duration": 0.002,
                "plate.max_frequency": 5000.0})
    ds = _invariants(r)
    np.testing.assert_allclose(ds["normal_force"].values, 1e9 * GRAVITY, rtol=1e-6)
    assert r.summary["solver"]["steps"] < 20 * 200


@pytest.mark.short_run
@pytest.mark.parametrize("method", EVENT_DRIVEN)
def test_a_stalled_run_ends_with_a_named_failure(method, monkeypatch):
    """The stall guard, the backstop for whatever the floors miss: with the floor check
    bypassed, 1e15 kg at an atol_acceleration of 1e-8 m/s^2 (nine orders below the floor)
    stops as `stalled` within its step budget, with a hint, instead of running for ever.

    adaptive-modal with its trapezoidal step (the one of the scenes the Hermite step does not
    cover); its Hermite step runs this case to the end (70 step pairs per output interval
    at 1e-8, 84 at 1e-10: its estimate is not swamped by the round-off), and its guard is
    tested below."""
    from roughvib.solvers import adaptive_modal, ida
    from roughvib.solvers.events import step_budget

    monkeypatch.setattr(ida, "check_tolerances", lambda *a: None)
    monkeypatch.setattr(adaptive_modal, "check_tolerances", lambda *a: None)
    monkeypatch.setattr(adaptive_modal, "hermite_applies", lambda system: False)
    # an absolute atol_acceleration (the accuracy preset's would scale with the pilot's level,
    # which at 1e15 kg is the round-off noise of the static load)
    r = _run(**{"solver.method": method, "block.mass": 1e15, "output.duration": 0.002,
                "plate.max_frequency": 2000.0, "solver.atol_acceleration": 1e-8})
    assert r.status == "stalled", r.summary["message"]
    msg = r.summary["message"]
    assert "within one output interval" in msg and "Hint:" in msg and "\n" not in msg
    assert r.summary["solver"]["steps"] <= step_budget(1e-5)


@pytest.mark.short_run
def test_the_hermite_loops_stall_guard(monkeypatch):
    """adaptive-modal's Hermite loop stops as `stalled` when its step attempts within one
    output interval exceed the budget (here forced to 8: its first steps, 1/256 of the output
    step, need more). Its ``steps`` are kept steps, two per accepted pair inside an
    interval: at most 2 x 8 before the guard stops it."""
    from roughvib.solvers import adaptive_modal

    monkeypatch.setattr(adaptive_modal, "step_budget", lambda output_step: 8)
    r = _run(**{"solver.method": "adaptive-modal", "output.duration": 0.002,
                "plate.max_frequency": 2000.0})
    assert r.status == "stalled", r.summary["message"]
    msg = r.summary["message"]
    assert "more than 8 step attempts within one output interval" in msg, msg
    assert "Hint:" in msg and "\n" not in msg
    assert r.summary["solver"]["blocks"] <= 8
    assert r.summary["solver"]["steps"] == 2 * r.summary["solver"]["blocks"]


@pytest.mark.short_run
def test_ida_stopped_by_its_jacobian_guard_in_the_first_call_reports_its_counts(monkeypatch):
    """The Jacobian guard firing inside the very first IDA call (here forced: one Jacobian
    per output interval, 20 000 // 20 000) stops the run as `stalled` and still reports IDA's
    own step and evaluation counts, validated before the first step, not "unavailable"."""
    from roughvib.solvers import ida

    monkeypatch.setattr(ida, "JACOBIANS_PER_STEP_BUDGET", 20_000)  # 20 000 // 20 000: one
    r = _run(**{"solver.method": "ida", "output.duration": 0.002,
                "plate.max_frequency": 2000.0})
    assert r.status == "stalled", r.summary["message"]
    assert "more than 1 Jacobians" in r.summary["message"]
    st = r.summary["solver"]
    assert "note" not in st, st.get("note")
    # IDA evaluated the residual before it asked for its first Jacobian; it took no step yet
    assert isinstance(st["steps"], int) and st["steps"] >= 0
    assert st["residual_evaluations"] > 0
