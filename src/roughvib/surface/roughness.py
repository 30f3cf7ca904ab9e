"""Roughness profiles (the kinematic input) and the choice of contact points.

``build_profile`` turns the ``[roughness]`` scene section into a :class:`Profile` on a uniform
grid (height z positive up, physics.md §1.4):

* ``none``: a flat profile;
* ``sinusoid``: z = amplitude cos(2 pi (s - s_centre) / wavelength), a crest under the block
  centre;
* ``synthetic``: seeded spectral synthesis of a Gaussian profile with the band-limited
  self-affine PSD of physics.md §5.1 (flat from the longest wavelength to the roll-off
  wavelength, then k^-(1+2H) to the shortest wavelength), rescaled to ``rms`` exactly;
* ``file``: measured heights (one column with ``spacing``, or two columns x, z).

The functional filter over the block length (physics.md §5.3) is applied in the wavenumber
domain: ``highpass`` 1 - sinc(kL/2) (default, reading 2), ``block-lowpass`` sinc(kL/2) (the
literal reading, with a warning), ``none``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from roughvib.scene import Block, Roughness, SceneError

__all__ = ["Profile", "build_profile", "profile_statistics", "select_contacts"]

_UNITS = {"m": 1.0, "um": 1e-6, "nm": 1e-9}


@dataclass(frozen=True)
class Profile:
    """A roughness profile on a uniform grid.

    Attributes
    ----------
    z : ndarray, shape (n,)
        Heights [m], positive up.
    dx : float
        Grid spacing [m].
    s0 : float
        Profile coordinate of z[0] [m].
    s_centre : float
        Profile coordinate under the block centre at t = 0 [m].
    stats : dict
        Realised ``rms`` [m], ``rms_slope`` [-], ``rms_curvature`` [1/m], ``kind``.
    """

    z: np.ndarray
    dx: float
    s0: float
    s_centre: float
    stats: dict = field(default_factory=dict)

    @property
    def s(self) -> np.ndarray:
        """Profile coordinates [m], shape (n,)."""
        return self.s0 + np.arange(self.z.size) * self.dx


def profile_statistics(z: np.ndarray, dx: float) -> dict:
    """rms [m], rms slope [-] and rms curvature [1/m] (central differences)."""
    z = np.asarray(z, dtype=float)
    zc = z - z.mean()
    slope = np.diff(z) / dx
    curv = np.diff(z, 2) / dx**2
    return {"rms": float(np.sqrt(np.mean(zc**2))),
            "rms_slope": float(np.sqrt(np.mean(slope**2))) if slope.size else 0.0,
            "rms_curvature": float(np.sqrt(np.mean(curv**2))) if curv.size else 0.0}


def _functional_filter(z: np.ndarray, dx: float, kind: str, length: float) -> np.ndarray:
    if kind == "none":
        return z
    k = 2 * np.pi * np.fft.rfftfreq(z.size, dx)
    sinc = np.sinc(k * length / 2 / np.pi)  # numpy sinc(x) = sin(pi x)/(pi x)
    if kind == "highpass":
        H = 1.0 - sinc
    else:
        warnings.warn("roughness.filter = 'block-lowpass' is the literal sinc low-pass over the "
                      "block length: it removes almost all short-wavelength input "
                      "(physics.md §5.3, reading 1)", stacklevel=3)
        H = sinc
    return np.fft.irfft(np.fft.rfft(z) * H, z.size)


def _synthetic(r: Roughness) -> np.ndarray:
    n = int(round(r.trace_length / r.spacing)) + 1
    rng = np.random.default_rng(r.seed)
    k = 2 * np.pi * np.fft.rfftfreq(n, r.spacing)
    kl, kh = 2 * np.pi / r.longest_wavelength, 2 * np.pi / r.shortest_wavelength
    k0 = 2 * np.pi / r.rolloff_wavelength
    psd = np.zeros_like(k)
    band = (k >= kl) & (k <= kh)
    psd[band] = np.where(k[band] < k0, 1.0, (k[band] / k0) ** (-(1 + 2 * r.hurst)))
    if not band.any():
        raise SceneError(f"roughness.trace_length ({r.trace_length} m) holds no wavenumber of "
                         f"the band [{r.shortest_wavelength}, {r.longest_wavelength}] m")
    spec = np.sqrt(psd) * np.exp(2j * np.pi * rng.random(k.size))
    return np.fft.irfft(spec, n)


def _read_file(r: Roughness, base_dir: Path) -> tuple[np.ndarray, float]:
    path = Path(r.path)
    if not path.is_absolute():
        path = base_dir / path
    try:
        lines = path.read_text().splitlines()
    except OSError as exc:
        raise SceneError(f"roughness.path {path} cannot be read: {exc.strerror}") from None
    rows = []
    for i, line in enumerate(lines, start=1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        parts = [p for p in text.replace(",", " ").replace(";", " ").split() if p]
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            raise SceneError(f"roughness.path {path} line {i}: not a number: "
                             f"{text!r}") from None
        if any(not math.isfinite(v) for v in vals):
            raise SceneError(f"roughness.path {path} line {i}: NaN or infinite height: "
                             f"{text!r}")
        rows.append(vals)
    if not rows:
        raise SceneError(f"roughness.path {path} holds no data")
    ncol = {len(v) for v in rows}
    if len(ncol) != 1 or ncol.pop() not in (1, 2):
        raise SceneError(f"roughness.path {path}: need one column (heights) or two (x, z) on "
                         f"every line, got {sorted({len(v) for v in rows})} columns")
    data = np.array(rows)
    scale = _UNITS[r.units]
    if data.shape[1] == 1:
        return data[:, 0] * scale, r.spacing
    x = data[:, 0] * scale
    dxs = np.diff(x)
    dx = float(np.mean(dxs)) if dxs.size else 0.0
    if dx <= 0 or np.max(np.abs(dxs - dx)) > 1e-6 * dx:
        bad = int(np.argmax(np.abs(dxs - dx))) + 2
        raise SceneError(f"roughness.path {path}: x must be uniformly spaced and increasing, "
                         f"line {bad} breaks it (spacing {dxs[bad - 2]:.6g} m vs mean "
                         f"{dx:.6g} m)")
    return data[:, 1] * scale, dx


def build_profile(roughness: Roughness, block: Block, base_dir: str | Path = ".") -> Profile:
    """Build the kinematic input profile of a scene.

    Parameters
    ----------
    roughness : Roughness
        The ``[roughness]`` section.
    block : Block
        For the functional filter length and the minimum profile length.
    base_dir : str or Path
        Directory relative file paths are resolved against.

    Returns
    -------
    Profile

    Raises
    ------
    SceneError
        Unreadable or malformed files, profiles shorter than the block plus margin.
    """
    r = roughness
    if r.reduce_3d:
        raise SceneError("roughness.reduce_3d = true is not available in this version "
                         "(3-D -> 2-D reduction is planned); use the reduced rms directly, "
                         "got true")
    if r.kind == "file":
        z, dx = _read_file(r, Path(base_dir))
    else:
        dx = r.spacing
        n = int(round(r.trace_length / dx)) + 1
        if r.kind == "none":
            z = np.zeros(n)
        elif r.kind == "sinusoid":
            s = np.arange(n) * dx
            sc = s[n // 2]
            z = r.amplitude * np.cos(2 * np.pi * (s - sc) / r.wavelength)
        else:
            z = _synthetic(r)
    n = z.size
    min_len = 2 * block.length
    if (n - 1) * dx < min_len:
        raise SceneError(f"roughness profile must be at least {min_len} m long (twice the "
                         f"block length, for the stroke), got {(n - 1) * dx:.6g} m")
    if r.kind in ("synthetic", "file"):
        z = _functional_filter(z - z.mean(), dx, r.filter, block.length)
    if r.kind == "synthetic":
        zr = np.sqrt(np.mean(z**2))
        z = z * (r.rms / zr) if zr > 0 else z
    s_centre = (n // 2) * dx
    stats = {"kind": r.kind, **profile_statistics(z, dx)}
    return Profile(z=np.ascontiguousarray(z), dx=float(dx), s0=0.0, s_centre=float(s_centre),
                   stats=stats)


def select_contacts(profile: Profile, n: int, window_length: float, min_separation: float
                    ) -> np.ndarray:
    """Profile coordinates of the n highest local maxima under the block, sorted.

    Maxima closer than ``min_separation`` to a higher chosen one are skipped (one asperity,
    one contact). A flat profile gives n points equally spaced over the window (the centre for
    n = 1).

    Raises
    ------
    SceneError
        Fewer than n admissible maxima in the window.
    """
    s = profile.s
    z = profile.z
    inside = np.abs(s - profile.s_centre) <= window_length / 2 + 1e-12 * window_length
    idx = np.flatnonzero(inside)
    zi = z[idx]
    if np.ptp(zi) <= 1e-15 * max(1.0, float(np.max(np.abs(zi)))):
        if n == 1:
            return np.array([profile.s_centre])
        return profile.s_centre + np.linspace(-window_length / 2, window_length / 2,
                                              n + 2)[1:-1]
    interior = idx[1:-1]
    is_max = (z[interior] >= z[interior - 1]) & (z[interior] > z[interior + 1])
    cand = interior[is_max]
    cand = cand[np.argsort(-z[cand], kind="stable")]
    chosen: list[int] = []
    for j in cand:
        if all(abs(s[j] - s[c]) >= min_separation for c in chosen):
            chosen.append(int(j))
            if len(chosen) == n:
                break
    if len(chosen) < n:
        raise SceneError(f"contact.points must not exceed the {len(chosen)} profile maxima "
                         f"under the block at least contact.min_separation = {min_separation} m "
                         f"apart, got {n}")
    return np.sort(s[chosen])
