"""Malformed and absurd input files, one class per reader: through the command line each is
refused with exit status 2 and one line on stderr that names the file and the rule.

The worst case of each class, as it was found, is in the parameters: a traceback (a Latin-1
byte in a friction table, an empty or unnormalised modes file, a WAV file cut to 30 bytes), a
run on damaged or absurd input (a truncated universal file, a friction coefficient of 1e300,
a profile in micrometres declared as metres), or a message that named neither file nor key (a
sidecar's ``"scale": "ten"``). Every refusal comes before a solve.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from scipy.io import wavfile

from roughvib.cli import main
from roughvib.scene import ModelValidityWarning

QUIET = ["--no-progress", "--quiet"]


def _refused(capsys, argv: list[str], *needles: str) -> str:
    """Run the command: exit status 2, and stderr one line holding every needle."""
    capsys.readouterr()
    with warnings.catch_warnings():  # a warning would be a second line on stderr
        warnings.simplefilter("error", ModelValidityWarning)
        assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("roughvib: error: ") and err.count("\n") == 1, err
    for needle in needles:
        assert needle in err, err
    return err


# --------------------------------------------------------------------------------------------
# friction tables (friction.law = "table")
# --------------------------------------------------------------------------------------------

FRICTION_TABLES = {
    "latin1": (b"velocity,mu\n0,0.3\n1,0.3 \xe9\n", "must be UTF-8 text"),
    "semicolons": (b"velocity;mu\n0;0,3\n1;0,3\n", "must separate its columns with commas"),
    "mu-1e300": (b"velocity,mu\n0,0.3\n1,1e300\n", "mu must be in [0, 10]"),
    "step-1e-200": (b"velocity,mu\n0,0.35\n1e-200,0.3\n1,0.3\n", "mu may change by at most"),
}


@pytest.mark.parametrize("case", sorted(FRICTION_TABLES))
def test_malformed_friction_tables(tmp_path, capsys, case):
    content, rule = FRICTION_TABLES[case]
    path = tmp_path / f"{case}.csv"
    path.write_bytes(content)
    _refused(capsys, ["run", "paper-handset", "--set", "plate.kind='rigid'", "--set",
                      "roughness.kind='none'", "--set", "friction.law='table'", "--set",
                      f"friction.table='{path}'", "--set", "excitation.force_amplitude=1.0",
                      "--set", "excitation.target_rms_velocity=none", "--set",
                      "output.transient=0", *QUIET, "--out", tmp_path / "run"],
             f"friction.parameters.table '{path}'", rule)
    assert not (tmp_path / "run").exists()


# --------------------------------------------------------------------------------------------
# modes files (plate.kind = "imported")
# --------------------------------------------------------------------------------------------

def _modes_file(tmp_path, case: str):
    from roughvib.physics.structures import export_modes
    from roughvib.physics.structures.exchange import write_modes
    from roughvib.scene import Plate

    modes = export_modes(Plate(max_frequency=2000.0), grid=(6, 5))
    arrays = {"frequency": modes.frequency, "nodes": modes.nodes, "shapes": modes.shapes}
    path = tmp_path / f"{case}.npz"
    if case == "empty":
        path.write_bytes(b"")
    elif case == "shapes-1e200":
        np.savez(path, **{**arrays, "shapes": modes.shapes * 1e200})
    elif case == "complex":
        np.savez(path, **{**arrays, "shapes": modes.shapes * (1 + 0.1j)})
    else:
        path = write_modes(tmp_path / f"{case}.unv", modes)
        lines = path.read_text().splitlines(keepends=True)
        if case == "truncated-unv":
            lines = lines[:len(lines) - 20]
        else:  # a value out of its field, which pyuff cannot read
            row = next(i for i, ln in enumerate(lines) if ln.strip() == "55") + 14
            lines[row] = lines[row][:-14] + "  nan\n"
        path.write_text("".join(lines))
    return path


MODES_FILES = {
    "empty": "got an empty file (0 bytes)",
    "shapes-1e200": "shapes [1/sqrt(kg)] must be mass-normalised, at most 2e+06",
    "complex": "shapes [1/sqrt(kg)] must be real numbers",
    "truncated-unv": "is truncated: dataset 55 opened on line",
    "nan-unv": "every value must be a finite number, got 'nan'",
}


@pytest.mark.parametrize("case", sorted(MODES_FILES))
def test_malformed_modes_files(tmp_path, capsys, case):
    path = _modes_file(tmp_path, case)
    _refused(capsys, ["run", "--set", "plate.kind='imported'", "--set",
                      f"plate.modes_file='{path}'", "--set", "plate.max_frequency=1000",
                      *QUIET, "--out", tmp_path / "run"],
             f"plate.modes_file '{path}'", MODES_FILES[case])
    assert not (tmp_path / "run").exists()


# --------------------------------------------------------------------------------------------
# measured records (roughvib validate)
# --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A run to validate against: a rigid base without roughness for 0.02 s (nothing here
    gets as far as comparing)."""
    import roughvib

    scene = roughvib.load_scene("paper", {"plate.kind": "rigid", "roughness.kind": "none",
                                          "output.duration": 0.02, "output.transient": 0.0,
                                          "output.progress": False})
    d = tmp_path_factory.mktemp("malformed") / "run"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelValidityWarning)  # the window: a part of a cycle
        roughvib.simulate(scene).save(d)
    return d


def _record(tmp_path, case: str):
    x = np.sin(np.arange(4800) / 10.0).astype(np.float32)
    if case == "directory":
        path = tmp_path / "d.csv"
        path.mkdir()
    elif case in ("wav-30-bytes", "sidecar-ten"):
        path = tmp_path / "rec.wav"
        wavfile.write(path, 48000, x)
        if case == "wav-30-bytes":
            path.write_bytes(path.read_bytes()[:30])
        else:
            path.with_suffix(".json").write_text(json.dumps({"scale": "ten", "units": "g"}))
    elif case == "csv-latin1":
        path = tmp_path / "rec.csv"
        path.write_bytes(b"time [s],a [\xb5m/s^2]\n0,1\n0.001,2\n")
    else:  # a universal file cut inside its dataset 58
        import pyuff

        path = tmp_path / "rec.uff"
        pyuff.UFF(str(path)).write_sets([pyuff.prepare_58(
            func_type=1, rsp_node=1, rsp_dir=3, ref_node=0, ref_dir=0, id1="plate",
            abscissa_spacing=1, abscissa_spec_data_type=17, ordinate_spec_data_type=12,
            orddenom_spec_data_type=0, z_axis_spec_data_type=0, ordinate_axis_units_lab="g",
            data=x.astype(float), x=np.arange(x.size) / 48000.0)], mode="overwrite")
        path.write_text("".join(path.read_text().splitlines(keepends=True)[:100]))
    return path


RECORDS = {
    "directory": ("d.csv", "is a directory, not a measured record file"),
    "wav-30-bytes": ("rec.wav", "the WAV file is truncated: its header declares"),
    "sidecar-ten": ("rec.json", "sidecar key 'scale' must be a number > 0 (g per full-scale "
                                "unit), got 'ten'"),
    "csv-latin1": ("rec.csv", "must be UTF-8 text (save it as UTF-8), got byte 0xb5"),
    "uff-truncated": ("rec.uff", "the universal file is truncated: dataset 58"),
}


@pytest.mark.parametrize("case", sorted(RECORDS))
def test_malformed_records(tmp_path, capsys, tiny_run, case):
    path = _record(tmp_path, case)
    name, rule = RECORDS[case]
    _refused(capsys, ["validate", tiny_run, path, "--signal", "plate"], name, rule)
    assert not (tiny_run / "validation").exists()


# --------------------------------------------------------------------------------------------
# roughness profile files (roughness.kind = "file")
# --------------------------------------------------------------------------------------------

def test_a_profile_in_micrometres_declared_as_metres(tmp_path, capsys):
    """x and heights in um read as m ran to 'success' (steps of 10 m, nothing left after the
    high-pass over the block length)."""
    rng = np.random.default_rng(5)
    x_um = np.arange(16001) * 10.0
    z_um = rng.normal(0.0, 0.35, x_um.size)
    path = tmp_path / "profile.txt"
    np.savetxt(path, np.column_stack([x_um, z_um]))
    _refused(capsys, ["run", "--set", "roughness.kind='file'", "--set",
                      f"roughness.path='{path}'", "--set", "roughness.units='m'", *QUIET,
                      "--out", tmp_path / "run"],
             f"roughness.path {path} (units = 'm'): the sampling step must be in [1e-09, "
             f"0.001] m", "roughness.units = 'um'")
