"""Inspection report of a scene's surface: profile, spectra, contact table and plots.

``write_surface_report(scene, out_dir)`` is what ``roughvib surface SCENE --out DIR`` writes:

* ``profile.csv``: the kinematic input profile z(s) [m] with its statistics as comments;
* ``spectrum_bands.csv``: third-octave wavelength band levels [dB re 1 um] of the whole
  profile and of the stretch one contact scans during the scene's stroke (Hann-windowed; the
  paper's Fig. 5: the contact does not see wavelengths longer than about its peak-to-peak
  stroke), plus the model target for synthetic profiles;
* ``spectrum_psd.csv``: the narrow-band wavenumber PSD of the profile;
* ``contacts.csv`` and ``contacts.json``: the contact points (profile and plate coordinates,
  heights, per-spring stiffness, scanned range) and the statistical contact (stiffness,
  micro-contacts, real area, pressure, plasticity index, resonance);
* ``profile.png`` and ``spectrum.png`` (band levels and narrow band over wavenumber, with a
  wavelength axis on top, each shown across the profile's bands and cut a stated margin
  below its content: :func:`roughvib.analysis.figures_data.surface_spectrum_view`).

The band levels reuse :func:`roughvib.analysis.spectra.wavenumber_band_levels` (imported when
the report is written; this is a report, downstream of the analysis stage). matplotlib is
imported lazily and drawn through its Agg canvas, so no pyplot state or backend is touched.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from roughvib.physics.surface.contact import (
    ContactLayout,
    ContactStiffness,
    contact_layout,
    contact_stiffness,
    scene_input,
)
from roughvib.physics.surface.field import hertz_filter
from roughvib.physics.surface.roughness import Profile, band_psd
from roughvib.scene import Scene, SceneError

__all__ = ["SURFACE_FILES", "scan_range", "write_surface_report"]


def scan_range(scene: Scene) -> tuple[float, float, str]:
    """Range of the block's tangential displacement, i.e. what each contact scans.

    * ``prescribed``: min and max of velocity t + amplitude sin(omega t) over the output
      duration;
    * ``force`` with a target rms velocity: +-sqrt(2) v_rms / omega (harmonic motion,
      docs/theory.md);
    * ``force`` with only T0: 0 ... 2 T0 / (m omega^2), the frictionless block started at rest
      (an upper bound);
    * no motion: (0, 0).

    Parameters
    ----------
    scene : Scene

    Returns
    -------
    lo, hi : float
        Displacement range relative to the start [m].
    how : str
        Which estimate was used.
    """
    exc = scene.excitation
    if exc.kind == "prescribed":
        t = np.linspace(0.0, scene.output.duration, 20001)
        x = exc.velocity * t + exc.amplitude * np.sin(exc.omega * t)
        return float(x.min()), float(x.max()), "prescribed motion over output.duration"
    if exc.frequency > 0 and exc.target_rms_velocity is not None:
        a = math.sqrt(2.0) * exc.target_rms_velocity / exc.omega
        return -a, a, "+-sqrt(2) v_rms / omega"
    if exc.frequency > 0 and exc.force_amplitude:
        a = exc.force_amplitude / (scene.block.mass * exc.omega**2)
        return 0.0, 2.0 * a, "frictionless upper bound 2 T0 / (m omega^2)"
    return 0.0, 0.0, "no tangential motion"


#: most rows of profile.csv (the input under the block; a finer grid is written sparser)
MAX_PROFILE_ROWS = 200_000


def _csv_rows(profile: Profile, span: float) -> slice:
    """The grid points of the profile within ``span`` / 2 of the block centre, every m-th so
    that at most :data:`MAX_PROFILE_ROWS` remain."""
    half = int(math.ceil(0.5 * span / profile.dx))
    c = int(round((profile.s_centre - profile.s0) / profile.dx))
    i0, i1 = max(c - half, 0), min(c + half + 1, profile.z.size)
    return slice(i0, i1, max(1, int(math.ceil((i1 - i0) / MAX_PROFILE_ROWS))))


def _model_band_levels(profile: Profile, scene: Scene, lower: np.ndarray, upper: np.ndarray
                       ) -> np.ndarray:
    """Band levels of the synthesis target: the model PSD G carried to the run's tail limit,
    times the functional filter's and the contact filter's squared gains, normalised so that
    the unfiltered surface has ``roughness.rms`` (as the synthesis does)."""
    r = scene.roughness
    n = profile.z.size
    k = 2.0 * np.pi * np.fft.rfftfreq(n, profile.dx)
    g = band_psd(k, r, shortest=profile.stats.get("shortest_wavelength"))
    if r.filter != "none":
        sinc = np.sinc(k * scene.block.length / 2.0 / np.pi)
        g = g * ((1.0 - sinc) if r.filter == "highpass" else sinc) ** 2
    total = g.sum()
    if total <= 0:
        return np.full(lower.size, np.nan)
    g = g / total * profile.stats.get("target_rms", profile.stats["rms"]) ** 2
    if profile.stats.get("spot_radius"):
        g = g * hertz_filter(k * profile.stats["spot_radius"]) ** 2
    out = np.full(lower.size, np.nan)
    for i, (a, b) in enumerate(zip(lower, upper, strict=True)):
        sel = (k >= a) & (k < b)
        if sel.any():
            p = g[sel].sum()
            out[i] = 10.0 * math.log10(p / 1e-12) if p > 0 else -np.inf
    return out


def _json_ready(value):
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_json_ready(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    return value


#: the files of a surface report
SURFACE_FILES = ("profile.csv", "contacts.csv", "spectrum_bands.csv", "spectrum_psd.csv",
                 "contacts.json", "profile.png", "spectrum.png")


def write_surface_report(scene: Scene, out_dir: str | Path, *,
                         overwrite: bool = False) -> dict[str, Path]:
    """Write the surface inspection report of a scene (see the module docstring).

    Each file appears complete or not at all (written under a temporary name and renamed).

    Parameters
    ----------
    scene : Scene
    out_dir : str or Path
        Created if missing.
    overwrite : bool
        Replace report files of the same names (:data:`SURFACE_FILES`) in ``out_dir``
        (without it they are refused, before anything is computed).

    Returns
    -------
    dict of str to Path
        ``profile_csv``, ``spectrum_csv``, ``psd_csv``, ``contacts_csv``, ``contacts_json``,
        ``profile_png``, ``spectrum_png``.

    Raises
    ------
    SceneError
        The profile cannot be built (e.g. a bad profile file).
    roughvib.rundir.OutputError
        ``out_dir`` cannot be created or written, or holds a report file and ``overwrite``
        is False (one line).
    roughvib.rundir.WriteError
        A file cannot be written (a full disk: the space needed and free).
    """
    from roughvib.analysis.spectra import wavenumber_spectrum
    from roughvib.rundir import claim_files, output_folder, write_file

    out = Path(out_dir)
    claim_files([out / n for n in SURFACE_FILES], overwrite=overwrite)
    output_folder(out)
    lo, hi, how = scan_range(scene)
    stroke = hi - lo
    inp = scene_input(scene, stroke=stroke if stroke > 0 else None)
    profile = inp.profile
    cl = contact_layout(scene, profile, inp.statistical)
    s_pts = cl.positions
    cs, statistical = _statistical_contact(scene, profile, cl)
    s_source = ("auto (statistical contact)" if cl.stiffness_source == "auto"
                else "scene (contact.stiffness)")

    paths: dict[str, Path] = {}
    paths["profile_csv"] = _write_profile_csv(out / "profile.csv", scene, profile, stroke)
    heights = _contact_heights(profile, s_pts)
    rows = _contact_rows(scene, profile, cl, heights, lo, hi)
    paths["contacts_csv"] = _write_contacts_csv(out / "contacts.csv", rows, cl, cs, s_source)
    bands = _band_spectra(scene, profile, s_pts, lo, hi)
    paths["spectrum_csv"] = _write_bands_csv(out / "spectrum_bands.csv", bands, lo, hi, how)
    k_nb, psd_nb = wavenumber_spectrum(profile.z, profile.dx)
    paths["psd_csv"] = _write_psd_csv(out / "spectrum_psd.csv", k_nb, psd_nb)
    report = {"scene": scene.name, "stiffness_used_N_per_m": cl.stiffness_total,
              "stiffness_source": s_source, "contact": cl.as_dict(),
              "statistical_contact": statistical,
              "contacts": rows, "profile": {"stats": profile.stats, "dx_m": profile.dx,
                                            "s0_m": profile.s0,
                                            "s_centre_m": profile.s_centre},
              "stroke": {"from_m": lo, "to_m": hi, "peak_to_peak_m": stroke, "estimate": how,
                         "reference_contact": bands.j_ref}}
    paths["contacts_json"] = _write_json(out / "contacts.json", report)
    paths["profile_png"] = write_file(out / "profile.png", lambda tmp: _plot_profile(
        tmp, profile, s_pts, heights, scene.block.length, bands.j_ref, lo, hi))
    paths["spectrum_png"] = write_file(out / "spectrum.png", lambda tmp: _plot_spectrum(
        tmp, bands.wavelength, bands.global_db, bands.contact_db, bands.model_db, stroke,
        k_nb, psd_nb))
    return paths


def _statistical_contact(scene: Scene, profile: Profile, cl: ContactLayout
                         ) -> tuple[ContactStiffness | None, dict]:
    """The statistical contact of the report: the layout's, or solved for the report from
    the profile's spectrum, and its JSON form (``{"error": message}`` where it cannot be
    solved)."""
    cs = cl.statistical
    if cs is None:
        try:
            cs = contact_stiffness(scene, surface=profile.raw_spectrum)
        except SceneError as err:
            statistical = {"error": str(err)}
    if cs is not None:
        statistical = cs.as_dict()
    return cs, statistical


def _write_profile_csv(path: Path, scene: Scene, profile: Profile, stroke: float) -> Path:
    """``profile.csv``: the input z(s) [m] under the block and its stroke [m], the profile's
    statistics as comments."""
    from roughvib.rundir import writing

    rows_z = _csv_rows(profile, scene.block.length + stroke)
    with writing(path, newline="") as fh:
        fh.write(f"# roughvib surface report, scene {scene.name!r}\n")
        for key, val in profile.stats.items():
            fh.write(f"# {key} = {val}\n")
        fh.write(f"# s_centre = {profile.s_centre} m (block centre at t = 0)\n")
        fh.write(f"# rows: the input under the block and its stroke, every "
                 f"{rows_z.step or 1}. sample of its grid of {profile.dx:.6g} m (exact values "
                 f"of the field there)\n")
        w = csv.writer(fh)
        w.writerow(["s_m", "z_m"])
        w.writerows(zip(profile.s[rows_z].tolist(), profile.z[rows_z].tolist(), strict=True))
    return path


def _contact_heights(profile: Profile, s_pts: np.ndarray) -> np.ndarray:
    """The profile's heights [m] at the contact points ``s_pts`` [m]: the grid value where a
    point lies on the grid, else linearly interpolated."""
    dx, z = profile.dx, profile.z
    i_pts = np.rint((s_pts - profile.s0) / dx).astype(int)
    on_grid = np.abs(profile.s0 + i_pts * dx - s_pts) < 1e-6 * dx
    return np.where(on_grid, z[np.clip(i_pts, 0, z.size - 1)], np.interp(s_pts, profile.s, z))


def _contact_rows(scene: Scene, profile: Profile, cl: ContactLayout, heights: np.ndarray,
                  lo: float, hi: float) -> list[dict]:
    """One row per contact point: profile and plate coordinates [m], height [m], depth below
    the highest contact [m], spring stiffness [N/m] and the range it scans over the stroke
    ``lo`` .. ``hi`` [m]."""
    x0, y0 = scene.plate.block_position
    k_spring = cl.stiffness_total / cl.n
    rows = []
    for j, (sp, zh) in enumerate(zip(cl.positions, heights, strict=True)):
        rows.append({"index": j, "s_m": float(sp), "offset_m": float(sp - profile.s_centre),
                     "plate_x_m": float(x0 + sp - profile.s_centre), "plate_y_m": float(y0),
                     "height_m": float(zh), "below_top_m": float(heights.max() - zh),
                     "stiffness_N_per_m": k_spring,
                     "scan_from_m": float(sp + lo), "scan_to_m": float(sp + hi)})
    return rows


def _write_contacts_csv(path: Path, rows: list[dict], cl: ContactLayout,
                        cs: ContactStiffness | None, s_source: str) -> Path:
    """``contacts.csv``: the contact rows, with the stiffness used and the statistical
    contact as comments."""
    from roughvib.rundir import writing

    with writing(path, newline="") as fh:
        fh.write(f"# s_total = {cl.stiffness_total} N/m ({s_source}), {cl.n} equal springs "
                 f"(contact.points: {cl.points_source}, selection {cl.selection})\n")
        if cs is not None:
            fh.write(f"# statistical ({cs.model}): s_total = {cs.s_total:.6g} N/m, "
                     f"micro-contacts = {cs.micro_contacts:.4g}, real area = "
                     f"{cs.real_area:.4g} m^2, mean pressure = {cs.mean_pressure:.4g} Pa, "
                     f"plasticity index = {cs.plasticity_index:.3g}, resonance = "
                     f"{cs.resonance_hz:.4g} Hz\n")
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return path


class _Bands(NamedTuple):
    """Third-octave wavelength band levels of a surface report [dB re 1 um]."""

    wavelength: np.ndarray   #: band centres [m]
    wavenumber: np.ndarray   #: band centres [rad/m]
    global_db: np.ndarray    #: the whole profile
    contact_db: np.ndarray   #: the stretch contact ``j_ref`` scans (NaN if too short)
    model_db: np.ndarray     #: the synthesis target (NaN but for a synthetic profile)
    j_ref: int               #: the contact nearest the block centre


def _band_spectra(scene: Scene, profile: Profile, s_pts: np.ndarray, lo: float, hi: float
                  ) -> _Bands:
    """The band levels of the whole profile, of the stretch the contact nearest the block
    centre scans over the stroke ``lo`` .. ``hi`` [m] (Hann-windowed) and of the model
    target."""
    from roughvib.analysis.spectra import wavenumber_band_levels

    s, z, dx = profile.s, profile.z, profile.dx
    lam_min, lam_max = 2.0 * dx, profile.length
    lam_c, lev_global = wavenumber_band_levels(z, dx, lambda_min=lam_min, lambda_max=lam_max)
    j_ref = int(np.argmin(np.abs(s_pts - profile.s_centre)))
    seg = (s >= s_pts[j_ref] + lo - 1e-9 * dx) & (s <= s_pts[j_ref] + hi + 1e-9 * dx)
    if seg.sum() >= 4:
        # the scanned stretch is not periodic: a Hann window (power-normalised) keeps the
        # leakage of its end mismatch out of the short-wavelength bands
        zs = z[seg] - z[seg].mean()
        win = np.hanning(zs.size)
        zs = zs * win / math.sqrt(float(np.mean(win**2)))
        _, lev_contact = wavenumber_band_levels(zs, dx, lambda_min=lam_min,
                                                lambda_max=lam_max, detrend=None)
    else:
        lev_contact = np.full(lam_c.size, np.nan)
    k_c = 2.0 * np.pi / lam_c
    k_lo, k_hi = k_c * 10.0 ** (-0.05), k_c * 10.0 ** 0.05
    if scene.roughness.kind == "synthetic" and not scene.roughness.reduce_3d:
        lev_model = _model_band_levels(profile, scene, k_lo, k_hi)
    else:
        lev_model = np.full(lam_c.size, np.nan)
    return _Bands(lam_c, k_c, lev_global, lev_contact, lev_model, j_ref)


def _write_bands_csv(path: Path, bands: _Bands, lo: float, hi: float, how: str) -> Path:
    """``spectrum_bands.csv``: the band levels (empty where a band has no FFT bin)."""
    from roughvib.rundir import writing

    with writing(path, newline="") as fh:
        fh.write("# third-octave wavelength bands, levels in dB re 1 um; contact = the stretch "
                 f"of contact {bands.j_ref} scanned over the stroke {lo:.6g} .. {hi:.6g} m "
                 f"({how}); empty = no FFT bin in the band\n")
        w = csv.writer(fh)
        w.writerow(["wavelength_m", "wavenumber_rad_per_m", "global_dB", "contact_dB",
                    "model_dB"])
        for row in zip(bands.wavelength, bands.wavenumber, bands.global_db, bands.contact_db,
                       bands.model_db, strict=True):
            w.writerow([f"{v:.6g}" if np.isfinite(v) else "" for v in row])
    return path


def _write_psd_csv(path: Path, k_nb: np.ndarray, psd_nb: np.ndarray) -> Path:
    """``spectrum_psd.csv``: the narrow-band wavenumber PSD [m^2/(rad/m)] over k [rad/m]."""
    from roughvib.rundir import writing

    with writing(path, newline="") as fh:
        fh.write("# one-sided wavenumber PSD (Welch, Hann), integral psd dk = variance\n")
        w = csv.writer(fh)
        w.writerow(["wavenumber_rad_per_m", "psd_m2_per_rad_per_m"])
        w.writerows(zip(k_nb.tolist(), psd_nb.tolist(), strict=True))
    return path


def _write_json(path: Path, report: dict) -> Path:
    """``contacts.json``: the report's dict, JSON-ready (:func:`_json_ready`)."""
    from roughvib.rundir import writing

    with writing(path) as fh:
        fh.write(json.dumps(_json_ready(report), indent=2) + "\n")
    return path


def _figure(nrows: int):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 3.2 * nrows), layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, 1, squeeze=False)[:, 0]


def _plot_profile(path: Path, profile: Profile, s_pts: np.ndarray, heights: np.ndarray,
                  window: float, j_ref: int, lo: float, hi: float) -> Path:
    fig, (ax1, ax2) = _figure(2)
    s_mm = profile.s * 1e3
    ax1.plot(s_mm, profile.z * 1e6, lw=0.4, color="C0")
    a, b = (profile.s_centre - window / 2) * 1e3, (profile.s_centre + window / 2) * 1e3
    ax1.axvspan(a, b, color="C1", alpha=0.15, label="block window")
    ax1.set_xlabel("profile coordinate s [mm]")
    ax1.set_ylabel("height z [µm]")
    ax1.set_title(f"kinematic input profile ({profile.stats.get('kind')}, rms "
                  f"{profile.stats.get('rms', 0.0) * 1e6:.3g} µm)")
    ax1.legend(loc="upper right", fontsize=8)
    inside = (profile.s >= profile.s_centre - window / 2) & \
             (profile.s <= profile.s_centre + window / 2)
    ax2.plot(s_mm[inside], profile.z[inside] * 1e6, lw=0.6, color="C0")
    ax2.plot(s_pts * 1e3, heights * 1e6, "v", color="C3", label="contact points")
    ax2.axvspan((s_pts[j_ref] + lo) * 1e3, (s_pts[j_ref] + hi) * 1e3, color="C2", alpha=0.2,
                label=f"stroke of contact {j_ref}")
    ax2.set_xlabel("profile coordinate s [mm]")
    ax2.set_ylabel("height z [µm]")
    ax2.set_title("under the block")
    ax2.legend(loc="upper right", fontsize=8)
    fig.savefig(path, dpi=120)
    return path


def _plot_spectrum(path: Path, lam: np.ndarray, lev_g: np.ndarray, lev_c: np.ndarray,
                   lev_m: np.ndarray, stroke: float, k_nb: np.ndarray, psd_nb: np.ndarray
                   ) -> Path:
    _spectrum_figure(lam, lev_g, lev_c, lev_m, stroke, k_nb, psd_nb).savefig(path, dpi=120)
    return path


def _spectrum_figure(lam: np.ndarray, lev_g: np.ndarray, lev_c: np.ndarray, lev_m: np.ndarray,
                     stroke: float, k_nb: np.ndarray, psd_nb: np.ndarray):
    """Both panels over wavenumber (a wavelength axis on top) across the profile's bands,
    each cut below its content (:func:`roughvib.analysis.figures_data.surface_spectrum_view`);
    returns the figure."""
    from roughvib.analysis.figures_data import surface_spectrum_view

    k_c = 2.0 * np.pi / lam
    view = surface_spectrum_view(k_c, lev_g, k_nb, psd_nb, others=(lev_c, lev_m))
    fig, (ax1, ax2) = _figure(2)
    ax1.semilogx(k_c, lev_g, "o-", ms=3, label="whole profile")
    ax1.semilogx(k_c, lev_c, "s-", ms=3, label="seen by one contact (stroke)")
    if np.any(np.isfinite(lev_m)):
        ax1.semilogx(k_c, lev_m, "k--", lw=0.8, label="synthesis target")
    if stroke > 0:
        ax1.axvline(2.0 * np.pi / stroke, color="0.5", ls=":",
                    label="wavelength = peak-to-peak stroke")
    ax1.set_ylim(*view.level_range)
    ax1.set_ylabel("roughness level [dB re 1 µm]")
    ax1.set_title(f"third-octave wavelength bands (cut {view.margin_db:g} dB below the profile's "
                  f"lowest band)", fontsize=10)
    ax1.legend(fontsize=8)
    pos = (k_nb > 0) & (psd_nb > 0)
    ax2.loglog(k_nb[pos], psd_nb[pos], lw=0.8)
    ax2.set_ylim(*view.psd_range)
    ax2.set_ylabel("PSD [m² / (rad/m)]")
    ax2.set_title(f"narrow-band wavenumber spectrum (Welch; cut {view.decades:g} decades below "
                  f"its lowest band average)", fontsize=10)
    for ax in (ax1, ax2):
        ax.set_xlim(*view.k_range)
        ax.set_xlabel("wavenumber k [rad/m]")
        # wavelength in mm = 2 pi / k * 1e3 (its own inverse)
        top = ax.secondary_xaxis("top", functions=(_k_to_mm, _k_to_mm))
        top.set_xlabel("wavelength [mm]")
    return fig


def _k_to_mm(x):
    x = np.asarray(x, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(x > 0, 2.0e3 * np.pi / np.where(x > 0, x, 1.0), np.inf)
