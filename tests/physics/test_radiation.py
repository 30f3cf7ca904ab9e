"""Radiated sound of the plate (roughvib.physics.radiation, roughvib.analysis.radiation).

The references are independent of the module's far-field (wavenumber) integral:

* a spatial Rayleigh integral written out here: the power of a baffled plate with real mode
  shapes is W = omega rho0 / (4 pi) sum_rs Re(V_r* V_s) I_rs,
  I_rs = int int phi_r(x) phi_s(x') sin(k R) / R dS dS' (the real part of the Rayleigh
  integral; the kernel is smooth, so a midpoint rule converges like h^2), hence
  sigma_rs = 2 k I_rs / (pi S) for shapes of maximum 1;
* Wallace's low-frequency closed form (J. Acoust. Soc. Am. 51 (1972) 946, Eq. 6);
* the asymptote sigma = (1 - f_c / f)^(-1/2) of a resonant mode above coincidence and the
  coincidence frequency from the longitudinal wave speed;
* the point-driven infinite plate, W = rho0 F_rms^2 / (2 pi c0 m''^2) far below coincidence
  (Cremer, Heckl & Petersson, *Structure-Borne Sound*, 3rd ed. (2005), ch. 7), which the
  modal sum of a large, strongly damped plate approaches (the edge radiation of its
  reverberant field, the remainder, falls as the damping rises);
* the plate acceleration each run stores (a sum over the solver's own modal states), which the
  modal states rebuilt from the contact forces must reproduce.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import roughvib
from roughvib.analysis.radiation import (
    RADIATION_COLUMNS,
    check_radiating_plate,
    modal_response,
    radiation_bands,
)
from roughvib.physics.plate import PlateModes, mode_shapes, plate_modes
from roughvib.physics.radiation import (
    AIR_DENSITY,
    SOUND_SPEED,
    coincidence_frequency,
    infinite_plate_point_force_power,
    modal_pressure,
    modal_radiation_efficiency,
    mutual_radiation_efficiency,
    wallace_low_frequency,
)
from roughvib.scene import Plate, SceneError, load_scene

A, B = 0.30, 0.26  # the paper's plate [m]
MICS = [[0.15, 0.13, 1.0], [0.05, 0.2, 0.25]]  # on axis at 1 m; near an edge at 25 cm [m]


def _rayleigh_sigma(r, s, f, *, a=A, b=B):
    """Mutual radiation efficiency by the spatial Rayleigh integral: midpoint rules on 24 x 24
    and 40 x 40 points, Richardson-extrapolated (their error falls like h^2)."""
    coarse, fine = _rayleigh_midpoint(r, s, f, a, b, 24), _rayleigh_midpoint(r, s, f, a, b, 40)
    return (40**2 * fine - 24**2 * coarse) / (40**2 - 24**2)


def _rayleigh_midpoint(r, s, f, a, b, N):
    k = 2 * math.pi * f / SOUND_SPEED
    x = (np.arange(N) + 0.5) * a / N
    y = (np.arange(N) + 0.5) * b / N
    X, Y = (g.ravel() for g in np.meshgrid(x, y, indexing="ij"))
    p1 = np.sin(r[0] * math.pi * X / a) * np.sin(r[1] * math.pi * Y / b)
    p2 = np.sin(s[0] * math.pi * X / a) * np.sin(s[1] * math.pi * Y / b)
    dS = a * b / N**2
    total = 0.0
    for i in range(0, X.size, 1024):
        R = np.hypot(X[i:i + 1024, None] - X[None, :], Y[i:i + 1024, None] - Y[None, :])
        kern = np.where(R > 0, np.sin(k * R) / np.where(R > 0, R, 1.0), k)
        total += p1[i:i + 1024] @ kern @ p2
    return 2 * k * total * dS * dS / (math.pi * a * b)


def test_coincidence_frequency_of_3mm_steel():
    plate = load_scene("paper").plate
    # independent form: f_c = c0^2 sqrt(12) / (2 pi h c_L), c_L^2 = E / (rho (1 - nu^2))
    c_l = math.sqrt(plate.youngs_modulus / (plate.density * (1 - plate.poisson_ratio**2)))
    expected = SOUND_SPEED**2 * math.sqrt(12) / (2 * math.pi * plate.thickness * c_l)
    assert coincidence_frequency(plate) == pytest.approx(expected, rel=1e-12)
    assert 3900 < expected < 4100  # "about 4 kHz"


# f_c = 3988 Hz: three frequencies below coincidence, three above
@pytest.mark.parametrize(("mode", "freq"), [((1, 1), 150.0), ((2, 1), 1000.0), ((5, 4), 1500.0),
                                            ((3, 2), 4500.0), ((1, 1), 6000.0),
                                            ((4, 3), 9000.0)])
def test_modal_efficiency_matches_spatial_rayleigh_integral(mode, freq):
    sigma = modal_radiation_efficiency([mode[0]], [mode[1]], A, B, [freq])[0, 0]
    # the extrapolated reference is good to about 1e-3 (the hardest case, the (5, 4) mode far
    # below its own acoustic coincidence, where the plate's cells cancel to 1 %)
    assert sigma == pytest.approx(_rayleigh_sigma(mode, mode, freq), rel=3e-3)


@pytest.mark.parametrize("mode", [(1, 1), (3, 1), (1, 3), (3, 3)])
def test_low_frequency_limit_is_wallace_closed_form(mode):
    f = 30.0  # k a = 0.16: the closed form's neglected terms are O((k a)^4)
    sigma = modal_radiation_efficiency([mode[0]], [mode[1]], A, B, [f])[0, 0]
    assert sigma == pytest.approx(wallace_low_frequency(*mode, A, B, f), rel=1e-3)


def test_resonant_modes_above_coincidence_tend_to_one():
    plate = load_scene("paper").plate
    fc = coincidence_frequency(plate)
    modes = plate_modes(plate, 45e3)
    for ratio in (2.0, 4.0, 10.0):
        r = int(np.argmin(np.abs(modes.frequency - ratio * fc)))
        f = modes.frequency[r]
        sigma = modal_radiation_efficiency(modes.n[r:r + 1], modes.m[r:r + 1], A, B, [f])[0, 0]
        # the infinite-plate asymptote (1 - f_c/f)^(-1/2), up to finite-size terms (measured
        # 0.13 % at 2 f_c)
        assert sigma == pytest.approx((1 - fc / f) ** -0.5, rel=0.01)
    assert sigma == pytest.approx(1.0, abs=0.06)  # 10 f_c: the limit 1 (asymptote 1.054)


def test_mutual_efficiency_matches_rayleigh_and_vanishes_between_parities():
    n, m = [1, 3, 2, 1], [1, 1, 1, 3]
    sig = mutual_radiation_efficiency(n, m, A, B, 800.0)
    assert np.allclose(sig, sig.T, rtol=1e-12, atol=0)
    assert np.allclose(np.diag(sig), modal_radiation_efficiency(n, m, A, B, [800.0])[:, 0],
                       rtol=1e-12)
    assert sig[0, 2] == 0.0 and sig[1, 2] == 0.0  # (2,1) is odd about x = a/2
    for i, j in ((0, 1), (0, 3), (1, 3)):  # same-parity pairs couple
        assert sig[i, j] == pytest.approx(_rayleigh_sigma((n[i], m[i]), (n[j], m[j]), 800.0),
                                          rel=5e-3, abs=1e-4 * abs(sig[i, i]))
    assert abs(sig[0, 1]) > 0.1 * sig[1, 1]  # and not negligibly at low frequency


def test_point_force_infinite_plate_closed_form():
    plate = load_scene("paper").plate
    low = infinite_plate_point_force_power(plate, 1.0, 1.0)
    assert low == pytest.approx(AIR_DENSITY / (2 * math.pi * SOUND_SPEED
                                               * plate.mass_per_area**2), rel=1e-6)
    with pytest.raises(ValueError, match="below coincidence"):
        infinite_plate_point_force_power(plate, 1.0, 5000.0)


def _modal_power_point_force(eta: float, f: float) -> float:
    """Band-averaged one-side power of a 2 m x 1.5 m plate, point force of amplitude 1 N,
    from the modal sum with modal radiation efficiencies [W]."""
    L, W = 2.0, 1.5
    pl = Plate(length=L, width=W, loss_factor=eta, max_frequency=6000.0,
               block_position=(1.0, 0.75), observation_position=(0.5, 0.5))
    md = plate_modes(pl)
    phi = mode_shapes(md, [0.37 * L], [0.41 * W])[:, 0]
    fr = f * np.geomspace(2 ** (-1 / 6), 2 ** (1 / 6), 9)
    sig = modal_radiation_efficiency(md.n, md.m, L, W, fr)
    w = 2 * math.pi * fr
    V = 1j * w * phi[:, None] / (md.modal_mass * (md.omega[:, None] ** 2 - w**2
                                                  + 2j * md.damping_ratio[:, None]
                                                  * md.omega[:, None] * w))
    power = AIR_DENSITY * SOUND_SPEED * L * W * np.sum(sig * np.abs(V) ** 2, axis=0) / 8
    return float(np.mean(power)), pl


def test_modal_sum_of_large_damped_plate_tends_to_infinite_plate():
    p_06, plate = _modal_power_point_force(0.6, 1000.0)
    p_03, _ = _modal_power_point_force(0.3, 1000.0)
    ref = float(infinite_plate_point_force_power(plate, 1 / math.sqrt(2), 1000.0))
    d06, d03 = 10 * math.log10(p_06 / ref), 10 * math.log10(p_03 / ref)
    assert abs(d06) < 1.0  # measured +0.44 dB: the edge radiation of the reverberant field
    assert 0 < d06 < d03  # which falls with the damping (measured +0.80 dB at eta = 0.3)


@pytest.mark.parametrize("loss_factor", [0.2, 2.0])  # 2.0: critically damped modes
def test_modal_response_of_a_harmonic_force_is_the_frequency_response(loss_factor):
    plate = Plate(loss_factor=loss_factor, max_frequency=2000.0)
    modes = plate_modes(plate)
    dt, f = 1e-5, 300.0
    t = np.arange(int(0.2 / dt)) * dt
    xy = np.array([[0.11, 0.09]])
    force = np.cos(2 * math.pi * f * t)[:, None]
    _, dq = modal_response(force, xy, dt, modes, q0=np.zeros(len(modes)))
    tail = t >= 0.1  # transients decayed (zeta omega_1 t > 10)
    basis = np.column_stack([np.cos(2 * math.pi * f * t[tail]), np.sin(2 * math.pi * f * t[tail])])
    coef, *_ = np.linalg.lstsq(basis, dq[tail], rcond=None)
    got = coef[0] - 1j * coef[1]  # complex amplitude for exp(+i omega t)
    w = 2 * math.pi * f
    phi = mode_shapes(modes, xy[:, 0], xy[:, 1])[:, 0]
    expected = 1j * w * phi / (modes.modal_mass * (modes.omega**2 - w**2
                                                   + 2j * modes.damping_ratio * modes.omega * w))
    assert np.allclose(got, expected, rtol=1e-4, atol=1e-4 * np.max(np.abs(expected)))


def test_first_order_hold_passes_a_harmonic_force_times_sinc_squared():
    """A force sampled at 1e-5 s and held linearly between samples drives a mode near
    resonance with the amplitude sinc^2(f dt) of the true force (-1.16 dB at 20 kHz): the
    factor the band levels undo. (A mode driven far above its resonance also picks up the
    hold's images above the Nyquist frequency, aliased back by the sampling: 1 % at 20 kHz.)"""
    plate = Plate(loss_factor=0.05, max_frequency=25e3)
    modes = plate_modes(plate)
    dt, f = 1e-5, 20e3
    t = np.arange(3000) * dt
    xy = np.array([[0.11, 0.09]])
    force = np.cos(2 * math.pi * f * t)[:, None]
    w = 2 * math.pi * f
    phi = mode_shapes(modes, xy[:, 0], xy[:, 1])[:, 0]
    expected = 1j * w * phi / (modes.modal_mass * (modes.omega**2 - w**2
                                                   + 2j * modes.damping_ratio * modes.omega * w))
    r = int(np.argmax(np.abs(expected)))  # the mode nearest resonance, within its bandwidth
    assert abs(modes.frequency[r] / f - 1) < modes.damping_ratio[r]
    sub = PlateModes(n=modes.n[r:r + 1], m=modes.m[r:r + 1], omega=modes.omega[r:r + 1],
                     modal_mass=modes.modal_mass, damping_ratio=modes.damping_ratio[r:r + 1],
                     length=modes.length, width=modes.width)
    _, dq = modal_response(force, xy, dt, sub, q0=np.zeros(1))
    tail = t >= 0.01  # 30 decay times of the mode
    basis = np.column_stack([np.cos(w * t[tail]), np.sin(w * t[tail])])
    coef, *_ = np.linalg.lstsq(basis, dq[tail, 0], rcond=None)
    got = coef[0] - 1j * coef[1]
    assert got / expected[r] == pytest.approx(np.sinc(f * dt) ** 2, rel=2e-3)


def test_modal_pressure_is_the_baffled_monopole_far_away():
    f, R = 100.0, 20.0
    k = 2 * math.pi * f / SOUND_SPEED
    G = modal_pressure([1], [1], A, B, [[A / 2, B / 2, R]], [f])[0, 0, 0]
    q = 4 * A * B / math.pi**2  # volume velocity of the (1,1) mode per unit amplitude
    mono = 1j * 2 * math.pi * f * AIR_DENSITY * q * np.exp(-1j * k * R) / (2 * math.pi * R)
    assert G == pytest.approx(mono, rel=5e-3)  # measured 0.27 % (patches, R / a = 67)


@pytest.mark.parametrize(("mode", "freq"), [((1, 1), 500.0), ((3, 2), 2000.0)])
def test_pressure_over_a_hemisphere_carries_the_modal_power(mode, freq):
    R = 6.0
    th, wt = np.polynomial.legendre.leggauss(24)
    th, wt = (th + 1) * math.pi / 4, wt * math.pi / 4
    ph = np.arange(48) * 2 * math.pi / 48
    TH, PH = (g.ravel() for g in np.meshgrid(th, ph, indexing="ij"))
    pts = np.column_stack([A / 2 + R * np.sin(TH) * np.cos(PH),
                           B / 2 + R * np.sin(TH) * np.sin(PH), R * np.cos(TH)])
    G = modal_pressure([mode[0]], [mode[1]], A, B, pts, [freq])[:, 0, 0]
    intensity = np.abs(G) ** 2 / (2 * AIR_DENSITY * SOUND_SPEED)  # far field, amplitude 1
    W = np.sum(intensity * R**2 * np.sin(TH) * np.repeat(wt, 48)) * 2 * math.pi / 48
    sigma = W / (AIR_DENSITY * SOUND_SPEED * A * B / 8)
    # measured 0.4 % (1,1) and 0.2 % (3,2): patches and the finite radius
    assert sigma == pytest.approx(
        modal_radiation_efficiency([mode[0]], [mode[1]], A, B, [freq])[0, 0], rel=1e-2)


def test_refusals_are_one_line():
    with pytest.raises(SceneError, match=r"^output.radiation needs .*plate.kind = 'rigid'$"):
        load_scene("paper", **{"output.radiation": True, "plate.kind": "rigid"})
    with pytest.raises(SceneError, match=r"^output.microphones needs output.radiation = true"):
        load_scene("paper", **{"output.microphones": MICS})
    with pytest.raises(SceneError, match=r"output.microphones\[0\]\[2\] must be > 0 m"):
        load_scene("paper", **{"output.radiation": True, "output.microphones": [[0, 0, 0]]})
    with pytest.raises(SceneError, match=r"output.radiating_sides must be an integer in \[1, 2\]"):
        load_scene("paper", **{"output.radiating_sides": 3})

    class Imported:
        kind = "imported"

    with pytest.raises(ValueError) as err:
        check_radiating_plate(Imported())
    assert "\n" not in str(err.value) and "imported" in str(err.value)
    check_radiating_plate(object())  # no kind: the built-in simply supported plate


@pytest.fixture(scope="module")
def radiating_run(tmp_path_factory):
    """A 0.03 s paper run with plate modes to 5 kHz and output.radiation, saved and loaded."""
    scene = load_scene("paper", **{"output.duration": 0.03, "output.transient": 0.0,
                                   "plate.max_frequency": 5000.0, "output.radiation": True,
                                   "output.microphones": MICS, "output.progress": False,
                                   "solver.atol_acceleration": 1e-5})
    with pytest.warns(roughvib.scene.ModelValidityWarning):  # a window shorter than a period
        result = roughvib.simulate(scene)
    assert result.ok, result.summary.get("message")
    out = tmp_path_factory.mktemp("radiation") / "run"
    result.save(out)
    return scene, result, roughvib.load_result(out), out


def test_modal_states_from_contact_forces_reproduce_the_solver(radiating_run):
    scene, result, _, _ = radiating_run
    ds = result.dataset
    F = ds["contact_force"].values
    xy = np.column_stack([ds["contact_x"].values, ds["contact_y"].values])
    modes = plate_modes(scene.plate)
    q, dq = modal_response(F, xy, scene.output.step, modes)
    phi = mode_shapes(modes, xy[:, 0], xy[:, 1])
    obs = mode_shapes(modes, *([c] for c in scene.plate.observation_position))[:, 0]
    acc = ((F @ phi.T) / modes.modal_mass - 2 * modes.damping_ratio * modes.omega * dq
           - modes.omega**2 * q) @ obs
    ref = ds["plate_vertical_acceleration"].values
    # measured on the full paper scene: error 40 dB below the signal in every band
    assert np.sqrt(np.mean((acc - ref) ** 2)) < 1e-2 * np.sqrt(np.mean(ref**2))


def test_radiation_table_velocity_is_the_space_average(radiating_run, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    scene, result, loaded, out = radiating_run
    table = loaded.extra["radiation"]
    assert tuple(table.columns) == RADIATION_COLUMNS
    assert (out / "radiation.csv").is_file()
    assert np.isfinite(table["sound_power_db"]).sum() >= 10
    # independent space average: velocity on a 12 x 12 grid of points, band powers of each
    # point's record (same Hann taper), averaged over the points
    ds = result.dataset
    F = ds["contact_force"].values
    xy = np.column_stack([ds["contact_x"].values, ds["contact_y"].values])
    modes = plate_modes(scene.plate)
    _, dq = modal_response(F, xy, scene.output.step, modes)
    g = (np.arange(12) + 0.5) / 12
    X, Y = (v.ravel() for v in np.meshgrid(g * scene.plate.length, g * scene.plate.width))
    v = dq @ mode_shapes(modes, X, Y)  # (T, 144)
    from roughvib.analysis.spectra import third_octave_bands

    fc, lo, hi = third_octave_bands(50.0, 20e3)
    ok = np.isfinite(table["mean_square_velocity_db"].to_numpy())
    # the table undoes the first-order hold's sinc^4 power gain (see the next test): divide
    # each FFT bin's power by it (periodic Hann taper, unit mean square), then sum the bands
    n, dt = v.shape[0], scene.output.step
    win = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)
    win /= np.sqrt(np.mean(win**2))
    spec = np.abs(np.fft.rfft((v - v.mean(axis=0)) * win[:, None], axis=0)) ** 2 / n**2
    spec[1:] *= 2.0
    if n % 2 == 0:
        spec[-1] /= 2.0
    f = np.fft.rfftfreq(n, dt)
    spec = spec.mean(axis=1) / np.sinc(f * dt) ** 4
    p = np.array([spec[(f >= a) & (f < b)].sum() for a, b in zip(lo, hi, strict=True)])
    level = 10 * np.log10(p[ok] / 1e-18)
    assert np.allclose(table["mean_square_velocity_db"].to_numpy()[ok], level, atol=0.05)
    # two radiating sides: twice the power, the same efficiency
    win = slice(0, ds.sizes["time"])
    one = radiation_bands(F, xy, scene.output.step, scene.plate, win)
    two = radiation_bands(F, xy, scene.output.step, scene.plate, win, sides=2)
    assert np.allclose(two.sound_power[ok], 2 * one.sound_power[ok], rtol=1e-12)
    assert np.allclose(two.radiation_efficiency[ok], one.radiation_efficiency[ok], rtol=1e-12)
    assert np.allclose(one.levels()["sound_power_db"][ok], table["sound_power_db"][ok],
                       atol=1e-4)  # the run's initial state is the static one


def test_microphone_levels_are_the_coherent_rayleigh_sum(radiating_run):
    """microphones.csv against the pressure summed bin by bin from transfer functions
    computed at every FFT bin (no interpolation), the same modal spectra."""
    from roughvib.analysis.spectra import third_octave_bands

    scene, result, loaded, out = radiating_run
    table = loaded.extra["microphones"]
    assert list(table.columns) == ["band_hz", "mic1_spl_db", "mic2_spl_db"]
    assert (out / "microphones.csv").is_file()
    ds = result.dataset
    F = ds["contact_force"].values
    xy = np.column_stack([ds["contact_x"].values, ds["contact_y"].values])
    dt = scene.output.step
    modes = plate_modes(scene.plate)  # all 35 modes lie below 4 x 5.6 kHz
    _, dq = modal_response(F, xy, dt, modes)
    n = dq.shape[0]
    taper = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)
    taper /= np.sqrt(np.mean(taper**2))
    X = np.fft.rfft((dq - dq.mean(axis=0)).T * taper, axis=1) / n
    f = np.fft.rfftfreq(n, dt)
    fc, lo, hi = third_octave_bands(50.0, 5000.0)
    ok = np.isfinite(table["mic1_spl_db"].to_numpy())
    for i, mic in enumerate(MICS):
        for b in np.flatnonzero(ok):
            sel = np.flatnonzero((f >= lo[b]) & (f < hi[b]))
            G = modal_pressure(modes.n, modes.m, A, B, [mic], f[sel])[0]  # (R, bins)
            P = np.sum(G * X[:, sel], axis=0) / np.sinc(f[sel] * dt) ** 2
            level = 10 * np.log10(np.sum(2 * np.abs(P) ** 2) / 4e-10)
            assert table[f"mic{i + 1}_spl_db"][b] == pytest.approx(level, abs=0.1)


def test_run_report_shows_the_radiation_figure(radiating_run, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    from roughvib.views import figures
    from roughvib.views.report import write_report

    _, _, loaded, out = radiating_run
    axes = figures.plot_radiation(loaded)
    for ax in axes:
        assert ax.has_data() and "[" in ax.get_xlabel() and "[" in ax.get_ylabel()
    monkeypatch.setattr(figures, "FIGURES", {})  # the other figures have their own tests
    html = write_report(out, out=tmp_path / "report.html").read_text()
    assert 'id="fig-radiation"' in html and "could not be drawn" not in html


# --------------------------------------------------------------------------------------------
# the roughness x velocity sweep of the radiated sound
# --------------------------------------------------------------------------------------------

def test_joint_fit_recovers_known_exponents():
    from roughvib.studies.sweep.tables import _joint_fit

    rng = np.random.default_rng(3)
    ra, v = (g.ravel() for g in np.meshgrid([0.2e-6, 0.35e-6, 0.7e-6], [0.01, 0.02, 0.04]))
    ra, v = np.tile(ra, 4), np.tile(v, 4)
    exact = 20 * np.log10(ra**0.8 * v**1.6) + 200.0
    f = _joint_fit(ra, v, exact)
    assert (f["a"], f["b"], f["c"]) == pytest.approx((0.8, 1.6, 200.0), rel=1e-9)
    assert f["b_db_per_doubling"] == pytest.approx(1.6 * 20 * math.log10(2), rel=1e-9)
    noisy = _joint_fit(ra, v, exact + rng.normal(0.0, 1.0, ra.size))
    assert noisy["a_low"] < 0.8 < noisy["a_high"] and noisy["b_low"] < 1.6 < noisy["b_high"]
    assert 0.5 < noisy["rms_residual"] < 1.5


def test_sweep_report_joint_fit_includes_radiated_power(tmp_path):
    import pandas as pd

    from roughvib.studies.sweep.report import _joint_blocks

    ra, v = (g.ravel() for g in np.meshgrid([0.2e-6, 0.4e-6], [0.01, 0.02, 0.04]))
    df = pd.DataFrame({"roughness.rms": ra, "excitation.target_rms_velocity": v,
                       "block_tangential_velocity_rms": v * 1.01,
                       "block_vertical_acceleration_level_db_re_1e-6": 20 * np.log10(v) + 150,
                       "plate_vertical_acceleration_level_db_re_1e-6": 20 * np.log10(ra) + 200,
                       "sound_power_level_db_re_1pW": 40 * np.log10(v * 1.01) + 90})
    blocks = _joint_blocks(df, ["roughness.rms", "excitation.target_rms_velocity"], tmp_path)
    fits = pd.read_csv(tmp_path / "joint_fit.csv").set_index("quantity")
    assert fits.loc["radiated power level", "b"] == pytest.approx(2.0, rel=1e-9)
    assert fits.loc["plate level", "a"] == pytest.approx(1.0, rel=1e-9)
    assert any(kind == "table" for kind, _ in blocks)
    # without radiation the column is NaN: no radiated-power row
    df["sound_power_level_db_re_1pW"] = np.nan
    _joint_blocks(df, ["roughness.rms", "excitation.target_rms_velocity"], tmp_path)
    assert "radiated power level" not in set(pd.read_csv(tmp_path / "joint_fit.csv").quantity)
    # only one of the two varies: no joint fit
    assert _joint_blocks(df, ["excitation.target_rms_velocity"], tmp_path) == []


def test_builtin_roughness_noise_sweep_runs_radiation():
    from roughvib.studies import sweep as sw

    assert "roughness-noise" in sw.builtin_sweeps()
    spec = sw.load_sweep("roughness-noise")
    assert spec.to_json()["seed_keys"] == ["roughness.seed"]
    assert spec.grid["roughness.rms"] == [0.175e-6, 0.35e-6, 0.7e-6]
    assert spec.fixed["output.radiation"] is True


def test_too_short_a_window_leaves_the_run_and_says_why(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    scene = load_scene("paper", **{"output.duration": 5e-5, "output.transient": 0.0,
                                   "plate.max_frequency": 3000.0, "output.radiation": True,
                                   "output.progress": False})
    with pytest.warns(roughvib.scene.ModelValidityWarning):
        result = roughvib.simulate(scene)
    assert result.ok and "radiation" not in result.extra
    assert "analysis window of >= 8 samples" in result.summary["radiation"]["error"]
    result.save(tmp_path / "run")
    assert not (tmp_path / "run" / "radiation.csv").exists()
