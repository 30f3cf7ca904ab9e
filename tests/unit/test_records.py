"""Measured records in (CSV, WAV, UFF 58, TDMS) and a run's exchange files out (roughvib.records).

The readers are checked on one synthetic record written by independent writers (numpy text,
scipy.io.wavfile and the standard library's wave module, pyuff, npTDMS) with the units and
scales of real instruments: each must give back the same samples in m/s^2 and the same rate,
to the resolution of its format. The exports are read back with pyuff and scipy.io.wavfile
(not with roughvib's readers) and compared with the run's own dataset.
"""

import json
import math
import wave

import numpy as np
import pytest
from scipy.io import wavfile

from roughvib.records import G_N, RecordError, export_run, read_record

FS = 96000.0


@pytest.fixture(scope="module")
def record():
    """A 0.2 s record at 96 kHz [m/s^2]: two tones and noise, peak about 30 m/s^2."""
    rng = np.random.default_rng(3)
    t = np.arange(int(0.2 * FS)) / FS
    x = 20 * np.sin(2 * np.pi * 440 * t) + 5 * np.sin(2 * np.pi * 9100 * t + 1)
    return t, x + rng.normal(0, 1.0, t.size)


def _one_line(exc: Exception, name: str) -> None:
    msg = str(exc)
    assert "\n" not in msg and name in msg, msg


# --------------------------------------------------------------------------------------------
# readers
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("header", "factor"), [("acceleration [g]", G_N),
                                                ("acceleration [m/s^2]", 1.0),
                                                ("plate (mm/s²)", 1e-3)])
def test_csv_header_units_are_honoured(tmp_path, record, header, factor):
    t, x = record
    p = tmp_path / "rec.csv"
    np.savetxt(p, np.column_stack([t, x / factor]), fmt="%.15g", delimiter=",",
               header=f"time [s],{header}", comments="")
    r = read_record(p)
    assert r.fs == pytest.approx(FS, rel=1e-12)
    assert r.units_from == "file"
    np.testing.assert_allclose(r.signal, x, rtol=1e-13, atol=1e-13)


def test_csv_without_units_takes_the_option_and_refuses_without(tmp_path, record):
    t, x = record
    p = tmp_path / "bare.txt"
    np.savetxt(p, np.column_stack([t * 1e3, x / G_N]), fmt="%.15g",
               header="t (ms)  a", comments="")  # blank-separated, time in ms
    r = read_record(p, units="g")
    assert (r.units, r.units_from) == ("g", "option")
    np.testing.assert_allclose(r.signal, x, rtol=1e-12, atol=1e-12)
    assert r.fs == pytest.approx(FS, rel=1e-9)
    with pytest.raises(RecordError) as e:
        read_record(p)
    _one_line(e.value, "bare.txt")


def test_csv_semicolons_and_decimal_commas(tmp_path, record):
    t, x = record
    p = tmp_path / "excel.csv"
    rows = [f"{a:.15g};{b:.15g}".replace(".", ",") for a, b in zip(t, x / G_N, strict=True)]
    p.write_text("Zeit (s);Beschleunigung (g)\n" + "\n".join(rows) + "\n", encoding="utf-8")
    r = read_record(p)
    assert r.units == "g" and r.fs == pytest.approx(FS, rel=1e-12)
    np.testing.assert_allclose(r.signal, x, rtol=1e-13, atol=1e-13)


def test_csv_column_choice_by_name_and_number(tmp_path, record):
    t, x = record
    p = tmp_path / "two.csv"
    np.savetxt(p, np.column_stack([t, x, 2 * x]), fmt="%.15g", delimiter=",",
               header="time [s],block [m/s^2],plate [m/s^2]", comments="")
    np.testing.assert_allclose(read_record(p, column="plate").signal, 2 * x, rtol=1e-13)
    np.testing.assert_allclose(read_record(p, column=1).signal, x, rtol=1e-13)
    with pytest.raises(RecordError) as e:
        read_record(p)  # two value columns: which one?
    _one_line(e.value, "two.csv")
    assert "block" in str(e.value) and "plate" in str(e.value)


def _wav_int(path, x, scale, bits):
    """Integer WAV with sample = round(x / scale * 2**(bits-1)), written without scipy for 24."""
    q = np.round(x / scale * 2.0 ** (bits - 1)).astype(np.int64)
    if bits == 24:
        with wave.open(str(path), "wb") as w:
            w.setnchannels(1)
            w.setsampwidth(3)
            w.setframerate(int(FS))
            w.writeframes(b"".join(int(v).to_bytes(3, "little", signed=True) for v in q))
    else:
        wavfile.write(path, int(FS), q.astype(np.int16 if bits == 16 else np.int32))


@pytest.mark.parametrize("bits", [16, 24, 32])
def test_wav_integer_samples_are_fractions_of_full_scale(tmp_path, record, bits):
    _, x = record
    scale = 50.0  # m/s^2 per full-scale unit
    p = tmp_path / f"rec{bits}.wav"
    _wav_int(p, x, scale, bits)
    r = read_record(p, scale=scale)
    assert r.fs == FS
    lsb = scale / 2.0 ** (bits - 1)
    assert np.max(np.abs(r.signal - x)) <= 0.5 * lsb * (1 + 1e-9)
    # the same file in g per full-scale unit
    rg = read_record(p, scale=scale / G_N, units="g")
    np.testing.assert_allclose(rg.signal, r.signal, rtol=1e-14)


def test_wav_float_and_multichannel(tmp_path, record):
    _, x = record
    p = tmp_path / "float.wav"
    wavfile.write(p, int(FS), np.column_stack([x / 100, x / 50]).astype(np.float32))
    r = read_record(p, scale=100.0, column=1)
    np.testing.assert_allclose(r.signal, x, rtol=2.0**-24, atol=0)
    r2 = read_record(p, scale=100.0, column="channel 2")
    np.testing.assert_allclose(r2.signal, 2 * x, rtol=2.0**-24, atol=0)
    with pytest.raises(RecordError) as e:
        read_record(p, column=1)  # no scale, no sidecar
    _one_line(e.value, "float.wav")


def test_uff58_written_by_pyuff(tmp_path, record):
    import pyuff

    t, x = record
    p = tmp_path / "rec.uff"
    sets = [pyuff.prepare_58(func_type=1, rsp_node=7, rsp_dir=3, ref_node=0, ref_dir=0,
                             id1="plate accel", abscissa_spacing=1, abscissa_spec_data_type=17,
                             ordinate_spec_data_type=12, orddenom_spec_data_type=0,
                             z_axis_spec_data_type=0, ordinate_axis_units_lab="g",
                             data=x / G_N, x=t)]
    pyuff.UFF(str(p)).write_sets(sets, mode="overwrite")
    r = read_record(p)
    assert r.fs == FS  # the header holds 1/96 kHz to six digits only: the rate is snapped
    assert (r.units, r.units_from, r.channel) == ("g", "file", "plate accel")
    np.testing.assert_allclose(r.signal, x, rtol=1e-10, atol=1e-10)


def test_tdms_written_by_nptdms(tmp_path, record):
    nptdms = pytest.importorskip("nptdms")
    _, x = record
    p = tmp_path / "rec.tdms"
    ch = nptdms.ChannelObject("accel", "plate", x / 1e-3,
                              properties={"wf_increment": 1.0 / FS, "wf_start_offset": 0.0,
                                          "unit_string": "mm/s^2"})
    other = nptdms.ChannelObject("accel", "block", x,
                                 properties={"wf_increment": 1.0 / FS, "unit_string": "m/s^2"})
    with nptdms.TdmsWriter(p) as w:
        w.write_segment([ch, other])
    r = read_record(p, column="plate")
    assert r.fs == pytest.approx(FS, rel=1e-12) and r.units == "mm/s^2"
    np.testing.assert_allclose(r.signal, x, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(read_record(p, column="accel/block").signal, x, rtol=1e-15)


@pytest.mark.parametrize("kind", ["nan", "units", "conflict", "uneven"])
def test_refusals_are_one_line_naming_the_file(tmp_path, record, kind):
    t, x = record
    x = x.copy()
    head = "time [s],acceleration [m/s^2]"
    units = None
    if kind == "nan":
        x[100] = np.nan
    elif kind == "units":
        head = "time [s],acceleration [furlong/s^2]"
    elif kind == "conflict":
        units = "g"
    else:
        t = t.copy()
        t[50] += 0.6 / FS
    p = tmp_path / f"bad_{kind}.csv"
    np.savetxt(p, np.column_stack([t, x]), fmt="%.15g", delimiter=",", header=head,
               comments="")
    with pytest.raises(RecordError) as e:
        read_record(p, units=units)
    _one_line(e.value, f"bad_{kind}.csv")


def _csv(path, t, x, head="time [s],acceleration [m/s^2]"):
    np.savetxt(path, np.column_stack([t, x]), fmt="%.15g", delimiter=",", header=head,
               comments="")
    return path


@pytest.mark.parametrize("kind, message", [
    ("latin1", "{p}: a CSV record must be UTF-8 text (save it as UTF-8), got byte 0xb5 at "
               "byte 23 on line 1"),  # was pandas' codec message
    ("text", "{p}: column 'acceleration' must hold numbers, got 'abc' in data row 3"),
    ("ragged", "{p}: not a readable CSV table (Error tokenizing data. C error: Expected 2 "
               "fields in line 6, saw 3)"),  # pandas' message ended in a newline: two lines
    ("g1e300", "{p}: samples of acceleration must be at most 1e+09 m/s^2 in magnitude (1e8 g, "
               "far beyond any accelerometer; wrong units or scale?), got 9.80665e+300 m/s^2 "
               "at sample 1 (units 'g')"),  # ran to NaN levels and exit status 0
])
def test_malformed_csv_records_are_refused_in_one_line(tmp_path, kind, message):
    p = tmp_path / f"{kind}.csv"
    rows = "0,1\n0.001,2\n0.002,3\n0.003,4\n"
    if kind == "latin1":
        p.write_bytes(b"time [s],acceleration [\xb5m/s^2]\n" + rows.encode())
    elif kind == "text":
        p.write_text("time [s],acceleration [m/s^2]\n" + rows.replace(",3", ",abc"))
    elif kind == "ragged":
        p.write_text("time [s],acceleration [m/s^2]\n" + rows + "0.004,5,6\n")
    else:
        p.write_text("time [s],acceleration [g]\n" + rows.replace(",2", ",1e300"))
    with pytest.raises(RecordError) as e:
        read_record(p)
    assert str(e.value) == message.format(p=p)


def _wav(path, x, **sidecar):
    wavfile.write(path, int(FS), (x / 50).astype(np.float32))
    if sidecar:
        path.with_suffix(".json").write_text(json.dumps(sidecar))
    return path


@pytest.mark.parametrize("cut", [4, 30, 44, 100, -1])
def test_a_truncated_wav_file_is_refused(tmp_path, record, cut):
    """Cut inside the header scipy raised struct.error (30 bytes) or said nothing useful;
    cut inside the samples it read the samples that were there."""
    full = _wav(tmp_path / "full.wav", record[1]).read_bytes()
    p = tmp_path / "cut.wav"
    p.write_bytes(full[:cut])
    with pytest.raises(RecordError) as e:
        read_record(p, scale=50.0)
    msg = str(e.value)
    if cut == 4:
        assert msg == (f"{p}: not a readable WAV file (it ends after 4 bytes, inside its 12-byte "
                       f"RIFF header: truncated?)")
    else:
        assert msg == (f"{p}: the WAV file is truncated: its header declares {len(full)} bytes, "
                       f"the file has {len(full[:cut])}")


@pytest.mark.parametrize("meta, message", [
    ({"scale": "ten", "units": "m/s^2"},
     "sidecar key 'scale' must be a number > 0 (m/s^2 per full-scale unit), got 'ten'"),
    ({"scale": -50, "units": "g"},
     "sidecar key 'scale' must be a number > 0 (g per full-scale unit), got -50"),
    ({"scale": None, "units": "g"},
     "sidecar key 'scale' must be a number > 0 (g per full-scale unit), got None"),
    ({"scale": True}, "sidecar key 'scale' must be a number > 0 (the sidecar's 'units' per "
                      "full-scale unit), got True"),
    ({"scale": 50, "units": 9.81}, "sidecar key 'units' must be a string (g, m/s^2, ...), "
                                   "got 9.81"),
    ({"scale": 50, "units": "furlong/s^2"}, "sidecar key 'units': unknown acceleration units "
                                            "'furlong/s^2'; accepted: g, mg, m/s^2"),
    ({"scale": 50, "units": "m/s^2", "start_time_s": "noon"},
     "sidecar key 'start_time_s' must be a finite number [s] (the time of the first sample), "
     "got 'noon'"),
])
def test_bad_sidecar_keys_are_named_with_the_sidecar(tmp_path, record, meta, message):
    """{"scale": "ten"} gave 'could not convert string to float' (no file, no key)."""
    p = _wav(tmp_path / "rec.wav", record[1], **meta)
    with pytest.raises(RecordError) as e:
        read_record(p)
    msg = str(e.value)
    assert msg.startswith(f"{p.with_suffix('.json')}: {message}"), msg
    assert "\n" not in msg


def test_a_broken_sidecar_is_refused_only_where_it_is_needed(tmp_path, record):
    p = _wav(tmp_path / "rec.wav", record[1])
    p.with_suffix(".json").write_text('{"scale": 50, "units": ')
    with pytest.raises(RecordError) as e:
        read_record(p)
    assert str(e.value).startswith(f"{p.with_suffix('.json')}: the sidecar of rec.wav must be a "
                                   f"readable JSON file (UTF-8) with 'scale' and 'units', got ")
    # with --scale the sidecar is not read for its scale: the record is read
    np.testing.assert_allclose(read_record(p, scale=50.0).signal, record[1], rtol=2.0**-23)


def _uff58(path, x):
    import pyuff

    t = np.arange(x.size) / FS
    sets = [pyuff.prepare_58(func_type=1, rsp_node=7, rsp_dir=3, ref_node=0, ref_dir=0,
                             id1="plate accel", abscissa_spacing=1, abscissa_spec_data_type=17,
                             ordinate_spec_data_type=12, orddenom_spec_data_type=0,
                             z_axis_spec_data_type=0, ordinate_axis_units_lab="g",
                             data=x / G_N, x=t)]
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    return path.read_text().splitlines(keepends=True)


def test_a_truncated_or_unreadable_uff58_record_is_refused(tmp_path, record):
    lines = _uff58(tmp_path / "full.uff", record[1][:400])
    p = tmp_path / "cut.uff"
    p.write_text("".join(lines[:60]))  # pyuff dropped the unfinished dataset: "no dataset 58"
    with pytest.raises(RecordError) as e:
        read_record(p)
    assert str(e.value) == (f"{p}: the universal file is truncated: dataset 58 opened on line 1 "
                            f"never ends (every dataset must end with a line '    -1'), got the "
                            f"end of the file on line 60")
    row = 20  # a data line (four E20.12 values)
    assert len(lines[row].split()) == 4
    for field, rule in (("   ****************", "every value must be a number, got "
                                                 "'****************'"),
                        ("  nan", "every value must be a finite number, got 'nan'")):
        bad = list(lines)
        bad[row] = lines[row][:-21] + field + "\n"
        p.write_text("".join(bad))
        with pytest.raises(RecordError) as e:
            read_record(p)
        msg = str(e.value)  # pyuff said "Error when reading data-set(s)." or read 399 samples
        assert msg.startswith(f"{p}: dataset 58 (lines 1-{len(lines)}")
        assert msg.endswith(f"line {row + 1}: {rule}"), msg


def test_a_truncated_tdms_record_and_bad_properties_are_refused(tmp_path, record):
    nptdms = pytest.importorskip("nptdms")
    x = record[1][:1000]

    def write(name, **props):
        ch = nptdms.ChannelObject("accel", "plate", x, properties={
            "wf_increment": 1.0 / FS, "unit_string": "m/s^2", **props})
        with nptdms.TdmsWriter(tmp_path / name) as w:
            w.write_segment([ch])
        return tmp_path / name

    full = write("full.tdms").read_bytes()
    p = tmp_path / "cut.tdms"
    p.write_bytes(full[:-100])  # npTDMS read 987 samples and only logged a warning
    with pytest.raises(RecordError) as e:
        read_record(p)
    assert str(e.value) == (f"{p}: the TDMS file is truncated or damaged: the segment at byte 0 "
                            f"declares {len(full)} bytes, the file ends {len(full) - 100} bytes "
                            f"after its start")
    for key, value, rule in (("wf_increment", "fast", "a number > 0 [s] (the sample interval)"),
                             ("wf_start_offset", "noon", "a finite number [s]")):
        p = write(f"{key}.tdms", **{key: value})
        with pytest.raises(RecordError) as e:  # was ValueError: could not convert ...
            read_record(p)
        assert str(e.value) == (f"{p}: channel 'accel/plate': property {key} must be {rule}, "
                                f"got {value!r}")


def test_a_directory_is_not_a_record(tmp_path):
    (tmp_path / "d.csv").mkdir()
    with pytest.raises(RecordError, match=r"d\.csv: is a directory, not a record file$"):
        read_record(tmp_path / "d.csv")


# --------------------------------------------------------------------------------------------
# export
# --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    import roughvib

    scene = roughvib.load_scene("paper", {"output.duration": 0.15, "output.transient": 0.0,
                                          "plate.max_frequency": 5000.0,
                                          "output.progress": False})
    d = tmp_path_factory.mktemp("lab") / "run"
    roughvib.simulate(scene).save(d)
    return d


def test_export_uff_reads_back_with_pyuff(run_dir, tmp_path):
    import pyuff

    from roughvib.results import load_result

    ds = load_result(run_dir).dataset
    dt = float(ds["time"][1] - ds["time"][0])
    for binary in (False, True):
        out = tmp_path / ("bin" if binary else "ascii")
        (path,) = export_run(run_dir, "uff", out=out, binary=binary)
        sets = pyuff.UFF(str(path)).read_sets()
        assert [s["id1"].strip() for s in sets] == ["block_acceleration", "plate_acceleration",
                                                   "normal_force"]
        for s, var, unit, kind, node in zip(
                sets, ["block_vertical_acceleration", "plate_vertical_acceleration",
                       "normal_force"], ["m/s^2", "m/s^2", "N"], [12, 12, 13], [1, 2, 3],
                strict=True):
            assert (s["type"], s["func_type"], s["rsp_node"], s["rsp_dir"]) == (58, 1, node, -3)
            assert s["ordinate_axis_units_lab"].strip() == unit
            assert s["ordinate_spec_data_type"] == kind
            assert s["abscissa_inc"] == pytest.approx(dt, rel=1e-12)
            ref = ds[var].values
            # ASCII holds 12 significant digits, binary the doubles themselves
            np.testing.assert_allclose(s["data"], ref, rtol=0 if binary else 1e-11,
                                       atol=0 if binary else 1e-11 * np.max(np.abs(ref)))
        # and roughvib's reader takes its own export
        r = read_record(path, column="plate_acceleration")
        assert r.fs == pytest.approx(1 / dt, rel=1e-12)


def test_export_wav_float32_scale_in_name_and_sidecar(run_dir, tmp_path):
    from roughvib.results import load_result

    ds = load_result(run_dir).dataset
    paths = export_run(run_dir, "wav", out=tmp_path)
    wavs = sorted(p for p in paths if p.suffix == ".wav")
    assert len(wavs) == 3
    for p in wavs:
        meta = json.loads(p.with_suffix(".json").read_text())
        scale = meta["scale"]
        tag = "ms2" if meta["units"] == "m/s^2" else "N"
        assert p.name == f"{meta['signal']}_{scale:g}{tag}_per_unit.wav"
        assert math.log10(scale) == round(math.log10(scale))  # a power of ten
        fs, w = wavfile.read(p)
        assert w.dtype == np.float32 and fs == round(meta["sample_rate_hz"]) == 100000
        assert np.max(np.abs(w)) <= 1.0
        ref = ds[meta["variable"]].values
        assert np.max(np.abs(ref)) > 0.1 * scale  # the smallest power of ten above the peak
        # float32 of x / scale: one rounding, relative error <= 2**-24
        np.testing.assert_allclose(w.astype(float) * scale, ref, rtol=2.0**-24, atol=0)
        assert meta["run_id"] == json.loads((run_dir / "summary.json").read_text())["run_id"]
    r = read_record(wavs[-1])  # the scale from the sidecar
    assert r.units_from == "file"


def test_export_csv_and_cli(run_dir, tmp_path, capsys, monkeypatch):
    from roughvib.cli import main
    from roughvib.results import load_result

    monkeypatch.chdir(tmp_path)
    ds = load_result(run_dir).dataset
    assert main(["export", str(run_dir), "--format", "csv", "--out", str(tmp_path)]) == 0
    path = tmp_path / capsys.readouterr().out.strip()
    head = path.read_text().splitlines()[0]
    assert head == ("time [s],block_acceleration [m/s^2],plate_acceleration [m/s^2],"
                    "normal_force [N]")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 0], ds["time"].values, rtol=1e-11, atol=1e-15)
    np.testing.assert_allclose(data[:, 3], ds["normal_force"].values, rtol=1e-11)
    r = read_record(path, column="block_acceleration")
    np.testing.assert_allclose(r.signal, ds["block_vertical_acceleration"].values, rtol=1e-11,
                               atol=1e-11 * float(np.max(np.abs(r.signal))))
    assert main(["export", str(run_dir), "--format", "csv", "--binary"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--binary" in err, err


def test_a_run_with_exports_is_replaced_as_a_whole(run_dir, tmp_path):
    """export/ and validation/ are roughvib's own folders: the next run into the directory
    replaces them with the rest (they belonged to the old run) instead of refusing."""
    import shutil

    from roughvib.results import load_result

    d = tmp_path / "run"
    shutil.copytree(run_dir, d)
    export_run(d, "csv")
    (d / "validation" / "lab").mkdir(parents=True)
    load_result(d).save(d)  # no --overwrite needed
    assert not (d / "export").exists() and not (d / "validation").exists()
    (d / "notes.txt").write_text("mine")
    with pytest.raises(Exception, match="notes.txt"):
        load_result(d).save(d)
