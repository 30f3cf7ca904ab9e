"""The surface inspection report: files, their agreement with the library, Fig. 5 behaviour."""

import csv
import json
import math

import numpy as np
import pytest

from roughvib.analysis import figures_data as fd
from roughvib.physics.surface.contact import contact_stiffness, scene_input
from roughvib.physics.surface.field import input_band
from roughvib.physics.surface.roughness import select_contacts
from roughvib.scene import load_scene
from roughvib.views.surface_report import scan_range, write_surface_report


def _rows(path):
    with path.open() as fh:
        return list(csv.DictReader(line for line in fh if not line.startswith("#")))


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    scene = load_scene("paper-100mms", {"contact.points": 10})
    out = tmp_path_factory.mktemp("surface")
    return scene, write_surface_report(scene, out)


def test_report_files_exist_and_match_the_library(report):
    scene, paths = report
    assert set(paths) == {"profile_csv", "spectrum_csv", "psd_csv", "contacts_csv",
                          "contacts_json", "profile_png", "spectrum_png"}
    for key in ("profile_png", "spectrum_png"):
        assert paths[key].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    lo, hi, _ = scan_range(scene)
    prof = scene_input(scene, stroke=hi - lo).profile
    rows = _rows(paths["profile_csv"])
    # the rows are grid points of the input under the block and its stroke, exactly
    s_rows = np.array([float(r["s_m"]) for r in rows])
    idx = np.rint((s_rows - prof.s0) / prof.dx).astype(int)
    np.testing.assert_allclose(s_rows, prof.s[idx], rtol=1e-15)
    np.testing.assert_allclose([float(r["z_m"]) for r in rows], prof.z[idx], rtol=1e-15)
    assert s_rows[0] <= prof.s_centre - scene.block.length / 2
    assert s_rows[-1] >= prof.s_centre + scene.block.length / 2
    pts = select_contacts(prof, scene.contact.points, scene.block.length,
                          scene.contact.min_separation)
    crow = _rows(paths["contacts_csv"])
    np.testing.assert_allclose([float(r["s_m"]) for r in crow], pts, rtol=1e-15)
    cs = contact_stiffness(scene)
    data = json.loads(paths["contacts_json"].read_text())
    assert data["stiffness_used_N_per_m"] == pytest.approx(cs.s_total, rel=1e-12)
    assert data["statistical_contact"]["micro_contacts"] == pytest.approx(cs.micro_contacts)
    assert float(crow[0]["stiffness_N_per_m"]) == pytest.approx(cs.s_total / 10)
    x0 = scene.plate.block_position[0]
    np.testing.assert_allclose([float(r["plate_x_m"]) for r in crow],
                               x0 + pts - prof.s_centre, rtol=1e-12)


def test_contact_spectrum_loses_wavelengths_longer_than_the_stroke(report):
    """Paper Fig. 5: one contact scans 2 sqrt(2) v_rms / omega = 6.4 mm at 100 mm/s."""
    scene, paths = report
    stroke = 2 * math.sqrt(2) * 0.1 / (2 * math.pi * 7)
    rows = _rows(paths["spectrum_csv"])
    lam = np.array([float(r["wavelength_m"]) for r in rows])

    def col(name):
        return np.array([float(r[name]) if r[name] else np.nan for r in rows])

    glob, cont, model = col("global_dB"), col("contact_dB"), col("model_dB")
    assert np.all(np.isnan(cont[lam > 1.3 * stroke]))
    band = (lam > 1.3 * stroke) & (lam < 0.035)
    assert band.sum() >= 5 and np.all(np.isfinite(glob[band]))
    live = np.isfinite(model) & (lam > 1e-4)
    np.testing.assert_allclose(glob[live], model[live], atol=0.01)
    short = (lam > 60e-6) & (lam < 0.5e-3)
    assert abs(np.nanmean(cont[short] - glob[short])) < 3.0


def _spectrum_data(paths):
    """The numbers behind spectrum.png, read back from the report's CSV files."""
    def col(rows, name):
        return np.array([float(r[name]) if r[name] else np.nan for r in rows])

    bands, psd = _rows(paths["spectrum_csv"]), _rows(paths["psd_csv"])
    return (col(bands, "wavelength_m"), col(bands, "global_dB"), col(bands, "contact_dB"),
            col(bands, "model_dB"), col(psd, "wavenumber_rad_per_m"),
            col(psd, "psd_m2_per_rad_per_m"))


def test_spectrum_figure_shows_where_the_profile_has_content(report):
    """spectrum.png runs over wavenumber across the roughness band and shows the levels and
    the density down to a floor below it, not the numerical floors of the bands the filter
    emptied (about -300 dB) and of the density beyond the shortest wavelength (1e-36)."""
    scene, paths = report
    lam, glob, cont, model, k, psd = _spectrum_data(paths)
    view = fd.surface_spectrum_view(2 * np.pi / lam, glob, k, psd, others=(cont, model))
    r = scene.roughness
    # the bands of the synthesis target within 60 dB of its strongest (the scene's band, less
    # what the block-length filter removes and what the contact filter takes 60 dB and more
    # off the tail) are shown whole, little more on either side
    target = np.isfinite(model) & (model >= np.nanmax(model) - 60.0)
    k_target = 2 * np.pi / lam[target]
    assert view.k_range[0] <= k_target.min() < 2 * view.k_range[0]
    assert view.k_range[1] / 2 < k_target.max() <= view.k_range[1]
    # every level of the profile in them is shown, the bands the filter emptied are not
    assert view.level_range[0] < glob[target].min() and view.level_range[1] > glob[target].max()
    assert np.nanmin(glob) < -200 < view.level_range[0]
    # the density: its average over every band shown is shown (single values dip into the
    # contact filter's zeros); the floor beyond the scene's tail limit is cut
    k_band = (2 * np.pi / r.longest_wavelength, 2 * np.pi / input_band(scene).shortest_wavelength)
    for kc in 2 * np.pi / lam[view.content]:
        sel = (k >= kc * 10**-0.05) & (k < kc * 10**0.05)
        if sel.any():
            assert psd[sel].mean() > view.psd_range[0]
    assert view.psd_range[0] > 1e-30 > psd.min()
    assert psd[k > 1.5 * k_band[1]].max() < view.psd_range[0]
    shown = (k >= view.k_range[0]) & (k <= view.k_range[1])
    assert view.psd_range[1] > psd[shown].max()


def test_spectrum_figure_axes_are_the_view(report):
    from roughvib.views.surface_report import _spectrum_figure

    scene, paths = report
    lam, glob, cont, model, k, psd = _spectrum_data(paths)
    lo, hi, _ = scan_range(scene)
    view = fd.surface_spectrum_view(2 * np.pi / lam, glob, k, psd, others=(cont, model))
    fig = _spectrum_figure(lam, glob, cont, model, hi - lo, k, psd)
    bands, narrow = fig.axes[:2]
    for ax in (bands, narrow):  # wavenumber, increasing to the right
        assert ax.get_xscale() == "log" and ax.get_xlim() == pytest.approx(view.k_range)
        assert ax.get_xlabel() == "wavenumber k [rad/m]"
    assert bands.get_ylim() == pytest.approx(view.level_range)
    assert narrow.get_ylim() == pytest.approx(view.psd_range)
    # each panel has a wavelength axis on top
    for ax in (bands, narrow):
        assert [a.get_xlabel() for a in ax.child_axes] == ["wavelength [mm]"]
    assert "cut 3 decades below" in narrow.get_title()
    assert "cut 10 dB below" in bands.get_title()


def test_scan_range_estimates():
    lo, hi, how = scan_range(load_scene("paper"))
    a = math.sqrt(2) * 0.01 / (2 * math.pi * 7)
    assert (lo, hi) == pytest.approx((-a, a)) and "v_rms" in how
    w = 2 * math.pi * 7
    # v > A w: monotonic, from 0 to x(T)
    pres = load_scene("paper", {"excitation.kind": "prescribed", "excitation.velocity": 0.01,
                                "excitation.amplitude": 1e-4, "output.duration": 0.1})
    lo, hi, _ = scan_range(pres)
    assert lo == 0.0
    assert hi == pytest.approx(0.01 * 0.1 + 1e-4 * math.sin(w * 0.1), rel=1e-12)
    # pure oscillation over three periods: +-A (to the 20001-point sampling)
    osc = load_scene("paper", {"excitation.kind": "prescribed", "excitation.velocity": 0.0,
                               "excitation.amplitude": 2e-4})
    lo, hi, _ = scan_range(osc)
    assert (lo, hi) == pytest.approx((-2e-4, 2e-4), rel=1e-6)
