"""What a run loads and how it writes: the fixed cost of a run stays low because it imports
only what it uses (docs/performance.md, "Fixed cost of a run"). These tests check module sets
and file contents, never times."""

import subprocess
import sys

import h5py
import numpy as np
import pytest
import xarray as xr

import roughvib
import roughvib.api
from roughvib.results import _write_netcdf

TINY = ["--set", "output.duration=0.005", "--set", "plate.max_frequency=2000", "--no-progress",
        "--quiet"]
# used by the studies and reports, by IDA or by dask's scheduler: never by an adaptive-modal run
NOT_IN_A_RUN = ("scipy.signal", "scipy.stats", "matplotlib", "sksundae", "distributed",
                "roughvib.studies.compare", "roughvib.views.report",
                "roughvib.views.figures", "roughvib.analysis.spectra")


def _loaded_after(code: str) -> set[str]:
    probe = f"import sys\n{code}\nprint(' '.join(sorted(sys.modules)))"
    p = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr
    return set(p.stdout.split())


def test_an_adaptive_modal_run_imports_only_what_it_uses(tmp_path):
    out = tmp_path / "run"
    loaded = _loaded_after(
        "from roughvib.cli import main\n"
        f"assert main(['run', 'paper-handset', '--out', {str(out)!r}, "
        f"'--set', 'solver.method=adaptive-modal', *{TINY!r}]) == 0")
    assert (out / "result.nc").is_file()
    assert "roughvib.solvers.adaptive_modal" in loaded and "xarray" in loaded  # it did run
    assert sorted(m for m in loaded if m.startswith(NOT_IN_A_RUN)) == []


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


def test_result_files_are_those_of_to_netcdf(tmp_path):
    scene = roughvib.load_scene("paper-handset", {"output.duration": 0.003,
                                                  "plate.max_frequency": 2000.0,
                                                  "solver.method": "adaptive-modal",
                                                  "output.progress": False})
    ds = roughvib.simulate(scene).to_dataset()
    ds.attrs = {k: v for k, v in ds.attrs.items() if not isinstance(v, dict | list)}
    ds.to_netcdf(tmp_path / "public.nc", engine="h5netcdf")
    _write_netcdf(ds, tmp_path / "ours.nc")
    a, b = _h5_tree(tmp_path / "public.nc"), _h5_tree(tmp_path / "ours.nc")
    assert len(a) > 10 and a.keys() == b.keys()
    for name in a:
        assert repr(a[name]) == repr(b[name]), name  # repr: NaN fill values compare equal
    assert xr.open_dataset(tmp_path / "ours.nc", engine="h5netcdf").identical(ds)
