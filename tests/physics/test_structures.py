"""Structure components (physics/structures): the built-in plate against closed forms, imported
modes against the plate they were exported from, the exchange format's checks."""

import math
import warnings

import numpy as np
import pytest

from roughvib.physics.plate import plate_modes, static_compliance
from roughvib.physics.structures import build_structure, export_modes
from roughvib.physics.structures.base import Structure, gauss_rectangle
from roughvib.physics.structures.exchange import ModeSet, read_modes, write_modes
from roughvib.physics.structures.imported import ImportedModes
from roughvib.physics.structures.plate import SimplySupportedPlate
from roughvib.scene import Plate, SceneError

PLATE = Plate(max_frequency=5000.0)  # the paper's plate, 44 modes: cheap
CENTRE, SIZE = (0.12, 0.11), (0.04, 0.04)


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="module")
def plate():
    return SimplySupportedPlate(PLATE)


@pytest.fixture(scope="module")
def imported():
    """The 5 kHz plate exported on a 3 mm grid (about 19 nodes per shortest wavelength)."""
    return ImportedModes(PLATE, export_modes(PLATE, grid=(101, 88)), source="test")


def test_plate_shapes_are_mass_normalised(plate):
    # int rho h phi_r phi_s dA = delta_rs on the plate (midpoint rule, exact for sin products)
    n = 240
    x = (np.arange(n) + 0.5) * PLATE.length / n
    y = (np.arange(n) + 0.5) * PLATE.width / n
    X, Y = np.meshgrid(x, y, indexing="ij")
    phi = plate.shapes(np.column_stack([X.ravel(), Y.ravel()]))
    dA = PLATE.length * PLATE.width / n**2
    gram = PLATE.mass_per_area * dA * phi @ phi.T
    np.testing.assert_allclose(gram, np.eye(plate.n_modes), atol=1e-9)


def test_plate_modes_give_the_static_compliance(plate):
    # kept modes (sum phi phi / omega^2, mass-normalised) + residual = exact Green's function
    pts = np.array([[0.11, 0.10], [0.13, 0.11], [0.2, 0.08]])
    phi = plate.shapes(pts)
    G = (phi / plate.omega[:, None] ** 2).T @ phi + plate.residual_compliance(pts)
    np.testing.assert_allclose(G, static_compliance(PLATE, pts), rtol=1e-10)


def test_plate_slopes_are_the_x_derivative(plate):
    p = np.array([[0.1234, 0.0567]])
    h = 1e-6
    fd = (plate.shapes(p + [h, 0]) - plate.shapes(p - [h, 0])) / (2 * h)
    np.testing.assert_allclose(plate.slopes(p), fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_patch_shapes_closed_form(plate):
    # the mean of sin(a x) sin(b y) over [x1, x2] x [y1, y2], written out here
    m = plate_modes(PLATE)
    a, b = m.n * math.pi / PLATE.length, m.m * math.pi / PLATE.width
    x1, x2 = CENTRE[0] - SIZE[0] / 2, CENTRE[0] + SIZE[0] / 2
    y1, y2 = CENTRE[1] - SIZE[1] / 2, CENTRE[1] + SIZE[1] / 2
    want = ((np.cos(a * x1) - np.cos(a * x2)) / (a * (x2 - x1))
            * (np.cos(b * y1) - np.cos(b * y2)) / (b * (y2 - y1))) / math.sqrt(m.modal_mass)
    np.testing.assert_allclose(plate.patch_shapes(CENTRE, SIZE), want, rtol=1e-12)
    # and the generic quadrature of the interface agrees with it
    np.testing.assert_allclose(Structure.patch_shapes(plate, CENTRE, SIZE), want, rtol=1e-10,
                               atol=1e-12)
    np.testing.assert_allclose(plate.patch_slopes(CENTRE, SIZE),
                               Structure.patch_slopes(plate, CENTRE, SIZE), rtol=1e-9,
                               atol=1e-9)


def test_patch_residual_converges():
    plate = SimplySupportedPlate(Plate())  # the paper's 50 kHz plate
    c16 = plate.patch_residual_compliance(CENTRE, SIZE)
    c32 = plate.patch_residual_compliance(CENTRE, SIZE, factor=32.0)
    assert c16 > 0
    assert abs(c32 - c16) < 1e-3 * c16
    # far below the point residual (the area mean filters the short waves)
    assert c16 < 0.01 * plate.residual_compliance([CENTRE])[0, 0]


def test_rigid_base_has_no_modes():
    rigid = build_structure(Plate(kind="rigid"))
    assert rigid.n_modes == 0
    assert rigid.shapes([CENTRE]).shape == (0, 1)
    assert rigid.residual_compliance([CENTRE]) is None


def test_imported_modes_reproduce_the_plate(plate, imported):
    np.testing.assert_allclose(imported.omega, plate.omega, rtol=1e-14)
    np.testing.assert_allclose(imported.damping_ratio, plate.damping_ratio)
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(0.02, 0.28, 50), rng.uniform(0.02, 0.24, 50)])
    scale = 1.0 / math.sqrt(plate_modes(PLATE).modal_mass)  # the shapes' maximum
    err = np.abs(imported.shapes(pts) - plate.shapes(pts)).max()
    assert err < 2e-4 * scale  # measured 3e-5 on this 3 mm grid
    slope_err = np.abs(imported.slopes(pts) - plate.slopes(pts)).max()
    assert slope_err < 1e-2 * np.abs(plate.slopes(pts)).max()
    # the largest node value: at most the shape's maximum, within the grid's sampling of it
    assert np.all(imported.max_shape() <= scale * (1 + 1e-12))
    assert np.all(imported.max_shape() > 0.99 * scale)


def test_imported_patch_shapes_by_quadrature(plate, imported):
    # the interpolated shapes' area means against the plate's closed form
    got = imported.patch_shapes(CENTRE, SIZE)
    want = plate.patch_shapes(CENTRE, SIZE)
    assert np.abs(got - want).max() < 2e-4 * np.abs(want).max()


def test_imported_residual_from_modes_above_the_cut(tmp_path):
    # a file with modes to 10 kHz, imported with max_frequency 5 kHz: the residual is the
    # static part of the modes between 5 and 10 kHz
    full = Plate(max_frequency=10e3)
    structure = ImportedModes(PLATE, export_modes(PLATE, grid=(101, 88), max_frequency=10e3),
                              source="test")
    assert structure.n_modes == plate_modes(PLATE).omega.size
    pts = np.array([CENTRE, (0.2, 0.08)])
    m10 = SimplySupportedPlate(full)
    extra = m10.omega > structure.omega[-1] * 1.000001
    phi = m10.shapes(pts)[extra]
    want = (phi / m10.omega[extra, None] ** 2).T @ phi
    np.testing.assert_allclose(structure.residual_compliance(pts), want, rtol=1e-3)


def test_imported_residual_converges_to_the_plate_series():
    """The residual compliance an imported structure sums from the file's modes above the cut
    and the built-in plate's exact series (physics/plate.py) are the same quantity: the sum
    over the modes between the cut and N x the cut plus the exact residual above N x the cut
    is the exact residual above the cut (to round-off), and the sum alone, from the modes
    exported to N x the cut and interpolated, converges to it as N grows, missing about 1/N
    of it (a thin plate's modal density is constant and its terms fall as 1/omega^2; the
    residual above omega_c is (2/pi) Y_inf / omega_c, docs/theory.md)."""
    pts = np.array([CENTRE, (0.2, 0.08)])
    exact = SimplySupportedPlate(PLATE).residual_compliance(pts)
    missing = []
    for n in (2, 4, 8):
        upto = SimplySupportedPlate(Plate(max_frequency=n * PLATE.max_frequency))
        above = upto.omega > 2 * math.pi * PLATE.max_frequency * (1 + 1e-12)
        phi = upto.shapes(pts)[above]
        series = (phi / upto.omega[above, None] ** 2).T @ phi
        np.testing.assert_allclose(series + upto.residual_compliance(pts), exact,
                                   rtol=1e-9, atol=1e-9 * np.abs(exact).max())
        modes = export_modes(PLATE, grid=(101, 88), max_frequency=n * PLATE.max_frequency)
        got = ImportedModes(PLATE, modes, source="test").residual_compliance(pts)
        # interpolated on the 3 mm grid: within 1 % of the sum over the exact shapes
        np.testing.assert_allclose(got, series, rtol=1e-2, atol=1e-2 * np.abs(series).max())
        missing.append(1.0 - np.diag(got) / np.diag(exact))
    missing = np.array(missing)  # (N, point)
    assert np.all(np.diff(missing, axis=0) < 0)  # converges
    # about 1/N missing: (f_cut / f_last) as the summary states
    np.testing.assert_allclose(missing, np.array([[1 / 2], [1 / 4], [1 / 8]]) * np.ones((1, 2)),
                               rtol=0.15)


def test_imported_residual_is_described_and_missing_one_is_noted():
    full = ImportedModes(PLATE, export_modes(PLATE, grid=(41, 36)), source="'m.npz'")
    n_above = (plate_modes(Plate(max_frequency=2 * PLATE.max_frequency)).omega.size
               - plate_modes(PLATE).omega.size)
    assert full.residual.startswith(f"the file's {n_above} modes from ")
    assert "f_cut/f_last = " in full.residual and full.notes == ()
    cut = export_modes(PLATE, grid=(41, 36), max_frequency=PLATE.max_frequency)
    bare = ImportedModes(PLATE, cut, source="'m.npz'")
    assert bare.residual_compliance([CENTRE]) is None and bare.residual.startswith("none")
    (note,) = bare.notes
    assert "plate.modes_file 'm.npz' holds no modes above plate.max_frequency" in note
    assert "\n" not in note
    off = ImportedModes(Plate(max_frequency=5000.0, residual_compliance=False), cut, "'m.npz'")
    assert off.notes == ()


def test_assembly_warns_of_a_missing_residual_and_honours_the_switch(tmp_path):
    from roughvib.model.system import assemble
    from roughvib.scene import ModelValidityWarning, load_scene

    write_modes(tmp_path / "cut.npz", export_modes(PLATE, grid=(41, 36),
                                                   max_frequency=PLATE.max_frequency))
    write_modes(tmp_path / "full.npz", export_modes(PLATE, grid=(41, 36)))
    over = {"plate.kind": "imported", "plate.max_frequency": PLATE.max_frequency}
    with pytest.warns(ModelValidityWarning, match="holds no modes above plate.max_frequency"):
        bare = assemble(load_scene("paper", {**over, "plate.modes_file": "cut.npz"}),
                        force_amplitude=0.9)
    assert any("no residual compliance" in w for w in bare.warnings)
    assert not bare.cres.any()
    full = assemble(load_scene("paper", {**over, "plate.modes_file": "full.npz"}),
                    force_amplitude=0.9)
    assert np.all(np.diag(full.cres) > 0)
    off = assemble(load_scene("paper", {**over, "plate.modes_file": "full.npz",
                                        "plate.residual_compliance": False}),
                   force_amplitude=0.9)
    assert not off.cres.any() and not any("residual" in w for w in off.warnings)


def _write(path, **arrays):
    np.savez(path, **arrays)
    return path


def _good():
    nodes = np.array([[0, 0], [1, 0], [0, 1], [1, 1.0]])
    return {"frequency": np.array([20.0, 10.0]), "nodes": nodes,
            "shapes": np.array([[1, 2, 3, 4.0], [0, 1, 0, 1.0]])}


def test_read_modes_sorts_by_frequency(tmp_path):
    m = read_modes(_write(tmp_path / "m.npz", **_good()))
    np.testing.assert_array_equal(m.frequency, [10.0, 20.0])
    np.testing.assert_array_equal(m.shapes[0], [0, 1, 0, 1.0])


@pytest.mark.parametrize("change, fragment", [
    ({"frequency": np.array([20.0, 0.0])},
     "mode 2 has frequency 0 Hz; rigid-body modes are not supported"),
    ({"frequency": np.array([20.0, -3.0])}, "every frequency must be finite and > 0 Hz"),
    ({"shapes": np.ones((2, 3))}, "shapes [1/sqrt(kg)] must have shape (R, N) = (2, 4)"),
    ({"shapes": np.array([[1, 2, np.nan, 4.0], [0, 1, 0, 1.0]])},
     "shapes [1/sqrt(kg)] must be finite"),
    ({"nodes": np.ones((4, 3))}, "nodes [m] must have shape (N, 2)"),
    ({"nodes": np.array([[0, 0], [1, 1], [2, 2], [3, 3.0]])}, "nodes [m] must span an area"),
    ({"damping_ratio": np.array([0.01, 1.5])}, "damping_ratio [-] must be in [0, 1)"),
    ({"frequency": None}, "missing frequency"),
    # shapes 1e200 times too large made the static equilibrium a singular matrix
    ({"shapes": np.array([[1, 2, 3, 4.0], [0, 1, 0, 1.0]]) * 1e200},
     "shapes [1/sqrt(kg)] must be mass-normalised, at most 2e+06 in magnitude (a modal mass "
     "of at least 1e-12 kg, the lightest plate within the sane ranges), got 4e+200 for mode 1"),
    # numpy dropped the imaginary part with a ComplexWarning
    ({"shapes": np.array([[1, 2, 3, 4.0], [0, 1, 0, 1.0]]) + np.array([[0, 0, 0.5j, 0]] * 2)},
     "shapes [1/sqrt(kg)] must be real numbers (real normal modes; realise complex modes "
     "before importing them), got 2 value(s) with an imaginary part, the first 3+0.5j at "
     "mode 1, node 3"),
])
def test_bad_modes_files_are_refused_in_one_line(tmp_path, change, fragment):
    arrays = {**_good(), **change}
    arrays = {k: v for k, v in arrays.items() if v is not None}
    path = _write(tmp_path / "bad.npz", **arrays)
    with pytest.raises(SceneError) as info:
        read_modes(path)
    msg = str(info.value)
    assert fragment in msg and "bad.npz" in msg and "\n" not in msg


def test_complex_arrays_with_a_zero_imaginary_part_are_read_as_real(tmp_path):
    arrays = _good()
    path = _write(tmp_path / "c.npz", **{**arrays, "shapes": arrays["shapes"] + 0j})
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ComplexWarning
        m = read_modes(path)
    assert m.shapes.dtype == float
    np.testing.assert_array_equal(m.shapes, arrays["shapes"][::-1])


def _damaged_npz(tmp_path, kind):
    path = tmp_path / "bad.npz"
    good = _write(tmp_path / "good.npz", **_good()).read_bytes()
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "truncated":
        path.write_bytes(good[:len(good) // 2])
    elif kind == "npy":
        np.save(tmp_path / "a.npy", np.ones(3))
        path.write_bytes((tmp_path / "a.npy").read_bytes())
    else:  # a member damaged inside a complete archive: its checksum fails
        np.savez_compressed(path, **_good())
        raw = bytearray(path.read_bytes())
        raw[60:80] = bytes(20)
        path.write_bytes(bytes(raw))
    return path


@pytest.mark.parametrize("kind, fragment", [
    ("empty", "must be a .npz file (a zip archive of arrays, as numpy.savez writes), got an "
              "empty file (0 bytes)"),  # was EOFError
    ("truncated", "bytes that are not a complete zip archive (truncated, or another format?)"),
    ("npy", "bytes that are not a complete zip archive"),  # was TypeError
    ("damaged", "is not a readable .npz file (damaged or truncated?): "),  # was BadZipFile
])
def test_damaged_npz_files_are_refused_in_one_line(tmp_path, kind, fragment):
    path = _damaged_npz(tmp_path, kind)
    with pytest.raises(SceneError) as info:
        read_modes(path)
    msg = str(info.value)
    assert msg.startswith(f"plate.modes_file {str(path)!r} ") and fragment in msg, msg
    assert "\n" not in msg


def _unv_lines(tmp_path):
    modes = export_modes(Plate(max_frequency=1000.0), grid=(6, 5))
    return write_modes(tmp_path / "plate.unv", modes).read_text().splitlines(keepends=True)


def test_a_truncated_universal_file_is_refused(tmp_path):
    """pyuff drops a dataset without its closing delimiter: a file cut inside a mode ran with
    the modes before the cut, without a word."""
    lines = _unv_lines(tmp_path)
    delims = [i + 1 for i, ln in enumerate(lines) if ln.rstrip() == "    -1"]
    assert len(delims) == 2 * (1 + len(read_modes(tmp_path / "plate.unv")))
    last_open = delims[-2]
    for cut in (last_open, last_open + 12, len(lines) - 1):
        path = tmp_path / f"cut{cut}.unv"
        path.write_text("".join(lines[:cut]))
        with pytest.raises(SceneError) as info:
            read_modes(path)
        assert str(info.value) == (
            f"plate.modes_file {str(path)!r} is truncated: dataset "
            f"{'55 ' if cut > last_open else ''}opened on line {last_open} never ends (every "
            f"dataset must end with a line '    -1'), got the end of the file on line {cut}")
    # cut after a dataset's closing line the file is complete (with fewer modes): nothing in
    # the format tells the two apart
    path = tmp_path / "whole.unv"
    path.write_text("".join(lines[:delims[-3]]))
    assert len(read_modes(path)) == len(read_modes(tmp_path / "plate.unv")) - 1


@pytest.mark.parametrize("value, fragment", [
    ("  nan", "every value must be a finite number, got 'nan'"),
    ("  ***********", "every value must be a number, got '***********'"),
    ("          NaN", "dataset 55 #1 (mode 1) must give a finite number at every node, got nan "
                    "at node 3"),  # read by pyuff, which then said 1 node lacked a value
])
def test_a_value_that_is_not_a_number_is_named_in_a_universal_file(tmp_path, value, fragment):
    lines = _unv_lines(tmp_path)
    first55 = next(i for i, ln in enumerate(lines) if ln.strip() == "55")
    row = first55 + 14  # the vertical displacement of the third node of the first mode
    assert lines[row - 1].strip() == "3"
    lines[row] = lines[row][:-14] + value + "\n"  # the last field (E13.5) replaced
    path = tmp_path / "nan.unv"
    path.write_text("".join(lines))
    with pytest.raises(SceneError) as info:
        read_modes(path)
    msg = str(info.value)
    if "NaN" not in value:
        fragment = f"dataset 55 (lines {first55}-{first55 + 2 * 30 + 10}), line {row + 1}: " \
            + fragment
    assert msg.startswith(f"plate.modes_file {str(path)!r}: ") and fragment in msg, msg


def test_points_outside_the_nodes_are_refused():
    modes = read_modes(_write("m.npz", **_good()))
    structure = ImportedModes(Plate(), modes, source="'m.npz'")
    assert structure.shapes([[0.5, 0.5]]).shape == (2, 1)
    with pytest.raises(SceneError, match=r"point \(1.5, 0.5\) m lies outside the convex hull"):
        structure.shapes([[1.5, 0.5]])


def test_universal_file_round_trip(tmp_path):
    modes = export_modes(Plate(max_frequency=1000.0), grid=(16, 14))
    back = read_modes(write_modes(tmp_path / "plate.unv", modes))
    np.testing.assert_allclose(back.frequency, modes.frequency, rtol=1e-5)  # 6 digits
    np.testing.assert_allclose(back.nodes, modes.nodes, atol=1e-9)
    np.testing.assert_allclose(back.shapes, modes.shapes, rtol=1e-5,
                               atol=1e-5 * np.abs(modes.shapes).max())
    np.testing.assert_allclose(back.damping_ratio, modes.damping_ratio)
    exact = read_modes(write_modes(tmp_path / "plate.npz", modes))
    np.testing.assert_array_equal(exact.shapes, modes.shapes)


def test_gauss_rectangle_weights_give_means():
    pts, w = gauss_rectangle((1.0, 2.0), (0.5, 0.25), 6)
    assert w.sum() == pytest.approx(1.0)
    # mean of x^2 y over the rectangle
    want = ((1.25**3 - 0.75**3) / 3 / 0.5) * 2.0
    assert (pts[:, 0] ** 2 * pts[:, 1]) @ w == pytest.approx(want, rel=1e-13)


def test_modeset_len():
    assert len(ModeSet(np.array([1.0]), np.zeros((3, 2)), np.ones((1, 3)))) == 1


def _round_trip(tmp_path, over):
    """The built-in plate's run and the run of its default export imported (the modes to
    EXPORT_FACTOR x plate.max_frequency, the default grid), with their accuracy measure."""
    import warnings

    import roughvib
    from roughvib.analysis.accuracy import measure_accuracy
    from roughvib.scene import ModelValidityWarning, load_scene

    scene = load_scene("paper", over)
    write_modes(tmp_path / "plate.npz", export_modes(scene.plate))
    imported = load_scene("paper", {**over, "plate.kind": "imported",
                                    "plate.modes_file": str(tmp_path / "plate.npz")})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelValidityWarning)  # a short window < a period
        ref = roughvib.simulate(scene, progress=False)
        got = roughvib.simulate(imported, progress=False)
    return ref, got, measure_accuracy(got, ref, period=scene.period,
                                      transient=scene.output.transient)


def test_export_then_import_reproduces_the_plate_run(tmp_path):
    """The accuracy contract (docs/accuracy.md) between the built-in plate's run and the run
    of its default export imported, over the first 0.05 s: bands within 1 dB, events within
    1e-6 s. The file holds the modes to 2 x the cut; those above it give the imported
    structure's residual compliance, about 1 - 1/2 of the exact one at the contact (a thin
    plate's modes to N x the cut miss about 1/N of it, test above)."""
    from roughvib.physics.structures import EXPORT_FACTOR

    over = {"output.duration": 0.05, "output.transient": 0.0,
            "excitation.force_amplitude": 0.9154,  # the calibrated T0 (no calibration here)
            "excitation.target_rms_velocity": "none", "contact.velocity_factor": False}
    ref, got, acc = _round_trip(tmp_path, over)
    assert acc["verdict"] == "pass", acc
    assert acc["events"]["matched"] >= 1
    res_ref = ref.summary["model"]["residual_compliance"]
    res_got = got.summary["model"]["residual_compliance"]
    assert res_ref["source"].startswith("exact") and res_got["source"].startswith("the file's")
    assert res_got["largest"] == pytest.approx((1 - 1 / EXPORT_FACTOR) * res_ref["largest"],
                                               rel=0.03)


@pytest.mark.slow
def test_default_export_round_trip_on_the_paper_run_bands_and_event_law(tmp_path):
    """The whole default paper run (3/7 s, calibrated T0) through the default export and back:
    bands, tangential velocity and energy audit meet the accuracy contract against the built-in
    plate, every event is matched, and the event-time error is the residual-compliance part the
    file leaves out. Stick and slip times move in proportion to the missing residual, so the
    error with the file's residual (modes to N = EXPORT_FACTOR x the cut, about 1/N of the
    exact residual missing) is about 1/N of the error with no residual at all. The event
    times alone miss the 1e-6 s limit on the physical input (docs/structures.md)."""
    import roughvib
    from roughvib.analysis.accuracy import measure_accuracy
    from roughvib.physics.structures import EXPORT_FACTOR
    from roughvib.scene import load_scene

    ref, got, acc = _round_trip(tmp_path, {})
    assert acc["events"]["unmatched"] == 0 and acc["events"]["matched"] >= 10
    others = [f for f in acc["failures"] if not f.startswith("event times off")]
    assert not others, others
    paper = load_scene("paper")
    bare = roughvib.simulate(load_scene("paper", {
        "plate.kind": "imported", "plate.modes_file": str(tmp_path / "plate.npz"),
        "plate.residual_compliance": False}), progress=False)
    acc_bare = measure_accuracy(bare, ref, period=paper.period,
                                transient=paper.output.transient)
    assert acc_bare["events"]["unmatched"] == 0
    ratio = acc["events"]["max_dt"] / acc_bare["events"]["max_dt"]
    assert ratio == pytest.approx(1 / EXPORT_FACTOR, abs=0.15), ratio


def test_cli_modes_export(tmp_path, capsys):
    from roughvib.cli import main

    out = tmp_path / "m.npz"
    assert main(["modes", "export", "paper", str(out), "--grid", "21", "19",
                 "--set", "plate.max_frequency=1000"]) == 0
    m = read_modes(out)  # by default to 2 x the cut: the modes above it give the residual
    assert m.nodes.shape == (21 * 19, 2) and len(m) == len(plate_modes(Plate(max_frequency=2e3)))
    assert main(["modes", "export", "paper", str(out), "--grid", "21", "19", "--set",
                 "plate.max_frequency=1000", "--max-frequency", "1000", "--overwrite"]) == 0
    assert len(read_modes(out)) == len(plate_modes(Plate(max_frequency=1e3)))
    assert main(["modes", "export", "paper", str(tmp_path / "m.txt")]) == 2
    assert main(["modes", "export", "paper", str(out), "--set", "plate.kind=rigid",
                 "--overwrite"]) == 2
    captured = capsys.readouterr()
    assert "above plate.max_frequency = 1000 Hz" in captured.out
    err = captured.err.strip().splitlines()
    assert "must end in one of .npz, .unv, .uff" in err[0]
    assert "has no modes to export" in err[1]


def test_cli_export_factor_is_the_structures_one():
    from roughvib.cli import modes
    from roughvib.physics.structures import EXPORT_FACTOR

    assert modes.EXPORT_FACTOR == EXPORT_FACTOR


@pytest.mark.parametrize("fmax", [2000.0, 100.0])  # 100 Hz: no mode kept, all residual
def test_area_patch_statics_match_the_area_mean_greens_function(fmax):
    """Static equilibrium with contact.patch = "area": the mean plate deflection under the block
    is m g times the area-mean of the exact static Green's function (Levy series, physics/
    plate.py) over the footprint, by Gauss quadrature here: modes + patch residual together."""
    from roughvib.model.system import GRAVITY, assemble
    from roughvib.scene import load_scene

    scene = load_scene("paper", {"contact.patch": "area", "plate.max_frequency": fmax,
                                 "contact.points": 3, "contact.stiffness": 3.1e6,
                                 "output.duration": 0.3})
    system = assemble(scene)
    y, _ = system.static_equilibrium()
    q = y[system.layout.slice("plate.q")]
    F = y[system.layout.slice("contact.force")]
    w = system.phi.T @ q + system.cres @ F      # what every contact feels [m]
    pts, wts = gauss_rectangle(scene.plate.block_position,
                               (scene.block.length, scene.block.width), 10)
    G = static_compliance(scene.plate, pts)
    want = scene.block.mass * GRAVITY * (wts @ G @ wts)
    np.testing.assert_allclose(w, want, rtol=2e-3)


@pytest.mark.parametrize("method", [
    "adaptive-modal", pytest.param("ida", marks=pytest.mark.slow),
    pytest.param("exact-modal", marks=pytest.mark.slow),
    pytest.param("paper", marks=pytest.mark.slow)])
def test_every_solver_runs_imported_modes_with_an_area_patch(tmp_path, method):
    """Every solver reads the same modal arrays: imported modes with the area patch run, and
    the energy audit of the event-driven solvers closes."""
    import warnings

    import roughvib
    from roughvib.scene import ModelValidityWarning, load_scene

    small = Plate(max_frequency=2000.0)
    write_modes(tmp_path / "m.npz", export_modes(small, grid=(41, 36)))
    scene = load_scene("paper", {"plate.kind": "imported", "contact.patch": "area",
                                 "plate.modes_file": str(tmp_path / "m.npz"),
                                 "plate.max_frequency": 2000.0, "solver.method": method,
                                 "output.duration": 0.01, "output.transient": 0.0})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelValidityWarning)
        result = roughvib.simulate(scene, progress=False)
    assert result.summary["status"] == "success"
    assert result.summary["model"]["modes"] == len(plate_modes(small))
    if method in ("ida", "adaptive-modal"):
        assert abs(result.summary["energy_audit"]["relative_residual"]) < 1e-5


@pytest.mark.parametrize("over, fragment", [
    ({"contact.patch": "disc"}, "contact.patch must be one of 'point', 'area', got 'disc'"),
    ({"plate.kind": "imported"}, "plate.modes_file must name a modes file"),
    ({"plate.kind": "imported", "plate.modes_file": "nowhere.npz"},
     "nowhere.npz' does not exist (relative paths are relative to the scene file)"),
    ({"plate.kind": "imported", "plate.modes_file": "modes.csv"},
     "modes.csv' must end in one of .npz, .unv, .uff"),
])
def test_bad_structure_keys_are_refused_in_one_line(tmp_path, over, fragment):
    from roughvib.model.system import assemble
    from roughvib.scene import load_scene

    with pytest.raises(SceneError) as info:
        assemble(load_scene("paper", over))
    assert fragment in str(info.value) and "\n" not in str(info.value)
