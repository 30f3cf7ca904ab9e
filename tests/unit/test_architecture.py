"""Imports point down the pipeline (design.md "Data flows one way"), also inside functions."""

import ast
from pathlib import Path

import roughvib

SRC = Path(roughvib.__file__).parent

# stage of each module; a module may import from its own stage and the ones above it
STAGES = {
    "scene": 0, "scenes": 0, "_version": 0,
    "physics": 1,
    "model": 2,
    "solvers": 3,
    "results": 4,
    "analysis": 5,
    "simulation": 6,  # simulate(): runs a solver and summarises the result with analysis.levels
    "views": 7,
    "studies": 8,
    "api": 9, "cli": 9,
    "__init__": 9,
}


def _stage(module: str) -> int:
    parts = module.split(".")
    assert parts[0] == "roughvib", module
    if len(parts) == 1:
        return STAGES["__init__"]
    return STAGES[parts[1]]


def _imports(path: Path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.startswith("roughvib"):
                if node.module == "roughvib":
                    for alias in node.names:
                        yield f"roughvib.{alias.name}" if alias.name in STAGES else "roughvib"
                else:
                    yield node.module
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("roughvib"):
                    yield alias.name


def test_every_module_has_a_stage():
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC).with_suffix("")
        assert rel.parts[0] in STAGES, f"{rel} has no stage in STAGES (and in design.md)"


def test_imports_only_point_down_the_pipeline():
    bad = []
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC).with_suffix("")
        own = STAGES[rel.parts[0]]
        for target in _imports(path):
            if _stage(target) > own:
                bad.append(f"{rel} (stage {own}) imports {target} (stage {_stage(target)})")
    assert not bad, "\n".join(bad)
