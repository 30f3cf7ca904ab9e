"""What a run loads and how it writes: the fixed cost of a run stays low because it imports
only what it uses (docs/performance.md, "Fixed cost of a run"). These tests check module sets
and file contents, never times."""

import os
import subprocess
import sys

import h5py
import numpy as np
import pytest
import xarray as xr

import roughvib
import roughvib.api
from roughvib.results import RunData, _write_netcdf, load_result

TINY = ["--set", "output.duration=0.005", "--set", "plate.max_frequency=2000", "--no-progress",
        "--quiet"]
# used by the studies and reports, by IDA, by xarray (with dask) to build and write a Dataset
# or by pandas for the event table: never by an adaptive-modal run that is saved
NOT_IN_A_RUN = ("scipy.signal", "scipy.stats", "matplotlib", "sksundae", "xarray", "dask", "pandas",
                "distributed", "roughvib.studies", "roughvib.views", "roughvib.analysis.spectra",
                "tqdm", "multiprocessing")


def _loaded_after(code: str, env: dict | None = None) -> set[str]:
    probe = f"import sys\n{code}\nprint(' '.join(sorted(sys.modules)))"
    p = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                       timeout=600, env=env)
    assert p.returncode == 0, p.stderr
    return set(p.stdout.split())


def test_an_adaptive_modal_run_imports_only_what_it_uses(tmp_path):
    # the paper scene (contact module, calibration, residual compliance, cubic spline); the
    # first run fills the cache, the second finds every scipy-backed result there
    env = {**os.environ, "ROUGHVIB_CACHE_DIR": str(tmp_path / "cache")}
    out = tmp_path / "run"
    run = ("from roughvib.cli import main\n"
           f"assert main(['run', 'paper', '--out', {str(out)!r}, "
           f"'--set', 'solver.method=adaptive-modal', *{TINY!r}]) == 0")
    first = _loaded_after(run, env)
    assert "scipy.interpolate" in first and "scipy.special" in first  # computed
    loaded = _loaded_after(run, env)
    assert (out / "result.nc").is_file()
    assert "roughvib.solvers.adaptive_modal" in loaded and "h5netcdf" in loaded  # it ran
    assert sorted(m for m in loaded if m.startswith(NOT_IN_A_RUN)) == []
    assert sorted(m for m in loaded if m.startswith(
        ("scipy.special", "scipy.optimize", "scipy.interpolate"))) == []


def test_the_command_line_imports_no_command_before_it_runs():
    # the parser of every command is built from the cli modules alone: numpy, numba, the
    # studies (with dask) and the views (with matplotlib) come with the command that uses them
    loaded = _loaded_after("import roughvib.cli\nroughvib.cli.build_parser()")
    assert "roughvib.cli.sweep" in loaded and "roughvib.cli.run" in loaded
    assert sorted(m for m in loaded if m.startswith(
        (*NOT_IN_A_RUN, "numpy", "numba", "scipy", "h5py", "h5netcdf", "roughvib.simulation",
         "roughvib.results"))) == []


def test_the_api_imports_each_name_from_its_stage_on_first_use():
    loaded = _loaded_after("from roughvib.api import simulate, load_scene")
    assert "roughvib.simulation" in loaded
    assert sorted(m for m in loaded if m.startswith((*NOT_IN_A_RUN, "roughvib.studies",
                                                     "roughvib.views"))) == []
    for name in roughvib.api.__all__:
        obj = getattr(roughvib.api, name)
        assert sys.modules[obj.__module__] is not None and obj.__name__ == name
    assert set(dir(roughvib.api)) >= set(roughvib.api.__all__)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        roughvib.api.nope  # noqa: B018


def _h5_tree(path) -> dict:
    """Every group, dataset and attribute of an HDF5 file, dimension references by name."""
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            attrs = {}
            for k, v in obj.attrs.items():
                if k in ("DIMENSION_LIST", "REFERENCE_LIST"):
                    continue
                attrs[k] = np.asarray(v).tobytes() if isinstance(v, np.ndarray) else v
            if isinstance(obj, h5py.Dataset):
                attrs["(dtype, shape, chunks, compression)"] = (
                    str(obj.dtype), obj.shape, obj.chunks, obj.compression)
                attrs["(data)"] = obj[()].tobytes()
                attrs["(dims)"] = [[f[r].name for r in refs]
                                   for refs in obj.attrs.get("DIMENSION_LIST", [])]
            out[name] = attrs

        f.visititems(visit)
        out["/"] = dict(f.attrs)
    return out


@pytest.mark.short_run
def test_result_files_are_those_of_to_netcdf(tmp_path):
    # a run's Result holds RunData; its file is the one xarray writes from the Dataset
    scene = roughvib.load_scene("paper-handset", {"output.duration": 0.003,
                                                  "plate.max_frequency": 2000.0,
                                                  "solver.method": "adaptive-modal",
                                                  "output.progress": False})
    result = roughvib.simulate(scene)
    data = result.__dict__["_dataset"]
    assert isinstance(data, RunData) and data.sizes == {"time": 301, "contact": 10}
    result.save(tmp_path / "run")
    assert isinstance(result.__dict__["_dataset"], RunData)  # saving built no Dataset
    ds = result.dataset  # built now, on first use
    assert isinstance(ds, xr.Dataset) and result.dataset is ds
    attrs = {k: v for k, v in ds.attrs.items() if not isinstance(v, dict | list)}
    data.write_netcdf(tmp_path / "ours.nc", attrs)
    ds.assign_attrs(attrs).to_netcdf(tmp_path / "xarray.nc", engine="h5netcdf")
    _write_netcdf(ds.assign_attrs(attrs), tmp_path / "store.nc")
    a = _h5_tree(tmp_path / "xarray.nc")
    assert len(a) > 10 and "contact_closed" in a
    for other in ("ours.nc", "store.nc"):
        b = _h5_tree(tmp_path / other)
        assert list(a) == list(b)  # the same variables in the same order
        for name in a:
            assert repr(a[name]) == repr(b[name]), (other, name)  # repr: NaN fills compare
    assert xr.open_dataset(tmp_path / "ours.nc", engine="h5netcdf").identical(
        ds.assign_attrs(attrs))
    saved = load_result(tmp_path / "run").dataset
    assert saved.drop_attrs(deep=False).identical(ds.drop_attrs(deep=False))


def test_run_data_coordinates_attributes_follow_xarray(tmp_path):
    # a coordinate that no variable has (a second dimension) goes to the global attribute
    data = RunData()
    data.add("a", ("t", "k"), np.ones((3, 2)), {"units": "m"})
    data.add("t", "t", np.arange(3.0), coord=True)
    data.add("kx", "k", np.arange(2.0), coord=True)
    data.add("w", "w", np.arange(4), coord=True)
    data.add("wx", "w", np.arange(4.0), coord=True)
    data.add("flag", "t", np.zeros(3, np.int8), {"flag_values": np.array([0, 1], np.int8)})
    data.attrs.update(title="x", n=1, f=0.5)
    data.write_netcdf(tmp_path / "ours.nc", data.attrs)
    data.to_dataset().to_netcdf(tmp_path / "xarray.nc", engine="h5netcdf")
    a, b = _h5_tree(tmp_path / "xarray.nc"), _h5_tree(tmp_path / "ours.nc")
    assert a["/"]["coordinates"] == "wx" and a["a"]["coordinates"] == "kx"
    assert list(a) == list(b) and all(repr(a[n]) == repr(b[n]) for n in a)


# --------------------------------------------------------------------------------------------
# the event log without pandas
# --------------------------------------------------------------------------------------------

BOUNCING = {"plate.kind": "rigid", "roughness.kind": "sinusoid", "roughness.amplitude": 10e-6,
            "roughness.wavelength": 0.73e-3, "excitation.kind": "prescribed",
            "excitation.velocity": 0.1, "excitation.amplitude": 0.0,
            "excitation.target_rms_velocity": None, "contact.points": 3,
            "output.duration": 0.01, "output.progress": False}


@pytest.fixture(scope="module")
def logs():
    """Event records of a bouncing run (lift-offs, touch-downs) and of the paper scene (stick,
    slip, friction branch), plus records with awkward values."""
    from roughvib.solvers.events import EventRecord

    bouncing = roughvib.simulate(roughvib.load_scene("paper", BOUNCING))
    paper = roughvib.simulate(roughvib.load_scene("paper-handset", {
        "output.duration": 0.02, "plate.max_frequency": 2000.0,
        "solver.method": "adaptive-modal", "output.progress": False}))
    base = paper.__dict__["_events"][0]
    odd = [EventRecord(**{**base.__dict__, **change}) for change in (
        {"kind": 'a "quoted", text', "margin_before": float("nan")},
        {"contact": 7, "normal_force": float("inf"), "contact_force": -0.0},
        {"time": 1e-300, "friction_after": 123456789012345.0, "regime_after": "x\ny"},
        {"regime_before": "", "regime_after": "", "contact": 0, "margin_after": 0.0},
        {"contact": float("nan"), "tangential_velocity": -1e-17, "kind": "slip"},
    )]
    out = {"bouncing": bouncing.__dict__["_events"], "paper": paper.__dict__["_events"],
           "odd": odd, "none": []}
    assert {"lift_off", "touch_down"} <= {r.kind for r in out["bouncing"]}
    assert {"stick", "slip"} <= {r.kind for r in out["paper"]}
    return out


@pytest.mark.short_run
@pytest.mark.parametrize("name", ["bouncing", "paper", "odd", "none"])
def test_events_csv_is_the_one_pandas_writes(logs, name, tmp_path):
    from roughvib.results import _write_events_csv, events_frame

    records = logs[name]
    ev = events_frame(records)
    ev.to_csv(tmp_path / "pandas.csv", index=False, float_format="%.12g")
    _write_events_csv(records, tmp_path / "ours.csv")
    assert (tmp_path / "ours.csv").read_bytes() == (tmp_path / "pandas.csv").read_bytes()


@pytest.mark.short_run
@pytest.mark.parametrize("name", ["bouncing", "paper"])
def test_event_counts_and_regime_series_from_records(logs, name):
    from roughvib.analysis.events import regime_series
    from roughvib.results import events_frame
    from roughvib.simulation import _events_by_kind

    records = logs[name]
    ev = events_frame(records)
    assert list(_events_by_kind(records).items()) == \
        list(ev["kind"].value_counts().to_dict().items())
    grid = np.linspace(0.0, 0.02, 2001)
    closed0 = np.array([1, 0, 1])
    for a, b in zip(regime_series(records, grid, closed0, True),
                    regime_series(ev, grid, closed0, True), strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)


@pytest.mark.short_run
def test_result_events_become_the_table_on_first_use(logs, tmp_path):
    from roughvib.results import Result, events_frame

    records = logs["bouncing"]
    result = Result(RunData(), list(records), {"status": "failed"}, "")
    assert isinstance(result.__dict__["_events"], list)  # not converted yet
    table = result.events
    assert table.equals(events_frame(records)) and result.events is table


@pytest.mark.short_run
def test_event_counts_keep_pandas_order_for_ties(logs):
    """value_counts: most frequent first, equal counts in order of first appearance."""
    from roughvib.results import events_frame
    from roughvib.simulation import _events_by_kind

    base = logs["paper"][0]
    kinds = ["slip", "stick", "lift_off", "stick", "touch_down", "slip", "lift_off",
             "latch_flip", "touch_down", "touch_down"]
    records = [type(base)(**{**base.__dict__, "kind": k, "time": 1e-3 * i})
               for i, k in enumerate(kinds)]
    want = events_frame(records)["kind"].value_counts().to_dict()
    assert list(_events_by_kind(records).items()) == list(want.items())
    assert _events_by_kind([]) == {}


@pytest.mark.parametrize("failed", [False, True])
def test_saved_files_are_those_xarray_and_pandas_write(tmp_path, failed):
    """The files of a saved run against the writing code they replace: the Dataset with its
    JSON-encoded provenance through ``to_netcdf(engine="h5netcdf")`` and the event table
    through ``to_csv`` (contact as Int64), for a complete and a failed run (partial.nc)."""
    import json
    import warnings

    from roughvib.results import _jsonable

    stop = {"solver.max_events": 1, "solver.event_window": 1.0} if failed else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = roughvib.simulate(roughvib.load_scene("paper-handset", {
            "output.duration": 0.01, "plate.max_frequency": 2000.0,
            "solver.method": "adaptive-modal", "output.progress": False, **stop}))
    assert result.ok is not failed
    result.save(tmp_path / "run")
    run_id = result.summary["run_id"]
    nc = "partial.nc" if failed else "result.nc"
    assert isinstance(result.__dict__["_dataset"], RunData)  # written without xarray
    assert isinstance(result.__dict__["_events"], list)  # and without pandas

    ds = result.dataset.copy()  # the reference: xarray and pandas, as saving used to be
    assert ds.sizes["time"] > 0 and len(result.events) > 0
    ds.attrs = {k: (json.dumps(_jsonable(v)) if isinstance(v, dict | list) else v)
                for k, v in ds.attrs.items()}
    assert {"roughvib_version", "software", "scene_toml", "solver_method"} <= set(ds.attrs)
    if failed:
        ds.attrs.update(status=result.status, message=str(result.summary.get("message", "")))
    ds.attrs["run_id"] = run_id
    ds.to_netcdf(tmp_path / "xarray.nc", engine="h5netcdf")
    a, b = _h5_tree(tmp_path / "xarray.nc"), _h5_tree(tmp_path / "run" / nc)
    assert list(a) == list(b)
    for name in a:
        assert repr(a[name]) == repr(b[name]), name
    ev = result.events.copy()
    ev["contact"] = ev["contact"].astype("Int64")
    ev.to_csv(tmp_path / "pandas.csv", index=False, float_format="%.12g")
    assert (tmp_path / "run" / "events.csv").read_bytes() == \
        (tmp_path / "pandas.csv").read_bytes()
