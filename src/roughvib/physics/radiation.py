"""Sound radiation of the baffled simply supported plate: modal radiation efficiencies.

This module owns the acoustics of the plate (docs/radiation.md): the coincidence frequency, the
radiation efficiency of each simply supported mode and the mutual efficiency of a pair of modes
(exact far-field integral of Wallace 1972), the low-frequency closed form of Wallace for the
tests, and the sound power of a point-driven infinite plate (the reference the modal sum of a
large plate tends to).

Conventions
-----------
* The plate lies in an infinite rigid baffle and radiates into air on one side (``sides=2``
  doubles the power of a plate in free field whose two sides do not interact, the usual
  approximation for a baffled plate radiating into two half spaces).
* Mode r <-> (n, m), shape sin(n pi x / a) sin(m pi y / b) (maximum 1, as
  :mod:`roughvib.physics.plate`); its space average of the square is 1/4.
* The radiation efficiency of mode r at angular frequency omega is
  sigma_r = W_r / (rho0 c0 S <v_r^2>), W_r the power radiated by the mode vibrating at omega
  with velocity amplitude 1 (so <v_r^2> = 1/8 over space and time) and S = a b.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from roughvib.scene import Plate

__all__ = [
    "AIR_DENSITY",
    "SHAPE_MEAN_SQUARE",
    "SOUND_SPEED",
    "coincidence_frequency",
    "infinite_plate_point_force_power",
    "modal_pressure",
    "modal_radiation_efficiency",
    "mutual_radiation_efficiency",
    "wallace_low_frequency",
]

#: density of air at 20 °C and 101.325 kPa [kg/m^3]
AIR_DENSITY = 1.204
#: speed of sound in air at 20 °C [m/s]
SOUND_SPEED = 343.0
#: space average of sin^2(n pi x / a) sin^2(m pi y / b) over the plate [-]
SHAPE_MEAN_SQUARE = 0.25

# Gauss-Legendre panels of the far-field integral: nodes per panel, and nodes per unit of
# k * max(a, b) (the integrand's peaks are about 2 pi / (k a) wide in angle; 2 nodes per unit
# put about 13 nodes across each peak); never fewer than _MIN_NODES per angle
_PANEL = 8
_NODES_PER_KA = 2.0
_MIN_NODES = 48


def coincidence_frequency(plate: Plate, sound_speed: float = SOUND_SPEED) -> float:
    """Coincidence (critical) frequency f_c = c0^2 / (2 pi) sqrt(m'' / B') [Hz].

    Above it the free bending wavenumber is smaller than the acoustic one and resonant modes
    radiate with efficiency near 1 (Cremer, Heckl & Petersson, *Structure-Borne Sound*, 3rd
    ed. (2005), chapter 7). 3 mm steel in air: about 4 kHz.
    """
    return sound_speed**2 / (2.0 * math.pi) * math.sqrt(plate.mass_per_area
                                                        / plate.bending_stiffness)


def _gauss_angles(k: float, size: float) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss-Legendre nodes and weights on [0, pi/2] fine enough for k * size."""
    n = max(_MIN_NODES, int(math.ceil(_NODES_PER_KA * k * size)))
    panels = int(math.ceil(n / _PANEL))
    x, w = np.polynomial.legendre.leggauss(_PANEL)
    edges = np.linspace(0.0, 0.5 * math.pi, panels + 1)
    half = 0.5 * np.diff(edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    nodes = (mid[:, None] + half[:, None] * x[None, :]).ravel()
    weights = (half[:, None] * w[None, :]).ravel()
    return nodes, weights


def _edge_factor(order: np.ndarray, arg: np.ndarray) -> np.ndarray:
    """A_n(alpha) = cs(alpha/2) / (n ((alpha / (n pi))^2 - 1)), cs = cos (n odd) or sin (even).

    The Fourier transform of sin(n pi x / a) on [0, a] at wavenumber kx = alpha / a is
    e^(-i alpha/2) (i for even n) * (-2 a / pi) A_n(alpha). At alpha = n pi (a removable
    0/0) the limit is -(n pi / 4) sin(n pi / 2) / n (odd n) or (n pi / 4) cos(n pi / 2) / n
    (even n).

    Parameters
    ----------
    order : ndarray of int, shape (N,)
    arg : ndarray, shape (P,)
        alpha = kx a >= 0 at the quadrature nodes.

    Returns
    -------
    ndarray, shape (N, P)
    """
    n = order[:, None].astype(float)
    odd = (order % 2 == 1)[:, None]
    half = 0.5 * arg[None, :]
    num = np.where(odd, np.cos(half), np.sin(half))
    ratio = arg[None, :] / (n * math.pi)
    den = ratio * ratio - 1.0
    near = np.abs(den) < 1e-7
    limit = np.where(odd, -np.sin(0.5 * n * math.pi), np.cos(0.5 * n * math.pi)) * math.pi / 4.0
    safe = np.where(near, 1.0, den)
    return np.where(near, limit, num / (n * safe))


def _far_field_factors(n: np.ndarray, m: np.ndarray, a: float, b: float, k: float
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Edge factors of the distinct orders at the quadrature nodes, weights and the prefactor.

    Returns ``(An, Bm, w, c)`` with ``An`` (len(unique n), P), ``Bm`` (len(unique m), P),
    ``w`` (P,) the node weights times sin(theta), and ``c = 64 k^2 a b / pi^6`` so that
    sigma_(nm,n'm') = c * sum_P An An' Bm Bm' w.
    """
    th, wt = _gauss_angles(k, max(a, b))
    ph, wp = _gauss_angles(k, max(a, b))
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    st = np.sin(TH).ravel()
    w = (wt[:, None] * wp[None, :]).ravel() * st
    alpha = k * a * st * np.cos(PH).ravel()
    beta = k * b * st * np.sin(PH).ravel()
    An = _edge_factor(np.asarray(n), alpha)
    Bm = _edge_factor(np.asarray(m), beta)
    return An, Bm, w, 64.0 * k * k * a * b / math.pi**6


def modal_radiation_efficiency(n: ArrayLike, m: ArrayLike, length: float, width: float,
                               freqs: ArrayLike, sound_speed: float = SOUND_SPEED
                               ) -> np.ndarray:
    """Radiation efficiency of simply supported plate modes in an infinite baffle.

    Parameters
    ----------
    n, m : array_like of int, shape (R,)
        Half-wave numbers along x (length a) and y (width b), >= 1.
    length, width : float
        a, b [m].
    freqs : array_like, shape (F,)
        Frequencies of vibration [Hz], > 0.
    sound_speed : float
        c0 [m/s].

    Returns
    -------
    ndarray, shape (R, F)
        sigma_r(f) [-], one side.

    Notes
    -----
    The exact far-field integral of Wallace (C. E. Wallace, "Radiation resistance of a
    rectangular panel", J. Acoust. Soc. Am. 51 (1972) 946-952, Eq. 5)::

        sigma = 64 k^2 a b / (pi^6 n^2 m^2) int_0^(pi/2) int_0^(pi/2)
                [cs(alpha/2) / ((alpha/(n pi))^2 - 1)]^2 [cs(beta/2) / ((beta/(m pi))^2 - 1)]^2
                sin(theta) dtheta dphi,
        alpha = k a sin(theta) cos(phi), beta = k b sin(theta) sin(phi),

    cs = cos for odd and sin for even orders, is evaluated with composite Gauss-Legendre
    quadrature of about 2 k max(a, b) nodes per angle (the integrand's peaks, at alpha = n pi
    and beta = m pi, are resolved by about 13 nodes each; 3 k max(a, b) nodes change the
    paper run's band powers by less than 1e-8 dB). All modes share the nodes, so the cost is
    that of one matrix product per frequency.
    """
    n = np.atleast_1d(np.asarray(n, dtype=np.int64))
    m = np.atleast_1d(np.asarray(m, dtype=np.int64))
    f = np.atleast_1d(np.asarray(freqs, dtype=float))
    if n.shape != m.shape or n.ndim != 1 or np.any(n < 1) or np.any(m < 1):
        raise ValueError("n and m must be 1-D arrays of equal length of integers >= 1")
    if np.any(~(f > 0)) or not np.all(np.isfinite(f)):
        raise ValueError("freqs must be finite and > 0 Hz")
    un, n_idx = np.unique(n, return_inverse=True)
    um, m_idx = np.unique(m, return_inverse=True)
    out = np.empty((n.size, f.size))
    for j, fj in enumerate(f):
        k = 2.0 * math.pi * fj / sound_speed
        An, Bm, w, c = _far_field_factors(un, um, length, width, k)
        table = (An * An * w) @ (Bm * Bm).T  # (unique n, unique m)
        out[:, j] = c * table[n_idx, m_idx]
    return out


def mutual_radiation_efficiency(n: ArrayLike, m: ArrayLike, length: float, width: float,
                                freq: float, sound_speed: float = SOUND_SPEED) -> np.ndarray:
    """Matrix of mutual radiation efficiencies sigma_rs of simply supported modes at one
    frequency.

    Parameters
    ----------
    n, m : array_like of int, shape (R,)
        Half-wave numbers of the modes.
    length, width : float
        a, b [m].
    freq : float
        Frequency [Hz].
    sound_speed : float
        c0 [m/s].

    Returns
    -------
    ndarray, shape (R, R)
        Symmetric; the diagonal is :func:`modal_radiation_efficiency`. With modal velocity
        amplitudes V_r (complex, at ``freq``), the radiated power of one side is
        ``rho0 c0 S / 8 * Re(V^H sigma V)``; neglecting the off-diagonal terms gives
        ``rho0 c0 S / 8 * sum_r sigma_rr |V_r|^2``. Pairs whose orders differ in parity along x
        or along y do not couple (their far fields are odd and even about the plate centre)
        and have sigma_rs = 0 exactly.

    Notes
    -----
    The same far-field integral as :func:`modal_radiation_efficiency` with the product of the
    two modes' edge factors in place of the square (Wallace 1972, for the cross terms).
    """
    n = np.atleast_1d(np.asarray(n, dtype=np.int64))
    m = np.atleast_1d(np.asarray(m, dtype=np.int64))
    k = 2.0 * math.pi * float(freq) / sound_speed
    An, Bm, w, c = _far_field_factors(n, m, length, width, k)
    G = An[:, None, :] * An[None, :, :]  # (R, R, P) is fine for the few dozen modes of a band
    H = Bm[:, None, :] * Bm[None, :, :]
    sig = c * np.einsum("rsp,rsp,p->rs", G, H, w)
    same = ((n[:, None] - n[None, :]) % 2 == 0) & ((m[:, None] - m[None, :]) % 2 == 0)
    return np.where(same, sig, 0.0)


def modal_pressure(n: ArrayLike, m: ArrayLike, length: float, width: float,
                   points: ArrayLike, freqs: ArrayLike, *, air_density: float = AIR_DENSITY,
                   sound_speed: float = SOUND_SPEED, spacing: float | None = None
                   ) -> np.ndarray:
    """Sound pressure at field points per unit modal velocity, by the Rayleigh integral.

    Parameters
    ----------
    n, m : array_like of int, shape (R,)
        Half-wave numbers of the modes.
    length, width : float
        a, b [m].
    points : array_like, shape (M, 3)
        Field points [x, y, z] [m] in the plate's frame, z > 0 (the radiating side).
    freqs : array_like, shape (F,)
        Frequencies [Hz].
    air_density, sound_speed : float
        rho0 [kg/m^3], c0 [m/s].
    spacing : float, optional
        Side of the patches the plate is cut into [m]; by default the smaller of a tenth of
        the shortest acoustic wavelength and a sixteenth of the shortest half wave of the
        modes (at least 16 patches along each side).

    Returns
    -------
    ndarray of complex, shape (M, R, F)
        G with p(x, f) = sum_r G_r(x, f) V_r(f), V_r the complex amplitude of the modal
        velocity (time convention exp(+i omega t)) [Pa s/m].

    Notes
    -----
    Rayleigh's first integral for a plate in an infinite rigid baffle,
    p(x) = i omega rho0 / (2 pi) int v(x') exp(-i k R) / R dS', R = ``|x - x'|``, by the
    midpoint rule on the patches (an error O(h^2); exact as the patches shrink, in the near as
    in the far field).
    """
    n = np.atleast_1d(np.asarray(n, dtype=np.int64))
    m = np.atleast_1d(np.asarray(m, dtype=np.int64))
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    f = np.atleast_1d(np.asarray(freqs, dtype=float))
    if pts.shape[1] != 3:
        raise ValueError("points must have shape (M, 3) with z > 0 m")
    _, _, height = pts.T
    if np.any(height <= 0):
        raise ValueError("points must have shape (M, 3) with z > 0 m")
    if spacing is None:
        spacing = min(sound_speed / f.max() / 10.0,
                      min(length / n.max(), width / m.max()) / 16.0)
    nx = max(16, int(math.ceil(length / spacing)))
    ny = max(16, int(math.ceil(width / spacing)))
    x = (np.arange(nx) + 0.5) * length / nx
    y = (np.arange(ny) + 0.5) * width / ny
    dS = length * width / (nx * ny)
    sx = np.sin(np.outer(n, x) * (math.pi / length))  # (R, nx)
    sy = np.sin(np.outer(m, y) * (math.pi / width))   # (R, ny)
    out = np.empty((pts.shape[0], n.size, f.size), dtype=complex)
    k = 2.0 * math.pi * f / sound_speed
    for i, (px, py, pz) in enumerate(pts):
        R = np.sqrt((x[:, None] - px) ** 2 + (y[None, :] - py) ** 2 + pz**2)  # (nx, ny)
        for j, kj in enumerate(k):
            kern = np.exp(-1j * kj * R) / R
            # sum_xy sx[r, x] sy[r, y] kern[x, y]
            out[i, :, j] = np.einsum("rx,xy,ry->r", sx, kern, sy, optimize=True)
        out[i] *= (1j * 2.0 * math.pi * f * air_density / (2.0 * math.pi) * dS)[None, :]
    return out


def wallace_low_frequency(n: int, m: int, length: float, width: float, freq: float,
                          sound_speed: float = SOUND_SPEED) -> float:
    """Wallace's low-frequency approximation of the radiation efficiency of an odd-odd mode.

    sigma ~ 32 k^2 a b / (pi^5 n^2 m^2) {1 - k^2 a b / 12 [(1 - 8 / (n pi)^2) a / b
    + (1 - 8 / (m pi)^2) b / a]} (Wallace 1972, Eq. 6, in this module's naming: n along a),
    valid for k a, k b << 1 (well below the mode's own acoustic "coincidence").

    Parameters
    ----------
    n, m : int
        Odd half-wave numbers.
    length, width, freq, sound_speed : float
        a, b [m], f [Hz], c0 [m/s].

    Returns
    -------
    float
        sigma [-].
    """
    if n % 2 == 0 or m % 2 == 0:
        raise ValueError(f"wallace_low_frequency is for odd-odd modes, got ({n}, {m})")
    a, b = length, width
    k = 2.0 * math.pi * freq / sound_speed
    corr = (k * k * a * b / 12.0) * ((1.0 - 8.0 / (n * math.pi) ** 2) * a / b
                                     + (1.0 - 8.0 / (m * math.pi) ** 2) * b / a)
    return 32.0 * k * k * a * b / (math.pi**5 * n * n * m * m) * (1.0 - corr)


def infinite_plate_point_force_power(plate: Plate, force_rms: float, freq: ArrayLike, *,
                                     air_density: float = AIR_DENSITY,
                                     sound_speed: float = SOUND_SPEED) -> np.ndarray:
    """Sound power radiated to one side by an undamped infinite plate under a point force,
    below coincidence [W].

    Parameters
    ----------
    plate : Plate
        Bending stiffness B' and mass per area m'' (the plate's size is not used).
    force_rms : float
        rms of the harmonic point force [N].
    freq : array_like
        Frequencies [Hz], below the coincidence frequency.
    air_density, sound_speed : float
        rho0 [kg/m^3], c0 [m/s].

    Returns
    -------
    ndarray, shape of ``freq``
        W = rho0 F_rms^2 / (2 pi c0 m''^2) * I(f / f_c),
        I = int_0^(pi/2) sin(t) / (1 - (f / f_c)^2 sin^4(t))^2 dt.

    Notes
    -----
    The velocity spectrum of the infinite plate driven by F is
    V(k_t) = i omega F / (B' k_t^4 - m'' omega^2) and only wavenumbers k_t < k radiate:
    ``W = rho0 omega / (8 pi^2) int |V|^2 / sqrt(k^2 - k_t^2) d^2k_t`` (amplitudes). With
    k_t = k sin(t) this is the expression above; far below coincidence I -> 1 and
    W = rho0 F_rms^2 / (2 pi c0 m''^2), independent of frequency (the near-field radiation of a
    point-excited plate: Cremer, Heckl & Petersson, *Structure-Borne Sound*, 3rd ed. (2005),
    chapter 7; F. Fahy and P. Gardonio, *Sound and Structural Vibration*, 2nd ed. (2007),
    chapter 3). I(0.25) = 1.07.
    """
    f = np.asarray(freq, dtype=float)
    fc = coincidence_frequency(plate, sound_speed)
    r2 = (f / fc) ** 2
    if np.any(r2 >= 1.0):
        raise ValueError(f"infinite_plate_point_force_power is for frequencies below "
                         f"coincidence ({fc:.0f} Hz), got {np.max(f)} Hz")
    t, w = np.polynomial.legendre.leggauss(64)
    t = 0.25 * math.pi * (t + 1.0)
    w = 0.25 * math.pi * w
    s = np.sin(t)
    integral = np.sum(w * s / (1.0 - np.multiply.outer(r2, s**4)) ** 2, axis=-1)
    m2 = plate.mass_per_area**2
    return air_density * force_rms**2 / (2.0 * math.pi * sound_speed * m2) * integral
