"""Every figure of a run (``FIGURES``: ``roughvib plot``, the run report, the gallery) and the
work-precision figure: no two texts overlap and none leaves the figure, at the size the
figure is shown, as drawn by its own function (no further layout call)."""

import matplotlib
import numpy as np
import pandas as pd
import pytest
from figure_text import text_problems

import roughvib
from roughvib.views.figures import FIGURES, plot_events, plot_friction_displacement

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One excitation period from rest with the plate modes to 2 kHz (a second of solver
    time): stick and slip, events, spectra and the friction loops all have content."""
    scene = roughvib.load_scene("paper", {"output.duration": 1 / 7, "output.transient": 0.0,
                                          "plate.max_frequency": 2000.0,
                                          "output.progress": False})
    result = roughvib.simulate(scene)
    assert result.ok, result.summary.get("message")
    return result


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


@pytest.mark.parametrize("name", sorted(FIGURES))
def test_figure_texts_stand_free(run, name):
    fig = FIGURES[name](run)
    assert text_problems(fig) == []


def test_the_check_finds_overlapping_texts():
    """The helper can fail: two titles at one place, a label beyond the figure's edge."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4, 3))
    ax.set_title("a title")
    ax.text(0.5, 1.02, "a title too", transform=ax.transAxes, ha="center")
    ax.text(1.2, 0.5, "outside", transform=ax.transAxes)
    problems = text_problems(fig)
    assert any("overlaps" in p and "a title too" in p for p in problems), problems
    assert any("'outside' reaches outside" in p for p in problems), problems


def test_events_upper_panels_share_the_bottom_time_axis(run):
    axes = plot_events(run)
    fig = axes[0].figure
    fig.canvas.draw()
    for ax in axes[:-1]:  # no time label without tick labels above the bottom panel
        assert ax.get_xlabel() == ""
        assert not any(t.get_visible() and t.get_text() for t in ax.get_xticklabels())
    assert axes[-1].get_xlabel() == "time [s]"
    assert any(t.get_text() for t in axes[-1].get_xticklabels())


def test_friction_displacement_title_states_a_clean_guard(run):
    axes = plot_friction_displacement(run, v_guard=0.999e-6)
    title = axes[1].get_title()
    assert "|v| < 1 µm/s" in title, title


def test_surface_spectrum_figure_texts_stand_free(tmp_path):
    """spectrum.png of ``roughvib surface paper``: two titles, wavelength axes on top."""
    from roughvib.analysis.spectra import wavenumber_band_levels, wavenumber_spectrum
    from roughvib.physics.surface.roughness import build_profile
    from roughvib.views.surface_report import _spectrum_figure

    scene = roughvib.load_scene("paper")
    prof = build_profile(scene.roughness, scene.block, scene.base_dir)
    lam, lev = wavenumber_band_levels(prof.z, prof.dx, lambda_min=2 * prof.dx,
                                      lambda_max=prof.length)
    k, psd = wavenumber_spectrum(prof.z, prof.dx)
    fig = _spectrum_figure(lam, lev, lev - 3.0, np.full(lam.size, np.nan), 6e-4, k, psd)
    assert text_problems(fig) == []


def _dense_table():
    """Like the paper scene's study: five methods, ladders and presets, some runs of two
    methods at about one cost and error, presets on ladder rungs."""
    rows = []
    def add(method, name, settings, times, errors, presets=()):
        for s, t, e in zip(settings, times, errors, strict=True):
            rows.append(dict(method=method, setting=s, setting_name=name, preset="",
                             wall_time=t, error=e))
        for p, s, t, e in presets:
            rows.append(dict(method=method, setting=s, setting_name=name, preset=p,
                             wall_time=t, error=e))
    rt = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9]
    add("adaptive-modal", "rtol", rt, [1.3, 1.5, 1.7, 3.0, 7.0, 14.0, 50.0],
        [0.08, 0.06, 0.03, 0.01, 3e-3, 3e-4, 1e-5],
        [("draft", 1e-4, 1.25, 0.07), ("standard", 1e-5, 1.4, 0.075),
         ("reference", 1e-6, 3.0, 0.05)])
    add("ida", "rtol", rt, [4.5, 4.8, 10.0, 9.0, 25.0, 45.0, 120.0],
        [25.0, 12.0, 10.0, 7.0, 0.5, 0.04, 0.01],
        [("draft", 1e-4, 4.6, 15.0), ("standard", 1e-6, 9.5, 7.5),
         ("reference", 1e-7, 38.0, 0.1)])
    st = [2e-5, 1e-5, 5e-6, 2.5e-6]
    add("exact-modal", "step [s]", st, [0.2, 0.6, 0.9, 1.2], [1.2, 0.3, 0.08, 0.02],
        [("draft", 1e-5, 0.6, 0.3), ("standard", 5e-6, 0.9, 0.08),
         ("reference", 2.5e-6, 1.2, 0.02)])
    add("newmark", "step [s]", st, [0.23, 0.65, 1.0, 1.9], [6.5, 6.0, 1.1, 0.35],
        [("draft", 1e-5, 0.66, 6.2), ("standard", 5e-6, 0.75, 1.2),
         ("reference", 2.5e-6, 2.0, 0.4)])
    add("paper", "step [s]", st, [1.5, 7.0, 20.0, 45.0], [2.2, 1.6, 0.9, 0.45],
        [("reference/standard/draft", 1e-5, 7.2, 1.7)])
    t = pd.DataFrame(rows)
    t["status"] = "success"
    rng = np.random.default_rng(3)
    for col in ("plate_band_db", "block_band_db", "velocity_rel_rms", "event_dt_max",
                "energy_rel_residual", "contract_ratio"):
        t[col] = t["error"] * rng.uniform(0.7, 1.4, len(t)) * {"plate_band_db": 1,
            "block_band_db": 1, "velocity_rel_rms": 1e-4, "event_dt_max": 1e-6,
            "energy_rel_residual": 1e-7, "contract_ratio": 1}[col]
    return t


@pytest.mark.parametrize("table", ["clustered", "dense"])
def test_work_precision_figure_texts_stand_free(tmp_path, table):
    from test_work_precision_view import _table

    from roughvib.views.work_precision import plot_work_precision

    rows = _table() if table == "clustered" else _dense_table()
    fig = plot_work_precision(rows, tmp_path / "wp.png", "work-precision, scene paper",
                              contract={"band_db": 1.0, "event_dt": 1e-6,
                                        "velocity_rel_rms": 1e-4, "energy_rel_residual": 1e-6})
    assert len(fig.axes[0].texts) == len(rows)  # every run labelled
    assert text_problems(fig) == []
