"""No literal positional index into a packed array anywhere in src/ (issue 26).

The kernels see flat arrays (the header ``off``, the scalars ``fp``, the regime ``reg``/``rf``,
the loop state ``ist``, the outputs, the solvers' state buffers); a position in one of them is
a named constant (``off[OFF_IZ]``, ``fp[FP_MASS]``, ``out[OUT_VX]``), never a number, so that
a new entry or a reordering cannot silently shift a meaning.

The rule, checked on the syntax tree of every module of the package:

* a subscript whose index is an integer literal, or a tuple with one (``a[3]``,
  ``a[r, 0, 1]``), is refused, with two exceptions kept deliberately small:

  1. ``x.shape[i]``: numpy's shape tuple, not one of ours;
  2. ``[0]`` and ``[-1]``: the first and the last element of a sequence (a time grid's ends,
     the first output row), which are not positions in a packed record; but never on the
     packed arrays of ``PACKED`` below, which take named positions without exception.

* in the modules that pack and run the kernels (``STRICT``: model/, solvers/ and the friction
  law) no other literal index is left either (a mode's [q, q'] components, the rows of a
  solver's buffers, the unknowns of a Newton step all have names);
* the other modules, written before the rule, keep at most their current count of other
  literal indices (``axes[1]``, the x and y columns of point lists, tick labels): ``RATCHET``
  may only go down, and a new module starts at zero.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "roughvib"

#: the packed arrays the kernels and solver loops read: no literal index at all, not even 0
PACKED = {"off", "args_off", "fp", "fpa", "reg", "rf", "ist", "out", "outbuf", "work", "tang",
          "zv", "energy", "cache", "d", "d0", "d1", "Y", "D", "U", "G", "tab", "table",
          "jac_count"}

#: modules (or folders) where no literal index is left at all
STRICT = ("model/", "solvers/", "physics/friction.py")

#: literal indices (other than the two exceptions) that the other modules held when the rule
#: came in; counts may only decrease
RATCHET = {
    # the x and y columns of the contact points where the modal arrays are built (the
    # structure's side of assemble), not a packed array of the kernels
    "model/system.py": 5,
    "physics/plate.py": 23, "physics/surface/interp.py": 2, "physics/surface/roughness.py": 1,
    # the file readers left roughness.py with 8 of its 38
    "physics/surface/measured.py": 8,
    "physics/surface/topography.py": 2,
    "analysis/accuracy.py": 3, "analysis/bands.py": 1, "analysis/compare.py": 4,
    "analysis/events.py": 2, "analysis/validation.py": 1, "cli/lab.py": 1, "records.py": 8,
    "views/validation.py": 3,
    "analysis/figures_data.py": 17, "analysis/levels.py": 5, "analysis/spectra.py": 8,
    "cli/results.py": 1, "results.py": 3, "simulation.py": 7,
    # scene.py (8 allowed, 3 held) split into the scene/ package: one each is left
    "scene/checks.py": 1, "scene/core.py": 1, "scene/solver_output.py": 1,
    "studies/compare.py": 3, "studies/sweep/ensemble.py": 4, "studies/sweep/report.py": 7,
    "studies/sweep/run.py": 4, "studies/sweep/spec.py": 3, "studies/sweep/tables.py": 1,
    "views/ensemble.py": 1, "views/figures.py": 39, "views/report.py": 8,
    "views/surface_report.py": 2, "views/sweep_report.py": 3, "views/work_precision.py": 3,
}


def _int_literal(node: ast.AST) -> int | None:
    if isinstance(node, ast.Constant) and type(node.value) is int:
        return node.value
    if (isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub)
            and isinstance(node.operand, ast.Constant) and type(node.operand.value) is int):
        return -node.operand.value
    return None


def _base_name(node: ast.AST) -> str:
    """The subscripted name: ``a`` of ``a[...]``, ``off`` of ``self.off[...]``."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return ""


def literal_indices(source: str) -> list[tuple[int, str, bool]]:
    """(line, expression, on a packed array) of every refused subscript in ``source``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Subscript):
            continue
        elts = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
        values = [v for v in (_int_literal(e) for e in elts) if v is not None]
        if not values:
            continue
        name = _base_name(node.value)
        if name == "shape":
            continue
        packed = name in PACKED
        if not packed and not isinstance(node.slice, ast.Tuple) and values[0] in (0, -1):
            continue
        found.append((node.lineno, ast.unparse(node), packed))
    return found


def _modules() -> list[Path]:
    return sorted(p for p in SRC.rglob("*.py") if "__pycache__" not in p.parts)


def test_no_literal_index_into_packed_arrays() -> None:
    bad = []
    for path in _modules():
        rel = path.relative_to(SRC).as_posix()
        hits = literal_indices(path.read_text(encoding="utf-8"))
        bad += [f"{rel}:{line}: {expr}" for line, expr, packed in hits if packed]
    assert not bad, "literal index into a packed array (use the named position):\n" + \
        "\n".join(bad)


def test_kernel_modules_have_no_literal_index() -> None:
    bad = []
    for path in _modules():
        rel = path.relative_to(SRC).as_posix()
        if not rel.startswith(STRICT) or rel in RATCHET:
            continue
        bad += [f"{rel}:{line}: {expr}"
                for line, expr, _ in literal_indices(path.read_text(encoding="utf-8"))]
    assert not bad, f"literal index in {', '.join(STRICT)}:\n" + "\n".join(bad)


def test_other_modules_only_lose_literal_indices() -> None:
    grown = []
    for path in _modules():
        rel = path.relative_to(SRC).as_posix()
        if rel.startswith(STRICT) and rel not in RATCHET:
            continue
        n = len(literal_indices(path.read_text(encoding="utf-8")))
        if n > RATCHET.get(rel, 0):
            grown.append(f"{rel}: {n} literal indices, at most {RATCHET.get(rel, 0)} allowed")
    assert not grown, "\n".join(grown)


def test_the_check_catches_what_it_must() -> None:
    """The checker itself: refused and allowed forms (so that the tests above can fail)."""
    src = ("off[9]\nfp[3]\nself.off[0]\nPhi[r, 0, 1]\nw[2]\nt[-1]\nt[0]\nx.shape[0]\n"
           "out[row, 8]\noff[OFF_K]\n")
    got = {expr: packed for _, expr, packed in literal_indices(src)}
    assert got == {"off[9]": True, "fp[3]": True, "self.off[0]": True, "Phi[r, 0, 1]": False,
                   "w[2]": False, "out[row, 8]": True}


def test_outputs_are_named_with_the_units_of_the_result() -> None:
    """Every kernel output declares the unit the result gives it; the columns tile the row."""
    from roughvib.model import kernels as kn
    from roughvib.results import VARIABLES

    for v in kn.OUTPUTS + kn.CONTACT_OUTPUTS:
        assert VARIABLES[v.name][0] == v.unit, v.name
    K = 3
    taken = []
    for col in kn.output_columns(K).values():
        taken += [col] if isinstance(col, int) else list(range(col.start, col.stop))
    assert sorted(taken) == list(range(kn.n_output_columns(K)))
    assert kn.out_force_column(2, K) == kn.output_columns(K)["contact_force"].start + 2
