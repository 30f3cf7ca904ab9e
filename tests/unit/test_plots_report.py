"""Figures, figure data and the HTML run report.

One short run (module fixture, ~10 s) feeds the figure and report tests; the analysis helpers
are checked on signals with known content. The report is also opened in a real headless
Chromium (tests/unit/browser.py): it loads, every figure decodes, every link lands, and a
screenshot is not blank. Without Chromium those tests skip, under CI=true they fail.
"""

from __future__ import annotations

import argparse
import base64
import html
import io
import math
import re
import subprocess
from html.parser import HTMLParser

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from browser import FLAGS, chromium, inspect_page

import roughvib
from roughvib.analysis import figures_data as fd
from roughvib.analysis.spectra import band_levels
from roughvib.cli.report import add_parsers
from roughvib.results import EVENT_COLUMNS, Result
from roughvib.scene import Scene, scene_to_toml
from roughvib.views import figures as plots
from roughvib.views.figures import FIGURES, save_figure
from roughvib.views.report import build_report, write_report

#: the module's run (the fixture ``run``) lasts 0.05 s on purpose (the marker is in
#: tests/conftest.py)
pytestmark = pytest.mark.short_run

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
REQUIRED_FIGURES = {"velocity", "friction-velocity", "friction-displacement", "acceleration",
                    "spectra", "wavenumber", "events"}
UNIT = re.compile(r"\[[^\]]+\]")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A 0.05 s paper run (plate modes to 5 kHz) saved and loaded back."""
    scene = roughvib.load_scene("paper", {"output.duration": 0.05, "plate.max_frequency": 5000,
                                          "solver.atol_acceleration": 1e-5,
                                          "output.progress": False})
    result = roughvib.simulate(scene)
    assert result.ok, result.summary.get("message")
    out = tmp_path_factory.mktemp("plots") / "run"
    result.save(out)
    return roughvib.load_result(out), out


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


# --------------------------------------------------------------------------------------------
# figures
# --------------------------------------------------------------------------------------------

def _categorical(axis) -> bool:
    """An axis whose tick labels are words (e.g. 'contact 3'), not numbers."""
    labels = [t.get_text() for t in axis.get_ticklabels() if t.get_text()]
    return bool(labels) and all(re.search(r"[a-zA-Z]{3,}", s) for s in labels)


def test_registry_names_the_paper_figures():
    assert REQUIRED_FIGURES <= set(FIGURES)


@pytest.mark.parametrize("name", sorted(REQUIRED_FIGURES))
def test_figure_renders_with_units_on_every_axis(run, name):
    result, _ = run
    fig = FIGURES[name](result)
    assert fig.axes
    for ax in fig.axes:
        assert ax.has_data(), f"{name}: an empty axes"
        xl, yl = ax.get_xlabel(), ax.get_ylabel()
        if not xl:  # a panel over a shared axis: the panel that shows it names it
            xl = next(o.get_xlabel() for o in fig.axes if o is not ax and o.get_xlabel()
                      and ax.get_shared_x_axes().joined(ax, o))
        assert UNIT.search(xl), f"{name}: x label without unit: {xl!r}"
        if not _categorical(ax.yaxis):
            assert UNIT.search(yl), f"{name}: y label without unit: {yl!r}"
        else:
            assert yl, f"{name}: unlabelled categorical y axis"
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=40)
    assert buf.getvalue().startswith(PNG_MAGIC)


def test_plot_functions_are_pure_and_draw_into_given_axes(run):
    import matplotlib.pyplot as plt

    from roughvib.views import figures as plots

    result, _ = run
    fig, ax = plt.subplots()
    n_before = len(plt.get_fignums())
    for fn in (plots.plot_velocity, plots.plot_friction_velocity, plots.plot_wavenumber,
               plots.plot_tangential_stiffness):
        ax.clear()
        assert fn(result, ax=ax) is ax
    fig2, axes = plt.subplots(1, 2)
    out = plots.plot_spectra(result, axes=axes)
    assert list(out) == list(axes)
    assert len(plt.get_fignums()) == n_before + 1  # only the one made here
    # without axes: exactly one new figure, returned through the Axes
    n = len(plt.get_fignums())
    a = plots.plot_acceleration(result)
    assert len(plt.get_fignums()) == n + 1 and a[0].figure is a[1].figure


def test_save_figure_writes_png_at_requested_dpi(run, tmp_path):
    result, _ = run
    fig = FIGURES["velocity"](result)
    w_in = fig.get_size_inches()[0]
    save_figure(fig, tmp_path / "v.png", dpi=50)
    import matplotlib.image as mpimg

    img = mpimg.imread(tmp_path / "v.png")
    assert abs(img.shape[1] - w_in * 50) <= 2


def test_spectra_noise_floor_adds_a_block_curve(run):
    from roughvib.views.figures import plot_spectra

    result, _ = run
    axes = plot_spectra(result, noise_rms=1e-3)
    labels = [ln.get_label() for ln in axes[0].get_lines()]
    assert any("noise" in s for s in labels)


def _assert_units(ax):
    assert UNIT.search(ax.get_xlabel()) and UNIT.search(ax.get_ylabel())


def test_multi_run_figures(run):
    from roughvib.views.figures import plot_band_comparison, plot_velocity_sweep

    result, _ = run
    ax = plot_band_comparison([result, result], ["a", "b"], quantity="plate")
    _assert_units(ax)
    assert len(ax.get_lines()) == 2
    with pytest.raises(ValueError, match="one label per run"):
        plot_band_comparison([result], ["a", "b"])
    runs = [Result(xr.Dataset(), pd.DataFrame(), {"scene": "x", "metrics": {
        "block_tangential_velocity_rms": v, "stick_fraction": 0.0,
        "block_vertical_acceleration_level_db_re_1e-6": 30 * math.log10(v),
        "plate_vertical_acceleration_level_db_re_1e-6": 33 * math.log10(v)}}, "")
        for v in (0.01, 0.02, 0.04)]
    ax = plot_velocity_sweep(runs)
    _assert_units(ax)
    assert any("9.0 dB/doubling" in t.get_text() for t in ax.get_legend().get_texts())


# --------------------------------------------------------------------------------------------
# figure data on signals of known content
# --------------------------------------------------------------------------------------------

def test_tapered_band_levels_tone_level_and_dynamic_range():
    fs, n = 1e5, 100_000  # 1 s: integer cycles for every integer frequency
    t = np.arange(n) / fs
    a1, a2 = 1.0, 1e-7  # 140 dB apart
    x = a1 * np.sin(2 * np.pi * 1000 * t) + a2 * np.sin(2 * np.pi * 20_000 * t)
    fc, lev = fd.tapered_band_levels(x, fs)
    i1 = int(np.argmin(abs(fc - 1000)))
    i2 = int(np.argmin(abs(fc - 19_953)))
    assert lev[i1] == pytest.approx(20 * math.log10(a1 / math.sqrt(2) / 1e-6), abs=0.01)
    assert lev[i2] == pytest.approx(20 * math.log10(a2 / math.sqrt(2) / 1e-6), abs=0.01)


def test_tapered_band_levels_suppress_leakage_of_a_truncated_record():
    # a 7.3 Hz tone cut off mid-cycle: the rectangular window leaks a 1/f^2 floor into every
    # band; the taper must keep the 5-20 kHz bands far lower
    fs = 1e5
    t = np.arange(28_571) / fs
    x = np.sin(2 * np.pi * 7.3 * t + 0.4)
    fc, rect = band_levels(x, fs)
    fc2, tap = fd.tapered_band_levels(x, fs)
    assert np.allclose(fc, fc2)
    hi = (fc > 5e3) & (fc < 2e4)
    assert np.all(tap[hi] < rect[hi] - 40.0)


def test_tapered_band_levels_white_noise_density():
    fs, n = 1e5, 200_000
    x = np.random.default_rng(3).standard_normal(n) * 0.01
    fc, lev = fd.tapered_band_levels(x, fs, fmin=1000, fmax=20_000)
    lo, hi = fc * 10 ** (-1 / 20), fc * 10 ** (1 / 20)
    expected = 10 * np.log10(0.01**2 * (hi - lo) / (fs / 2) / 1e-12)
    assert np.max(np.abs(lev - expected)) < 0.5


def _sdof_result(stiffness: float, mass: float, damping: float) -> Result:
    """A block on springs over a base moving as band-limited noise, in closed form."""
    scene = Scene().with_overrides({"block.mass": mass, "block.vertical_damping": damping,
                                    "contact.stiffness": stiffness, "output.duration": 1.0})
    fs, n, K = 1e5, 100_000, 2
    rng = np.random.default_rng(7)
    f = np.fft.rfftfreq(n, 1 / fs)
    U = (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)) * (f < 5000)
    U[0] = 0
    w = 2 * np.pi * f
    T = stiffness / (stiffness - mass * w**2 + 1j * w * damping)  # m z'' = -r z' - s (z - u)
    u = np.fft.irfft(U, n)
    u *= 1e-8 / np.std(u)
    z_dyn = np.fft.irfft(np.fft.rfft(u) * T, n)
    z = mass * 9.81 / stiffness + z_dyn
    F = (stiffness / K) * (z - u)
    assert F.min() > 0
    ds = xr.Dataset({"block_vertical_displacement": ("time", z),
                     "contact_force": (("time", "contact"), np.repeat(F[:, None], K, 1))},
                    coords={"time": np.arange(n) / fs, "contact": np.arange(K)})
    summary = {"model": {"contact_stiffness_total": stiffness}}
    return Result(ds, pd.DataFrame(columns=EVENT_COLUMNS), summary, scene_to_toml(scene))


def test_transmissibility_peaks_at_the_spring_mass_resonance():
    s, m, r = 3.1e6, 0.221, 20.0
    res = _sdof_result(s, m, r)
    f, T = fd.transmissibility(res, resolution=10.0)
    fn = math.sqrt(s / m) / (2 * math.pi)
    below = (f > 20) & (f < 0.2 * fn)
    assert np.allclose(T[below], 1.0, atol=0.06)
    sel = (f > 100) & (f < 3000)
    assert abs(f[sel][np.argmax(T[sel])] - fn) <= 10.0
    far = (f > 3 * fn) & (f < 4000)
    assert np.allclose(T[far], (fn / f[far]) ** 2, rtol=0.15)


def test_velocity_sweep_recovers_a_power_law():
    v = np.array([0.01, 0.02, 0.04, 0.1])
    runs = []
    for vi in v:
        summ = {"scene": "x", "metrics": {
            "block_tangential_velocity_rms": vi, "stick_fraction": 0.0,
            "block_vertical_acceleration_level_db_re_1e-6": 10 * 3.2 * math.log10(vi) + 150,
            "plate_vertical_acceleration_level_db_re_1e-6": 10 * 3.5 * math.log10(vi) + 160}}
        runs.append(Result(xr.Dataset(), pd.DataFrame(), summ, ""))
    table, fits = fd.velocity_sweep(runs[::-1])
    assert list(table["v_rms"]) == sorted(v)
    assert fits["block"].exponent == pytest.approx(3.2)
    assert fits["plate"].db_per_doubling == pytest.approx(3.5 * 10 * math.log10(2))


def test_stiffness_guard_and_contact_input_stroke(run):
    result, _ = run
    loop, k, guard = fd.tangential_stiffness(result, v_guard=1e-5)
    assert guard == 1e-5
    assert np.all(np.isnan(k[np.abs(loop.velocity) < 1e-5]))
    cs = fd.contact_input_spectra(result, contact=0)
    x = result.dataset["block_tangential_displacement"].values[fd.analysis_window(result)]
    assert cs.stroke == pytest.approx(np.ptp(x))
    # the contact's spectrum has no bin between 0 and about 2 pi / stroke
    assert cs.k_contact[1] == pytest.approx(2 * np.pi / cs.stroke, rel=0.5)
    with pytest.raises(ValueError, match="contact must be"):
        fd.contact_input_spectra(result, contact=99)


def _timeline_result(n_contacts: int, events: list[dict]) -> Result:
    """A 0.4 s Result that holds only its time axis, contacts and event log."""
    ds = xr.Dataset(coords={"time": np.linspace(0.0, 0.4, 401),
                            "contact": np.arange(n_contacts)})
    return Result(ds, pd.DataFrame(events, columns=EVENT_COLUMNS), {}, "")


def test_events_figure_says_no_lift_off_when_no_contact_opens(run):
    result, _ = run
    # the contact force stays positive throughout: the contact never opens
    assert float(result.dataset["contact_force"].min()) > 0.0
    tl = fd.regime_timeline(result)
    assert not tl.lifts_off and tl.lift_off == [[]] * result.dataset.sizes["contact"]
    assert tl.stick  # the block does stick: the panel is not empty
    ax = FIGURES["events"](result).axes[2]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["lift-off", "block stick"]
    k = result.dataset.sizes["contact"]
    assert [t.get_text() for t in ax.texts] == [
        "none: the contact stays closed throughout" if k == 1
        else f"none: all {k} contacts stay closed throughout"]
    assert "no lift-off" in ax.get_title() and "red" not in ax.get_title()
    # several contacts, none of which opens: one row for all of them
    ax = plots.plot_regime_timeline(_timeline_result(3, []))
    assert [t.get_text() for t in ax.texts] == ["none: all 3 contacts stay closed throughout"]


def test_events_figure_draws_a_row_per_contact_when_one_lifts_off():
    result = _timeline_result(3, [{"time": 0.1, "kind": "lift_off", "contact": 1},
                                  {"time": 0.15, "kind": "touch_down", "contact": 1},
                                  {"time": 0.3, "kind": "lift_off", "contact": 2}])
    tl = fd.regime_timeline(result)
    # contact 2 is still open when the run ends
    assert tl.lifts_off and tl.lift_off == [[], [(0.1, 0.15)], [(0.3, 0.4)]]
    ax = plots.plot_regime_timeline(result)
    assert [t.get_text() for t in ax.get_yticklabels()] == ["contact 0", "contact 1",
                                                            "contact 2", "block stick"]
    assert "red: contact open" in ax.get_title() and not ax.texts


def test_stiffness_scale_covers_the_slip_branch_not_the_spikes():
    rng = np.random.default_rng(1)
    slip = rng.uniform(-1e3, 1e3, 2000)  # |dT/dx| uniform on [0, 1e3] N/m
    k = np.concatenate([slip, [5e8, -5e8], np.full(300, 4e5), [np.nan]])
    stick = np.r_[np.zeros(2002, dtype=bool), np.ones(301, dtype=bool)]
    sc = fd.stiffness_scale(k, stick)
    assert sc.limit == pytest.approx(950.0, rel=0.03)  # the 95 % quantile of |U(-1e3, 1e3)|
    assert sc.stick_median == 4e5 and sc.coverage == 0.95
    assert sc.beyond == pytest.approx((0.05 * 2000 + 2 + 300) / 2302, abs=0.01)
    with pytest.raises(ValueError, match="coverage must be in"):
        fd.stiffness_scale(k, stick, coverage=0.0)


def test_stiffness_panel_is_linear_over_the_slip_branch(run):
    result, _ = run
    loop, k, _ = fd.tangential_stiffness(result)
    sc = fd.stiffness_scale(k, loop.stick)
    # paper Fig. 9b: in stick dT/dx is far above its value in slip
    assert sc.stick_median > 5 * sc.limit
    ax = plots.plot_tangential_stiffness(result)
    assert ax.get_yscale() == "linear"
    assert ax.get_ylim() == pytest.approx((-1.1e-3 * sc.limit, 1.1e-3 * sc.limit))
    said = re.search(r"median ([0-9.]+) (kN|MN)/m, off the scale", ax.get_title())
    assert said, ax.get_title()
    value = float(said[1]) * {"kN": 1e3, "MN": 1e6}[said[2]]
    assert value == pytest.approx(sc.stick_median, rel=5e-3)


def test_contact_resonance_spring_mass_from_the_scene(run):
    result, _ = run
    scene = fd.scene_of(result)
    cr = fd.contact_resonance(result)
    F = result.dataset["contact_force"].values[fd.analysis_window(result)]
    closed = float(np.mean(F > 0))
    expected = math.sqrt(scene.contact.stiffness * closed / scene.block.mass) / (2 * math.pi)
    assert cr.spring_mass == pytest.approx(expected, rel=1e-12)


# --------------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------------

_VOID = {"meta", "img", "br", "hr", "link", "input", "col", "area", "base", "source", "wbr"}


class _Checker(HTMLParser):
    """Collects images, links and ids, and checks that elements nest and close."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.imgs: list[dict] = []
        self.ids: set[str] = set()
        self.tags: set[str] = set()
        self.refs: list[str] = []
        self.text: list[str] = []
        self.doctype = False

    def handle_decl(self, decl):
        self.doctype = decl.lower() == "doctype html"

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.add(tag)
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "img":
            self.imgs.append(a)
        for key in ("src", "href"):
            if key in a and tag != "img":
                self.refs.append(a[key])
        if tag not in _VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
        else:
            self.stack.pop()

    def handle_data(self, data):
        self.text.append(data)


@pytest.fixture(scope="module")
def report(run):
    _, out = run
    path = write_report(out)
    return path


def test_report_is_valid_self_contained_html(report):
    text = report.read_text(encoding="utf-8")
    p = _Checker()
    p.feed(text)
    p.close()
    assert p.doctype
    assert not p.errors and not p.stack, (p.errors, p.stack)
    assert {"html", "head", "body", "title", "table", "pre"} <= p.tags
    assert "script" not in p.tags and "link" not in p.tags
    assert all(r.startswith("#") for r in p.refs), p.refs  # in-page links only
    for img in p.imgs:
        assert img["src"].startswith("data:image/png;base64,")


def test_report_embeds_every_figure(report):
    p = _Checker()
    p.feed(report.read_text(encoding="utf-8"))
    for name in FIGURES:
        assert f"fig-{name}" in p.ids
    imgs = {img["alt"]: img["src"] for img in p.imgs}
    assert set(imgs) == {f"figure {name}" for name in FIGURES}
    for src in imgs.values():
        png = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert png.startswith(PNG_MAGIC)


def test_report_holds_scene_tables_and_phase_table(run, report):
    result, _ = run
    p = _Checker()
    p.feed(report.read_text(encoding="utf-8"))
    text = " ".join(p.text)
    for section in ("levels", "resonance", "bands", "model", "solver", "energy", "phases",
                    "figures", "scene"):
        assert section in p.ids
    assert "[block]" in text and "mass = 0.221" in text  # the scene, unescaped by the parser
    assert "stick fraction [-]" in text and "dB re 1e-6 m/s²" in text
    steps = result.summary["solver"]["steps"]
    assert re.search(rf"\bsteps\b\s+{steps}\b", text)


def test_report_of_a_failed_run(tmp_path):
    summary = {"format_version": 1, "status": "event_storm", "message": "too many events",
               "scene": "paper", "solver": {"steps": 12}, "last_events": [
                   {"time": 0.1, "kind": "lift_off", "contact": 3, "tangential_velocity": 0.0,
                    "normal_force": 1.0}]}
    Result(xr.Dataset(), pd.DataFrame(columns=EVENT_COLUMNS), summary,
           scene_to_toml(Scene())).save(tmp_path / "bad")
    path = write_report(tmp_path / "bad")
    p = _Checker()
    p.feed(path.read_text(encoding="utf-8"))
    assert not p.errors and not p.imgs
    assert "event_storm" in " ".join(p.text) and "last-events" in p.ids


def test_build_report_escapes_text():
    summ = {"status": "x<y>", "message": "<script>alert(1)</script>", "scene": "a&b"}
    html = build_report(Result(xr.Dataset(), pd.DataFrame(columns=EVENT_COLUMNS), summ,
                               "name = '<b>'"))
    assert "<script>" not in html and "&lt;script&gt;" in html


def test_report_cli_handler_and_a_broken_figure(run, tmp_path, capsys, monkeypatch):
    """``roughvib report`` writes the report and prints its path; a figure that raises is a
    note in the report, not a failed report (one test: as two, each drew every figure, 2.8 s)."""
    from roughvib.views import figures as plots

    def broken(result):
        raise RuntimeError("no ink")

    monkeypatch.setitem(plots.FIGURES, "broken", broken)
    _, out = run
    parser = argparse.ArgumentParser(prog="roughvib")
    add_parsers(parser.add_subparsers(dest="command"))
    target = tmp_path / "r.html"
    args = parser.parse_args(["report", str(out), "--out", str(target), "--dpi", "40"])
    assert args.func(args) == 0
    assert target.exists() and capsys.readouterr().out.strip() == str(target)
    p = _Checker()
    p.feed(target.read_text(encoding="utf-8"))
    assert not p.errors and "fig-broken" in p.ids
    assert "could not be drawn: RuntimeError: no ink" in " ".join(p.text)
    assert len(p.imgs) == len(plots.FIGURES) - 1
    args = parser.parse_args(["report", str(tmp_path / "nowhere")])
    assert args.func(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("roughvib: error:") and "nowhere" in err
    sub = parser._subparsers._group_actions[0].choices["report"]
    assert "example" in sub.epilog and sub.formatter_class is argparse.RawDescriptionHelpFormatter


def test_report_in_headless_chromium(report, tmp_path):
    seen = inspect_page(report, tmp_path)
    assert seen["ready"] == "complete" and seen["title"].startswith("roughvib report")
    assert seen["text_length"] > 1000
    assert len(seen["images"]) == len(FIGURES)
    for img in seen["images"]:
        assert img["decoded"] and img["width"] > 0 and img["height"] > 0, img
        assert img["inked_pixels"] > 100, img  # not a blank picture
        assert img["shown_width"] > 0 and img["shown_height"] > 0, img
    nav = [link for link in seen["links"] if link["href"].startswith("#")]
    assert len(nav) >= 8 and len(nav) == len(seen["links"])
    assert all(link["resolves"] and link["shown"] for link in nav), nav


def test_report_screenshot_in_headless_chromium(report, tmp_path):
    import matplotlib.image as mpimg

    shot = tmp_path / "report.png"
    cmd = [chromium(), *FLAGS, f"--user-data-dir={tmp_path / 'profile'}",
           f"--screenshot={shot}", "--window-size=1200,2400", report.resolve().as_uri()]
    proc = subprocess.run(cmd, capture_output=True, timeout=180, check=False)
    assert shot.exists(), proc.stderr.decode(errors="replace")[-2000:]
    img = mpimg.imread(shot)
    assert img.shape[0] >= 2000 and img.shape[1] >= 1100
    # a page that rendered text, tables and figures is not one flat colour
    assert float(np.std(img[..., :3])) > 0.02


def _tone_result(block: np.ndarray, plate: np.ndarray, fs: float) -> Result:
    """A Result that holds only the two accelerations (on a 1 s scene)."""
    scene = Scene().with_overrides({"output.duration": 1.0})
    ds = xr.Dataset({fd.ACCELERATIONS[0]: ("time", block), fd.ACCELERATIONS[1]: ("time", plate)},
                    coords={"time": np.arange(block.size) / fs})
    return Result(ds, pd.DataFrame(columns=EVENT_COLUMNS), {}, scene_to_toml(scene))


def test_acceleration_spectra_filters_from_the_record_start_and_averages_over_the_window():
    # a loud 100 Hz tone and a tone 120 dB below it at 10 kHz; the filter bank (run from
    # t = 0, averaged over the window) reads both; filters started at the window would ring
    # in on the loud tone's onset and bury the quiet one
    fs = 1e5
    t = np.arange(100_001) / fs
    loud, quiet = 1.0, 1e-6
    block = loud * np.sin(2 * np.pi * 100 * t + 0.5) + quiet * np.sin(2 * np.pi * 10e3 * t)
    res = _tone_result(block, 0.5 * block, fs)
    win = fd.analysis_window(res)
    assert win.start > 0  # there is a run-in to settle the filters
    sp = fd.acceleration_spectra(res)
    assert sp.band_method == "filter"
    i100 = int(np.argmin(abs(sp.centres - 100)))
    i10k = int(np.argmin(abs(sp.centres - 10e3)))
    expect = 20 * math.log10(quiet / math.sqrt(2) / 1e-6)
    assert sp.band_db["block"][i100] == pytest.approx(expect + 120, abs=0.1)
    assert sp.band_db["block"][i10k] == pytest.approx(expect, abs=0.2)
    assert sp.band_db["plate"][i10k] == pytest.approx(expect - 20 * math.log10(2), abs=0.2)
    from roughvib.analysis.bands import band_levels as bank_levels

    cold = bank_levels(block[win], fs, fmax=50e3)  # the filters started at the window
    assert cold.level_db[i10k] > expect + 20
    # band_method="fft" is the Hann-tapered FFT band sum of the window
    sf = fd.acceleration_spectra(res, band_method="fft")
    np.testing.assert_array_equal(sf.band_db["block"],
                                  fd.tapered_band_levels(block[win], fs)[1])


def _kv_rows(html_text: str, section: str) -> list[tuple[str, str, str]]:
    """The (quantity, value, unit) rows of the quantity/value/unit tables of one section."""
    body = html_text.split(f"<section id='{section}'>", 1)[1].split("</section>", 1)[0]
    cell = r"<td(?: class='key')?>(.*?)</td>"
    return [tuple(html.unescape(c) for c in m.groups())
            for m in re.finditer(rf"<tr>{cell}{cell}{cell}</tr>", body)]


def _significant_digits(text: str) -> int:
    mantissa = text.lstrip("-").split("e")[0].replace(".", "").lstrip("0")
    return len(mantissa)


def test_report_solver_statistics_read_as_labels_with_units(run, report):
    result, _ = run
    solver = result.summary["solver"]
    text = report.read_text(encoding="utf-8")
    rows = _kv_rows(text, "solver")
    by_label = {q: (v, u) for q, v, u in rows}
    assert len(rows) >= 10
    for q, _, _ in rows:  # labels, not the summary's keys
        assert "_" not in q, q
    assert by_label["largest step taken"] == (f"{solver['largest_step']:.4g}", "s")
    assert by_label["steps"] == (str(solver["steps"]), "")  # a count: whole, no unit
    assert by_label["solver wall time"][1] == "s"
    assert by_label["relative tolerance (rtol)"] == (f"{solver['rtol']:.4g}", "-")
    for kind, n in result.summary["events_by_kind"].items():
        assert by_label[f"events: {kind.replace('_', ' ')}"] == (str(n), "")
    # every number of the report's quantity tables with at most 4 significant digits
    for section in ("levels", "model", "solver", "energy"):
        for q, v, _ in _kv_rows(text, section):
            if re.fullmatch(r"-?\d+(\.\d+)?(e[-+]\d+)?", v) and ("." in v or "e" in v):
                assert _significant_digits(v) <= 4, (section, q, v)
    energy = {q for q, _, _ in _kv_rows(text, "energy")}
    assert "dissipated by friction" in energy and all("_" not in q for q in energy)


def test_energy_audit_that_was_not_computed_is_one_note_not_a_table_of_na():
    """A `solver.method = "paper"` run keeps no energy integrals: its summary holds an audit of
    None values and a note saying why; the report shows the note (escaped), not n/a rows."""
    note = "not computed: solver.method = 'paper' keeps no energy integrals <no states>"
    audit = {"excitation_work": None, "friction_dissipation": None, "residual": None,
             "relative_residual": None, "t_end": 0.2}
    summ = {"status": "success", "message": "ok", "scene": "paper",
            "energy_audit": audit, "energy_audit_note": note}
    text = build_report(Result(xr.Dataset(), pd.DataFrame(columns=EVENT_COLUMNS), summ, ""))
    assert not _kv_rows(text, "energy")
    assert f"<p class='note'>energy audit {html.escape(note)}</p>" in text
    # an audit of None values without a note (a summary written before the note existed)
    del summ["energy_audit_note"]
    text = build_report(Result(xr.Dataset(), pd.DataFrame(columns=EVENT_COLUMNS), summ, ""))
    assert not _kv_rows(text, "energy")
    assert "<p class='note'>energy audit not computed</p>" in text
