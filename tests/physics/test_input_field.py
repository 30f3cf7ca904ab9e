"""The input surface as a field, the contact filter and the summits at the scale of the spots.

Closed forms: the contact filter is the Fourier transform of the along-track Hertz weight
1 - x^2/a^2 (checked against quadrature of that weight); the field's samples are its Fourier
sum evaluated directly; its moments are the bins' power. Invariants: one seed and one spectrum
give one surface whatever the grid or the tail limit; the statistical contact's count and spot
radius converge as the tail is carried to shorter wavelengths (where counting the band's own
summits grows without bound). Convergence: on the default scene, refining the grid, changing
the interpolant and halving the tail limit move no band within 60 dB of the strongest by
more than 0.5 dB.
"""

import math

import numpy as np
import pytest
from scipy import integrate, optimize

import roughvib
from roughvib.analysis.accuracy import REPRESENTATION, SIGNALS, band_deviations
from roughvib.api import simulate
from roughvib.physics.surface import field as fld
from roughvib.physics.surface.contact import contact_stiffness, scene_input
from roughvib.physics.surface.roughness import band_psd, synthetic_field

# --------------------------------------------------------------------------------------------
# the contact filter
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("q", [1e-4, 5e-3, 0.3, 1.0, 2.5, 4.0, 7.0, 15.0, 60.0])
def test_hertz_filter_is_the_transform_of_the_parabolic_weight(q):
    """H(k a) = integral_-a^a (1 - x^2/a^2) cos(k x) dx / (4 a / 3), by quadrature."""
    a = 1.0
    num = integrate.quad(lambda x: (1 - x * x) * math.cos(q * x), -a, a, limit=400,
                         epsabs=1e-14, epsrel=1e-13)[0]
    assert fld.hertz_filter(q) == pytest.approx(num / (4 * a / 3), rel=1e-9, abs=1e-12)


def test_hertz_filter_zero_and_envelope():
    """First zero where tan q = q (q = 4.4934), and |H| <= 3 / q^2 (1 + 1/q) beyond it."""
    q0 = optimize.brentq(lambda q: float(fld.hertz_filter(q)), 4.0, 5.0, xtol=1e-14)
    assert q0 == pytest.approx(4.493409457909064, rel=1e-12)
    q = np.linspace(5.0, 500.0, 20001)
    assert np.all(np.abs(fld.hertz_filter(q)) <= 3 / q**2 * (1 + 1 / q))
    # the series and the closed form meet without a step at q = 1e-2
    assert fld.hertz_filter(0.01 - 1e-12) == pytest.approx(fld.hertz_filter(0.01 + 1e-12),
                                                            rel=1e-10)


def test_smooth_fft_lengths_are_scipys():
    from scipy.fft import next_fast_len

    rng = np.random.default_rng(3)
    for n in [1, 2, 7, 8, 9, 11, 16000, 16001, 1_600_001, *rng.integers(1, 10**8, 300)]:
        assert fld._smooth_length(int(n)) == next_fast_len(int(n), real=True), n


# --------------------------------------------------------------------------------------------
# one surface for a seed
# --------------------------------------------------------------------------------------------

def _paper_spectrum(shortest, seed=1):
    scene = roughvib.load_scene("paper")
    r = scene.roughness
    return fld.synthetic_spectrum(lambda k: band_psd(k, r, shortest=shortest), r.trace_length,
                                  shortest, seed)


def test_samples_are_the_fourier_sum_on_any_grid():
    spec = _paper_spectrum(20e-6)
    rng = np.random.default_rng(0)
    for spacing in (10e-6, 4e-6, 1.1e-6):
        z, dx = spec.sample(spacing)
        assert dx <= spacing and z.size * dx == pytest.approx(spec.period, rel=1e-14)
        i = rng.integers(0, z.size, 25)
        direct, _, _ = spec.evaluate(i * dx)
        np.testing.assert_allclose(z[i], direct, rtol=0, atol=1e-12 * np.max(np.abs(z)))


def test_a_shorter_tail_adds_bins_and_changes_none():
    long, short = _paper_spectrum(50e-6), _paper_spectrum(1e-6)
    j = long.n_bins
    np.testing.assert_array_equal(short.coefficients[: j + 1], long.coefficients)
    assert short.n_bins > 40 * j


def test_moments_are_the_power_of_the_bins():
    spec = _paper_spectrum(20e-6)
    z, dx = spec.sample(2e-6)
    m0, m2, m4 = spec.moments()
    k = 2 * np.pi * np.fft.rfftfreq(z.size, dx)
    p = np.abs(np.fft.rfft(z)) ** 2 * 2 / z.size**2
    assert np.sum(p) == pytest.approx(m0, rel=1e-10)
    assert np.sum(p * k**2) == pytest.approx(m2, rel=1e-10)
    assert np.sum(p * k**4) == pytest.approx(m4, rel=1e-10)


def test_the_input_is_the_filtered_field_scaled_to_the_rms_before_the_filter():
    scene = roughvib.load_scene("paper")
    r = scene.roughness
    plain, st0 = synthetic_field(r, scene.block.length, 1e-6)
    seen, st1 = synthetic_field(r, scene.block.length, 1e-6, spot_radius=4e-6)
    assert math.sqrt(plain.variance()) == pytest.approx(r.rms, rel=1e-12)
    np.testing.assert_allclose(seen.coefficients,
                               plain.coefficients * fld.hertz_filter(plain.wavenumbers * 4e-6),
                               rtol=1e-14)
    assert st1["filtered_rms"] < st0["filtered_rms"] == pytest.approx(r.rms, rel=1e-12)


# --------------------------------------------------------------------------------------------
# summits at the scale of the spots
# --------------------------------------------------------------------------------------------

def test_the_spot_radius_is_the_fixed_point_of_the_mean_micro_contact():
    from roughvib.physics.surface.contact import (
        _surface_source,
        solve_contact,
        spot_radius_of,
        summit_parameters,
    )

    scene = roughvib.load_scene("paper")
    cs = contact_stiffness(scene)
    sp = summit_parameters(*_surface_source(scene).moments(cs.spot_radius))
    sol = solve_contact(cs.load, sp.density, sp.radius, sp.std, cs.nominal_area,
                        cs.effective_modulus)
    assert spot_radius_of(sol) == pytest.approx(cs.spot_radius, rel=1e-8)
    assert cs.micro_contacts == pytest.approx(sol.micro_contacts, rel=1e-8)


def test_count_and_spot_converge_as_the_tail_grows_where_band_summits_do_not():
    """Carried from 5 um to 0.25 um, the tail multiplies the band's own summit count (a 1 nm
    spot filters nothing) by more than three; counted at the scale of the spots the count and
    the spot radius move by less than 1 %, and the stiffness by less than 0.5 %."""
    counts, spots, stiff, band = [], [], [], []
    for lam in (5e-6, 1e-6, 0.25e-6):
        over = {"roughness.shortest_wavelength": lam}
        cs = contact_stiffness(roughvib.load_scene("paper", over))
        counts.append(cs.micro_contacts)
        spots.append(cs.spot_radius)
        stiff.append(cs.s_total)
        raw = contact_stiffness(roughvib.load_scene("paper", {**over,
                                                              "contact.spot_radius": 1e-9}))
        band.append(raw.micro_contacts)
    assert band[-1] > 3 * band[0]
    assert abs(counts[-1] / counts[1] - 1) < 0.01 and abs(spots[-1] / spots[1] - 1) < 0.01
    assert abs(stiff[-1] / stiff[1] - 1) < 0.005


def test_the_contact_module_does_not_follow_the_runs_speed():
    a = contact_stiffness(roughvib.load_scene("paper"))
    b = contact_stiffness(roughvib.load_scene("paper-100mms", {"contact.velocity_factor": False}))
    assert a.micro_contacts == b.micro_contacts and a.spot_radius == b.spot_radius


# --------------------------------------------------------------------------------------------
# the representation converges on the default scene
# --------------------------------------------------------------------------------------------

def _bands_moved(a, b):
    out = {}
    t = a.dataset["time"].values
    win = t >= 1.0 / 7.0
    for name, var in SIGNALS.items():
        d = band_deviations(a.dataset[var].values[win], b.dataset[var].values[win], 1e5,
                            contract=REPRESENTATION)
        out[name] = float(np.nanmax(np.abs(d["deviation_db"][d["checked"]])))
    return out


@pytest.fixture(scope="module")
def default_paper():
    scene = roughvib.load_scene("paper", {"output.progress": False})
    return scene, simulate(scene)


@pytest.mark.parametrize("change", ["half grid", "cubic", "half tail"])
def test_the_default_bands_do_not_move_when_the_representation_is_refined(default_paper,
                                                                          change):
    scene, ref = default_paper
    band = scene_input(scene).band
    over = {"half grid": {"roughness.spacing": band.spacing / 2},
            "cubic": {"roughness.interpolation": "cubic"},
            "half tail": {"roughness.shortest_wavelength": band.shortest_wavelength / 2,
                          "roughness.spacing": band.spacing / 2}}[change]
    other = simulate(roughvib.load_scene("paper", {"output.progress": False, **over}),
                     force_amplitude=ref.summary["force_amplitude"])
    moved = _bands_moved(ref, other)
    assert max(moved.values()) <= REPRESENTATION.band_db, moved


# --------------------------------------------------------------------------------------------
# a measured profile is read between its samples by band-limited interpolation
# --------------------------------------------------------------------------------------------

def _as_profile(z, dx):
    from roughvib.physics.surface.roughness import Profile

    return Profile(z=np.asarray(z, dtype=float), dx=dx, s0=0.0, s_centre=0.0, stats={})


def test_a_measured_field_is_the_file_at_its_samples_and_band_limited_between_them():
    from roughvib.physics.surface.roughness import measured_field

    rng = np.random.default_rng(1)
    z = rng.standard_normal(1001) * 1e-6
    p = measured_field(_as_profile(z, 1e-5), 2e-5, 2.5e-6, 1, tail=False, spot_radius=None)
    assert p.dx == pytest.approx(2.5e-6) and not p.periodic
    np.testing.assert_allclose(p.z[::4], z - z.mean(), atol=1e-18)
    # a sinusoid of 7.3 samples per wavelength, read between the samples inside the record
    s = np.arange(2001) * 1e-5
    lam = 7.3e-5
    wave = np.cos(2 * np.pi * s / lam)
    p = measured_field(_as_profile(wave, 1e-5), 2e-5, 2.5e-6, 1, tail=False, spot_radius=None)
    sf = np.arange(p.z.size) * p.dx
    inner = (sf > 0.003) & (sf < 0.017)  # the field has the samples' mean removed
    exact = np.cos(2 * np.pi * sf[inner] / lam) - wave.mean()
    assert np.max(np.abs(p.z[inner] - exact)) < 1e-5


def test_the_fitted_tail_has_the_files_hurst_exponent():
    """A file cut from a synthetic surface of H = 0.8 at 10 um: the fit of its shortest resolved
    decade gives H within 0.1, and the tail's bins continue that line."""
    from roughvib.physics.surface.roughness import measured_field

    # the surface down to the samples' Nyquist wavelength, sampled at 10 um (no aliasing)
    scene = roughvib.load_scene("paper", {"roughness.shortest_wavelength": 20e-6,
                                          "roughness.spacing": 10e-6,
                                          "contact.filter": "none"})
    prof = scene_input(scene).profile
    p = measured_field(_as_profile(prof.z, prof.dx), 1e-6, 0.25e-6, 3, tail=True,
                       spot_radius=None)
    assert p.stats["tail"] == "fitted"
    assert p.stats["hurst_fit"] == pytest.approx(0.8, abs=0.1)
    assert p.stats["shortest_wavelength"] == pytest.approx(1e-6, rel=1e-3)


@pytest.fixture(scope="module")
def measured_file(tmp_path_factory):
    """The paper's synthetic surface down to 25 um written as a measured file at 10 um: a
    measurement whose samples resolve its band (an instrument's filters stop what its
    samples cannot hold)."""
    scene = roughvib.load_scene("paper", {"roughness.shortest_wavelength": 25e-6,
                                          "roughness.spacing": 10e-6, "contact.filter": "none"})
    prof = scene_input(scene).profile
    path = tmp_path_factory.mktemp("measured") / "trace.txt"
    np.savetxt(path, prof.z * 1e6)
    return path


def test_a_measured_profiles_bands_do_not_move_when_its_grid_is_refined(measured_file):
    """The file's bins, their fitted tail and the contact filter, sampled on the "auto" grid
    and on half of it: no band within 60 dB of the strongest moves by more than 0.5 dB."""
    over = {"roughness.kind": "file", "roughness.path": str(measured_file),
            "roughness.units": "um", "roughness.spacing": 10e-6, "output.progress": False}
    scene = roughvib.load_scene("paper", over)
    band = scene_input(scene).band
    a = simulate(scene)
    assert a.summary["model"]["profile"]["tail"] == "fitted"
    b = simulate(roughvib.load_scene("paper", {**over, "roughness.shortest_wavelength":
                                               band.shortest_wavelength}),
                 force_amplitude=a.summary["force_amplitude"])
    assert b.summary["model"]["profile"]["shortest_wavelength"] == pytest.approx(
        a.summary["model"]["profile"]["shortest_wavelength"], rel=1e-3)
    moved = _bands_moved(a, b)
    assert max(moved.values()) <= REPRESENTATION.band_db, moved


def test_a_span_averaged_surface_too_fine_to_synthesise_is_refused_by_its_tail_key():
    from roughvib.scene import SceneError

    with pytest.raises(SceneError, match=r"^roughness.shortest_wavelength must be >= "
                                         r"1.8\de-05 m with roughness.reduce_3d = true"):
        scene_input(roughvib.load_scene("paper", {"roughness.reduce_3d": True,
                                                  "roughness.shortest_wavelength": 5e-6}))
