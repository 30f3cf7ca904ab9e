"""Each compiled callee compiles once: no literal arguments between compiled functions.

numba types a literal or a module constant passed at a call site as ``Literal[int]`` (or
``Literal[bool]``) and compiles the called function once per value, next to its ``int64``
version. The Hermite step (everything inlined into ``_hstep``) took 12 s to compile, and the
root search's constant slot made it compile twice. The loops pass constants through
:func:`roughvib.model.kernels.runtime_int` / ``runtime_bool`` instead.
"""
import ast
import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from numba import njit

import roughvib
from roughvib.model import kernels as kn

SRC = Path(roughvib.__file__).parent
CONSTANT = re.compile(r"[A-Z][A-Z0-9_]*")
SLOT = 42


def _decorator_njit(fn: ast.FunctionDef) -> tuple[bool, bool]:
    """(compiled, inlined) of a function definition by its decorators."""
    for d in fn.decorator_list:
        call = d if isinstance(d, ast.Call) else None
        target = call.func if call else d
        if getattr(target, "id", getattr(target, "attr", "")) == "njit":
            inline = any(k.arg == "inline" and getattr(k.value, "value", None) == "always"
                         for k in (call.keywords if call else []))
            return True, inline
    return False, False


def _literal_arguments(trees: dict[str, ast.Module]) -> list[str]:
    """Calls from a compiled function to a compiled, not inlined one (by name, over all
    ``trees``) with an int or bool literal or a module constant (UPPER_CASE, not a local) as
    an argument."""
    plain = {}
    for tree in trees.values():
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef):
                compiled, inline = _decorator_njit(node)
                if compiled:
                    plain.setdefault(node.name, set()).add(not inline)
    plain = {name for name, kinds in plain.items() if kinds == {True}}
    found = []
    for where, tree in trees.items():
        for fn in ast.walk(tree):
            if not (isinstance(fn, ast.FunctionDef) and _decorator_njit(fn)[0]):
                continue
            local = {a.arg for a in fn.args.args}
            local |= {n.id for n in ast.walk(fn)
                      if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}
            for call in ast.walk(fn):
                if not isinstance(call, ast.Call):
                    continue
                name = getattr(call.func, "id", getattr(call.func, "attr", None))
                if name not in plain:
                    continue
                for arg in call.args:
                    literal = (isinstance(arg, ast.Constant) and type(arg.value) in (int, bool))
                    constant = ((isinstance(arg, ast.Name) and CONSTANT.fullmatch(arg.id)
                                 and arg.id not in local)
                                or (isinstance(arg, ast.Attribute)
                                    and CONSTANT.fullmatch(arg.attr)))
                    if literal or constant:
                        found.append(f"{where}:{call.lineno} {fn.name} -> {name}("
                                     f"{ast.unparse(arg)})")
    return found


def test_runtime_int_keeps_one_specialisation():
    @njit
    def callee(slot, x):
        return x + slot

    @njit
    def direct(x):
        return callee(SLOT, x)

    @njit
    def wrapped(x, flag):
        return callee(kn.runtime_int(SLOT), x) + kn.runtime_bool(True) * flag

    assert wrapped(1.0, 1.0) == 44.0
    assert [str(s[0]) for s in callee.signatures] == ["int64"]
    assert direct(1.0) == 43.0  # the mechanism guarded against: a second, literal version
    assert [str(s[0]) for s in callee.signatures] == ["int64", "Literal[int](42)"]


def test_no_compiled_call_passes_a_literal_or_a_constant():
    trees = {str(p.relative_to(SRC)): ast.parse(p.read_text(encoding="utf-8"))
             for p in SRC.rglob("*.py")}
    assert _literal_arguments(trees) == []


def test_the_check_catches_literal_arguments():
    code = textwrap.dedent("""
        SLOT = 3
        @njit(cache=True)
        def callee(s, x):
            return x
        @njit(cache=True, inline="always")
        def inlined(s, x):
            return x
        @njit(cache=True)
        def caller(x, M):
            K = 2
            return (callee(SLOT, x) + callee(0, x) + callee(kn.FP_MASS, x) + callee(M, x)
                    + callee(K, x) + inlined(SLOT, x) + callee(kn.runtime_int(SLOT), x))
    """)
    found = _literal_arguments({"m.py": ast.parse(code)})
    assert sorted(f.split(" -> ")[1] for f in found) == ["callee(0)", "callee(SLOT)",
                                                         "callee(kn.FP_MASS)"]


SIGNATURES = """
import json, sys, warnings
import roughvib
from roughvib.solvers import adaptive_modal as am
warnings.simplefilter("ignore")
for over in ({}, {"friction.law": "coulomb"}):
    r = roughvib.simulate(roughvib.load_scene("paper", {"output.duration": 0.01,
                                                        "output.progress": False, **over}))
    assert r.ok, r.summary["message"]
print(json.dumps({f: [str(s) for s in getattr(am, f).signatures]
                  for f in ("_hstep", "_hermite_fill", "_fill_slot", "implicit_step")}))
"""


@pytest.mark.slow
def test_the_step_loops_compile_each_callee_once(tmp_path):
    """Both adaptive-modal loops compiled from scratch (an empty numba cache): the step, the
    maps and the trapezoidal step each have one specialisation (the Hermite step's literal
    slot cost 12 s of a first run's 75 s)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    out = subprocess.run([sys.executable, "-c", SIGNATURES], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=900, check=True)
    sigs = json.loads(out.stdout.strip().splitlines()[-1])
    assert {f: len(s) for f, s in sigs.items()} == dict.fromkeys(sigs, 1), sigs
