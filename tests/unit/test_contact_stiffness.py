"""Statistical contact stiffness: GW / GT, summit statistics, worked numbers.

References: quadrature of the defining integrals, the closed-form exponential-summit result
k = P / sigma_s, a finite-difference dP/d(approach), a table of worked numbers
(computed independently by hand before the code), and direct peak counting on synthetic
profiles against the exact Gaussian-process formulas (Rice, Cartwright-Longuet-Higgins).
"""

import math

import numpy as np
import pytest
from scipy import integrate

from roughvib.physics.surface.contact import (
    contact_stiffness,
    effective_modulus,
    gw_integral,
    solve_contact,
    summit_parameters,
    velocity_factor,
)
from roughvib.physics.surface.roughness import spectral_moments, synthesize_profile
from roughvib.scene import Roughness, SceneError, load_scene

STEEL_E_STAR = 2.1e11 / (2 * (1 - 0.3**2))
AREA = 1.6e-3


def _quad_f(n, h, pdf, lower=-np.inf):
    a = max(h, lower)
    return integrate.quad(lambda s: (s - h) ** n * pdf(s), a, np.inf, epsabs=0,
                          epsrel=1e-11, limit=200)[0]


def _gauss(s):
    return math.exp(-s * s / 2) / math.sqrt(2 * math.pi)


def _expo(s):
    return math.exp(-(s + 1.0)) if s >= -1.0 else 0.0


@pytest.mark.parametrize("n", [0.0, 0.5, 1.0, 1.5, 2.0, 2.5])
def test_gw_integrals_against_quadrature(n):
    for h in (-1.5, 0.0, 1.0, 2.5, 4.0, 6.0):
        assert gw_integral(n, h) == pytest.approx(_quad_f(n, h, _gauss), rel=1e-8)
        assert gw_integral(n, h, "exponential") == pytest.approx(
            _quad_f(n, h, _expo, lower=-1.0), rel=1e-8)


def test_exponential_summits_give_k_equal_p_over_sigma_exactly():
    sigma = 3.3e-6
    for load in (0.1, 2.168, 5.327, 40.0):
        for model in ("gw", "gt"):
            sol = solve_contact(load, 1.2e8, 150e-6, sigma, AREA, STEEL_E_STAR, model=model,
                                distribution="exponential")
            # F_n = Gamma(n+1) e^-(h+1): GW 1.5 G(3/2)/G(5/2) = 1, GT 2.5 G(5/2)/G(7/2) = 1
            assert sol.stiffness * sigma / load == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("model", ["gw", "gt"])
def test_stiffness_is_the_tangent_of_the_load_curve(model):
    """k = dP/d(approach) by a central difference in load: delta d = sigma_s (h1 - h2)."""
    args = (1.23e8, 149e-6, 3.34e-6, AREA, STEEL_E_STAR)
    p0, dp = 2.168, 1e-4
    a = solve_contact(p0 - dp, *args, model=model)
    b = solve_contact(p0 + dp, *args, model=model)
    mid = solve_contact(p0, *args, model=model)
    k_fd = 2 * dp / (3.34e-6 * (a.h - b.h))
    assert mid.stiffness == pytest.approx(k_fd, rel=1e-6)


# worked numbers: (sigma, rolloff, mass) -> printed values; each checked to half a unit in its
# last printed digit. The 1.4 um row needs the 0.25 mm roll-off (grit-80-like): with 0.5 mm it
# gives R = 372 um and eta = 1.23e8, not the printed 213 um and 1.5e8.
TABLE = [
    (3.5e-6, 0.5e-3, 0.221, {"summit_radius": (149e-6, 0.5e-6), "summit_density": (1.2e8, 0.05e8),
                             "summit_std": (3.34e-6, 0.005e-6), "separation": (4.33, 0.005),
                             "micro_contacts": (1.5, 0.05), "s_total": (3.1e6, 0.05e6),
                             "stiffness_ratio": (4.8, 0.05), "resonance_hz": (599, 0.5)}),
    (3.5e-6, 0.5e-3, 0.543, {"separation": (4.14, 0.005), "micro_contacts": (3.5, 0.05),
                             "s_total": (7.4e6, 0.05e6), "stiffness_ratio": (4.7, 0.05),
                             "resonance_hz": (589, 0.5)}),
    (7e-6, 0.5e-3, 0.221, {"summit_radius": (74e-6, 0.5e-6), "summit_std": (6.7e-6, 0.05e-6),
                           "separation": (4.47, 0.005), "micro_contacts": (0.8, 0.05),
                           "s_total": (1.6e6, 0.05e6), "stiffness_ratio": (5.0, 0.05),
                           "resonance_hz": (430, 0.5)}),
    (7e-6, 0.5e-3, 0.543, {"separation": (4.28, 0.005), "micro_contacts": (1.8, 0.05),
                           "s_total": (3.8e6, 0.05e6), "stiffness_ratio": (4.8, 0.05),
                           "resonance_hz": (422, 0.5)}),
    (1.4e-6, 0.25e-3, 0.221, {"summit_radius": (213e-6, 0.5e-6),
                              "summit_density": (1.5e8, 0.05e8),
                              "summit_std": (1.26e-6, 0.005e-6), "separation": (4.09, 0.005),
                              "micro_contacts": (5.0, 0.05), "s_total": (8.0e6, 0.05e6),
                              "stiffness_ratio": (4.6, 0.05), "resonance_hz": (955, 0.5)}),
    (1.4e-6, 0.25e-3, 0.543, {"separation": (3.89, 0.005), "micro_contacts": (11.6, 0.05),
                              "s_total": (1.9e7, 0.05e7), "stiffness_ratio": (4.4, 0.05),
                              "resonance_hz": (937, 0.5)}),
]


#: the paper's band and grid as numbers
PAPER_BAND = {"shortest_wavelength": 50e-6, "spacing": 10e-6}
#: the summits of the paper's band, as the worked numbers count them: the band stops at 50 um
#: and a spot of 1 nm filters nothing in it (H = 1 - 3e-9 at 50 um)
BAND_SCALE = {"roughness.shortest_wavelength": 50e-6, "contact.spot_radius": 1e-9}


@pytest.mark.parametrize("sigma,rolloff,mass,expect", TABLE)
def test_physics_worked_numbers(sigma, rolloff, mass, expect):
    scene = load_scene("paper", {"roughness.raw_rms": sigma,
                                 "roughness.rolloff_wavelength": rolloff, "block.mass": mass,
                                 "contact.stiffness": "auto", **BAND_SCALE})
    cs = contact_stiffness(scene)
    for key, (value, tol) in expect.items():
        assert abs(getattr(cs, key) - value) <= tol * (1 + 1e-9), (key, getattr(cs, key))
    assert cs.load == pytest.approx(mass * 9.81)
    assert cs.effective_modulus == pytest.approx(115.4e9, rel=1e-3)
    m0, m2, m4 = spectral_moments(scene.roughness)
    if sigma == 3.5e-6 and rolloff == 0.5e-3:
        assert math.sqrt(m2) == pytest.approx(0.07, abs=0.005)  # "rms slope 0.07"


@pytest.mark.parametrize("mass", [0.221, 0.543])
def test_gw_and_gt_agree_for_the_default_surface(mass):
    base = {"block.mass": mass, "contact.stiffness": "auto", **BAND_SCALE}
    gw = contact_stiffness(load_scene("paper", base))
    gt = contact_stiffness(load_scene("paper", {**base, "contact.model": "gt"}))
    assert gt.model == "gt" and gw.model == "gw"
    assert abs(gt.s_total / gw.s_total - 1) < 0.05
    assert abs(gt.micro_contacts / gw.micro_contacts - 1) < 0.05


def _quad_moments(r, sigma, areal, spot=0.0):
    """Moments of the model spectrum by scipy's quadrature, normalised to ``sigma`` over the
    band, weighted by the Hertz filter 3 (sin q - q cos q) / q^3 of spots of radius ``spot``
    (written out here, q = k spot) for m2 and m4 (m0 unfiltered: the normalisation)."""
    kl, k0, kh = (2 * np.pi / r.longest_wavelength, 2 * np.pi / r.rolloff_wavelength,
                  2 * np.pi / r.shortest_wavelength)
    q = (2 if areal else 1) + 2 * r.hurst

    def shape(k):
        return 1.0 if k < k0 else (k / k0) ** (-q)

    def filt(k):
        x = k * spot
        return 1.0 if x < 1e-3 else (3 * (math.sin(x) - x * math.cos(x)) / x**3) ** 2

    def mom(n, weigh=True):
        f = (lambda k: k**n * shape(k) * filt(k)) if weigh else (lambda k: k**n * shape(k))
        return integrate.quad(f, kl, kh, points=[k0], limit=2000, epsrel=1e-12)[0]

    if not areal:
        i0 = mom(0, weigh=False)
        return sigma**2 * mom(0) / i0, sigma**2 * mom(2) / i0, sigma**2 * mom(4) / i0
    # m_n = integral over the plane of kx^n S2 = integral_0^2pi cos^n dtheta int k^(n+1) S2 dk
    ang = {n: integrate.quad(lambda t, n=n: math.cos(t) ** n, 0, 2 * math.pi)[0]
           for n in (0, 2, 4)}
    i0 = ang[0] * mom(1, weigh=False)
    return (sigma**2 * ang[0] * mom(1) / i0, sigma**2 * ang[2] * mom(3) / i0,
            sigma**2 * ang[4] * mom(5) / i0)


@pytest.mark.parametrize("areal", [False, True])
def test_spectral_moments_against_quadrature(areal):
    r = Roughness(hurst=0.7, rolloff_wavelength=0.3e-3, **PAPER_BAND)
    got = spectral_moments(r, 2e-6, areal=areal)
    np.testing.assert_allclose(got, _quad_moments(r, 2e-6, areal), rtol=1e-9)
    scene = load_scene("paper", {"roughness.reduce_3d": areal, "contact.stiffness": "auto",
                                 "roughness.shortest_wavelength": 50e-6})
    cs = contact_stiffness(scene)
    sp = summit_parameters(*_quad_moments(scene.roughness, 3.5e-6, areal, spot=cs.spot_radius))
    assert cs.summit_density == pytest.approx(sp.density, rel=1e-9)
    assert cs.summit_radius == pytest.approx(sp.radius, rel=1e-9)


def _count_peaks(z, dx, up=8):
    """Maxima of the band-limited periodic profile: zero crossings (+ to -) of the spectral
    slope on an 8x FFT-upsampled grid; heights and curvatures interpolated to the crossing."""
    n = z.size
    k = 2 * np.pi * np.fft.rfftfreq(n, dx)
    zf = np.fft.rfft(z)
    big = up * n

    def back(x):
        y = np.zeros(big // 2 + 1, dtype=complex)
        y[:x.size] = x
        return np.fft.irfft(y * up, big)

    zu, z1, z2 = back(zf), back(1j * k * zf), back(-(k**2) * zf)
    j = np.flatnonzero((z1 > 0) & (np.roll(z1, -1) <= 0))
    j1 = (j + 1) % big
    t = z1[j] / (z1[j] - z1[j1])
    return j.size / (n * dx), zu[j] + t * (zu[j1] - zu[j]), -(z2[j] + t * (z2[j1] - z2[j]))


def test_mccool_summits_agree_with_peak_counting_on_synthetic_profiles():
    """What is comparable between a profile and McCool's areal summits (isotropic Gaussian):

    * profile peaks per metre D_p = sqrt(m4/m2) / (2 pi) (Rice), and areal summit density
      eta_s = m4 / (6 pi sqrt(3) m2) = (2 pi / (3 sqrt(3))) D_p^2 = 1.2092 D_p^2 (Nayak);
    * the curvature at profile maxima is Rayleigh with scale sqrt(m4): mean sqrt(pi m4 / 2);
      McCool's summit curvature (8/3) sqrt(m4 / pi) is 1.2004 times that;
    * peak heights: the profile variance m0 (1 - (pi/2 - 1)/alpha) (Cartwright-Longuet-
      Higgins) and McCool's areal sigma_s^2 = m0 (1 - 0.8968/alpha) are different definitions:
      1.8 % apart in std at alpha = 9.9, inside the 5 % stated for sigma_s.

    Counting on 8 synthetic 0.16 m profiles (about 1600 peaks each): profile quantities
    within 3 % of the exact formulas, McCool's eta_s, R, sigma_s within 5 % of the counted
    equivalents.
    """
    sigma = 3.5e-6
    m0, m2, m4 = _quad_moments(Roughness(**PAPER_BAND), sigma, areal=False)
    alpha = m0 * m4 / m2**2
    dens, curv, hstd = [], [], []
    for seed in range(8):
        r = Roughness(filter="none", seed=seed, **PAPER_BAND)
        z = synthesize_profile(r, rms=sigma)
        d, h, c = _count_peaks(z, r.spacing)
        dens.append(d)
        curv.append(c.mean())
        hstd.append(h.std())
    d, c, hs = np.mean(dens), np.mean(curv), np.mean(hstd)
    assert d == pytest.approx(math.sqrt(m4 / m2) / (2 * math.pi), rel=0.03)
    assert c == pytest.approx(math.sqrt(math.pi * m4 / 2), rel=0.03)
    assert hs == pytest.approx(math.sqrt(m0 * (1 - (math.pi / 2 - 1) / alpha)), rel=0.03)
    sp = summit_parameters(m0, m2, m4)
    assert sp.density == pytest.approx(2 * math.pi / (3 * math.sqrt(3)) * d**2, rel=0.05)
    assert sp.radius == pytest.approx(1 / ((8 / 3) * math.sqrt(2) / math.pi * c), rel=0.05)
    assert sp.std == pytest.approx(hs, rel=0.05)


def test_summit_keys_velocity_factor_and_errors():
    over = {"contact.stiffness": "auto", "contact.summit_density": 2e8,
            "contact.summit_radius": 100e-6, "contact.summit_std": 2e-6}
    cs = contact_stiffness(load_scene("paper", over))
    assert cs.summit_source == "keys" and math.isnan(cs.surface_rms)
    assert (cs.summit_density, cs.summit_radius, cs.summit_std) == (2e8, 100e-6, 2e-6)
    ref = solve_contact(0.221 * 9.81, 2e8, 100e-6, 2e-6, AREA, STEEL_E_STAR)
    assert cs.s_total == pytest.approx(ref.stiffness, rel=1e-12)
    assert cs.resonance_hz == pytest.approx(math.sqrt(cs.s_total / 0.221) / (2 * math.pi))
    assert cs.mean_pressure == pytest.approx(cs.load / cs.real_area)
    assert cs.plasticity_index == pytest.approx(STEEL_E_STAR / 3e9 * math.sqrt(2e-6 / 100e-6))
    part = contact_stiffness(load_scene("paper", {"contact.summit_radius": 300e-6}))
    assert part.summit_source == "moments+keys" and part.summit_radius == 300e-6

    assert velocity_factor(0.01) == pytest.approx(1.0)
    assert velocity_factor(0.1) == pytest.approx(0.33, rel=1e-12)
    base = contact_stiffness(load_scene("paper-100mms", {"contact.velocity_factor": False}))
    vf = contact_stiffness(load_scene("paper-100mms"))  # the built-in scene applies the factor
    assert vf.velocity_factor == pytest.approx(0.33)
    assert vf.s_total == pytest.approx(0.33 * base.s_total, rel=1e-12)
    # no stated rms velocity: the factor is 1 (the static stiffness), and the result says why
    plain = contact_stiffness(load_scene("paper", {"contact.velocity_factor": False}))
    forced = contact_stiffness(load_scene("paper", {"contact.velocity_factor": True,
                                                    "excitation.force_amplitude": 1.0,
                                                    "excitation.target_rms_velocity": "none"}))
    assert forced.velocity_factor == 1.0 and forced.s_total == plain.s_total
    assert forced.velocity_factor_note.startswith("contact.velocity_factor not applied: no "
                                                  "excitation.target_rms_velocity")
    assert vf.velocity_factor_note == "" and plain.velocity_factor_note == ""
    with pytest.raises(SceneError, match=r"roughness.raw_rms must be > 0 m"):
        contact_stiffness(load_scene("paper", {"roughness.raw_rms": 0.0}))
    assert effective_modulus(2.1e11, 0.3) == pytest.approx(STEEL_E_STAR)


@pytest.mark.parametrize("over", [
    {"excitation.kind": "prescribed", "excitation.velocity": 0.0, "excitation.amplitude": 0.0},
    {"excitation.force_amplitude": 0.0, "excitation.target_rms_velocity": "none"},
])
def test_a_block_that_does_not_slide_keeps_the_static_stiffness(over):
    """The default contact.velocity_factor = true never refuses a block at rest: the factor,
    a fit of the sliding contact that diverges as v_rms -> 0, is 1 there (no elevation)."""
    scene = load_scene("paper", over)
    assert scene.contact.velocity_factor is True  # the default, not set by the test
    at_rest = contact_stiffness(scene)
    static = contact_stiffness(load_scene("paper", {**over, "contact.velocity_factor": False}))
    assert at_rest.velocity_factor == 1.0 and at_rest.s_total == static.s_total
    assert "the block does not slide" in at_rest.velocity_factor_note
