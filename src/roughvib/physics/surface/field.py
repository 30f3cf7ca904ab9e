"""The rough surface as a field, and the contact filter (docs/theory.md, "The input field").

A synthetic surface is one periodic function of the profile coordinate s,

    z(s) = Re sum_j c_j exp(i k_j s),   k_j = 2 pi j / P,   j = 0 .. J,

with P = ``roughness.trace_length`` and J = floor(P / lambda_min) (the tail's shortest
wavelength). A seed fixes the phases of the c_j in the order of j, and the PSD fixes their
moduli, so one seed and one PSD give one surface: sampling it on a finer grid resolves the
same surface more finely, and carrying the tail to a shorter wavelength adds bins without
touching the others (:class:`SurfaceSpectrum`, :func:`synthetic_spectrum`).

What one contact sees is that surface averaged over its real contact spot. A Hertz spot of
radius a presses with p(r) ~ sqrt(1 - r^2 / a^2); integrated across the track, its weight along
the track is w(x) ~ 1 - x^2 / a^2 on ``|x| < a``, and the normalised Fourier transform of that
parabola is the contact filter (:func:`hertz_filter`)

    H(q) = 3 (sin q - q cos q) / q^3,   q = k a,

1 at q = 0, -3 dB at q = 1.81, first zero at q = 4.493, falling as 3 / q^2 beyond.

:func:`input_band` resolves a scene's ``"auto"`` tail limit and grid: the tail is carried to
the wavelength that the rms sliding speed maps to the top of the output band, so that no band
level shown depends on where the tail stops; the grid takes four samples per shortest
wavelength of the filtered field (eight without the contact filter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "MAX_BINS",
    "PAPER_SHORTEST_WAVELENGTH",
    "InputBand",
    "SurfaceSpectrum",
    "hertz_filter",
    "input_band",
    "scene_speed",
    "synthetic_spectrum",
]

#: most Fourier bins a synthetic surface carries (the tail stops at trace_length / MAX_BINS:
#: 38 nm for the 0.16 m trace); sampling such a surface takes an FFT of 2 MAX_BINS points
MAX_BINS = 2**22
#: the short end of the paper's measured band [m]; an ``"auto"`` tail never stops above it
PAPER_SHORTEST_WAVELENGTH = 50e-6
#: samples per shortest wavelength of the ``"auto"`` grid, with and without the contact
#: filter: the filtered field holds little near its band edge, the unfiltered one its tail
SAMPLES_PER_WAVELENGTH = {"hertz": 4, "none": 8}


def hertz_filter(q: np.ndarray | float) -> np.ndarray:
    """Contact filter of a Hertz spot: 3 (sin q - q cos q) / q^3.

    The normalised Fourier transform of the along-track weight ``1 - x^2/a^2`` (``|x| < a``),
    which is the Hertz pressure of a spot of radius a integrated across the track.

    Parameters
    ----------
    q : array_like
        k a: angular wavenumber [rad/m] times the spot radius [m], >= 0.

    Returns
    -------
    ndarray
        H(q) [-], the shape of ``q``; 1 at q = 0 (series 1 - q^2/10 + q^4/280 below
        q = 1e-2, where the closed form loses digits).
    """
    q = np.asarray(q, dtype=float)
    out = np.empty_like(q)
    small = np.abs(q) < 1e-2
    qs = q[small]
    out[small] = 1.0 - qs**2 / 10.0 + qs**4 / 280.0
    ql = q[~small]
    out[~small] = 3.0 * (np.sin(ql) - ql * np.cos(ql)) / ql**3
    return out


@dataclass(frozen=True)
class SurfaceSpectrum:
    """A periodic height field z(s) = Re sum_j c_j exp(i 2 pi j s / P), j = 0 .. J.

    Attributes
    ----------
    period : float
        P [m].
    coefficients : ndarray of complex, shape (J + 1,)
        c_j [m]; c_0 = 0 (zero mean).
    """

    period: float
    coefficients: np.ndarray

    @property
    def n_bins(self) -> int:
        """J, the highest bin [-]."""
        return int(self.coefficients.size - 1)

    @property
    def wavenumbers(self) -> np.ndarray:
        """k_j = 2 pi j / P [rad/m], shape (J + 1,)."""
        return 2.0 * np.pi / self.period * np.arange(self.coefficients.size)

    @property
    def shortest_wavelength(self) -> float:
        """P / J [m] (inf for J = 0)."""
        return self.period / self.n_bins if self.n_bins else math.inf

    def variance(self) -> float:
        """Mean square height sum_j ``|c_j|^2`` / 2 [m^2] (exact)."""
        c = self.coefficients[1:]
        return 0.5 * float(np.sum(c.real**2 + c.imag**2))

    def moments(self) -> tuple[float, float, float]:
        """Spectral moments m0, m2, m4 of the field (exact) [m^2], [-], [1/m^2]."""
        k = self.wavenumbers[1:]
        p = 0.5 * np.abs(self.coefficients[1:]) ** 2
        return float(np.sum(p)), float(np.sum(p * k**2)), float(np.sum(p * k**4))

    def with_gain(self, gain: np.ndarray | float) -> SurfaceSpectrum:
        """The field with every bin multiplied by ``gain`` (a filter, a scale) [-]."""
        return SurfaceSpectrum(self.period, self.coefficients * gain)

    def grid_size(self, spacing: float) -> int:
        """Samples over one period for a grid no coarser than ``spacing`` [m]: the smallest
        length 2^a 3^b 5^c (fast for numpy's FFT) >= P / spacing that also exceeds 2 J + 1
        (no bin at or above the grid's Nyquist wavenumber)."""
        n = max(int(math.ceil(self.period / spacing * (1.0 - 1e-12))), 2 * self.n_bins + 2, 8)
        return _smooth_length(n)

    def sample(self, spacing: float) -> tuple[np.ndarray, float]:
        """The field on a uniform grid over one period, s_i = i dx.

        Parameters
        ----------
        spacing : float
            Largest grid spacing wanted [m].

        Returns
        -------
        z : ndarray, shape (n,)
            Heights z(i dx) [m], exact (one inverse FFT of the bins).
        dx : float
            P / n [m], <= ``spacing``.
        """
        return self.sample_on(self.grid_size(spacing))

    def sample_on(self, n: int) -> tuple[np.ndarray, float]:
        """The field on exactly ``n`` points over one period (n > 2 J + 1), s_i = i P / n.

        Returns
        -------
        z : ndarray, shape (n,)
            [m].
        dx : float
            P / n [m].
        """
        if n < 2 * self.n_bins + 2:
            raise ValueError(f"n must exceed 2 J + 1 = {2 * self.n_bins + 1}, got {n}")
        full = np.zeros(n // 2 + 1, dtype=complex)
        full[: self.coefficients.size] = self.coefficients * (n / 2.0)
        return np.fft.irfft(full, n), self.period / n

    def evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Height, slope and curvature at arbitrary points by the direct sum (for tests).

        Parameters
        ----------
        s : array_like, shape (m,)
            Profile coordinates [m].

        Returns
        -------
        z, dz, d2z : ndarray, shape (m,)
            [m], [-], [1/m]; O(m J) work.
        """
        s = np.atleast_1d(np.asarray(s, dtype=float))
        k = self.wavenumbers
        e = np.exp(1j * np.outer(s, k)) * self.coefficients
        return ((e.sum(axis=1)).real, (e @ (1j * k)).real, (e @ (-(k**2))).real)


def _smooth_length(n: int) -> int:
    """The smallest integer >= n whose prime factors are 2, 3 and 5."""
    best = 1 << max(int(n - 1).bit_length(), 0)  # a power of two always qualifies
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


def synthetic_spectrum(psd, period: float, shortest_wavelength: float, seed: int
                       ) -> SurfaceSpectrum:
    """Seeded random-phase bins of a one-sided PSD, up to a shortest wavelength.

    ``|c_j| = sqrt(2 G(k_j) dk)`` with dk = 2 pi / P, so that the variance is the PSD's
    integral over the bins; the phases are ``2 pi u_j`` with u_j the j-th draw of
    ``numpy.random.default_rng(seed).random`` (j = 0 .. J, u_0 unused). Bin j has the same
    phase whatever J is: a shorter tail limit adds bins and changes none.

    Parameters
    ----------
    psd : callable
        G(k) [m^2/(rad/m)] of an array of angular wavenumbers [rad/m].
    period : float
        P [m].
    shortest_wavelength : float
        lambda_min [m]; J = floor(P / lambda_min) (at most :data:`MAX_BINS`).
    seed : int
        Random seed.

    Returns
    -------
    SurfaceSpectrum
    """
    n_bins = min(int(math.floor(period / shortest_wavelength * (1.0 + 1e-12))), MAX_BINS)
    k = 2.0 * np.pi / period * np.arange(n_bins + 1)
    amp = np.sqrt(2.0 * np.asarray(psd(k), dtype=float) * (2.0 * np.pi / period))
    u = np.random.default_rng(seed).random(n_bins + 1)
    c = amp * np.exp(2j * np.pi * u)
    c[0] = 0.0
    return SurfaceSpectrum(float(period), c)


# --------------------------------------------------------------------------------------------
# what a scene's "auto" keys resolve to
# --------------------------------------------------------------------------------------------


def scene_speed(scene) -> float:
    """The sliding speed that sets the ``"auto"`` tail limit: the rms speed [m/s].

    Force-driven: ``excitation.target_rms_velocity``, else the free block's rms speed
    T0 / (sqrt(2) m omega) under the given force (an upper bound). Prescribed: the rms of
    velocity + amplitude omega cos(omega t). 0 for a block that does not move.
    """
    exc = scene.excitation
    if exc.kind == "prescribed":
        return math.sqrt(exc.velocity**2 + 0.5 * (exc.amplitude * exc.omega) ** 2)
    if exc.target_rms_velocity is not None:
        return float(exc.target_rms_velocity)
    if exc.force_amplitude and exc.omega > 0:
        return float(exc.force_amplitude) / (math.sqrt(2.0) * scene.block.mass * exc.omega)
    return 0.0


@dataclass(frozen=True)
class InputBand:
    """The resolved band and grid of a scene's input field.

    Attributes
    ----------
    shortest_wavelength : float
        lambda_min, where the surface's tail stops [m].
    spacing : float
        Grid spacing asked of the field [m] (the grid is P / n, no coarser).
    shortest_source, spacing_source : {"auto", "scene"}
    speed : float
        The rms sliding speed the ``"auto"`` limit used [m/s].
    top_frequency : float
        The output band's top, 1 / (2 output.step) [Hz].
    """

    shortest_wavelength: float
    spacing: float
    shortest_source: str
    spacing_source: str
    speed: float
    top_frequency: float

    def as_dict(self) -> dict:
        """Plain dict (JSON-ready)."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def input_band(scene) -> InputBand:
    """Resolve ``roughness.shortest_wavelength`` and ``roughness.spacing`` of a scene.

    ``shortest_wavelength = "auto"``: v_rms / f_top, the wavelength that the rms sliding speed
    maps to the top of the output band f_top = 1 / (2 output.step) (0.2 um at 10 mm/s and
    50 kHz), no longer than the paper's 50 um and no shorter than trace_length /
    :data:`MAX_BINS` or, with ``roughness.spacing`` given, twice the spacing (the shortest
    wavelength that grid holds). At higher speeds (the slip peaks reach about twice the rms)
    the band's top comes from longer wavelengths that the field holds; at lower speeds from
    shorter ones that it lacks, but the contact filter leaves their share at f_top small (it
    grows with the speed to the power 5.6 for a self-affine tail with H = 0.8,
    docs/theory.md).

    ``spacing = "auto"``: lambda_min / 4 with the Hertz contact filter (the filtered field is
    weak near its band edge: a cubic spline on it reads the band next to the edge 0.1 dB low,
    on lambda_min / 2 0.4 dB low), lambda_min / 8 with ``contact.filter = "none"``.

    Parameters
    ----------
    scene : Scene

    Returns
    -------
    InputBand
    """
    r = scene.roughness
    f_top = 0.5 / scene.output.step
    speed = scene_speed(scene)
    if isinstance(r.shortest_wavelength, str):
        floor = r.trace_length / MAX_BINS
        if not isinstance(r.spacing, str) and r.kind != "file":
            floor = max(floor, 2.0 * float(r.spacing))  # a grid given: its Nyquist
        lam = speed / f_top if speed > 0 else PAPER_SHORTEST_WAVELENGTH
        lam = max(min(max(lam, floor), PAPER_SHORTEST_WAVELENGTH), floor)
        src = "auto"
    else:
        lam, src = float(r.shortest_wavelength), "scene"
    if isinstance(r.spacing, str) or r.kind == "file":  # a file's spacing: its samples
        spacing = lam / SAMPLES_PER_WAVELENGTH[scene.contact.filter]
        ssrc = "auto"
    else:
        spacing, ssrc = float(r.spacing), "scene"
    return InputBand(shortest_wavelength=float(lam), spacing=float(spacing),
                     shortest_source=src, spacing_source=ssrc, speed=float(speed),
                     top_frequency=float(f_top))


# --------------------------------------------------------------------------------------------
# spectral moments seen at the scale of the contact spots
# --------------------------------------------------------------------------------------------

#: quadrature points per decade of wavenumber for the moments of a model PSD
_POINTS_PER_DECADE = 2000
#: the contact filter's square falls as 9 / q^4; above this q a bin adds nothing to a moment
_Q_NEGLIGIBLE = 1e4


@dataclass(frozen=True)
class ModelPSD:
    """A model PSD over a band, whose moments are integrated (see :meth:`moments`).

    Attributes
    ----------
    psd : callable
        One-sided profile PSD G(k) [m^2/(rad/m)], or the isotropic areal PSD S2(``|k|``)
        [m^2/(rad/m)^2] when ``areal``.
    k_low, k_high : float
        Band [rad/m]; ``k_high`` may be inf (a tail without end: only the moments seen
        through the contact filter exist).
    areal : bool
    key : dict
        What the PSD depends on (for the on-disk cache).
    breaks : tuple of float
        Wavenumbers where the PSD has a kink (the roll-off) [rad/m].
    """

    psd: object
    k_low: float
    k_high: float
    areal: bool
    key: dict
    breaks: tuple = ()

    def moments(self, radius: float) -> tuple[float, float, float]:
        """m0, m2, m4 [m^2, -, 1/m^2] of a profile of the surface averaged over Hertz spots of
        ``radius`` [m] (0: unfiltered): the PSD weighted by ``H(k a)^2``, integrated by
        Simpson's rule in log k between the PSD's kinks (``breaks``), with
        ``_POINTS_PER_DECADE`` points (1e-12 relative on the smooth pieces). For
        ``areal``, a profile along x through the isotropic surface filtered by the
        two-dimensional H(``|k|`` a): m_n = c_n integral S2 H^2 k^(n+1) dk with c_0, c_2, c_4 =
        2 pi, pi, 3 pi / 4."""
        hi = self.k_high if radius <= 0 else min(self.k_high, _Q_NEGLIGIBLE / radius)
        if not math.isfinite(hi):
            raise ValueError("the moments of an unbounded self-affine tail diverge without the "
                             "contact filter: give a spot radius > 0 or a finite k_high")
        if not hi > self.k_low:
            return 0.0, 0.0, 0.0
        cn, powers = (((2.0 * math.pi, math.pi, 0.75 * math.pi), (1, 3, 5)) if self.areal
                      else ((1.0, 1.0, 1.0), (0, 2, 4)))
        edges = sorted({self.k_low, hi, *(b for b in self.breaks if self.k_low < b < hi)})
        total = np.zeros(3)
        for lo, up in zip(edges[:-1], edges[1:], strict=True):
            n = 2 * max(int(math.log10(up / lo) * _POINTS_PER_DECADE) // 2, 32) + 1
            k = np.geomspace(lo, up, n)
            w = np.asarray(self.psd(k), dtype=float) * k  # dk = k d(ln k)
            if radius > 0:
                w = w * hertz_filter(k * radius) ** 2
            simpson = np.ones(n)
            simpson[1:-1:2], simpson[2:-1:2] = 4.0, 2.0
            step = math.log(up / lo) / (n - 1)
            total += [c * step / 3.0 * float(np.dot(simpson, w * k**p))
                      for c, p in zip(cn, powers, strict=True)]
        m0, m2, m4 = (float(v) for v in total)
        return m0, m2, m4


@dataclass(frozen=True)
class DiscretePSD:
    """Measured spectral power per bin (see :meth:`moments`).

    Attributes
    ----------
    k : ndarray, shape (m,)
        Angular wavenumbers of the bins [rad/m].
    power : ndarray, shape (m,)
        Mean square height per bin [m^2] (summing to the variance).
    """

    k: np.ndarray
    power: np.ndarray

    @property
    def key(self) -> dict:
        """What the moments depend on (for the on-disk cache)."""
        import hashlib

        h = hashlib.sha256(np.ascontiguousarray(self.k).tobytes())
        h.update(np.ascontiguousarray(self.power).tobytes())
        return {"discrete": h.hexdigest()}

    def moments(self, radius: float) -> tuple[float, float, float]:
        """m0, m2, m4 of the bins weighted by ``H(k a)^2`` [m^2, -, 1/m^2]."""
        p = self.power * (hertz_filter(self.k * radius) ** 2 if radius > 0 else 1.0)
        return (float(np.sum(p)), float(np.sum(p * self.k**2)), float(np.sum(p * self.k**4)))
