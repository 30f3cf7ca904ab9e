"""The numbers of the "Contact module" section of docs/theory.md.

Usage (from the repository root)::

    python docs/figures/contact_count.py            # prints the tables (about a minute)

1. The statistical contact (``contact.points = "auto"``, ``contact.stiffness = "auto"``) of
   the built-in surfaces and loads: micro-contacts n_c, the contact points N, the spot radius
   a, s_total, the rigid-plate resonance.
1b. The summits counted on the surface's band itself (a 1 nm spot filters nothing) against
   those counted at the scale of the spots, as the tail is carried from 50 um to 0.25 um.
2. The rms roughness at which the count of the paper scene's load reaches the paper's ten.
3. The finite-population check of the mean-field count: the GW summit model (Gaussian summit
   heights of density eta, radius R, std sigma_s, Hertz contacts, a rigid flat) evaluated for
   the block's own nominal area by Monte Carlo. Each draw is a Poisson number of summits
   with Gaussian heights; the flat sinks until the Hertz forces carry m g; the summits then
   in contact and their tangent stiffness are counted. GW's closed forms are the mean field
   (infinite-area) limit of this.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize, stats

import roughvib
from roughvib.physics.surface.contact import contact_stiffness

CASES = [("paper (grit 80)", 0.221, 3.5e-6), ("paper-heavy", 0.543, 3.5e-6),
         ("paper-rough (grit 40)", 0.221, 7e-6), ("rough, heavy", 0.543, 7e-6),
         ("smooth", 0.221, 1.4e-6), ("smooth, heavy", 0.543, 1.4e-6)]


def scene(mass: float, raw_rms: float, **over):
    return roughvib.load_scene("paper", {"block.mass": mass, "roughness.raw_rms": raw_rms,
                                         **over})


def finite_population(cs, draws: int = 4000, seed: int = 0, h0: float = 2.0):
    """Mean count and stiffness of the summits in contact at equilibrium, over draws."""
    rng = np.random.default_rng(seed)
    eta, R, sig = cs.summit_density, cs.summit_radius, cs.summit_std
    P, E, A = cs.load, cs.effective_modulus, cs.nominal_area
    # only summits above h0 sigma_s can touch at these loads (h ~ 4): draw those
    lam = eta * A * stats.norm.sf(h0)
    c = (4.0 / 3.0) * E * math.sqrt(R) * sig**1.5
    counts, stiff = np.empty(draws), np.empty(draws)
    for i in range(draws):
        z = stats.norm.isf(rng.random(rng.poisson(lam)) * stats.norm.sf(h0))

        def excess(d, z=z):
            return c * np.sum(np.clip(z - d, 0.0, None) ** 1.5) - P

        d = optimize.brentq(excess, h0, float(z.max()), xtol=1e-13)
        w = np.clip(z - d, 0.0, None) * sig
        counts[i] = np.sum(w > 0)
        stiff[i] = 2.0 * E * np.sum(np.sqrt(R * w))
    return counts, stiff


def main() -> None:
    print("| surface | m [kg] | raw rms [um] | n_c (GW) | N | n_c (GT) | spot a [um] | "
          "s_total [N/m] | f_c [Hz] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for label, m, s in CASES:
        gw = contact_stiffness(scene(m, s, **{"contact.velocity_factor": False}))
        gt = contact_stiffness(scene(m, s, **{"contact.velocity_factor": False,
                                              "contact.model": "gt"}))
        print(f"| {label} | {m} | {s * 1e6:g} | {gw.micro_contacts:.2f} | {gw.points} | "
              f"{gt.micro_contacts:.2f} | {gw.spot_radius * 1e6:.2f} | {gw.s_total:.3g} | "
              f"{gw.resonance_hz:.0f} |")

    print("\n| tail to [um] | n_c, band's summits | a [um] | s_total [N/m] | n_c, spot scale | "
          "a [um] | s_total [N/m] |")
    print("|---|---|---|---|---|---|---|")
    for lam in (50e-6, 20e-6, 10e-6, 5e-6, 2e-6, 1e-6, 0.5e-6, 0.25e-6):
        band = contact_stiffness(scene(0.221, 3.5e-6, **{"roughness.shortest_wavelength": lam,
                                                         "contact.spot_radius": 1e-9}))
        spot = contact_stiffness(scene(0.221, 3.5e-6, **{"roughness.shortest_wavelength": lam}))
        # the band's own spots: the mean micro-contact radius those summits give
        a_band = math.sqrt(band.real_area / (math.pi * band.micro_contacts))
        print(f"| {lam * 1e6:g} | {band.micro_contacts:.2f} | {a_band * 1e6:.2f} | "
              f"{band.s_total:.3g} | {spot.micro_contacts:.2f} | {spot.spot_radius * 1e6:.2f} | "
              f"{spot.s_total:.3g} |")

    def n_of(log_rms):
        return contact_stiffness(scene(0.221, math.exp(log_rms))).micro_contacts - 9.5

    ten = math.exp(optimize.brentq(n_of, math.log(0.1e-6), math.log(3.5e-6)))
    print(f"\nn_c reaches 9.5 (N = 10) at 0.221 kg for a raw rms of {ten * 1e6:.2f} um")

    print("\n| surface | m [kg] | n_c (GW) | E[N] finite | P(N = 1) | s_total GW [N/m] | "
          "E[s] finite [N/m] | ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for label, m, s in CASES[:4] + [("paper, 5 kg", 5.0, 3.5e-6),
                                    ("paper, 20 kg", 20.0, 3.5e-6)]:
        cs = contact_stiffness(scene(m, s, **{"contact.velocity_factor": False}))
        n, k = finite_population(cs, draws=4000 if m < 1 else 300)
        print(f"| {label} | {m} | {cs.micro_contacts:.2f} | {n.mean():.2f} | "
              f"{np.mean(n == 1):.2f} | {cs.s_total:.3g} | {k.mean():.3g} | "
              f"{k.mean() / cs.s_total:.2f} |")


if __name__ == "__main__":
    main()
