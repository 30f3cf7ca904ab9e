"""The contact count of the contact module (``contact.points = "auto"``).

References: the closed form of the count for exponential summits, monotonicity in load and rms
roughness at fixed spectral shape, and a direct count of summits above the separation on a
synthetic isotropic Gaussian surface whose spectral moments are known exactly.
"""

import math

import numpy as np
import pytest

import roughvib
from roughvib.physics.surface.contact import (
    contact_count,
    contact_layout,
    contact_stiffness,
    gw_integral,
    scene_input,
    solve_contact,
    summit_parameters,
)
from roughvib.physics.surface.roughness import select_contacts

E_STAR = 2.1e11 / (2 * (1 - 0.3**2))


def test_count_rule():
    assert [contact_count(n) for n in (0.0, 0.2, 0.78, 1.49, 1.51, 3.46, 27.3)] == \
        [1, 1, 1, 1, 2, 3, 27]
    with pytest.raises(ValueError):
        contact_count(float("nan"))


def test_exponential_summits_give_the_closed_form_count():
    """F_n = Gamma(n+1) exp(-(h+1)): P = (4/3) eta A E* R^1/2 s^3/2 Gamma(5/2) e^-(h+1) and
    n_c = eta A e^-(h+1), so n_c = P / (E* sqrt(pi R) s^3/2), proportional to the load and
    independent of the summit density."""
    R, s, area = 150e-6, 3.3e-6, 1.6e-3
    for load in (0.5, 2.168, 5.327):
        for eta in (5e7, 2e8):
            sol = solve_contact(load, eta, R, s, area, E_STAR, distribution="exponential")
            assert sol.micro_contacts == pytest.approx(
                load / (E_STAR * math.sqrt(math.pi * R) * s**1.5), rel=1e-10)


def test_count_rises_with_load_and_falls_with_rms_roughness_at_fixed_spectral_shape():
    def stat(**over):
        return contact_stiffness(roughvib.load_scene("paper", over))

    masses = [0.1, 0.221, 0.543, 1.0, 2.0]
    n_load = [stat(**{"block.mass": m}).micro_contacts for m in masses]
    assert all(b > a for a, b in zip(n_load, n_load[1:], strict=False))
    pts = [stat(**{"block.mass": m}).points for m in masses]
    assert pts == sorted(pts) and pts[-1] > pts[0]
    # same band, roll-off and Hurst exponent: only the rms changes (m0, m2, m4 all scale with
    # rms^2, so the summit density stays, R ~ 1/rms, sigma_s ~ rms)
    rms = [1.4e-6, 3.5e-6, 7e-6, 14e-6]
    cs = [stat(**{"roughness.raw_rms": r, "block.mass": 0.543}) for r in rms]
    n_rough = [c.micro_contacts for c in cs]
    assert all(b < a for a, b in zip(n_rough, n_rough[1:], strict=False))
    assert [c.points for c in cs] == sorted((c.points for c in cs), reverse=True)
    assert cs[0].points > cs[-1].points
    # counted on the band itself (a 1 nm spot filters nothing), the summit density is the
    # band's alone; at the scale of the spots it follows the spot radius, which the rms moves
    band = {"roughness.shortest_wavelength": 50e-6, "contact.spot_radius": 1e-9}
    cb = [stat(**{"roughness.raw_rms": r, "block.mass": 0.543, **band}) for r in rms]
    assert all(c.summit_density == pytest.approx(cb[0].summit_density, rel=1e-12) for c in cb)


def _surface(n, dx, seed, lam_min=50e-6, lam0=0.5e-3, hurst=0.8):
    """Periodic isotropic Gaussian surface by 2-D FFT (independent of roughvib's synthesis),
    and its exact profile moments m0, m2, m4 along x from its own discrete spectrum."""
    rng = np.random.default_rng(seed)
    k1 = 2 * np.pi * np.fft.fftfreq(n, dx)
    kx, ky = np.meshgrid(k1, k1, indexing="ij")
    k = np.hypot(kx, ky)
    kl, k0, kh = 2 * np.pi / (n * dx / 2), 2 * np.pi / lam0, 2 * np.pi / lam_min
    shape = np.zeros_like(k)
    band = (k >= kl) & (k <= kh)
    shape[band] = np.where(k[band] < k0, 1.0, (k[band] / k0) ** (-(2 + 2 * hurst)))
    spec = np.sqrt(shape) * (rng.standard_normal(k.shape) + 1j * rng.standard_normal(k.shape))
    z = np.fft.ifft2(spec).real
    p = np.abs(np.fft.fft2(z)) ** 2 / n**4  # sum p = mean z^2 (Parseval)
    return z, float(p.sum()), float((p * kx**2).sum()), float((p * kx**4).sum())


def _summit_heights(z):
    """Heights of the grid points above all eight neighbours (periodic)."""
    top = np.ones(z.shape, dtype=bool)
    for a in (-1, 0, 1):
        for b in (-1, 0, 1):
            if a or b:
                top &= z > np.roll(np.roll(z, a, 0), b, 1)
    return z[top]


def test_count_agrees_with_a_direct_count_of_summits_above_the_separation():
    """GW count n_c = eta A F0(h) at the separation that carries the load, against the summits
    of a synthetic surface above that separation (mean summit plane + h sigma_s).

    Scatter: summits above a high level are nearly independent, so the direct count is
    Poisson-like with standard deviation sqrt(n_c) (12 seeds of this surface gave 0.4-0.7
    sqrt(n_c), the summits being more regular than a Poisson process). Bias: the
    8-neighbour summit of a grid with 10 points per shortest wavelength misses about 2 % of
    the continuous surface's summits (measured over those seeds: total summits 0.98 of
    eta A). Tolerance: 3 sqrt(n_c) + 0.03 n_c.
    """
    n, dx = 1024, 5e-6
    z, m0, m2, m4 = _surface(n, dx, seed=11)
    scale = (3.5e-6) ** 2 / m0  # the default raw rms; all three moments scale alike
    z *= math.sqrt(scale)
    m0, m2, m4 = m0 * scale, m2 * scale, m4 * scale
    sp = summit_parameters(m0, m2, m4)
    area = (n * dx) ** 2
    heights = _summit_heights(z)
    # the summit density itself (Nayak): within the grid bias and the Poisson scatter
    assert heights.size == pytest.approx(sp.density * area,
                                         abs=3 * math.sqrt(sp.density * area)
                                         + 0.03 * sp.density * area)
    counts = []
    for h_target in (0.5, 1.0, 1.5):
        # the load that puts the flat at h_target, then the model solves for h from the load
        load = ((4 / 3) * sp.density * area * E_STAR * math.sqrt(sp.radius) * sp.std**1.5
                * gw_integral(1.5, h_target))
        sol = solve_contact(load, sp.density, sp.radius, sp.std, area, E_STAR)
        assert sol.h == pytest.approx(h_target, rel=1e-9)
        direct = int(np.sum(heights > sp.mean_height + sol.h * sp.std))
        tol = 3 * math.sqrt(sol.micro_contacts) + 0.03 * sol.micro_contacts
        assert abs(direct - sol.micro_contacts) <= tol, (h_target, direct, sol.micro_contacts)
        counts.append(direct)
    assert counts[0] > counts[1] > counts[2]  # more load, lower separation, more contacts


def test_layout_takes_the_auto_count_and_the_selection_rule():
    scene = roughvib.load_scene("paper-heavy")
    profile = scene_input(scene).profile
    cl = contact_layout(scene, profile)
    cs = contact_stiffness(scene)
    assert cl.n == cs.points == max(1, round(cs.micro_contacts)) and cl.points_source == "auto"
    assert cl.stiffness_total == pytest.approx(cs.s_total, rel=1e-12)
    np.testing.assert_array_equal(cl.positions,
                                  select_contacts(profile, cs.points, 0.04, 0.2e-3))
    # the paper-literal rule: the ten highest maxima, no separation constraint
    hs = scene.with_overrides({"contact.points": 10, "contact.selection": "highest"})
    hl = contact_layout(hs, profile)
    assert hl.min_separation == 0.0 and hl.stiffness_source == "auto"
    np.testing.assert_array_equal(hl.positions, select_contacts(profile, 10, 0.04, 0.0))
    i = np.rint((hl.positions - profile.s0) / profile.dx).astype(int)
    window = np.abs(profile.s - profile.s_centre) <= 0.02 + 1e-9
    zi = profile.z
    interior = np.flatnonzero(window)[1:-1]
    maxima = interior[(zi[interior] >= zi[interior - 1]) & (zi[interior] > zi[interior + 1])]
    top10 = np.sort(zi[maxima])[::-1][:10]
    np.testing.assert_allclose(np.sort(zi[i])[::-1], top10)
    sep = contact_layout(hs.with_overrides({"contact.selection": "separated"}), profile)
    assert np.min(np.diff(sep.positions)) >= 0.2e-3 - 1e-12
