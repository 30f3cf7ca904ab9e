"""A measured record against a run (roughvib validate): closed-form checks on records made from
the run's own signal.

A record that *is* the run's plate signal must read 0 dB in every band; twice that signal
+20 log10(2) = +6.02 dB; the signal resampled to another rate the same levels, except in the
bands the lower rate cannot hold, which are left out and named; white noise of known rms puts a
floor at ``rms**2 * bandwidth / (fs/2)`` under the bands it swamps. Each record goes through a
file and the reader, as a measurement would.
"""

import json
import math
import shutil

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from scipy.io import wavfile
from scipy.signal import resample_poly

from roughvib.analysis.spectra import add_noise_floor
from roughvib.analysis.validation import (
    compare_record,
    noise_rms_band_levels,
    validation_velocity_exponent,
)
from roughvib.records import Record, RecordError, export_run, read_record
from roughvib.results import SUMMARY_DIGEST, load_result, seal_summary
from roughvib.views.validation import validate, validation_section

DB2 = 20 * math.log10(2.0)  # 6.0206 dB


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The paper scene for 0.3 s: one whole excitation period after the run-in."""
    import roughvib

    scene = roughvib.load_scene("paper", {"output.duration": 0.3, "output.progress": False})
    d = tmp_path_factory.mktemp("validation") / "run"
    roughvib.simulate(scene).save(d)
    result = load_result(d)
    return d, result, result.dataset["plate_vertical_acceleration"].values


def _wav(path, x, fs, scale):
    wavfile.write(path, int(fs), (np.asarray(x) / scale).astype(np.float32))
    return path


class _Done:
    def __init__(self, returncode, out):
        self.returncode, self.stdout, self.stderr = returncode, out.out, out.err


@pytest.fixture
def cli(capsys, monkeypatch, tmp_path):
    """``roughvib ARGS`` in this process (the CLI's main), run in tmp_path."""
    from roughvib.cli import main

    monkeypatch.chdir(tmp_path)

    def run(*args):
        capsys.readouterr()
        status = main([str(a) for a in args])
        return _Done(status, capsys.readouterr())
    return run


def test_own_signal_reads_zero_db_and_twice_reads_six(run, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    d, result, x = run
    (csv,) = export_run(d, "csv", out=tmp_path)
    v0 = compare_record(result, read_record(csv, column="plate_acceleration"))
    assert len(v0.table) >= 20 and not v0.left_out
    assert np.all(np.abs(v0.table["difference_db"]) <= 0.05)
    assert abs(v0.overall_difference_db) <= 0.05
    twice = read_record(_wav(tmp_path / "twice.wav", 2 * x, 100000, scale=10.0), scale=10.0)
    v2 = compare_record(result, twice)
    np.testing.assert_allclose(v2.table["difference_db"], DB2, atol=0.05)
    assert v2.overall_difference_db == pytest.approx(DB2, abs=0.05)
    # the same bands on both sides, and the simulated column is the run's own
    np.testing.assert_array_equal(v0.table["band_hz"], v2.table["band_hz"])
    np.testing.assert_allclose(v0.table["simulated_db"], v2.table["simulated_db"], rtol=0)


def test_96_khz_record_lines_up(run, tmp_path):
    """resample_poly (Kaiser beta 9) to 96 kHz: within 0.1 dB to 31.5 kHz; the 40 kHz band
    reaches 44.7 kHz, 93 % of the record's Nyquist frequency, in the resampling filter's
    transition band (measured -0.18 dB there), so 0.5 dB. No band is lost: the run (100 kHz)
    and the record both hold bands up to 40 kHz."""
    d, result, x = run
    y = resample_poly(x, 24, 25, window=("kaiser", 9.0))
    rec = read_record(_wav(tmp_path / "r96k.wav", y, 96000, scale=10.0), scale=10.0)
    v = compare_record(result, rec)
    assert v.fs_record == 96000 and v.table["band_hz"].iloc[-1] == 40000
    low = v.table["band_hz"] <= 31500
    assert np.all(np.abs(v.table["difference_db"][low]) <= 0.1)
    assert np.all(np.abs(v.table["difference_db"][~low]) <= 0.5)
    assert not v.left_out
    assert any("96000 Hz" in n for n in v.notes)


def test_bands_above_the_record_nyquist_are_left_out_and_said(run, tmp_path):
    """At 88.2 kHz the 40 kHz band (upper edge 44.67 kHz) is above the Nyquist frequency.

    The levels still line up, within the two filter banks' difference: designed at 100 kHz and
    at 88.2 kHz, a band may be filtered at another decimation stage, and a band much quieter
    than a neighbour picks up a different share of the neighbour's skirt (both within class 1).
    Measured: at most 0.05 dB where no neighbour is 8 dB louder, 0.28 dB elsewhere (the 2.5 kHz
    band, 15 dB below a neighbour)."""
    d, result, x = run
    y = resample_poly(x, 441, 500, window=("kaiser", 12.0))
    rec = read_record(_wav(tmp_path / "r88k.wav", y, 88200, scale=10.0), scale=10.0)
    v = compare_record(result, rec)
    assert v.table["band_hz"].iloc[-1] == 31500
    assert [f for f, _ in v.left_out] == [40000]
    assert "Nyquist" in v.left_out[0][1]
    assert "left out: 40 kHz (above the record's Nyquist frequency 44.1 kHz)" in \
        v.summary_line()
    lv = v.table["simulated_db"].to_numpy()
    louder_neighbour = np.maximum(np.r_[lv[1:], -np.inf], np.r_[-np.inf, lv[:-1]]) - lv
    d = np.abs(v.table["difference_db"].to_numpy())
    assert np.all(d[louder_neighbour < 8.0] <= 0.1)
    assert np.all(d <= 1.0)


def test_white_noise_floor_marks_the_swamped_bands(run, tmp_path):
    d, result, x = run
    sigma = 3e-3  # m/s^2 rms, white to 50 kHz: 70 dB re 1e-6 m/s^2 overall
    noisy = add_noise_floor(x, 100000, sigma, seed=1)
    rec = read_record(_wav(tmp_path / "noisy.wav", noisy, 100000, 10.0), scale=10.0)
    v = compare_record(result, rec, noise_rms=sigma)
    t = v.table
    # the floor is the closed form rms^2 * bandwidth / (fs/2)
    fc = 1000 * 10 ** (np.rint(10 * np.log10(t["band_hz"] / 1000)) / 10)
    np.testing.assert_allclose(t["noise_db"], noise_rms_band_levels(fc, sigma, 100000))
    under = t["simulated_db"] < t["noise_db"] - 10
    over = t["simulated_db"] > t["noise_db"] + 10
    assert under.sum() >= 3 and over.sum() >= 10
    assert t["at_noise_floor"][under].all() and not t["at_noise_floor"][over].any()
    # swamped bands read the floor (within the scatter of a 0.14 s noise record)
    np.testing.assert_allclose(t["measured_db"][under], t["noise_db"][under], atol=1.5)
    # the largest difference reported (summary, report) is that of the bands above the floor
    clear = ~t["at_noise_floor"].astype(bool)
    largest = v.to_summary()["max_abs_difference_db"]
    assert largest == pytest.approx(t["difference_db"][clear].abs().max())
    assert largest < t["difference_db"][under].abs().min()
    # a measured noise record instead of the rms: the same bands are marked
    noise = add_noise_floor(np.zeros_like(x), 100000, sigma, seed=2)
    nrec = read_record(_wav(tmp_path / "noise.wav", noise, 100000, 10.0), scale=10.0)
    vn = compare_record(result, rec, noise=nrec)
    assert vn.table["at_noise_floor"][under].all()
    assert not vn.table["at_noise_floor"][over].any()


@pytest.mark.parametrize("kind", ["short", "rate"])
def test_short_or_slow_records_are_refused_in_one_line(run, tmp_path, kind, cli):
    d, result, x = run
    if kind == "short":  # 0.1 s < one period of 7 Hz
        p = _wav(tmp_path / "short.wav", x[:10000], 100000, 10.0)
    else:  # 48 kHz cannot hold the 40 kHz band
        p = _wav(tmp_path / "slow.wav", resample_poly(x, 12, 25), 48000, 10.0)
    with pytest.raises(RecordError) as e:
        compare_record(result, read_record(p, scale=10.0))
    assert "\n" not in str(e.value) and p.name in str(e.value)
    work = tmp_path / "run"  # the module's run stays without validations
    shutil.copytree(d, work)
    proc = cli("validate", work, p, "--signal", "plate", "--scale", 10)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and p.name in proc.stderr
    if kind == "rate":  # what the refusal proposes works
        ok = cli("validate", work, p, "--signal", "plate", "--scale", 10, "--fmax", 20000)
        assert ok.returncode == 0, ok.stderr


def test_validate_writes_the_files_and_the_report_lists_them(run, tmp_path, cli):
    d, result, x = run
    work = tmp_path / "run"
    shutil.copytree(d, work)
    rec = _wav(tmp_path / "lab.wav", 2 * x, 100000, 10.0)
    proc = cli("validate", work, rec, "--signal", "plate", "--scale", 10, "--noise-rms",
                1e-4)
    assert proc.returncode == 0, proc.stderr
    assert len(proc.stdout.strip().splitlines()) == 1 and "overall +6.02 dB" in proc.stdout
    folder = work / "validation" / "lab"
    bands = pd.read_csv(folder / "bands.csv")
    assert list(bands.columns) == ["band_hz", "simulated_db", "measured_db", "difference_db",
                                   "noise_db", "at_noise_floor"]
    np.testing.assert_allclose(bands["measured_db"] - bands["simulated_db"],
                               bands["difference_db"], atol=2e-4)
    s = json.loads((folder / "validation.json").read_text())
    assert s["overall_difference_db"] == pytest.approx(DB2, abs=0.05)
    assert (folder / "validation.png").stat().st_size > 10000
    html = validation_section(work)
    assert "lab.wav" in html and "+6.02" in html and "data:image/png;base64," in html
    assert validation_section(d) is None  # the untouched run has none
    # the run report shows it (a bare result: no figures of its own to draw)
    from roughvib.results import EVENT_COLUMNS, Result
    from roughvib.views.report import build_report

    bare = Result(xr.Dataset(), pd.DataFrame(columns=EVENT_COLUMNS),
                  {"status": "failed", "scene": "paper"}, "")
    page = build_report(bare, run_dir=work)
    assert "Validation against measurements" in page and "lab.wav" in page
    assert "Validation against measurements" not in build_report(bare, run_dir=d)
    # a block record against the plate's run is compared too, as asked, just differently
    vb = validate(work, [rec], signal="block", scale=10.0)[0]
    assert vb.signal == "block"
    assert not np.allclose(vb.table["difference_db"], DB2, atol=0.05)


def test_velocity_exponent_of_measured_and_simulated_levels(run, tmp_path, cli):
    """Two 'runs' whose friction velocities differ by a factor 2 (a copy of the run with its
    v_rms doubled in summary.json, sealed again), with records at 1x and 2x the signal:
    measured levels rise 6.02 dB per doubling, simulated ones 0."""
    d, result, x = run
    a, b = tmp_path / "a", tmp_path / "b"
    shutil.copytree(d, a)
    shutil.copytree(d, b)
    s = json.loads((b / "summary.json").read_text())
    s["metrics"]["block_tangential_velocity_rms"] *= 2
    s.pop(SUMMARY_DIGEST)  # a run at twice the velocity: sealed as the run would seal it
    (b / "summary.json").write_text(json.dumps(seal_summary(s)))
    ra = _wav(tmp_path / "va.wav", x, 100000, 10.0)
    rb = _wav(tmp_path / "vb.wav", 2 * x, 100000, 10.0)
    proc = cli("validate", a, ra, b, rb, "--signal", "plate", "--scale", 10)
    assert proc.returncode == 0, proc.stderr
    last = proc.stdout.strip().splitlines()[-1]
    assert last.startswith("velocity exponent (plate, 2 runs): measured 6.02 dB per doubling")
    assert "simulated 0.00 dB per doubling" in last or "simulated -0.00 dB" in last
    # and the fit itself on three points of a known slope
    pts = [{"v_rms": v, "overall_measured_db": 9.5 * math.log2(v) + 1,
            "overall_simulated_db": 9.0 * math.log2(v)} for v in (0.005, 0.01, 0.02)]
    e = validation_velocity_exponent(pts)
    assert e["measured"]["db_per_doubling"] == pytest.approx(9.5, abs=1e-9)
    assert e["simulated"]["exponent"] == pytest.approx(9.0 / (10 * math.log10(2)), abs=1e-9)


def test_record_dataclass_refuses_nan_in_one_line():
    with pytest.raises(RecordError) as e:
        Record("lab/x.wav", np.array([0.0, np.nan, 1.0]), 1000.0, "m/s^2", "option", "c")
    assert "\n" not in str(e.value) and "lab/x.wav" in str(e.value)


@pytest.mark.parametrize("kind", ["nan", "units"])
def test_cli_refuses_nan_and_unknown_units_in_one_line(run, tmp_path, cli, kind):
    d, result, x = run
    t = np.arange(x.size) * 1e-5
    y = x.copy()
    unit = "furlong/s^2" if kind == "units" else "m/s^2"
    if kind == "nan":
        y[1234] = np.nan
    p = tmp_path / f"lab_{kind}.csv"
    np.savetxt(p, np.column_stack([t, y]), fmt="%.12g", delimiter=",",
               header=f"time [s],plate [{unit}]", comments="")
    proc = cli("validate", d, p, "--signal", "plate")
    assert proc.returncode == 2 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("roughvib: error: ") and p.name in lines[0]
    assert not (d / "validation").exists()


def test_lab_commands_have_help_with_examples(capsys):
    from roughvib.cli import build_parser

    for cmd in ("validate", "export"):
        with pytest.raises(SystemExit) as info:
            build_parser().parse_args([cmd, "--help"])
        assert info.value.code == 0
        out = capsys.readouterr().out
        assert "examples:" in out and f"roughvib {cmd} runs/paper" in out


def test_the_overall_levels_name_their_method_and_the_summarys_level(run, tmp_path, monkeypatch):
    """'simulated 100.0 dB' beside the summary's 100.1 dB for the same window: two methods.
    The line says its overall levels are energy sums of the compared bands (checked against
    the table) and gives the summary's level as what it is, the broadband rms of the window
    (checked against the time series)."""
    from roughvib.analysis import figures_data as fd

    monkeypatch.chdir(tmp_path)
    d, result, x = run
    (csv,) = export_run(d, "csv", out=tmp_path)
    v = compare_record(result, read_record(csv, column="plate_acceleration"))
    band_sum = 10 * math.log10(np.sum(10 ** (v.table["simulated_db"].to_numpy() / 10)))
    assert v.overall_simulated_db == pytest.approx(band_sum, abs=1e-9)
    win = fd.analysis_window(result)
    broadband = 20 * math.log10(np.sqrt(np.mean(x[win] ** 2)) / 1e-6)
    assert v.info["simulated_broadband_db"] == pytest.approx(broadband, abs=1e-6)
    line = v.summary_line()
    assert (f"simulated {band_sum:.1f} dB re 1e-6 m/s^2, energy sums of the bands compared; "
            f"the run summary's {broadband:.1f} dB is the broadband rms)") in line
    assert json.loads(json.dumps(v.to_summary()))["simulated_broadband_db"] == \
        pytest.approx(broadband, abs=1e-6)
    # the figure's legend says the same: its level is the band sum, not a "total" of the signal
    import matplotlib.pyplot as plt

    from roughvib.views.validation import plot_validation

    axes = plot_validation(v)
    labels = [t.get_text() for t in axes[0].get_legend().get_texts()]
    plt.close(axes[0].figure)
    assert labels[0] == f"simulated {v.signal}, band sum {band_sum:.1f} dB"
    assert labels[1] == f"measured ({csv.name}), band sum {v.overall_measured_db:.1f} dB"
