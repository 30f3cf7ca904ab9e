"""The kinematic input profile of a scene, and the choice of contact points.

This module owns the roughness input (docs/theory.md): everything between the ``[roughness]``
scene section and the uniform-grid height profile z(s) (positive up) the solver interpolates.

``build_profile`` makes a :class:`Profile` from one of

* ``none``: a flat profile (zeros);
* ``sinusoid``: z = amplitude cos(2 pi (s - s_centre) / wavelength), a crest under the block
  centre (not filtered);
* ``synthetic``: the field of :func:`synthetic_field` (seeded Fourier bins of the
  self-affine PSD, carried to the scene's tail limit, functionally filtered, scaled to
  ``rms`` exactly, seen through the contact filter), sampled on the scene's grid;
* ``synthetic`` with ``reduce_3d``: an isotropic 2-D surface of rms ``raw_rms``,
  span-averaged across the block width
  (:func:`~roughvib.physics.surface.synthesis.synthesize_span_averages`); the reduction (about
  -23 dB over 40 mm) is the physics, so the result is not rescaled;
* ``file``: a measured profile (:mod:`roughvib.physics.surface.measured`), a matrix of traces
  or a map span-averaged like the synthetic surface; :func:`measured_field` then reads it as
  a field (its own Fourier bins, a fitted tail, the contact filter).

The functional filter over the block length (docs/theory.md, :func:`functional_filter`) is
``highpass`` 1 - sinc(kL/2) (reading 2, default), ``block-lowpass`` sinc(kL/2) (reading 1,
with a warning) or ``none``. It is applied to ``synthetic`` and ``file`` profiles. The model
spectra are in :mod:`roughvib.physics.surface.spectra`, with their conventions.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from roughvib.physics.surface.field import (
    MAX_BINS,
    PAPER_SHORTEST_WAVELENGTH,
    DiscretePSD,
    InputBand,
    SurfaceSpectrum,
    hertz_filter,
    synthetic_spectrum,
)
from roughvib.physics.surface.measured import (
    PAPER_SPACING,
    MeasuredProfile,
    read_measured,
    read_profile_file,
)
from roughvib.physics.surface.spectra import areal_psd, band_psd, spectral_moments
from roughvib.physics.surface.synthesis import (
    _n_points,
    cbrt2_positions,
    span_average,
    synthesize_profile,
    synthesize_span_averages,
    trapezoid_weights,
    uniform_positions,
)
from roughvib.scene import Block, Roughness, SceneError, user_stacklevel

__all__ = [
    "MeasuredProfile",
    "Profile",
    "areal_psd",
    "band_psd",
    "build_profile",
    "cbrt2_positions",
    "functional_filter",
    "profile_statistics",
    "read_measured",
    "read_profile_file",
    "select_contacts",
    "span_average",
    "spectral_moments",
    "synthesize_profile",
    "synthesize_span_averages",
    "trapezoid_weights",
    "uniform_positions",
]


# --------------------------------------------------------------------------------------------
# the profile
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Profile:
    """The kinematic input profile on a uniform grid.

    Attributes
    ----------
    z : ndarray, shape (n,)
        Heights [m], positive up, after the 3-D -> 2-D reduction and the functional filter.
    dx : float
        Grid spacing [m].
    s0 : float
        Profile coordinate of ``z[0]`` [m].
    s_centre : float
        Profile coordinate under the block centre at t = 0 (the grid point in the middle of
        the trace) [m].
    stats : dict
        Always: ``kind``, ``n``, ``length`` [m], realised ``rms`` [m], ``rms_slope`` [-],
        ``rms_curvature`` [1/m], ``derivatives`` (how slope and curvature were taken),
        ``filter``. ``synthetic``: ``seed``, ``target_rms`` [m]. ``reduce_3d`` and trace
        matrices: ``raw_rms`` [m], ``reduced_rms`` [m] (before the filter), ``reduction_db``
        [dB], ``n_traces``; see :func:`build_profile`.
    """

    z: np.ndarray
    dx: float
    s0: float
    s_centre: float
    stats: dict = field(default_factory=dict)
    #: a measured surface's raw spectrum (DiscretePSD of its traces before span averaging and
    #: filtering), for the statistical contact; None for the model surfaces
    raw_spectrum: object = field(default=None, repr=False, compare=False)
    #: True when z holds one period of a periodic field (the synthetic surfaces)
    periodic: bool = False

    @property
    def s(self) -> np.ndarray:
        """Profile coordinates [m], shape (n,)."""
        return self.s0 + np.arange(self.z.size) * self.dx

    @property
    def length(self) -> float:
        """Covered length (n - 1) dx [m]."""
        return (self.z.size - 1) * self.dx


def profile_statistics(z: np.ndarray, dx: float, *, periodic: bool = False) -> dict:
    """rms height, rms slope and rms curvature of a profile.

    Parameters
    ----------
    z : ndarray, shape (n,)
        Heights [m].
    dx : float
        Spacing [m].
    periodic : bool
        True for a band-limited periodic profile (spectral synthesis): slope and curvature are
        taken spectrally, which is exact and comparable with sqrt(m2), sqrt(m4). Otherwise
        first and second differences (they under-read content near the grid's Nyquist
        wavenumber: -0.6 dB in slope at 5 points per wavelength).

    Returns
    -------
    dict
        ``rms`` [m] (about the mean), ``rms_slope`` [-], ``rms_curvature`` [1/m],
        ``derivatives`` ("spectral" or "finite-difference").
    """
    z = np.asarray(z, dtype=float)
    zc = z - z.mean() if z.size else z
    rms = float(np.sqrt(np.mean(zc**2))) if z.size else 0.0
    if periodic and z.size >= 3:
        n = z.size
        k = 2.0 * np.pi * np.fft.rfftfreq(n, dx)
        p = np.abs(np.fft.rfft(zc)) ** 2
        w = np.full(k.size, 2.0)
        w[0] = 1.0
        if n % 2 == 0:
            w[-1] = 1.0
        scale = 1.0 / n**2
        slope = math.sqrt(float(np.sum(w * p * k**2)) * scale)
        curv = math.sqrt(float(np.sum(w * p * k**4)) * scale)
        how = "spectral"
    else:
        d1 = np.diff(z) / dx
        d2 = np.diff(z, 2) / dx**2
        slope = float(np.sqrt(np.mean(d1**2))) if d1.size else 0.0
        curv = float(np.sqrt(np.mean(d2**2))) if d2.size else 0.0
        how = "finite-difference"
    return {"rms": rms, "rms_slope": slope, "rms_curvature": curv, "derivatives": how}


# --------------------------------------------------------------------------------------------
# functional filter (docs/theory.md)
# --------------------------------------------------------------------------------------------


def functional_filter(z: np.ndarray, dx: float, kind: str, length: float, *,
                      periodic: bool = True) -> np.ndarray:
    """Apply the functional (contact) filter over the block length.

    ``highpass``: H(k) = 1 - sinc(kL/2), the profile minus its running mean over the block
    length (reading 2, removes wavelengths longer than L). ``block-lowpass``: H = sinc(kL/2),
    the literal reading 1 (warns: it removes almost all short-wavelength input).
    ``none``: unchanged.

    Parameters
    ----------
    z : ndarray, shape (n,)
        Heights [m].
    dx : float
        Spacing [m].
    kind : {"highpass", "block-lowpass", "none"}
    length : float
        Block length L [m].
    periodic : bool
        True: the profile is periodic over n dx (synthesis), filter its FFT. False (measured
        data): filter the even extension [z, z reversed] instead, which has no jump at the
        ends, and keep the first half.

    Returns
    -------
    ndarray, shape (n,)
    """
    if kind == "none":
        return np.asarray(z, dtype=float).copy()
    z = np.asarray(z, dtype=float)
    n = z.size
    ext = z if periodic else np.concatenate([z, z[::-1]])
    m = ext.size
    h = functional_gain(2 * np.pi * np.fft.rfftfreq(m, dx), kind, length)
    return np.fft.irfft(np.fft.rfft(ext) * h, m)[:n]


def functional_gain(k: np.ndarray, kind: str, length: float) -> np.ndarray:
    """Gain of the functional filter over the block length at angular wavenumbers k.

    ``highpass``: 1 - sinc(kL/2); ``block-lowpass``: sinc(kL/2) (warns, see
    :func:`functional_filter`); ``none``: 1.

    Parameters
    ----------
    k : ndarray
        [rad/m].
    kind : {"highpass", "block-lowpass", "none"}
    length : float
        Block length L [m].

    Returns
    -------
    ndarray, shape of ``k``
        [-].
    """
    if kind not in ("highpass", "block-lowpass", "none"):
        raise ValueError(f"filter must be 'highpass', 'block-lowpass' or 'none', got {kind!r}")
    if kind == "none":
        return np.ones_like(np.asarray(k, dtype=float))
    sinc = np.sinc(np.asarray(k, dtype=float) * length / 2 / np.pi)  # sin(pi x)/(pi x)
    if kind == "highpass":
        return 1.0 - sinc
    warnings.warn("roughness.filter = 'block-lowpass' is the literal sinc low-pass over the "
                  "block length: it removes almost all short-wavelength input "
                  "(docs/theory.md)", stacklevel=user_stacklevel())
    return sinc


# --------------------------------------------------------------------------------------------
# build the profile
# --------------------------------------------------------------------------------------------


def _check_filtered(before: np.ndarray, after: np.ndarray, r: Roughness, length: float) -> None:
    """Refuse a functional filter that removed the whole profile (a block shorter than every
    wavelength of the profile: ``highpass`` then leaves zero heights)."""
    peak = float(np.max(np.abs(before))) if before.size else 0.0
    if peak > 0 and not float(np.max(np.abs(after))) > 1e-12 * peak:
        raise SceneError(f"roughness.filter = {r.filter!r} over block.length = {length:g} m "
                         f"removes the whole profile (the block must be longer than the "
                         f"profile's shortest wavelengths), got block.length {length:g} m")


def _reduction_db(reduced: np.ndarray, raw_rms: float) -> float:
    rr = float(np.sqrt(np.mean((reduced - reduced.mean()) ** 2)))
    if raw_rms <= 0 or rr <= 0:
        return float("-inf") if raw_rms > 0 else float("nan")
    return 20.0 * math.log10(rr / raw_rms)


def synthetic_field(roughness: Roughness, block_length: float, shortest: float,
                    spot_radius: float | None = None) -> tuple[SurfaceSpectrum, dict]:
    """The synthetic input surface as a field (docs/theory.md, "The input field").

    The bins of :func:`~roughvib.physics.surface.field.synthetic_spectrum` with the PSD
    :func:`~roughvib.physics.surface.spectra.band_psd` carried down to ``shortest``, over the
    period ``trace_length``;
    functionally filtered (:func:`functional_gain`); scaled so that its rms is
    ``roughness.rms`` exactly; then, with ``spot_radius``, seen through the contact filter.

    Parameters
    ----------
    roughness : Roughness
    block_length : float
        L of the functional filter [m].
    shortest : float
        Tail limit lambda_min [m].
    spot_radius : float, optional
        Contact-filter radius a [m]; None: unfiltered.

    Returns
    -------
    spectrum : SurfaceSpectrum
        The input field.
    stats : dict
        ``seed``, ``target_rms`` [m], ``shortest_wavelength`` [m], ``n_bins``,
        ``spot_radius`` [m] or None, ``contact_filter``, ``filtered_rms`` [m] (after the
        contact filter), ``surface_rms_slope`` [-] (before it).

    Raises
    ------
    SceneError
        No bin of the band fits the trace, or the functional filter removes them all.
    """
    r = roughness
    spec = synthetic_spectrum(lambda k: band_psd(k, r, shortest=shortest), r.trace_length,
                              shortest, r.seed)
    if not spec.variance() > 0:
        raise SceneError(f"roughness.trace_length ({r.trace_length} m) holds no wavenumber of "
                         f"the band [{shortest:.3g}, {r.longest_wavelength}] m, got "
                         f"{r.trace_length} m")
    k = spec.wavenumbers
    spec = spec.with_gain(functional_gain(k, r.filter, block_length))
    var = spec.variance()
    if not var > 0:
        raise SceneError(f"roughness.filter = {r.filter!r} over block.length = "
                         f"{block_length:g} m removes the whole profile (the block must be "
                         f"longer than the profile's shortest wavelengths), got block.length "
                         f"{block_length:g} m")
    spec = spec.with_gain(r.rms / math.sqrt(var))
    _, m2, _ = spec.moments()
    surface_slope = math.sqrt(m2)
    if spot_radius is not None:
        spec = spec.with_gain(hertz_filter(k * spot_radius))
    stats = {"seed": r.seed, "target_rms": r.rms, "shortest_wavelength": float(shortest),
             "n_bins": spec.n_bins, "spot_radius": spot_radius,
             "contact_filter": "none" if spot_radius is None else "hertz",
             "filtered_rms": math.sqrt(spec.variance()),
             "surface_rms_slope": surface_slope}
    return spec, stats


def _contact_filtered(z: np.ndarray, dx: float, spot_radius: float | None, *,
                      periodic: bool) -> np.ndarray:
    """A sampled profile seen through the contact filter (none for ``spot_radius`` None);
    not periodic: the even extension is filtered, as in :func:`functional_filter`."""
    if spot_radius is None:
        return z
    n = z.size
    ext = z if periodic else np.concatenate([z, z[::-1]])
    k = 2 * np.pi * np.fft.rfftfreq(ext.size, dx)
    return np.fft.irfft(np.fft.rfft(ext) * hertz_filter(k * spot_radius), ext.size)[:n]


def section_band(r: Roughness) -> InputBand:
    """The band of a ``[roughness]`` section on its own, without a scene to resolve ``"auto"``
    from: its numbers, ``"auto"`` read as the paper's 50 um band and its 10 um grid (or half
    a shorter given band)."""
    lam = (PAPER_SHORTEST_WAVELENGTH if isinstance(r.shortest_wavelength, str)
           else float(r.shortest_wavelength))
    dx = min(PAPER_SPACING, lam / 2.0) if isinstance(r.spacing, str) else float(r.spacing)
    return InputBand(shortest_wavelength=lam, spacing=dx, shortest_source="scene",
                     spacing_source="scene", speed=0.0, top_frequency=math.inf)


def _numeric_band(r: Roughness) -> Roughness:
    """The section with ``"auto"`` band keys replaced by the paper's 50 um band and 10 um
    grid (for the span-averaged surface, which is synthesised on a plain grid)."""
    from dataclasses import replace

    if isinstance(r.shortest_wavelength, str) or isinstance(r.spacing, str):
        band = section_band(r)
        return replace(r, shortest_wavelength=band.shortest_wavelength, spacing=band.spacing)
    return r


def build_profile(roughness: Roughness, block: Block, base_dir: str | Path = ".", *,
                  stroke: float | None = None, band: InputBand | None = None,
                  spot_radius: float | None = None) -> Profile:
    """Build the kinematic input profile of a scene.

    Parameters
    ----------
    roughness : Roughness
        The ``[roughness]`` section.
    block : Block
        Length (functional filter, minimum profile length) and width (span averaging).
    base_dir : str or Path
        Directory relative file paths are resolved against (``Scene.base_dir``).
    stroke : float, optional
        Peak-to-peak tangential travel of the block [m]; the profile must cover
        block.length + stroke. Default: block.length (the profile then spans at least two
        block lengths). The solver checks the actual travel again at run time.
    band : InputBand, optional
        The resolved tail limit and grid (:func:`~roughvib.physics.surface.field.input_band`)
        of a synthetic surface (``reduce_3d`` off), which is the field of
        :func:`synthetic_field` sampled over one period (``trace_length``) on a grid no
        coarser than ``band.spacing``. Default :func:`section_band`: the section's own
        numbers, ``"auto"`` read as the paper's band and grid.
    spot_radius : float, optional
        Radius a of the contact spots [m]: the input is the surface seen through the contact
        filter :func:`~roughvib.physics.surface.field.hertz_filter` of ``k a``. None: no
        contact filter. ``sinusoid`` and ``none`` are never filtered (test inputs).

    Returns
    -------
    Profile
        ``s0 = 0``, ``s_centre`` the middle grid point. ``reduce_3d`` adds to ``stats``:
        ``raw_rms`` (surface rms), ``raw_trace_rms`` (one trace on the centre line),
        ``reduced_rms`` (span average before the filter), ``reduction_db``,
        ``reduction_db_cbrt2`` (the same surface averaged over the paper's 2^(1/3) layout, for
        reference), ``n_traces``, ``trace_pitch``. A trace matrix adds ``raw_rms`` (mean trace
        rms), ``reduced_rms``, ``reduction_db``, ``n_traces``.

    Raises
    ------
    SceneError
        Unreadable or malformed files, profiles shorter than the block plus the stroke.
    """
    r = roughness
    raw_spectrum = None
    moments = None  # of a synthetic field: from its bins
    bl = block.length
    stroke = bl if stroke is None else float(stroke)
    min_len = bl + stroke
    reason = f"block.length {bl:g} m + stroke {stroke:g} m"
    stats: dict = {"kind": r.kind}
    periodic = False
    if r.kind == "file":
        z, dx, raw_spectrum = _measured_input(r, block, base_dir, min_len, reason,
                                              spot_radius, stats)
    elif r.kind == "synthetic" and not r.reduce_3d:
        periodic = True
        z, dx, moments = _synthetic_input(r, bl, band, min_len, reason, spot_radius, stats)
    else:
        z, dx, r, periodic = _grid_input(r, block, min_len, reason, spot_radius, stats)
    if not np.all(np.isfinite(z)):  # the interpolant (spline) needs finite heights
        raise SceneError(f"roughness.kind = {r.kind!r} gives a profile with non-finite heights "
                         f"(check roughness.rms, amplitude, raw_rms and the band), got "
                         f"{int(np.count_nonzero(~np.isfinite(z)))} of {z.size} samples")
    n = z.size
    stats.update(n=int(n), length=float((n if periodic else n - 1) * dx), filter=r.filter)
    stats.update(moments if moments is not None else profile_statistics(z, dx, periodic=periodic))
    s_centre = (n // 2) * dx
    return Profile(z=np.ascontiguousarray(z, dtype=float), dx=float(dx), s0=0.0,
                   s_centre=float(s_centre), stats=stats, raw_spectrum=raw_spectrum,
                   periodic=periodic)


def _measured_input(r: Roughness, block: Block, base_dir: str | Path, min_len: float,
                    reason: str, spot_radius: float | None, stats: dict
                    ) -> tuple[np.ndarray, float, DiscretePSD]:
    """The input of a measured profile (``roughness.kind = "file"``): its traces span-averaged
    over the block width, functional- and contact-filtered; what it is goes into ``stats``.

    Returns
    -------
    z : ndarray
        Heights [m].
    dx : float
        Spacing [m].
    raw_spectrum : DiscretePSD
        The raw traces' own spectrum (:func:`_raw_spectrum`), for the statistical contact.
    """
    bl = block.length
    meas = read_measured(r, block, base_dir, min_length=min_len, min_length_reason=reason)
    dx = meas.dx
    stats.update(path=str(meas.path), layout=meas.layout, sha256=meas.sha256)
    if meas.z.ndim == 2:
        traces = meas.z - meas.z.mean(axis=0)
        y = meas.y if meas.y is not None else np.linspace(-block.width / 2,
                                                          block.width / 2,
                                                          traces.shape[1])
        z = span_average(traces, y)
        raw = float(np.mean(np.sqrt(np.mean(traces**2, axis=0))))
        stats.update(n_traces=int(traces.shape[1]), raw_rms=raw,
                     reduced_rms=float(np.sqrt(np.mean(z**2))),
                     reduction_db=_reduction_db(z, raw),
                     trace_span=float(np.ptp(y)))
    else:
        z = meas.z.copy()
    # moments of the raw measured surface (before span averaging and filtering) feed the
    # statistical contact model (contact.stiffness = "auto", docs/theory.md)
    raw_traces = meas.z if meas.z.ndim == 2 else meas.z[:, None]
    per = [profile_statistics(raw_traces[:, j], dx) for j in range(raw_traces.shape[1])]
    stats["raw_moments"] = tuple(float(np.mean([p[key] ** 2 for p in per]))
                                 for key in ("rms", "rms_slope", "rms_curvature"))
    raw_spectrum = _raw_spectrum(raw_traces, dx)
    if r.filter != "none":
        raw_z = z
        z = functional_filter(z - z.mean(), dx, r.filter, bl, periodic=False)
        _check_filtered(raw_z - raw_z.mean(), z, r, bl)
    stats.update(shortest_wavelength=2.0 * meas.dx)
    z = _contact_filtered(z, dx, spot_radius, periodic=False)
    return z, dx, raw_spectrum


def _synthetic_input(r: Roughness, bl: float, band: InputBand | None, min_len: float,
                     reason: str, spot_radius: float | None, stats: dict
                     ) -> tuple[np.ndarray, float, dict]:
    """The input of a synthetic surface (``reduce_3d`` off): the field of
    :func:`synthetic_field` sampled over one period on the band's grid (``band``, default
    :func:`section_band`); ``bl`` the block length [m]. Returns the heights [m], the spacing
    [m] and the field's exact spectral moments (rms height [m], slope [-], curvature [1/m]).

    Raises
    ------
    SceneError
        ``roughness.trace_length`` shorter than ``min_len`` [m].
    """
    if band is None:
        band = section_band(r)
    if r.trace_length < min_len * (1.0 - 1e-12):
        raise SceneError(f"roughness.trace_length must cover the stroke plus the block "
                         f"length ({reason} = {min_len:.6g} m), got {r.trace_length} m")
    spec, info = synthetic_field(r, bl, band.shortest_wavelength, spot_radius)
    z, dx = spec.sample(band.spacing)
    stats.update(info)
    m0, m2, m4 = spec.moments()  # exact, and an FFT of millions of points cheaper
    moments = {"rms": math.sqrt(m0), "rms_slope": math.sqrt(m2),
               "rms_curvature": math.sqrt(m4), "derivatives": "spectral"}
    return z, dx, moments


def _grid_input(r: Roughness, block: Block, min_len: float, reason: str,
                spot_radius: float | None, stats: dict
                ) -> tuple[np.ndarray, float, Roughness, bool]:
    """The input of the kinds sampled on the section's own grid: ``none``, ``sinusoid``, and
    a synthetic surface reduced from 3-D (span-averaged traces, filtered).

    Returns
    -------
    z : ndarray
        Heights [m].
    dx : float
        Spacing [m].
    roughness : Roughness
        The section, with its band made numeric for a reduced surface.
    periodic : bool
        Whether the profile is one period of a periodic field.

    Raises
    ------
    SceneError
        ``roughness.trace_length`` shorter than ``min_len`` [m].
    """
    bl = block.length
    periodic = False
    dx = section_band(r).spacing
    n = int(round(r.trace_length / dx)) + 1
    if (n - 1) * dx < min_len * (1.0 - 1e-12):
        raise SceneError(f"roughness.trace_length must cover the stroke plus the block "
                         f"length ({reason} = {min_len:.6g} m), got {r.trace_length} m")
    if r.kind == "none":
        z = np.zeros(n)
    elif r.kind == "sinusoid":
        s = np.arange(n) * dx
        z = r.amplitude * np.cos(2 * np.pi * (s - s[n // 2]) / r.wavelength)
    else:
        periodic = True
        r = _numeric_band(r)
        raw_z = _reduce_3d(r, block, stats)
        z = functional_filter(raw_z - raw_z.mean(), dx, r.filter, bl)
        _check_filtered(raw_z - raw_z.mean(), z, r, bl)
        z = _contact_filtered(z, dx, spot_radius, periodic=True)
        stats.update(seed=r.seed)
    return z, dx, r, periodic


#: the decade of a measured profile's own spectrum that its tail is fitted to: wavelengths
#: from 20 to 4 samples (below 4 samples a stylus tip and the instrument's filters take their
#: share; above, the fit would reach the roll-off)
TAIL_FIT_SAMPLES = (20.0, 4.0)
#: a fitted Hurst exponent outside this range is no self-affine tail: the tail is left off
TAIL_HURST_RANGE = (0.05, 1.0)


def fit_tail_hurst(c: np.ndarray, k: np.ndarray, dx: float) -> tuple[float, float, str]:
    """Hurst exponent of a measured spectrum's shortest resolved decade.

    A least-squares line through log ``|c_j|^2`` against log k_j over the wavelengths of
    :data:`TAIL_FIT_SAMPLES` samples; a self-affine profile has the slope -(1 + 2H).

    Parameters
    ----------
    c : ndarray of complex, shape (J + 1,)
        Fourier bins of the profile [m].
    k : ndarray, shape (J + 1,)
        Their angular wavenumbers [rad/m].
    dx : float
        The profile's sample spacing [m].

    Returns
    -------
    hurst : float
        H [-] (NaN when no fit).
    level : float
        The fitted ``|c|^2`` at the decade's short end [m^2] (NaN when no fit).
    note : str
        Why there is no tail ("" when the fit holds).
    """
    lo, hi = (2.0 * np.pi / (n * dx) for n in TAIL_FIT_SAMPLES)
    sel = (k >= lo) & (k <= hi) & (np.abs(c) > 0)
    if np.count_nonzero(sel) < 8:
        return math.nan, math.nan, "too few bins to fit a tail"
    slope, icept = np.polyfit(np.log(k[sel]), np.log(np.abs(c[sel]) ** 2), 1)
    hurst = (-slope - 1.0) / 2.0
    h_lo, h_hi = TAIL_HURST_RANGE
    if not h_lo <= hurst <= h_hi:
        return float(hurst), math.nan, (f"the fitted spectral slope {slope:.3g} is no "
                                         f"self-affine tail (Hurst exponent {hurst:.3g} outside "
                                         f"{h_lo}..{h_hi})")
    return float(hurst), float(math.exp(icept + slope * math.log(hi))), ""


def measured_field(profile: Profile, shortest: float, spacing: float, seed: int, *,
                   tail: bool, spot_radius: float | None) -> Profile:
    """A measured profile as a field: its own Fourier bins, a fitted tail, the contact filter.

    The profile's even extension [z, z reversed] (no jump at its ends) is one period of the
    bins its samples resolve, down to twice their spacing; with ``tail`` the spectrum goes on
    below that with the self-affine slope of :func:`fit_tail_hurst`, bin by bin to
    ``shortest`` (moduli on the fitted line, phases from ``numpy.random.default_rng(seed)``);
    the contact filter of ``spot_radius`` weighs every bin; and the field is sampled on a grid
    no coarser than ``spacing``, of which the first half of the period is the profile. At the
    file's own samples the field without tail and filter is the file (band-limited
    interpolation, not a spline's images).

    Parameters
    ----------
    profile : Profile
        The measured profile (:func:`build_profile`, ``kind = "file"``), on its file grid.
    shortest : float
        Where the tail stops [m].
    spacing : float
        Largest grid spacing of the result [m].
    seed : int
        Phases of the tail.
    tail : bool
        Continue the spectrum below the file's band.
    spot_radius : float or None
        Contact-filter radius [m]; None: no filter.

    Returns
    -------
    Profile
        Not periodic; ``stats`` gain ``file_spacing``, ``tail`` ("fitted" or why not),
        ``hurst_fit``, ``shortest_wavelength``, ``contact_filter``, ``spot_radius`` and the
        statistics of the result.
    """
    from dataclasses import replace

    z = np.asarray(profile.z, dtype=float)
    n, dx = z.size, profile.dx
    ext = np.concatenate([z - z.mean(), (z - z.mean())[::-1]])
    m = ext.size
    c = np.fft.rfft(ext) * (2.0 / m)
    c[0] = 0.0
    c[-1] *= 0.5  # the Nyquist bin of the even-length extension is counted once
    period = m * dx
    k = 2.0 * np.pi / period * np.arange(c.size)
    stats = dict(profile.stats, file_spacing=float(dx))
    hurst, level, why = fit_tail_hurst(c, k, dx) if tail else (math.nan, math.nan, "off")
    stats["hurst_fit"] = None if math.isnan(hurst) else float(hurst)
    if tail and not why and shortest < 2.0 * dx:
        j_max = min(int(math.floor(period / shortest * (1.0 + 1e-12))), MAX_BINS)
        kj = 2.0 * np.pi / period * np.arange(c.size, j_max + 1)
        _, shortest_fitted = TAIL_FIT_SAMPLES
        k_ref = 2.0 * np.pi / (shortest_fitted * dx)
        amp = np.sqrt(level * (kj / k_ref) ** (-(1.0 + 2.0 * hurst)))
        u = np.random.default_rng(seed).random(kj.size)
        c = np.concatenate([c, amp * np.exp(2j * np.pi * u)])
        stats.update(tail="fitted", shortest_wavelength=float(period / j_max))
    else:
        stats.update(tail=why or "none", shortest_wavelength=float(2.0 * dx))
    spec = SurfaceSpectrum(period, c)
    if spot_radius is not None:
        spec = spec.with_gain(hertz_filter(spec.wavenumbers * spot_radius))
        stats.update(spot_radius=float(spot_radius), contact_filter="hertz")
    # an integer refinement of the file's grid, so that its samples are grid points
    factor = max(int(math.ceil(dx / spacing * (1.0 - 1e-12))), 1)
    factor = max(factor, int(math.ceil((2 * spec.n_bins + 2) / m)))
    fine, dx_fine = spec.sample_on(m * factor)
    keep = (n - 1) * factor + 1
    zf = np.ascontiguousarray(fine[:keep])
    stats.update(profile_statistics(zf, dx_fine), n=int(zf.size),
                 length=float((zf.size - 1) * dx_fine))
    return replace(profile, z=zf, dx=float(dx_fine), stats=stats, periodic=False)


def _raw_spectrum(traces: np.ndarray, dx: float) -> DiscretePSD:
    """Mean power per FFT bin of measured traces (n, m), mean removed: the raw spectrum the
    statistical contact counts summits on (docs/theory.md)."""
    t = traces - traces.mean(axis=0)
    n = t.shape[0]
    p = np.abs(np.fft.rfft(t, axis=0)) ** 2 * (2.0 / n**2)
    p[0] = 0.0
    if n % 2 == 0:
        p[-1] *= 0.5  # the Nyquist bin is real: counted once
    return DiscretePSD(k=2.0 * np.pi * np.fft.rfftfreq(n, dx), power=p.mean(axis=1))


def contact_filtered_profile(profile: Profile, spot_radius: float | None) -> Profile:
    """The profile seen through the contact filter of spots of ``spot_radius`` [m] (None:
    unchanged). A periodic field is filtered exactly through its FFT, a measured profile
    through its even extension (:func:`functional_filter`); ``stats`` gains
    ``spot_radius`` and ``contact_filter`` and the rms, slope and curvature of the result."""
    if spot_radius is None:
        return profile
    z = _contact_filtered(profile.z, profile.dx, spot_radius, periodic=profile.periodic)
    stats = dict(profile.stats, spot_radius=float(spot_radius), contact_filter="hertz")
    stats.update(profile_statistics(z, profile.dx, periodic=profile.periodic))
    from dataclasses import replace

    return replace(profile, z=np.ascontiguousarray(z), stats=stats)


#: most Fourier modes of the 2-D surface that ``reduce_3d`` synthesises (its cost grows with
#: the square of the shortest wavelength's inverse: 8e6 at 50 um, 5e7 at 20 um)
MAX_AREAL_MODES = 6e7


def _reduce_3d(r: Roughness, block: Block, stats: dict) -> np.ndarray:
    """Span average of the 2-D surface over the block width, traces at the profile spacing.

    ``roughness.trace_layout = "uniform"`` (default) uses a trace pitch equal to
    ``roughness.spacing`` (10 um), far below the spanwise correlation length of the band
    (>= 50 um), so the trapezoidal average is the continuous width average of docs/theory.md
    (-23 dB for the default surface, the analytic value is -23.1 dB). ``"cbrt2"`` uses the
    paper's 2^(1/3) layout (about -10 dB; see :func:`cbrt2_positions`). Both reductions of the
    same surface are reported in ``stats``.
    """
    width = block.width
    period_y = 2.0 * max(width, r.longest_wavelength)
    modes = 0.5 * math.pi * (r.trace_length / r.shortest_wavelength) \
        * (period_y / r.shortest_wavelength)
    if modes > MAX_AREAL_MODES:
        lam = math.sqrt(0.5 * math.pi * r.trace_length * period_y / MAX_AREAL_MODES)
        raise SceneError(f"roughness.shortest_wavelength must be >= {lam:.3g} m with "
                         f"roughness.reduce_3d = true (the 2-D surface then holds "
                         f"{modes:.3g} Fourier modes, more than {MAX_AREAL_MODES:.0e}), got "
                         f"{r.shortest_wavelength} m")
    if r.raw_rms == 0.0:
        stats.update(raw_rms=0.0, reduced_rms=0.0, reduction_db=float("nan"))
        return np.zeros(_n_points(r))
    yu = uniform_positions(width, r.spacing)
    yc = cbrt2_positions(width, r.spacing)
    layouts = {"uniform": (yu, trapezoid_weights(yu)),
               "cbrt2": (yc, trapezoid_weights(yc)),
               "centre": (np.zeros(1), np.ones(1))}
    out, info = synthesize_span_averages(r, layouts)
    z = out[r.trace_layout]
    used = yu if r.trace_layout == "uniform" else yc
    stats.update(raw_rms=r.raw_rms,
                 raw_trace_rms=float(np.sqrt(np.mean(out["centre"] ** 2))),
                 reduced_rms=float(np.sqrt(np.mean(z**2))),
                 reduction_db=_reduction_db(z, r.raw_rms),
                 reduction_db_uniform=_reduction_db(out["uniform"], r.raw_rms),
                 reduction_db_cbrt2=_reduction_db(out["cbrt2"], r.raw_rms),
                 trace_layout=r.trace_layout, n_traces=int(used.size),
                 trace_pitch=float(used[1] - used[0]), period_y=info["period_y"])
    return z


# --------------------------------------------------------------------------------------------
# contact points (docs/theory.md)
# --------------------------------------------------------------------------------------------


def _ranked(idx: np.ndarray, z: np.ndarray, s: np.ndarray, s_centre: float, tie: float
            ) -> np.ndarray:
    """idx sorted by height (highest first); heights within ``tie`` rank by distance to the
    centre, then by position, so equal crests (a sinusoid) are taken from the centre out."""
    if idx.size == 0:
        return idx
    zq = np.round((z[idx].max() - z[idx]) / tie)
    order = np.lexsort((s[idx], np.abs(s[idx] - s_centre), zq))
    return idx[order]


def select_contacts(profile: Profile, n: int, window_length: float, min_separation: float
                    ) -> np.ndarray:
    """Profile coordinates of the n highest local maxima under the block, sorted.

    Rules, in order:

    1. The window is ``|s - s_centre| <= window_length / 2`` (grid points).
    2. Flat window (height range below 1e-12 of the largest ``|z|``, or exactly zero, e.g. kind
       ``none``): n points equally spaced with equal gaps to each other and to the window
       edges, ``s_centre + linspace(-w/2, w/2, n + 2)[1:-1]`` (n = 1: the centre).
       ``min_separation`` is not applied.
    3. Otherwise the local maxima (z[i] >= z[i-1] and z[i] > z[i+1], neighbours taken from the
       whole profile) are ranked by height; heights equal within 1e-9 of the window's height
       range rank by distance to the centre (so on ``sinusoid`` one contact sits exactly at
       the centre crest). Greedily, a maximum is taken if it is at least ``min_separation``
       from every point already taken.
    4. If fewer than n maxima qualify, the remaining points are the highest other grid points
       of the window that respect the separation (a ``UserWarning`` says so): on a smooth
       long-wave profile they sit on the flanks next to the crests and carry no static load.

    Parameters
    ----------
    profile : Profile
    n : int
        Number of contact points N_c (>= 1).
    window_length : float
        Block length [m].
    min_separation : float
        Minimum distance between two chosen points [m].

    Returns
    -------
    ndarray, shape (n,)
        Sorted profile coordinates [m] (grid points, except in the flat case).

    Raises
    ------
    SceneError
        n < 1, or not even rule 4 finds n points ``min_separation`` apart in the window.
    """
    if n < 1:
        raise SceneError(f"contact.points must be >= 1, got {n}")
    s = profile.s
    z = profile.z
    half = window_length / 2
    sc = profile.s_centre
    inside = np.flatnonzero(np.abs(s - sc) <= half + 1e-9 * profile.dx)
    if inside.size == 0:
        raise SceneError(f"block.length must cover at least one profile point, got "
                         f"{window_length} m")
    zi = z[inside]
    zrange = float(np.ptp(zi))
    if zrange == 0.0 or zrange <= 1e-12 * float(np.max(np.abs(zi))):
        return sc + np.linspace(-half, half, n + 2)[1:-1]
    tie = 1e-9 * zrange
    i = inside[(inside > 0) & (inside < z.size - 1)]
    cand = i[(z[i] >= z[i - 1]) & (z[i] > z[i + 1])]
    tol = 1e-9 * profile.dx
    chosen: list[int] = []

    def take(order: np.ndarray) -> None:
        for j in order:
            if len(chosen) == n:
                return
            if not chosen or np.min(np.abs(s[chosen] - s[j])) >= min_separation - tol:
                chosen.append(int(j))

    take(_ranked(cand, z, s, sc, tie))
    if len(chosen) < n:
        n_max = len(chosen)
        rest = np.setdiff1d(inside, np.asarray(chosen, dtype=int))
        take(_ranked(rest, z, s, sc, tie))
        if len(chosen) < n:
            raise SceneError(f"contact.points: only {len(chosen)} points at least "
                             f"contact.min_separation = {min_separation} m apart were found in "
                             f"the block window of {window_length} m (highest first); lower "
                             f"contact.points or contact.min_separation, got {n}")
        warnings.warn(f"only {n_max} local maxima at least {min_separation} m apart under the "
                      f"block; the other {n - n_max} contact points are the highest remaining "
                      f"profile points", stacklevel=user_stacklevel())
    return np.sort(s[chosen])
