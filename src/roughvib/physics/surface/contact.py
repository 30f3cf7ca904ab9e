"""Statistical normal contact stiffness of the block on the plate (docs/theory.md).

This module owns the contact sub-program: summit statistics from spectral moments
(Nayak / McCool), the Greenwood-Williamson (GW) and Greenwood-Tripp (GT) models solved at the
static load m g, and the resulting tangent ("incremental") stiffness s_total that the solver
splits over its contact springs, with the number of micro-contacts, real contact area, mean
pressure, plasticity index and the rigid-plate contact resonance.

Model summary (``h = d / sigma_s`` the separation of the flat from the mean summit plane in
summit standard deviations, ``F_n(h) = integral_h^inf (s - h)^n phi*(s) ds``):

GW, one equivalent rough surface (density eta, radius R, summit std sigma_s) on a flat::

    P   = (4/3) eta A_n E* R^(1/2) sigma_s^(3/2) F_3/2(h)
    k   = 2 eta A_n E* (R sigma_s)^(1/2) F_1/2(h)          (= dP/d(approach))
    n_c = eta A_n F_0(h) ,   A_r = pi eta A_n R sigma_s F_1(h)

GT, two rough surfaces each with summit density eta and radius beta, composite std sigma.
Derived from two paraboloids of radius beta at lateral offset r, Hertz with the effective
radius beta/2 (so E* is the usual 1/E* = sum (1 - nu_i^2)/E_i, which makes the constant
agree with Greenwood-Williamson's)::

    P   = (16 sqrt(2) pi / 15) (eta beta sigma)^2 sqrt(sigma / beta) E* A_n F_5/2(h)
    k   = (5/2) (P / sigma) F_3/2(h) / F_5/2(h)
    n_c = 4 pi eta^2 beta sigma A_n F_1(h) ,   A_r = pi^2 (eta beta sigma)^2 A_n F_2(h)

The equivalent GW surface of two surfaces with comparable summits has 1/R = 1/beta + 1/beta
(docs/theory.md), so GT is fed beta = 2 R, eta = eta_s, sigma = sigma_s. With that mapping
the two models agree within 1 % in stiffness and micro-contact count for the default surface;
with beta = R (reading "beta is the summit radius" literally) GT is 4.8-4.9 % softer.

The number of contact points of the 2-D model (``contact.points = "auto"``,
:func:`contact_count`) is the expected number of micro-contacts n_c rounded to the nearest
integer, at least one; :func:`contact_layout` resolves a scene's contact points, stiffness
and their sources in one place for the model and the surface report.

For Gaussian summits ``F_n(h) = Gamma(n+1) exp(-h^2/4) D_-(n+1)(h) / sqrt(2 pi)`` (D the parabolic
cylinder function); an exponential summit distribution (standardised: phi*(s) = exp(-(s+1)),
s >= -1) gives F_n = Gamma(n+1) exp(-(h+1)) and exactly k = P / sigma_s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from roughvib._cache import cached_values, code_fingerprint
from roughvib.physics.surface.field import InputBand, ModelPSD, input_band
from roughvib.physics.surface.roughness import Profile, select_contacts
from roughvib.scene import MAX_CONTACTS, SANE_BOUNDS, Scene, SceneError

__all__ = [
    "GRAVITY",
    "ContactLayout",
    "ContactSolution",
    "ContactStiffness",
    "SummitParameters",
    "contact_count",
    "contact_layout",
    "contact_stiffness",
    "effective_modulus",
    "gw_integral",
    "solve_contact",
    "summit_parameters",
    "velocity_factor",
]

GRAVITY = 9.81  # m/s^2, the paper's value (same as roughvib.model.system.GRAVITY)

# the paper's elevation effect: stiffness factor 1 at 10 mm/s and 0.33 at 100 mm/s [P]
_VF_REF = 0.01
_VF_EXPONENT = math.log10(0.33)

_DISTRIBUTIONS = ("gaussian", "exponential")
#: the log of a vanishing contact integral in the root search for the separation: far below
#: any log(load / c), so a separation where the integral vanishes carries less than the load
LOG_OF_ZERO = -1e300


# --------------------------------------------------------------------------------------------
# building blocks
# --------------------------------------------------------------------------------------------


def gw_integral(n: float, h: float | np.ndarray, distribution: str = "gaussian"
                ) -> float | np.ndarray:
    """F_n(h) = integral_h^inf (s - h)^n phi*(s) ds for a standardised summit distribution.

    Parameters
    ----------
    n : float
        Order (> -1), e.g. 0, 1/2, 1, 3/2, 2, 5/2.
    h : float or ndarray
        Standardised separation [-].
    distribution : {"gaussian", "exponential"}
        Standard normal phi*, or the standardised exponential exp(-(s+1)) on s >= -1 (mean 0,
        std 1).

    Returns
    -------
    float or ndarray
        F_n(h) [-].
    """
    from scipy import special  # here, not at the top: a run with a cached contact needs none

    h = np.asarray(h, dtype=float)
    if distribution == "gaussian":
        d, _ = special.pbdv(-n - 1.0, h)
        out = special.gamma(n + 1.0) * np.exp(-h * h / 4.0) * d / math.sqrt(2.0 * math.pi)
    elif distribution == "exponential":
        u = np.maximum(-(h + 1.0), 0.0)  # below the support the lower limit is s = -1
        # integral_{max(h,-1)}^inf (s-h)^n e^{-(s+1)} ds
        #   = Gamma(n+1) e^{-(h+1)}            for h >= -1
        #   = e^{u} Gamma(n+1, u), u = -(1+h)  for h < -1
        out = np.where(h >= -1.0, special.gamma(n + 1.0) * np.exp(-(h + 1.0)),
                       np.exp(u) * special.gamma(n + 1.0) * special.gammaincc(n + 1.0, u))
    else:
        raise ValueError(f"distribution must be one of {_DISTRIBUTIONS}, got {distribution!r}")
    return float(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class SummitParameters:
    """Summit statistics of an isotropic Gaussian surface (Nayak / McCool).

    Attributes
    ----------
    density : float
        eta_s = m4 / (6 pi sqrt(3) m2) [1/m^2].
    radius : float
        R = 1 / kappa_s, kappa_s = (8/3) sqrt(m4 / pi) [m].
    std : float
        sigma_s = sqrt((1 - 0.8968 / alpha) m0) [m].
    alpha : float
        Bandwidth parameter m0 m4 / m2^2 [-].
    rms, rms_slope, rms_curvature : float
        sqrt(m0) [m], sqrt(m2) [-], sqrt(m4) [1/m].
    mean_height : float
        Mean summit height above the mean plane of the surface, 4 sqrt(m0 / (pi alpha))
        [m] (McCool 1986); the GW separation d is measured from this plane.
    """

    density: float
    radius: float
    std: float
    alpha: float
    rms: float
    rms_slope: float
    rms_curvature: float
    mean_height: float


def summit_parameters(m0: float, m2: float, m4: float) -> SummitParameters:
    """Summit density, radius and height spread from profile spectral moments (docs/theory.md).

    Parameters
    ----------
    m0, m2, m4 : float
        Profile spectral moments of the (isotropic) surface: variance [m^2], mean-square slope
        [-], mean-square curvature [1/m^2].

    Returns
    -------
    SummitParameters

    Raises
    ------
    ValueError
        Non-positive moments or alpha <= 0.8968 (no real summit spread).
    """
    if not (m0 > 0 and m2 > 0 and m4 > 0):
        raise ValueError(f"spectral moments must be > 0, got m0={m0}, m2={m2}, m4={m4}")
    alpha = m0 * m4 / m2**2
    if alpha <= 0.8968:
        raise ValueError(f"bandwidth alpha = m0 m4 / m2^2 must exceed 0.8968, got {alpha}")
    return SummitParameters(
        density=m4 / (6.0 * math.pi * math.sqrt(3.0) * m2),
        radius=1.0 / ((8.0 / 3.0) * math.sqrt(m4 / math.pi)),
        std=math.sqrt((1.0 - 0.8968 / alpha) * m0),
        alpha=alpha, rms=math.sqrt(m0), rms_slope=math.sqrt(m2), rms_curvature=math.sqrt(m4),
        mean_height=4.0 * math.sqrt(m0 / (math.pi * alpha)))


def effective_modulus(e1: float, nu1: float, e2: float | None = None,
                      nu2: float | None = None) -> float:
    """Contact modulus E*: 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2 [Pa].

    Parameters
    ----------
    e1, nu1 : float
        Young's modulus [Pa] and Poisson ratio [-] of body 1.
    e2, nu2 : float, optional
        Body 2; default the same material (steel on steel: 115.4 GPa).
    """
    e2 = e1 if e2 is None else e2
    nu2 = nu1 if nu2 is None else nu2
    return 1.0 / ((1.0 - nu1**2) / e1 + (1.0 - nu2**2) / e2)


def velocity_factor(v_rms: float) -> float:
    """The paper's velocity ("elevation") factor of the contact stiffness (docs/theory.md).

    (v_rms / 0.01 m/s)^log10(0.33): 1 at 10 mm/s, 0.33 at 100 mm/s.

    Parameters
    ----------
    v_rms : float
        rms sliding velocity [m/s], > 0.
    """
    if not v_rms > 0:
        raise ValueError(f"v_rms must be > 0 m/s, got {v_rms}")
    return (v_rms / _VF_REF) ** _VF_EXPONENT


@dataclass(frozen=True)
class ContactSolution:
    """A statistical contact solved at one load (see :func:`solve_contact`)."""

    h: float
    stiffness: float
    micro_contacts: float
    real_area: float


def solve_contact(load: float, density: float, radius: float, std: float, area: float,
                  modulus: float, model: str = "gw", distribution: str = "gaussian"
                  ) -> ContactSolution:
    """Solve a statistical contact model for the separation at a given load.

    Parameters
    ----------
    load : float
        Normal load P [N], > 0.
    density : float
        Summit density eta [1/m^2].
    radius : float
        GW: summit radius R of the equivalent surface [m]. GT: the radius beta of each of the
        two surfaces' summits [m] (``contact_stiffness`` passes beta = 2 R).
    std : float
        Summit height std sigma_s (GT: composite sigma) [m].
    area : float
        Nominal area A_n [m^2].
    modulus : float
        E* [Pa].
    model : {"gw", "gt"}
    distribution : {"gaussian", "exponential"}
        Standardised summit height distribution.

    Returns
    -------
    ContactSolution
        ``h`` [-], ``stiffness`` [N/m] (tangent dP/d(approach)), ``micro_contacts`` [-],
        ``real_area`` [m^2].

    Raises
    ------
    ValueError
        Non-positive inputs, unknown model, or a load beyond the range of the model
        (h < -8: the surfaces are pressed flat).
    """
    for name, v in (("load", load), ("density", density), ("radius", radius), ("std", std),
                    ("area", area), ("modulus", modulus)):
        if not (v > 0 and math.isfinite(v)):
            raise ValueError(f"{name} must be a finite number > 0, got {v}")
    if model == "gw":
        c = (4.0 / 3.0) * density * area * modulus * math.sqrt(radius) * std**1.5
        order = 1.5
    elif model == "gt":
        c = ((16.0 * math.sqrt(2.0) * math.pi / 15.0) * (density * radius * std) ** 2
             * math.sqrt(std / radius) * modulus * area)
        order = 2.5
    else:
        raise ValueError(f"model must be 'gw' or 'gt', got {model!r}")
    target = math.log(load / c)

    def f(h: float) -> float:
        v = gw_integral(order, h, distribution)
        return (math.log(v) if v > 0 else LOG_OF_ZERO) - target

    lo, hi = -8.0, 8.0
    if f(lo) < 0:
        raise ValueError(f"load {load} N exceeds the range of the {model.upper()} model "
                         f"(separation h < {lo}): the surfaces would be pressed flat")
    while f(hi) > 0:
        hi *= 2.0
        if hi > 64.0:
            raise ValueError(f"load {load} N is too small for the {model.upper()} model "
                             f"(separation h > 64)")
    from scipy import optimize

    h = optimize.brentq(f, lo, hi, xtol=1e-14, rtol=1e-14, maxiter=200)
    F = lambda n: gw_integral(n, h, distribution)  # noqa: E731
    if model == "gw":
        k = 2.0 * density * area * modulus * math.sqrt(radius * std) * F(0.5)
        n_c = density * area * F(0.0)
        a_r = math.pi * density * area * radius * std * F(1.0)
    else:
        k = 2.5 * load / std * F(1.5) / F(2.5)
        n_c = 4.0 * math.pi * density**2 * radius * std * area * F(1.0)
        a_r = math.pi**2 * (density * radius * std) ** 2 * area * F(2.0)
    return ContactSolution(h=float(h), stiffness=float(k), micro_contacts=float(n_c),
                     real_area=float(a_r))


def _solve_contact_cached(load: float, density: float, radius: float, std: float, area: float,
                          modulus: float, model: str) -> ContactSolution:
    """:func:`solve_contact` (Gaussian summits) through the on-disk cache of
    ``roughvib._cache``: its special functions and root finder need ``scipy.special`` and
    ``scipy.optimize``, whose imports cost a short run more than the solution. Exact; an
    input the model cannot carry raises (and is not stored) as before."""
    inputs = {"load": float(load), "density": float(density), "radius": float(radius),
              "std": float(std), "area": float(area), "modulus": float(modulus),
              "model": model, "distribution": "gaussian"}

    def compute() -> dict[str, float]:
        sol = solve_contact(load, density, radius, std, area, modulus, model=model)
        return {f.name: getattr(sol, f.name) for f in fields(sol)}

    values, _ = cached_values("contact-solution", inputs, compute,
                              code=code_fingerprint([__file__]))
    return ContactSolution(**values)


# --------------------------------------------------------------------------------------------
# the scene-level result
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ContactStiffness:
    """Statistical contact at the static load (docs/theory.md).

    Attributes
    ----------
    s_total : float
        Total incremental normal stiffness [N/m], including the velocity factor.
    micro_contacts : float
        Expected number of micro-contacts n_c [-].
    points : int
        Contact points of the 2-D model for ``contact.points = "auto"``:
        :func:`contact_count` of ``micro_contacts`` [-].
    real_area : float
        Real contact area A_r [m^2].
    mean_pressure : float
        P / A_r [Pa].
    plasticity_index : float
        psi = (E*/H) sqrt(sigma_s / R) [-] (> 1: first contact is plastic).
    separation : float
        h = d / sigma_s [-].
    summit_density : float
        eta_s [1/m^2].
    summit_radius : float
        R of the equivalent surface [m] (GT uses beta = 2 R per surface).
    summit_std : float
        sigma_s [m].
    resonance_hz : float
        Rigid-plate contact resonance sqrt(s_total / m) / (2 pi) [Hz].
    model : str
        "gw" or "gt".
    load : float
        Static load m g [N].
    stiffness_ratio : float
        kappa = k sigma_s / P before the velocity factor [-] (4.4-5.0 for Gaussian summits).
    velocity_factor : float
        Applied factor [-] (1 when ``contact.velocity_factor`` is off).
    effective_modulus : float
        E* [Pa].
    nominal_area : float
        A_n = block length x width [m^2].
    surface_rms : float
        rms of the raw surface used for the moments [m] (NaN if all summit keys were given).
    summit_source : str
        "moments", "keys" or "moments+keys".
    velocity_factor_note : str
        Why ``contact.velocity_factor = true`` was not applied (factor 1): a block that does
        not slide, or no stated rms velocity; empty when it was applied or is off.
    spot_radius : float
        Mean radius a of the micro-contacts [m], the scale the summits are counted at and the
        radius of the contact filter.
    spot_radius_source : {"auto", "scene"}
        The fixed point of :func:`contact_stiffness`, or ``contact.spot_radius``.
    """

    s_total: float
    micro_contacts: float
    points: int
    real_area: float
    mean_pressure: float
    plasticity_index: float
    separation: float
    summit_density: float
    summit_radius: float
    summit_std: float
    resonance_hz: float
    model: str
    load: float
    stiffness_ratio: float
    velocity_factor: float
    effective_modulus: float
    nominal_area: float
    surface_rms: float
    summit_source: str
    spot_radius: float
    spot_radius_source: str
    velocity_factor_note: str = ""

    def as_dict(self) -> dict:
        """Plain dict of the fields (JSON-ready)."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def contact_count(micro_contacts: float) -> int:
    """Contact points of the 2-D model from the expected number of micro-contacts.

    N = max(1, round(n_c)): each micro-contact of the areal surface becomes one contact point
    at its position along the sliding direction (the 2-D model has no y); a loaded block
    rests on at least one. docs/theory.md ("Contact module") gives the reasoning and its
    limits.

    Parameters
    ----------
    micro_contacts : float
        n_c [-], >= 0.

    Returns
    -------
    int
        N >= 1.
    """
    if not (micro_contacts >= 0 and math.isfinite(micro_contacts)):
        raise ValueError(f"micro_contacts must be a finite number >= 0, got {micro_contacts}")
    return max(1, int(round(micro_contacts)))


def _scene_v_rms(scene: Scene) -> tuple[float | None, str]:
    """The rms sliding velocity the velocity factor is evaluated at [m/s], or None and why
    the factor is not applied.

    The factor is the paper's fit of the stiffness of a *sliding* contact against its rms
    velocity (docs/theory.md); it diverges as v_rms -> 0, where a block at rest has no
    elevation effect at all. A block that does not slide (a prescribed motion of zero rms, a
    force-driven block with no force and no target) therefore keeps the contact module's
    static stiffness (factor 1); so does a force-driven block whose rms velocity the scene
    does not state (no ``excitation.target_rms_velocity``), because the factor is defined on
    the scene's stated velocity, which is only known after such a run.
    """
    exc = scene.excitation
    if exc.kind == "prescribed":
        v = math.sqrt(exc.velocity**2 + 0.5 * (exc.amplitude * exc.omega) ** 2)
        if v > 0:
            return v, ""
        return None, ("the block does not slide (excitation.velocity and "
                      "excitation.amplitude are 0): factor 1, the static contact stiffness")
    if exc.target_rms_velocity is not None:
        return float(exc.target_rms_velocity), ""
    if not exc.force_amplitude:
        return None, ("the block does not slide (excitation.force_amplitude = 0 N): factor 1, "
                      "the static contact stiffness")
    return None, (f"no excitation.target_rms_velocity to evaluate it at (force_amplitude = "
                  f"{exc.force_amplitude} N only): factor 1, the static contact stiffness")


def _summits_in_range(sp: SummitParameters, given: dict) -> bool:
    """Whether the summits derived (not given) lie in the ranges of their keys (docs/scenes.md):
    height spread >= the lowest ``contact.summit_std``, radius <= the largest
    ``contact.summit_radius``."""
    std_lo, _, _ = SANE_BOUNDS["contact.summit_std"]
    _, rad_hi, _ = SANE_BOUNDS["contact.summit_radius"]
    return ((given["std"] is not None or sp.std >= std_lo)
            and (given["radius"] is not None or sp.radius <= rad_hi))


def _lowest_raw_rms(usable, value: float) -> float | None:
    """The lowest ``roughness.raw_rms`` above ``value`` (unusable) that the contact module can
    use [m], or None if none up to the key's largest value is (then the band is at fault).
    ``usable(rms) -> bool``. A coarse scan in log rms finds the first usable value (with summit
    keys given, too rough a surface may be unusable as well), bisection refines it."""
    _, hi, _ = SANE_BOUNDS["roughness.raw_rms"]
    lo = max(value, 1e-300)
    grid = np.geomspace(lo, hi, max(int(math.ceil(math.log10(hi / lo))), 1) + 1)  # decades
    prev = grid[0]
    for x in grid[1:]:
        if usable(float(x)):
            lo_log, hi_log = math.log(prev), math.log(x)
            while hi_log - lo_log > 1e-3:
                mid = 0.5 * (lo_log + hi_log)
                lo_log, hi_log = (lo_log, mid) if usable(math.exp(mid)) else (mid, hi_log)
            return math.exp(hi_log)
        prev = x
    return None


#: bracket of the spot radius [m] searched by the self-consistent summit scale
_SPOT_BRACKET = (1e-10, 1e-2)


def _surface_source(scene: Scene):
    """The raw surface's PSD model of a scene's ``[roughness]`` section, over its band down to
    the resolved tail limit (:func:`~roughvib.physics.surface.field.input_band`)."""
    from roughvib.physics.surface.roughness import areal_psd, band_psd

    r = scene.roughness
    # an "auto" tail is where the run's input stops, not the surface: the contact counts the
    # summits of the whole self-affine tail, which its filter makes converge
    lam = 0.0 if isinstance(r.shortest_wavelength, str) else float(r.shortest_wavelength)
    psd = ((lambda k: areal_psd(k, r, r.raw_rms, shortest=lam)) if r.reduce_3d
           else (lambda k: band_psd(k, r, r.raw_rms, shortest=lam)))
    key = {"raw_rms": r.raw_rms, "hurst": r.hurst, "rolloff": r.rolloff_wavelength,
           "longest": r.longest_wavelength, "shortest": lam, "areal": bool(r.reduce_3d)}
    return ModelPSD(psd=psd, k_low=2.0 * math.pi / r.longest_wavelength,
                    k_high=2.0 * math.pi / lam if lam else math.inf, areal=bool(r.reduce_3d),
                    key=key, breaks=(2.0 * math.pi / r.rolloff_wavelength,))


def _summits_at(source, radius: float, given: dict) -> SummitParameters | None:
    """Summit statistics of the surface seen at spot ``radius``, the given keys overriding."""
    sp = summit_parameters(*source.moments(radius))
    over = {"density": given["density"], "radius": given["radius"], "std": given["std"]}
    if all(v is None for v in over.values()):
        return sp
    return SummitParameters(
        density=over["density"] if over["density"] is not None else sp.density,
        radius=over["radius"] if over["radius"] is not None else sp.radius,
        std=over["std"] if over["std"] is not None else sp.std, alpha=sp.alpha, rms=sp.rms,
        rms_slope=sp.rms_slope, rms_curvature=sp.rms_curvature, mean_height=sp.mean_height)


def spot_radius_of(sol: ContactSolution) -> float:
    """Mean radius of the micro-contacts, sqrt(A_r / (pi n_c)) [m]."""
    return math.sqrt(sol.real_area / (math.pi * sol.micro_contacts))


def _spot_scale_contact(source, given: dict, solve, fixed_radius: float | None
                        ) -> tuple[float, SummitParameters, ContactSolution]:
    """The summit statistics at the scale of the contact spots (docs/theory.md).

    Summits are counted on the surface as the spots see it, its spectrum weighted by the
    contact filter H(k a)^2, and a is the mean spot radius that those summits give at the
    load: the fixed point a = a_GW(a) in log a (unique: a_GW grows slower than a, about as
    a^0.6 for H = 0.8). A given ``fixed_radius`` takes that a instead.
    """
    def at(a: float) -> tuple[SummitParameters, ContactSolution]:
        sp = _summits_at(source, a, given)
        return sp, solve(sp)

    if fixed_radius is not None:
        sp, sol = at(fixed_radius)
        return float(fixed_radius), sp, sol

    def g(u: float) -> float:
        _, sol = at(math.exp(u))
        return math.log(spot_radius_of(sol)) - u

    from scipy import optimize

    lo, hi = (math.log(v) for v in _SPOT_BRACKET)
    u = optimize.brentq(g, lo, hi, xtol=1e-10, rtol=1e-12, maxiter=200)
    a = math.exp(u)
    sp, sol = at(a)
    return a, sp, sol


def _spot_scale_cached(source, given: dict, load: float, area: float, e_star: float,
                       model: str, fixed_radius: float | None
                       ) -> tuple[float, SummitParameters, ContactSolution]:
    """:func:`_spot_scale_contact` through the on-disk cache (exact values)."""
    beta_factor = 1.0 if model == "gw" else 2.0

    def solve(sp: SummitParameters) -> ContactSolution:
        return solve_contact(load, sp.density, beta_factor * sp.radius, sp.std, area, e_star,
                             model=model)

    inputs = {"source": source.key, "given": {k: (None if v is None else float(v))
                                              for k, v in given.items()},
              "load": float(load), "area": float(area), "modulus": float(e_star),
              "model": model, "fixed_radius": fixed_radius}

    def compute() -> dict[str, float]:
        a, sp, sol = _spot_scale_contact(source, given, solve, fixed_radius)
        out = {"spot_radius": a}
        out.update({f"sp_{f.name}": getattr(sp, f.name) for f in fields(sp)})
        out.update({f"sol_{f.name}": getattr(sol, f.name) for f in fields(sol)})
        return out

    from roughvib.physics.surface import field as field_module

    values, _ = cached_values("spot-scale-contact", inputs, compute,
                              code=code_fingerprint([__file__, field_module.__file__]))
    sp = SummitParameters(**{f.name: values[f"sp_{f.name}"] for f in fields(SummitParameters)})
    sol = ContactSolution(**{f.name: values[f"sol_{f.name}"]
                             for f in fields(ContactSolution)})
    return float(values["spot_radius"]), sp, sol


def _refuse_raw_rms(scene: Scene, given: dict, solve) -> None:
    """Raise, naming ``roughness.raw_rms``, when a larger rms would give the contact module
    usable summits (then the rms, not the band, is at fault), with the lowest such rms."""
    def usable(rms: float) -> bool:
        s2 = scene.with_overrides({"roughness.raw_rms": rms})
        try:
            _, sp, _ = solve(_surface_source(s2))
        except (ValueError, ArithmeticError):
            return False
        return _summits_in_range(sp, given)

    value = scene.roughness.raw_rms
    need = _lowest_raw_rms(usable, value)
    if need is None:
        return
    std_lo, _, _ = SANE_BOUNDS["contact.summit_std"]
    _, rad_hi, _ = SANE_BOUNDS["contact.summit_radius"]
    raise SceneError(
        f"roughness.raw_rms must be >= {need:.3g} m for the contact module ('auto' contact "
        f"points, stiffness or spot radius) on this band: a smoother surface gives no summits "
        f"that carry the block within the ranges of contact.summit_std (>= {std_lo:g} m) and "
        f"summit_radius (<= {rad_hi:g} m, docs/scenes.md), got {value!r} m")


def contact_stiffness(scene: Scene, surface=None) -> ContactStiffness:
    """Tangent normal contact stiffness of the scene at the static load m g.

    Summit parameters: ``contact.summit_density``, ``summit_radius``, ``summit_std`` where
    given; the others from the spectral moments of the raw surface **at the scale of the
    contact spots** (McCool, :func:`summit_parameters`): the surface's PSD weighted by the
    contact filter H(k a)^2 of the mean spot radius a, which is itself the mean spot radius
    sqrt(A_r / (pi n_c)) those summits give at the load (a fixed point; ``contact.spot_radius``
    given takes that a). Counting summits on the raw band instead would make their number
    follow the shortest wavelength of the band, which for a self-affine surface is a limit
    of the measurement, not of the surface (Greenwood and Wu 2001). The surface defaults to
    the model PSD of ``[roughness]`` at the rms ``roughness.raw_rms``, down to the resolved
    tail limit: the areal PSD when ``reduce_3d`` is set, the profile PSD of
    :func:`.band_psd` otherwise. Both bodies are steel of the plate's E and nu; A_n = block
    length x width.

    Parameters
    ----------
    scene : Scene
    surface : object with ``moments(radius)`` and ``key``, optional
        The raw surface's spectrum (a measured one,
        :class:`~roughvib.physics.surface.field.DiscretePSD`); overrides the model.

    Returns
    -------
    ContactStiffness

    Raises
    ------
    SceneError
        raw_rms = 0 without summit keys, or a load outside the model's range. (The velocity
        factor of a block that does not slide, or of a scene without a stated rms velocity,
        is 1; ``velocity_factor_note`` says so.)
    """
    c, r, blk, plt = scene.contact, scene.roughness, scene.block, scene.plate
    given = {"density": c.summit_density, "radius": c.summit_radius, "std": c.summit_std}
    need_moments = any(v is None for v in given.values())
    e_star = effective_modulus(plt.youngs_modulus, plt.poisson_ratio)
    area = blk.length * blk.width
    load = blk.mass * GRAVITY
    fixed = None if isinstance(c.spot_radius, str) else float(c.spot_radius)
    if need_moments:
        if surface is None:
            if r.raw_rms <= 0:
                raise SceneError("roughness.raw_rms must be > 0 m for contact.stiffness = "
                                 "'auto' (or give contact.summit_density, summit_radius and "
                                 "summit_std), got 0.0 m")
            surface = _surface_source(scene)
        source = "moments" if all(v is None for v in given.values()) else "moments+keys"
    else:
        surface, source = _KeysOnly(), "keys"

    def solve(src):
        return _spot_scale_cached(src, given, load, area, e_star, c.model, fixed)

    failure = None
    try:
        a, sp, sol = solve(surface)
        if not _summits_in_range(sp, given):
            failure = (f"summits of height spread {sp.std:.3g} m and radius {sp.radius:.3g} m, "
                       f"outside the ranges of contact.summit_std and summit_radius")
    except (ValueError, ArithmeticError) as err:
        failure = str(err)
    if failure is not None:
        if isinstance(surface, ModelPSD) and r.raw_rms > 0:
            _refuse_raw_rms(scene, given, solve)
        raise SceneError(f"contact.model = {c.model!r} cannot carry block.mass = {blk.mass} kg "
                         f"on the summits of this surface ({failure}), got roughness.raw_rms "
                         f"{r.raw_rms} m and summit keys {given}")
    eta, rad, std = sp.density, sp.radius, sp.std
    v_rms, vf_note = _scene_v_rms(scene) if c.velocity_factor else (None, "")
    vf = velocity_factor(v_rms) if v_rms is not None else 1.0
    if c.velocity_factor and vf_note:
        vf_note = f"contact.velocity_factor not applied: {vf_note}"
    s_total = sol.stiffness * vf
    return ContactStiffness(
        s_total=float(s_total), micro_contacts=sol.micro_contacts,
        points=contact_count(sol.micro_contacts), real_area=sol.real_area,
        mean_pressure=float(load / sol.real_area),
        plasticity_index=float(e_star / c.hardness * math.sqrt(std / rad)),
        separation=sol.h, summit_density=eta, summit_radius=rad, summit_std=std,
        resonance_hz=float(math.sqrt(s_total / blk.mass) / (2.0 * math.pi)), model=c.model,
        load=float(load), stiffness_ratio=float(sol.stiffness * std / load),
        velocity_factor=float(vf), effective_modulus=float(e_star), nominal_area=float(area),
        surface_rms=sp.rms if need_moments else float("nan"), summit_source=source,
        spot_radius=float(a), spot_radius_source="scene" if fixed is not None else "auto",
        velocity_factor_note=vf_note)


class _KeysOnly:
    """A surface known only by the three summit keys: its moments are never needed."""

    key = {"keys-only": True}

    def moments(self, radius: float) -> tuple[float, float, float]:
        # summit_parameters needs alpha > 0.8968: any positive consistent triple serves,
        # the keys replace all three derived values
        return 1.0, 1.0, 2.0


# --------------------------------------------------------------------------------------------
# the contact points and stiffness the model uses
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ContactLayout:
    """The contact points and total stiffness of a scene, and where they came from.

    Attributes
    ----------
    positions : ndarray, shape (N,)
        Profile coordinates of the contact points at x = 0 [m], sorted.
    stiffness_total : float
        s_total [N/m], split equally over the N points.
    points_source, stiffness_source : {"scene", "auto"}
        ``contact.points`` / ``contact.stiffness`` as given, or from the statistical model.
    selection : {"separated", "highest"}
        ``contact.selection``.
    min_separation : float
        The separation applied in the selection [m] (0 for ``highest``).
    statistical : ContactStiffness or None
        The statistical contact, when either value is ``"auto"``.
    """

    positions: np.ndarray
    stiffness_total: float
    points_source: str
    stiffness_source: str
    selection: str
    min_separation: float
    statistical: ContactStiffness | None

    @property
    def n(self) -> int:
        """Number of contact points N [-]."""
        return int(self.positions.size)

    def as_dict(self) -> dict:
        """Plain dict (JSON-ready) of everything but the positions."""
        return {"points": self.n, "points_source": self.points_source,
                "stiffness_total": self.stiffness_total,
                "stiffness_source": self.stiffness_source, "selection": self.selection,
                "min_separation": self.min_separation,
                "micro_contacts": (self.statistical.micro_contacts
                                   if self.statistical is not None else None)}


@dataclass(frozen=True)
class SceneInput:
    """A scene's kinematic input and the statistical contact it was filtered with.

    Attributes
    ----------
    profile : Profile
        The input profile: the surface seen through the contact filter.
    band : InputBand
        The resolved tail limit and grid.
    statistical : ContactStiffness or None
        The statistical contact, when the contact points, the stiffness or the spot radius
        come from it.
    """

    profile: Profile
    band: InputBand
    statistical: ContactStiffness | None


def _needs_statistics(scene: Scene) -> bool:
    c, r = scene.contact, scene.roughness
    filtered = c.filter == "hertz" and r.kind in ("synthetic", "file")
    return (isinstance(c.points, str) or isinstance(c.stiffness, str)
            or (filtered and isinstance(c.spot_radius, str)))


def scene_input(scene: Scene, *, stroke: float | None = None) -> SceneInput:
    """Build a scene's input profile, through the contact filter where it applies.

    Order: the tail limit and grid (:func:`~roughvib.physics.surface.field.input_band`); the
    statistical contact when anything comes from it (:func:`contact_stiffness`, on a
    measured surface's own spectrum); the profile (:func:`.build_profile`) seen through the
    contact filter of the spot radius (``contact.filter = "hertz"``; ``synthetic`` and
    ``file`` surfaces only).

    Parameters
    ----------
    scene : Scene
    stroke : float, optional
        As for :func:`.build_profile`.

    Returns
    -------
    SceneInput
    """
    from roughvib.physics.surface.roughness import build_profile, measured_field

    c, r = scene.contact, scene.roughness
    band = input_band(scene)
    need = _needs_statistics(scene)
    filtered = c.filter == "hertz" and r.kind in ("synthetic", "file")
    # the statistical contact is asked for the spot radius alone: if it cannot be solved
    # (an extreme load, no summit statistics), the run goes on without the contact filter
    # and says so, rather than refuse a scene whose contact is given
    spot_only = isinstance(c.points, int) and not isinstance(c.stiffness, str)
    stat, note = None, ""
    profile = None
    if r.kind == "file":
        profile = build_profile(r, scene.block, scene.base_dir, stroke=stroke, band=band)
    if need:
        try:
            stat = contact_stiffness(scene, surface=profile.raw_spectrum
                                     if profile is not None else None)
        except SceneError as err:
            if not spot_only:
                raise
            note = (f"contact filter not applied: the statistical contact gives no spot radius "
                    f"for this scene ({err}); set contact.spot_radius [m] to filter")
    spot = None
    if filtered:
        spot = (float(c.spot_radius) if not isinstance(c.spot_radius, str)
                else stat.spot_radius if stat is not None else None)
    if profile is None:
        profile = build_profile(r, scene.block, scene.base_dir, stroke=stroke, band=band,
                                spot_radius=spot)
    else:  # a measured profile: its own bins, a fitted tail, the contact filter
        profile = measured_field(profile, band.shortest_wavelength, band.spacing, r.seed,
                                 tail=r.tail == "fit", spot_radius=spot)
    if note:
        profile.stats["contact_filter_note"] = note
    return SceneInput(profile=profile, band=band, statistical=stat)


def contact_layout(scene: Scene, profile: Profile,
                   statistical: ContactStiffness | None = None) -> ContactLayout:
    """Resolve the contact points and total stiffness of a scene on its profile.

    ``contact.points`` and ``contact.stiffness`` are taken as given, or, when ``"auto"``,
    from :func:`contact_stiffness` (the micro-contact count through :func:`contact_count`,
    the stiffness with the velocity factor). The points are the highest profile maxima
    under the block (:func:`~roughvib.physics.surface.roughness.select_contacts`), at least
    ``contact.min_separation`` apart for ``selection = "separated"``, with no separation
    constraint for ``"highest"``.

    Parameters
    ----------
    scene : Scene
    profile : Profile
        The scene's profile (a measured one brings the spectrum of its raw surface).
    statistical : ContactStiffness, optional
        The statistical contact already solved (:func:`scene_input`).

    Returns
    -------
    ContactLayout

    Raises
    ------
    SceneError
        The statistical model cannot be solved, or it asks for more than ``MAX_CONTACTS``
        points.
    """
    c = scene.contact
    auto_n, auto_s = isinstance(c.points, str), isinstance(c.stiffness, str)
    stat = statistical
    if stat is None and (auto_n or auto_s):
        stat = contact_stiffness(scene, surface=profile.raw_spectrum)
    if auto_n:
        n = stat.points
        if n > MAX_CONTACTS:
            raise SceneError(f"contact.points = 'auto' asks for {n} contact points "
                             f"({stat.micro_contacts:.4g} micro-contacts at block.mass = "
                             f"{scene.block.mass} kg), more than {MAX_CONTACTS}; give "
                             f"contact.points as a number, got 'auto'")
    else:
        n = int(c.points)
    s_total = stat.s_total if auto_s else float(c.stiffness)
    sep = c.min_separation if c.selection == "separated" else 0.0
    pos = np.asarray(select_contacts(profile, n, scene.block.length, sep), dtype=float)
    return ContactLayout(positions=pos, stiffness_total=float(s_total),
                         points_source="auto" if auto_n else "scene",
                         stiffness_source="auto" if auto_s else "scene",
                         selection=c.selection, min_separation=float(sep), statistical=stat)
