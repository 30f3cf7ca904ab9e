"""The outputs of a run: declared once (``roughvib.model.variables``: name, unit, description)
and written by one function for every solver (``kernels.write_output_row``), which leaves no
column unwritten (issue 45).

A new output is one entry in the declaration and one argument of ``write_output_row``: these
tests fail when the two disagree (a declared column that no argument fills), when a module
writes an output column itself, or when a solver leaves a column NaN where the quantity
exists.
"""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest

import roughvib
from roughvib.model import kernels as kn
from roughvib.model import variables as va
from roughvib.results import VARIABLES

SRC = Path(roughvib.__file__).parent
#: the outputs that prescribed motion leaves NaN: without a tangential state there is no
#: friction model (simulation.py notes it in the variables' attributes)
NO_FRICTION = ("friction_force", "friction_coefficient")


def test_every_variable_is_declared_once_with_one_unit_and_description():
    names = [v.name for v in va.VARIABLE_TABLE]
    assert len(names) == len(set(names))
    for v in va.VARIABLE_TABLE:
        assert isinstance(v.unit, str) and v.unit.strip() == v.unit and v.unit, v
        assert isinstance(v.description, str) and v.description.strip(), v
    # the result's table and the kernels' columns are this declaration, not copies of it
    assert VARIABLES == {v.name: (v.unit, v.description) for v in va.VARIABLE_TABLE}
    assert list(VARIABLES) == names
    assert kn.OUTPUTS is va.OUTPUTS and kn.CONTACT_OUTPUTS is va.CONTACT_OUTPUTS
    for K in (1, 4):
        cols = kn.output_columns(K)
        assert list(cols) == [v.name for v in va.OUTPUTS + va.CONTACT_OUTPUTS]
        taken = []
        for col in cols.values():
            taken += [col] if isinstance(col, int) else list(range(col.start, col.stop))
        assert sorted(taken) == list(range(kn.n_output_columns(K)))
        for k in range(K):
            assert kn.out_force_column(k, K) == cols["contact_force"].start + k
            assert kn.out_roughness_column(k, K) == cols["roughness_input"].start + k


def test_the_output_positions_are_the_names_positions():
    for j, v in enumerate(va.OUTPUTS):
        const = {name for name in dir(va) if name.startswith("OUT_")
                 and not name.startswith("OUT_C_") and getattr(va, name) == j}
        assert len(const) == 1, (v.name, const)


def test_write_output_row_fills_every_column_from_its_arguments():
    """One argument per output: every column of a row gets a value, and in the order of the
    declaration (the fixed outputs, then the per-contact blocks)."""
    write = getattr(kn.write_output_row, "py_func", kn.write_output_row)
    params = list(inspect.signature(write).parameters)
    assert params[:2] == ["out", "tangential"]
    assert len(params) == 2 + len(va.OUTPUTS) + len(va.CONTACT_OUTPUTS)
    K = 3
    row = np.full(kn.n_output_columns(K), np.nan)
    fixed = [10.0 + j for j in range(len(va.OUTPUTS))]
    force = np.array([1.0, 2.0, 3.0])
    height = np.array([-4.0, -5.0, -6.0])
    kn.write_output_row(row, True, *fixed, force, height)
    assert np.isfinite(row).all()
    assert list(row[:va.N_OUT_FIXED]) == fixed
    cols = kn.output_columns(K)
    assert list(row[cols["contact_force"]]) == [1.0, 2.0, 3.0]
    assert list(row[cols["roughness_input"]]) == [4.0, 5.0, 6.0]  # -h, positive down
    # prescribed motion: no friction model
    kn.write_output_row(row, False, *fixed, force, height)
    for name in NO_FRICTION:
        assert np.isnan(row[cols[name]])
    assert np.isfinite(np.delete(row, [cols[n] for n in NO_FRICTION])).all()


def _writes_an_output_column(target: ast.expr) -> bool:
    """Whether an assignment target is ``x[..., OUT_*]`` or ``x[out_*_column(...)]``."""
    if not isinstance(target, ast.Subscript):
        return False
    for node in ast.walk(target.slice):
        name = node.id if isinstance(node, ast.Name) else (
            node.attr if isinstance(node, ast.Attribute) else "")
        if name.startswith("OUT_") or name in ("out_force_column", "out_roughness_column"):
            return True
    return False


def test_the_writer_check_catches_what_it_must():
    def targets(src):
        return [_writes_an_output_column(n.targets[0]) for n in ast.parse(src).body]
    assert targets("out[row, kn.OUT_Z] = z\nout[OUT_MU] = m\n"
                   "out[kn.out_force_column(k, K)] = f\nx[OUT] = 1\nfric = out[OUT_X]\n"
                   ) == [True, True, True, False, False]


def test_only_write_output_row_writes_output_columns():
    writers = []
    for path in SRC.rglob("*.py"):
        tree = ast.parse(path.read_text())
        for fn in ast.walk(tree):
            if not isinstance(fn, ast.FunctionDef):
                continue
            for node in ast.walk(fn):
                targets = (node.targets if isinstance(node, ast.Assign) else
                           [node.target] if isinstance(node, ast.AugAssign | ast.AnnAssign)
                           else [])
                if any(_writes_an_output_column(t) for t in targets):
                    writers.append(f"{path.relative_to(SRC)}:{fn.name}")
    assert sorted(set(writers)) == ["model/kernels.py:write_output_row"]


#: every solver on the paper scene for a few ms (moreau runs the set-valued law only)
SOLVERS = {"ida": {}, "adaptive-modal": {}, "exact-modal": {}, "newmark": {},
           "moreau": {"friction.law": "coulomb"}, "paper": {}}


@pytest.mark.filterwarnings("ignore::roughvib.scene.ModelValidityWarning")  # a short window
@pytest.mark.parametrize("motion", ["force", "prescribed"])
@pytest.mark.parametrize("method", list(SOLVERS))
def test_every_solver_fills_every_output(method, motion):
    over = {"output.progress": False, "output.duration": 0.003, "output.transient": 0.0,
            "solver.method": method, **SOLVERS[method]}
    if motion == "prescribed":
        over.update({"excitation.kind": "prescribed", "excitation.velocity": 0.01,
                     "excitation.amplitude": 0.0, "excitation.target_rms_velocity": "none"})
    scene = roughvib.load_scene("paper", over)
    r = roughvib.simulate(scene)
    assert r.status == "success", r.summary
    ds = r.to_dataset()
    assert ds.sizes["time"] == round(scene.output.duration / scene.output.step) + 1
    for name in VARIABLES:
        values = ds[name].values
        if motion == "prescribed" and name in NO_FRICTION:
            assert np.isnan(values).all(), name
        else:
            assert np.isfinite(values).all(), (method, motion, name)
