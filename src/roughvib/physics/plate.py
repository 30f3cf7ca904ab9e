"""Simply supported Kirchhoff plate: modes, shapes, static and residual compliance, mobility.

This module owns the linear plate (docs/theory.md): the mode set for a frequency band, the
(unnormalised) mode shapes, the exact static Green's function, the residual compliance of the
truncated modes and the frequency-response (mobility) functions used to check the modal model.

Conventions
-----------
* Plate coordinates (x, y) in m, 0 <= x <= a (length, sliding direction), 0 <= y <= b (width).
* Mode r <-> half-wave numbers (n, m); shape phi_r(x, y) = sin(alpha_n x) sin(beta_m y) with
  alpha_n = n pi / a, beta_m = m pi / b (maximum 1, not mass-normalised).
* Every mode has the same modal mass M = rho h a b / 4 and the natural frequency
  omega_nm = sqrt(B'/m'') (alpha_n^2 + beta_m^2), B' = E h^3 / (12 (1 - nu^2)), m'' = rho h
  (Feldmann 2012, Eq. 5; Leissa, *Vibration of Plates*, NASA SP-160 (1969), §4.1).
* Deflection is positive in the direction of the applied point force; compliances are in m/N and
  mobilities (velocity / force) in m/(N s).

The static Green's function is the Levy single series (Timoshenko & Woinowsky-Krieger, *Theory
of Plates and Shells*, 2nd ed. (1959), §§ 30, 36) written with the method of images across the
strip; each image's sum over the half-wave number is evaluated in closed form with
polylogarithms, so the result is exact to rounding error and costs a few hundred operations per
pair of points (see :func:`static_compliance`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from roughvib._cache import cached_arrays, code_fingerprint
from roughvib.scene import Plate

__all__ = [
    "PlateModes",
    "infinite_plate_mobility",
    "mode_shapes",
    "plate_modes",
    "point_mobility",
    "residual_compliance",
    "static_compliance",
    "transfer_mobility",
]

# largest number of (mode x frequency) complex entries held at once by the mobility functions
_CHUNK = 1 << 21


@dataclass(frozen=True)
class PlateModes:
    """The kept modes of a simply supported plate, in ascending frequency.

    Attributes
    ----------
    n : ndarray of int, shape (R,)
        Half-wave number along x (plate length a).
    m : ndarray of int, shape (R,)
        Half-wave number along y (plate width b).
    omega : ndarray of float, shape (R,)
        Angular natural frequencies omega_r [rad/s], ascending.
    modal_mass : float
        M_r = rho h a b / 4 [kg], the same for every mode (shapes have maximum 1).
    damping_ratio : ndarray of float, shape (R,)
        Modal damping ratio zeta_r = loss_factor / 2 [-].
    length, width : float
        Plate length a and width b [m] (needed to evaluate the shapes).
    """

    n: np.ndarray
    m: np.ndarray
    omega: np.ndarray
    modal_mass: float
    damping_ratio: np.ndarray
    length: float
    width: float

    @property
    def frequency(self) -> np.ndarray:
        """Natural frequencies f_r = omega_r / (2 pi) [Hz], shape (R,)."""
        return self.omega / (2.0 * np.pi)

    def __len__(self) -> int:
        return int(self.omega.size)


def plate_modes(plate: Plate, max_frequency: float | None = None) -> PlateModes:
    """All modes (n, m) of the simply supported plate with f_nm <= max_frequency.

    Parameters
    ----------
    plate : Plate
        Geometry and material; ``plate.kind`` is not looked at.
    max_frequency : float, optional
        Upper frequency limit [Hz] (inclusive). Defaults to ``plate.max_frequency``.

    Returns
    -------
    PlateModes
        R modes in ascending frequency (ties in (n, m) order); R may be 0.

    Raises
    ------
    ValueError
        ``max_frequency`` is not a positive finite number.

    Notes
    -----
    omega_nm = sqrt(B'/m'') ((n pi / a)^2 + (m pi / b)^2), the exact Kirchhoff frequencies of a
    simply supported rectangular plate (Leissa 1969, Eq. 4.3; paper Eq. 5).
    """
    fmax = plate.max_frequency if max_frequency is None else float(max_frequency)
    if not (math.isfinite(fmax) and fmax > 0.0):
        raise ValueError(f"max_frequency must be a finite number > 0 Hz, got {max_frequency}")
    a, b = plate.length, plate.width
    c = plate.wave_speed_factor
    wmax = 2.0 * math.pi * fmax
    kmax = math.sqrt(wmax / c)  # largest wavenumber [rad/m]
    n_max = int(kmax * a / math.pi) + 1
    m_max = int(kmax * b / math.pi) + 1
    n, m = np.meshgrid(np.arange(1, n_max + 1), np.arange(1, m_max + 1), indexing="ij")
    n, m = n.ravel(), m.ravel()
    omega = plate.mode_omega(n, m)
    keep = plate.keeps_mode(omega, fmax)
    n, m, omega = n[keep], m[keep], omega[keep]
    order = np.lexsort((m, n, omega))
    return PlateModes(
        n=n[order].astype(np.int64),
        m=m[order].astype(np.int64),
        omega=omega[order],
        modal_mass=plate.mass_per_area * a * b / 4.0,
        damping_ratio=np.full(order.size, plate.loss_factor / 2.0),
        length=a,
        width=b,
    )


def mode_shapes(modes: PlateModes, x: ArrayLike, y: ArrayLike) -> np.ndarray:
    """Mode shapes phi_r(x_p, y_p) = sin(n pi x / a) sin(m pi y / b) at P points.

    Parameters
    ----------
    modes : PlateModes
    x, y : array_like, shape (P,) or scalar
        Plate coordinates of the points [m].

    Returns
    -------
    ndarray, shape (R, P)
        Dimensionless shape values (maximum 1).
    """
    x = np.atleast_1d(np.asarray(x, dtype=float))
    y = np.atleast_1d(np.asarray(y, dtype=float))
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"x and y must be 1-D arrays of equal length, got shapes {x.shape} "
                         f"and {y.shape}")
    return (np.sin(np.outer(modes.n, x) * (math.pi / modes.length))
            * np.sin(np.outer(modes.m, y) * (math.pi / modes.width)))


# --------------------------------------------------------------------------------------------
# static Green's function
# --------------------------------------------------------------------------------------------

# The near branch of the polylogarithm expands in mu = ln z for |mu| <= sqrt(1 + pi^2) = 3.3;
# the terms fall like 2 (|mu| / 2 pi)^k <= 2 * 0.53^k, so 64 terms reach 1e-17.
_LI_TERMS = 64
# The far branch (Re mu < -1, |z| < 1/e) sums z^n / n^s directly; 40 terms reach e^-40.
_LI_DIRECT = 40


@lru_cache(maxsize=4)
def _li_coefficients(s: int) -> np.ndarray:
    """Taylor coefficients c_k of Li_s(e^mu) - mu^(s-1)/(s-1)! (-ln(-mu)), k = 0.._LI_TERMS-1.

    c_k = zeta(s - k) / k! for k != s - 1 and c_(s-1) = H_(s-1) / (s-1)! (harmonic number).
    Kept in the on-disk cache (``roughvib._cache``, exact): computing them needs
    ``scipy.special``, whose import costs a run more than the whole residual compliance.
    """
    arrays, _ = cached_arrays("polylog-coefficients", {"s": int(s), "terms": _LI_TERMS},
                              lambda: {"c": _li_coefficients_computed(s)},
                              code=code_fingerprint([__file__]))
    return arrays["c"]


def _li_coefficients_computed(s: int) -> np.ndarray:
    from scipy.special import zeta  # only when the coefficients are not in the cache

    k = np.arange(_LI_TERMS)
    c = np.empty(_LI_TERMS)
    for kk in k:
        if kk == s - 1:
            c[kk] = sum(1.0 / j for j in range(1, s)) / math.factorial(s - 1)
        else:
            c[kk] = zeta(float(s - kk)) / math.factorial(int(kk))
    return c


def _polylog_exp(s: int, mu: np.ndarray) -> np.ndarray:
    """Polylogarithm Li_s(e^mu) for integer s >= 2 and Re(mu) <= 0, elementwise.

    Parameters
    ----------
    s : int
        Order (2 or 3 here).
    mu : ndarray of complex
        Logarithm of the argument; Re(mu) <= 0 (|z| <= 1).

    Returns
    -------
    ndarray of complex, same shape as ``mu``

    Notes
    -----
    For |z| >= 1/e the expansion in mu = ln z,
    Li_s(e^mu) = mu^(s-1)/(s-1)! [H_(s-1) - ln(-mu)] + sum_(k != s-1) zeta(s-k) mu^k / k!,
    valid for |mu| < 2 pi (D. C. Wood, "The computation of polylogarithms", Tech. Rep. 15-92,
    University of Kent (1992); DLMF §25.12(ii)) is used after Im(mu) is reduced to (-pi, pi];
    for |z| < 1/e the defining series sum z^n / n^s.
    """
    mu = np.asarray(mu, dtype=complex)
    mu = mu.real + 1j * (np.pi - np.mod(np.pi - mu.imag, 2.0 * np.pi))
    out = np.empty(mu.shape, dtype=complex)
    near = mu.real >= -1.0

    w = mu[near]
    c = _li_coefficients(s)
    acc = np.full(w.shape, c[-1], dtype=complex)
    for ck in c[-2::-1]:
        acc = acc * w + ck
    nonzero = w != 0
    safe = np.where(nonzero, w, 1.0)
    log_term = np.where(nonzero, safe ** (s - 1) * np.log(-safe), 0.0)
    out[near] = acc - log_term / math.factorial(s - 1)

    z = np.exp(mu[~near])
    acc = np.zeros(z.shape, dtype=complex)
    zn = np.ones(z.shape, dtype=complex)
    for j in range(1, _LI_DIRECT + 1):
        zn = zn * z
        acc += zn / float(j) ** s
    out[~near] = acc
    return out


def _levy_image_sum(kappa: np.ndarray, theta_1: np.ndarray, theta_2: np.ndarray) -> np.ndarray:
    """S = sum_(n>=1) sin(n th1) sin(n th2) (1 + n kappa) exp(-n kappa) / n^3 in closed form.

    With sin sin = [cos(n (th1 - th2)) - cos(n (th1 + th2))] / 2 and z = exp(-kappa + i theta),
    S = Re[F(th1 - th2) - F(th1 + th2)] / 2, F = Li_3(z) + kappa Li_2(z). All arrays broadcast.
    """
    kappa, t1, t2 = np.broadcast_arrays(kappa, theta_1, theta_2)
    # one call per order: stack the difference and the sum angles
    mu = np.stack([-kappa + 1j * (t1 - t2), -kappa + 1j * (t1 + t2)])
    f = _polylog_exp(3, mu) + kappa * _polylog_exp(2, mu)
    return 0.5 * (f[0].real - f[1].real)


# images farther than this (in units of kappa = pi d / L) add less than (1 + 45) e^-45 ~ 1e-18
# of the series scale, i.e. nothing in double precision
_KAPPA_CUTOFF = 45.0


def static_compliance(plate: Plate, points: ArrayLike) -> np.ndarray:
    """Exact static compliance matrix (Green's function) of the plate between points [m/N].

    G[i, j] is the static deflection at point j per unit normal force at point i; it equals the
    converged Navier double series 4/(a b B') sum_nm phi_nm(i) phi_nm(j) / (alpha_n^2 +
    beta_m^2)^2 = sum over all modes of phi_r(i) phi_r(j) / (M omega_r^2).

    Parameters
    ----------
    plate : Plate
    points : array_like, shape (P, 2) or (2,)
        Plate coordinates (x, y) [m], inside or on the boundary of [0, a] x [0, b].

    Returns
    -------
    ndarray, shape (P, P)
        Symmetric; positive definite for distinct interior points. The diagonal (point
        compliance) is finite for a Kirchhoff plate.

    Raises
    ------
    ValueError
        ``points`` has the wrong shape or a point is off the plate.

    Notes
    -----
    Levy form (Timoshenko & Woinowsky-Krieger 1959, §36): with the series taken along the
    shorter side L1 (index n, theta = n pi u / L1) and the other side L2, the 1-D Green's
    function of D (d^2/dv^2 - alpha^2)^2 on the infinite line is
    ``(1 + alpha |d|) exp(-alpha |d|) / (4 alpha^3)``; odd images of the source about v = 0 and
    v = L2 (sources at v1 + 2 j L2 with sign +1 and -v1 + 2 j L2 with sign -1) satisfy
    w = w'' = 0 on both edges. Hence::

        G = L1^2 / (2 pi^3 B') sum_images sign S(kappa, pi u1 / L1, pi u2 / L1),
        kappa = pi |v2 - v_image| / L1,

    with S summed over n in closed form by ``_levy_image_sum``. The direct term carries the
    slow n^-3 convergence of the point compliance; evaluating it in closed form removes every
    truncation error, and the images decay like exp(-2 pi ``|j|`` L2 / L1), so all with
    kappa < 45 are kept (a handful for any aspect ratio).
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1:
        pts = pts[None, :]
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (P, 2), got {np.shape(points)}")
    a, b = plate.length, plate.width
    off = ((pts[:, 0] < 0.0) | (pts[:, 0] > a) | (pts[:, 1] < 0.0) | (pts[:, 1] > b)
           | ~np.isfinite(pts).all(axis=1))
    if off.any():
        raise ValueError(f"points must lie on the plate [0, {a}] x [0, {b}] m, got "
                         f"{pts[off][0].tolist()}")
    # series along the shorter side keeps the number of images small
    if a <= b:
        L1, L2, u, v = a, b, pts[:, 0], pts[:, 1]
    else:
        L1, L2, u, v = b, a, pts[:, 1], pts[:, 0]
    P = pts.shape[0]
    iu, ju = np.triu_indices(P)
    th1, th2 = np.pi * u[iu] / L1, np.pi * u[ju] / L1
    v1, v2 = v[iu], v[ju]
    j_max = int(math.ceil((_KAPPA_CUTOFF * L1 / math.pi + 2.0 * L2) / (2.0 * L2)))
    j = np.arange(-j_max, j_max + 1)[:, None]
    # (images, pairs): distances of the +1 images and of the -1 images from the response point
    d_plus = np.abs(v2 - v1 + 2.0 * j * L2)
    d_minus = np.abs(v2 + v1 + 2.0 * j * L2)
    dist = np.concatenate([d_plus, d_minus])
    sign = np.concatenate([np.ones_like(d_plus), -np.ones_like(d_minus)])
    kappa = np.pi * dist / L1
    used = kappa < _KAPPA_CUTOFF
    total = np.zeros(iu.size)
    cols = np.broadcast_to(np.arange(iu.size), kappa.shape)[used]
    s_val = _levy_image_sum(kappa[used], th1[cols], th2[cols])
    np.add.at(total, cols, sign[used] * s_val)
    total *= L1**2 / (2.0 * np.pi**3 * plate.bending_stiffness)
    G = np.empty((P, P))
    G[iu, ju] = total
    G[ju, iu] = total
    return G


def _check_modes(plate: Plate, modes: PlateModes) -> None:
    if not (math.isclose(plate.length, modes.length) and math.isclose(plate.width, modes.width)):
        raise ValueError(f"modes belong to a {modes.length} x {modes.width} m plate, not to the "
                         f"{plate.length} x {plate.width} m plate given")


def residual_compliance(plate: Plate, modes: PlateModes, points: ArrayLike) -> np.ndarray:
    """Static compliance of the modes left out of ``modes`` between points [m/N].

    C_res = G_static,exact - sum_(r in modes) phi_r(i) phi_r(j) / (M omega_r^2)
    (docs/theory.md), the quasi-static flexibility of the truncated modes.

    Parameters
    ----------
    plate : Plate
        The plate the modes were computed for.
    modes : PlateModes
        The kept modes (all modes below a cut-off, as from :func:`plate_modes`).
    points : array_like, shape (P, 2) or (2,)
        Plate coordinates (x, y) [m].

    Returns
    -------
    ndarray, shape (P, P)
        Symmetric, positive semi-definite (a sum of the rank-one terms of the missing modes).
        At a point, about (2 / pi) Y_inf / omega_max for a full mode set up to omega_max.
    """
    _check_modes(plate, modes)
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1:
        pts = pts[None, :]
    G = static_compliance(plate, pts)
    phi = mode_shapes(modes, pts[:, 0], pts[:, 1])
    flex = phi / (modes.modal_mass * modes.omega[:, None] ** 2)
    return G - flex.T @ phi


def transfer_mobility(plate: Plate, modes: PlateModes, excitation: ArrayLike,
                      response: ArrayLike, freqs: ArrayLike, *,
                      residual: bool = False) -> np.ndarray:
    """Transfer mobility: velocity at ``response`` per unit force at ``excitation`` [m/(N s)].

    Y(omega) = i omega sum_r phi_r(e) phi_r(o) / (M (omega_r^2 - omega^2 + 2 i zeta_r omega_r
    omega)), plus i omega C_res(e, o) if ``residual`` (time convention exp(+i omega t)).

    Parameters
    ----------
    plate : Plate
    modes : PlateModes
    excitation, response : array_like, shape (2,)
        Plate coordinates (x, y) of the force and of the response point [m].
    freqs : array_like, shape (F,)
        Frequencies [Hz].
    residual : bool, optional
        Add the static compliance of the truncated modes (:func:`residual_compliance`).

    Returns
    -------
    ndarray of complex, shape (F,)
        Reciprocal: swapping ``excitation`` and ``response`` gives the same result.
    """
    _check_modes(plate, modes)
    pe = np.asarray(excitation, dtype=float).reshape(2)
    po = np.asarray(response, dtype=float).reshape(2)
    w = 2.0 * np.pi * np.atleast_1d(np.asarray(freqs, dtype=float))
    phi = mode_shapes(modes, [pe[0], po[0]], [pe[1], po[1]])
    num = phi[:, 0] * phi[:, 1] / modes.modal_mass
    wr = modes.omega
    cr = 2.0 * modes.damping_ratio * wr
    receptance = np.zeros(w.size, dtype=complex)
    step = max(1, _CHUNK // max(1, wr.size))
    for lo in range(0, w.size, step):
        wc = w[lo:lo + step]
        den = wr[:, None] ** 2 - wc[None, :] ** 2 + 1j * cr[:, None] * wc[None, :]
        receptance[lo:lo + step] = num @ (1.0 / den)
    if residual:
        receptance += residual_compliance(plate, modes, np.array([pe, po]))[0, 1]
    return 1j * w * receptance


def point_mobility(plate: Plate, modes: PlateModes, point: ArrayLike, freqs: ArrayLike, *,
                   residual: bool = False) -> np.ndarray:
    """Point (driving-point) mobility Y = v / F at one point [m/(N s)].

    Parameters
    ----------
    plate : Plate
    modes : PlateModes
    point : array_like, shape (2,)
        Plate coordinates (x, y) [m].
    freqs : array_like, shape (F,)
        Frequencies [Hz].
    residual : bool, optional
        Add i omega C_res of the truncated modes.

    Returns
    -------
    ndarray of complex, shape (F,)
        Re(Y) >= 0 at every frequency (a passive point); see :func:`transfer_mobility`.
    """
    return transfer_mobility(plate, modes, point, point, freqs, residual=residual)


def infinite_plate_mobility(plate: Plate) -> float:
    """Point mobility of the infinite plate, Y_inf = 1 / (8 sqrt(B' m'')) [m/(N s)].

    Real and frequency-independent (Cremer, Heckl & Petersson, *Structure-Borne Sound*, 3rd ed.
    (2005), §5.3); the band average of Re(Y) of the finite plate tends to it.
    """
    return 1.0 / (8.0 * math.sqrt(plate.bending_stiffness * plate.mass_per_area))
