"""Imports point down the pipeline (docs/architecture.md), also inside functions: one folder per
stage, no import cycles, and the command line is imported by nothing but its entry points."""

import ast
from pathlib import Path

import roughvib

SRC = Path(roughvib.__file__).parent

# stage of each top-level module or folder; a module may import from its own stage and the
# ones above it (lower numbers)
STAGES = {
    "scene": 0, "scenes": 0, "_version": 0, "_eventlog": 0, "_progress": 0,
    "_errors": 0,  # WriteError, the one-line error of a failed write (a leaf)
    "_cache": 0,  # the on-disk cache of preprocessing results (a leaf)
    "physics": 1,  # plate, friction, surface/
    "model": 2,
    "solvers": 3,
    "results": 4, "rundir": 4,  # a run directory: checks, lock, atomic publish
    "records": 4,  # measured records in (CSV, WAV, UFF 58, TDMS), a run's exchange files out
    "analysis": 5,
    "simulation": 6,  # simulate(): runs a solver and summarises the result with analysis.levels
    "views": 7,  # figures, the HTML builder and the reports
    "studies": 8,  # compare, sweep/: many runs of simulate()
    "api": 9, "cli": 9,  # entry points
    "__init__": 10, "_compat": 10, "__main__": 10,
}
#: modules whose stage is not their folder's: the solver registry lives beside the solvers but
#: is read by scene validation, so it is stage 0 (it names the solve functions as strings and
#: imports them only when a run calls one, docs/architecture.md)
MODULE_STAGES = {"solvers.registry": 0}


def _module_name(path: Path) -> str:
    rel = path.relative_to(SRC).with_suffix("")
    parts = ["roughvib", *rel.parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in SRC.rglob("*.py")}


def _stage(module: str) -> int:
    parts = module.split(".")
    assert parts[0] == "roughvib", module
    if len(parts) == 1:
        return STAGES["__init__"]
    return MODULE_STAGES.get(".".join(parts[1:]), STAGES[parts[1]])


def _imports(path: Path):
    """Every roughvib module a file imports (at module level or in functions)."""
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.startswith("roughvib"):
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    yield sub if sub in MODULES else node.module
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("roughvib"):
                    yield alias.name


def test_every_module_has_a_stage():
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC).with_suffix("")
        assert rel.parts[0] in STAGES, f"{rel} has no stage in STAGES (and in architecture.md)"


def test_imports_only_point_down_the_pipeline():
    bad = []
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC).with_suffix("")
        own = _stage(_module_name(path))
        for target in _imports(path):
            if _stage(target) > own:
                bad.append(f"{rel} (stage {own}) imports {target} (stage {_stage(target)})")
    assert not bad, "\n".join(bad)


def test_nothing_outside_cli_imports_the_cli():
    # the entry points that run the CLI: the console script names roughvib.cli:main, and
    # `python -m roughvib` is __main__.py
    bad = []
    for name, path in MODULES.items():
        if name.startswith("roughvib.cli") or name == "roughvib.__main__":
            continue
        bad += [f"{name} imports {t}" for t in _imports(path)
                if t == "roughvib.cli" or t.startswith("roughvib.cli.")]
    assert not bad, "\n".join(bad)


def test_no_import_cycles():
    graph = {name: sorted({t for t in _imports(path) if t in MODULES and t != name})
             for name, path in MODULES.items()}
    state: dict[str, int] = {}  # 1 on the stack, 2 done
    cycles = []

    def visit(node, stack):
        state[node] = 1
        for nxt in graph[node]:
            if state.get(nxt) == 1:
                cycles.append(" -> ".join(stack[stack.index(nxt):] + [nxt]))
            elif nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])
    assert not cycles, "\n".join(cycles)


def test_the_checks_see_imports():
    # guard against a test that cannot fail: the graph holds the imports we know of
    assert "roughvib.cli.args" in set(_imports(MODULES["roughvib.cli.sweep"]))
    assert "roughvib.simulation" in set(_imports(MODULES["roughvib.studies.sweep.run"]))
    assert "roughvib.views.sweep_report" in set(_imports(MODULES["roughvib.studies.sweep.report"]))
