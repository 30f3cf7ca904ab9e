"""Measured topography in instrument formats (ISO 25178-71 SDF, X3P) through SurfaceTopography.

The reference is the plain-text reader: the same heights written as a text trace matrix with
their y positions must give the same profile, span average and raw moments. The SDF file is
written by hand from the format (ISO 25178-71 ASCII: header lines ``key = value`` up to ``*``,
then NumProfiles rows of NumPoints values in Zscale units, then ``*``), the X3P file with
SurfaceTopography's own writer.
"""

import sys

import numpy as np
import pytest

import roughvib
from roughvib.model.system import assemble
from roughvib.physics.surface.roughness import build_profile, read_measured
from roughvib.physics.surface.topography import uses_topography
from roughvib.scene import SceneError

DX, DY = 10e-6, 1e-3      # m
NX, NY = 901, 7           # 9 mm along the sliding direction, 6 mm across


def _heights(ny=NY, seed=3):
    rng = np.random.default_rng(seed)
    # smooth random traces: white noise low-passed by a 5-point moving average, ~0.5 um rms
    w = rng.standard_normal((NX + 4, ny))
    return np.stack([np.convolve(w[:, j], np.ones(5) / 5, mode="valid")
                     for j in range(ny)], axis=1) * 1e-6


def _write_sdf(path, z, zscale=1e-6):
    nx, ny = z.shape
    head = ["aISO-1.0", "ManufacID   = roughvib-test", "CreateDate  = 010120250000",
            "ModDate     = 010120250000", f"NumPoints   = {nx}", f"NumProfiles = {ny}",
            f"Xscale      = {DX:.6E}", f"Yscale      = {DY:.6E}", f"Zscale      = {zscale:.6E}",
            "Zresolution = -1", "Compression = 0", "DataType    = 7", "CheckType   = 0", "*"]
    rows = [" ".join(f"{v:.12g}" for v in z[:, j] / zscale) for j in range(ny)]
    path.write_text("\n".join(head + rows + ["*", ""]))


def _write_text(path, z):
    y = (np.arange(z.shape[1]) - (z.shape[1] - 1) / 2) * DY
    lines = ["# y: " + " ".join(f"{v:.12g}" for v in y * 1e6)]
    lines += [" ".join(f"{v:.12g}" for v in row * 1e6) for row in z]
    path.write_text("\n".join(lines) + "\n")


def _scene(path, **over):
    base = {"roughness.kind": "file", "roughness.path": str(path), "roughness.units": "um",
            "roughness.spacing": DX, "block.length": 4e-3, "block.width": 6e-3,
            "output.progress": False}
    base.update(over)
    return roughvib.load_scene("paper", base)


def _same_profile(a, b):
    np.testing.assert_allclose(a.z, b.z, rtol=0, atol=1e-9 * np.max(np.abs(b.z)))
    assert a.dx == pytest.approx(b.dx, rel=1e-12)
    np.testing.assert_allclose(a.stats["raw_moments"], b.stats["raw_moments"], rtol=1e-8)
    assert a.stats["n_traces"] == b.stats["n_traces"]
    assert a.stats["reduced_rms"] == pytest.approx(b.stats["reduced_rms"], rel=1e-8)


def test_suffix_rule_and_forced_formats():
    assert uses_topography("a.sdf", "auto") and uses_topography("b.X3P", "auto")
    assert uses_topography("c.datx", "auto") and uses_topography("d.sur", "auto")
    assert not uses_topography("e.txt", "auto") and not uses_topography("f.csv", "auto")
    assert uses_topography("e.txt", "topography") and not uses_topography("a.sdf", "text")


def test_netcdf_and_hdf5_are_recognised_by_their_first_bytes(tmp_path):
    # the magic numbers of the formats (netCDF classic / 64-bit offset / 64-bit data, HDF5),
    # written by hand: the content decides, not the suffix
    for i, head in enumerate([b"CDF\x01", b"CDF\x02", b"CDF\x05", b"\x89HDF\r\n\x1a\n"]):
        (tmp_path / f"scan{i}.dat").write_bytes(head + b"\x00" * 32)
        assert uses_topography(f"scan{i}.dat", "auto", base_dir=tmp_path)
        assert not uses_topography(f"scan{i}.dat", "text", base_dir=tmp_path)
    (tmp_path / "cdf.txt").write_text("CDF is not a magic number in text\n1.0\n")
    assert not uses_topography(tmp_path / "cdf.txt", "auto")
    assert not uses_topography(tmp_path / "missing.nc", "auto")  # the text reader names it


def test_surface_topography_netcdf_reads_like_the_text_trace_matrix(tmp_path, monkeypatch):
    """SurfaceTopography's own netCDF (contact.engineering's exchange format) with format
    'auto': it used to reach the text reader and be refused as not UTF-8."""
    st = pytest.importorskip("SurfaceTopography")
    monkeypatch.chdir(tmp_path)
    z = _heights()
    top = st.Topography(z, physical_sizes=(NX * DX, NY * DY), unit="m")
    top.to_netcdf(str(tmp_path / "scan.nc"))
    assert (tmp_path / "scan.nc").read_bytes()[:3] == b"CDF"
    _write_text(tmp_path / "same.txt", z)
    auto = _scene("scan.nc").with_overrides({"roughness.units": "m"})
    assert auto.roughness.format == "auto"
    a = build_profile(auto.roughness, auto.block, auto.base_dir)
    b = build_profile(*(lambda s: (s.roughness, s.block, s.base_dir))(
        _scene(tmp_path / "same.txt")))
    assert a.stats["layout"] == "map" and a.stats["n_traces"] == NY
    # netCDF keeps the pixel sizes in float32 (relative 6e-8): the heights are exact, the
    # grid spacing (and so the filter and the moments) agree to float32
    assert a.dx == pytest.approx(b.dx, rel=1e-7)
    np.testing.assert_allclose(a.z, b.z, rtol=0, atol=1e-6 * np.max(np.abs(b.z)))
    np.testing.assert_allclose(a.stats["raw_moments"], b.stats["raw_moments"], rtol=1e-6)


def test_sdf_written_from_the_standard_reads_like_the_text_trace_matrix(tmp_path):
    pytest.importorskip("SurfaceTopography")
    z = _heights()
    _write_sdf(tmp_path / "map.sdf", z)
    _write_text(tmp_path / "map.txt", z)
    sdf = _scene(tmp_path / "map.sdf")
    txt = _scene(tmp_path / "map.txt")
    meas = read_measured(sdf.roughness, sdf.block, sdf.base_dir)
    assert meas.layout == "map" and meas.z.shape == (NX, NY)
    np.testing.assert_allclose(meas.z, z, rtol=0, atol=1e-9 * np.max(np.abs(z)))
    np.testing.assert_allclose(meas.y, (np.arange(NY) - 3) * DY, rtol=1e-12, atol=1e-15)
    a = build_profile(sdf.roughness, sdf.block, sdf.base_dir)
    b = build_profile(txt.roughness, txt.block, txt.base_dir)
    _same_profile(a, b)
    # the span average is the trapezoidal mean of the traces (equal spacing)
    w = np.ones(NY)
    w[[0, -1]] = 0.5
    assert a.stats["reduced_rms"] == pytest.approx(float(np.std(z @ (w / w.sum()))), rel=1e-6)
    # and it feeds the model: the whole scene assembles, moments from the measured surface
    system = assemble(sdf.with_overrides({"plate.kind": "rigid", "contact.points": 2}))
    assert system.calibration["contact_stiffness"]["summit_source"] == "moments"


def test_x3p_map_wider_than_the_block_is_cropped_to_the_block_width(tmp_path):
    st = pytest.importorskip("SurfaceTopography")
    z = _heights(ny=11, seed=5)  # 10 mm wide; the block is 6 mm wide: the central 7 traces
    top = st.Topography(z, physical_sizes=(NX * DX, 11 * DY), unit="m")
    top.to_x3p(str(tmp_path / "map.x3p"))
    _write_text(tmp_path / "centre.txt", z[:, 2:9])
    a = build_profile(*(lambda s: (s.roughness, s.block, s.base_dir))(
        _scene(tmp_path / "map.x3p")))
    b = build_profile(*(lambda s: (s.roughness, s.block, s.base_dir))(
        _scene(tmp_path / "centre.txt")))
    assert a.stats["n_traces"] == 7
    _same_profile(a, b)


def test_short_map_gives_a_one_line_error(tmp_path):
    pytest.importorskip("SurfaceTopography")
    _write_sdf(tmp_path / "short.sdf", _heights()[:200])
    with pytest.raises(SceneError, match=r"short.sdf: too few points along x") as info:
        build_profile(*(lambda s: (s.roughness, s.block, s.base_dir))(
            _scene(tmp_path / "short.sdf")))
    assert "\n" not in str(info.value)


def test_missing_extra_gives_a_one_line_error_naming_the_install(tmp_path, monkeypatch):
    (tmp_path / "map.sdf").write_text("aISO-1.0\n*\n")
    monkeypatch.setitem(sys.modules, "SurfaceTopography", None)  # import fails
    scene = _scene(tmp_path / "map.sdf")
    with pytest.raises(SceneError) as info:
        build_profile(scene.roughness, scene.block, scene.base_dir)
    msg = str(info.value)
    assert "\n" not in msg and "pip install 'roughvib[topography]'" in msg
    assert "map.sdf" in msg
