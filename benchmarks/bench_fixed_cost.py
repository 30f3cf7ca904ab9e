"""Benchmark: the fixed cost of a run (everything but the integration), cold and warm caches.

Run on demand, not by the tests:

    python benchmarks/bench_fixed_cost.py [--repeat 5] [--duration 0.01]
                                          [--method adaptive-modal] [--method ida]
                                          [--src path/to/other/src]

For each solver method the script runs ``python -m roughvib run paper`` over a short duration
in fresh subprocesses, three ways:

* **cold**: empty numba and roughvib cache directories (``NUMBA_CACHE_DIR``,
  ``ROUGHVIB_CACHE_DIR`` pointed at new temporary directories): every kernel is compiled and
  every cached preprocessing result computed, as in the first run after an install;
* **warm**: the same cache directories after that first run, as in every later run;
* **instrumented** (warm): the same command run by this script in ``--child`` mode, which
  times each stage of the run with ``time.perf_counter`` (exclusive times: a stage's own time
  without the stages and imports nested in it): imports by top-level package, scene load,
  profile synthesis, contact module, plate modes, residual compliance, force calibration,
  numba dispatch and cache loading per kernel module, integration, dataset, summary, energy
  audit, saving. "unattributed" is the subprocess's wall time minus everything timed inside
  it: interpreter start-up and shut-down, argument parsing.

The uninstrumented runs give the headline: fixed cost = subprocess wall time - the solver's own
``wall_time`` from summary.json. Each figure is the median over ``--repeat`` runs; the load
average before the runs is printed, because other processes on the machine inflate the
timings. A ``python -X importtime`` run lists the slowest imports of a warm run.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

# (module, attribute, label): functions timed in --child mode, patched where they are looked up
STAGES = [
    ("roughvib.scene", "load_scene", "scene load + validation"),
    ("roughvib.rundir", "RunDirectory.open", "run directory check + lock"),
    ("roughvib.rundir", "RunDirectory.close", "run directory check + lock"),
    ("roughvib.model.system", "build_profile", "profile synthesis"),
    ("roughvib.model.system", "check_profile", "profile checks + validity warnings"),
    ("roughvib.model.system", "validity_warnings", "profile checks + validity warnings"),
    ("roughvib.model.system", "contact_layout", "contact module"),
    ("roughvib.model.system", "plate_modes", "plate modes + mode shapes"),
    ("roughvib.model.system", "mode_shapes", "plate modes + mode shapes"),
    ("roughvib.model.system", "residual_compliance", "residual compliance"),
    ("roughvib.model.system", "calibrated_force_amplitude", "force calibration"),
    ("roughvib.model.system", "calibrate_force_amplitude", "force calibration"),  # before cache
    ("roughvib.model.system", "cached_coefficients", "profile interpolant"),
    ("roughvib.model.system", "build_coefficients", "profile interpolant"),
    ("roughvib.model.system", "assemble", "assembly (rest)"),
    ("roughvib.solvers.ida", "solve_ida", "integration"),
    ("roughvib.simulation", "solve_ida", "integration"),  # where it was imported before
    ("roughvib.solvers.adaptive_modal", "solve_adaptive_modal", "integration"),
    ("roughvib.solvers.fixed_step", "solve_fixed_step", "integration"),
    ("roughvib.solvers.paper_scheme", "solve_paper_scheme", "integration"),
    ("roughvib.simulation", "_build_dataset", "dataset"),
    ("roughvib.simulation", "_add_regimes", "dataset"),
    ("roughvib.simulation", "events_frame", "event table"),
    ("roughvib.simulation", "energy_audit", "energy audit"),
    ("roughvib.simulation", "_metrics", "summary (metrics, provenance, scene.toml)"),
    ("roughvib.simulation", "_provenance", "summary (metrics, provenance, scene.toml)"),
    ("roughvib.simulation", "scene_to_toml", "summary (metrics, provenance, scene.toml)"),
    ("roughvib.simulation", "simulate", "simulate (rest)"),
    ("roughvib.results", "Result.save", "saving files"),
    ("roughvib.cli.run", "_print_summary", "printing the summary"),
    ("roughvib.cli.run", "cmd_run", "run command (rest)"),
]


# --------------------------------------------------------------------------------------------
# child: one instrumented run
# --------------------------------------------------------------------------------------------


class _Clock:
    """Exclusive time per label: nested timed calls are subtracted from the enclosing one."""

    def __init__(self) -> None:
        self.totals: dict[str, float] = {}
        self.stack: list[list] = []  # [label, start, nested time]

    def enter(self, label: str) -> None:
        self.stack.append([label, time.perf_counter(), 0.0])

    def leave(self) -> None:
        label, start, nested = self.stack.pop()
        elapsed = time.perf_counter() - start
        self.totals[label] = self.totals.get(label, 0.0) + elapsed - nested
        if self.stack:
            self.stack[-1][2] += elapsed

    def wrap(self, fn, label):
        def timed(*args, **kwargs):
            self.enter(label)
            try:
                return fn(*args, **kwargs)
            finally:
                self.leave()

        timed.__wrapped__ = fn
        return timed


def _patch(clock: _Clock, module, attr: str, label: str) -> None:
    owner = module
    *path, name = attr.split(".")
    for part in path:
        owner = getattr(owner, part)
    if hasattr(owner, name) and not hasattr(getattr(owner, name), "__wrapped__"):
        setattr(owner, name, clock.wrap(getattr(owner, name), label))


def _numba_group(dispatcher) -> str:
    mod = getattr(dispatcher.py_func, "__module__", "?")
    return "numba load/compile: " + mod.removeprefix("roughvib.")


def child(out: str, argv: list[str]) -> int:
    t_start = time.perf_counter()
    clock = _Clock()
    pending = {}
    for mod, attr, label in STAGES:
        pending.setdefault(mod, []).append((attr, label))
    bootstrap = sys.modules["_frozen_importlib"]
    find_and_load = bootstrap._find_and_load

    def timed_find_and_load(name, import_):
        # called by every import statement and importlib.import_module for a module that is not
        # in sys.modules yet: the module's own import time goes to its top-level package
        clock.enter("import " + name.split(".")[0])
        try:
            module = find_and_load(name, import_)
        finally:
            clock.leave()
        for attr, label in pending.pop(name, ()):
            _patch(clock, module, attr, label)
        if name == "numba.core.dispatcher":
            disp = module.Dispatcher
            compile_ = disp.compile

            def timed_compile(self, sig):  # a cache load or a compilation
                clock.enter(_numba_group(self))
                try:
                    return compile_(self, sig)
                finally:
                    clock.leave()

            disp.compile = timed_compile
        return module

    bootstrap._find_and_load = timed_find_and_load
    clock.enter("run command (rest)")
    try:
        from roughvib.cli import main

        status = main(argv)
    finally:
        clock.leave()
        bootstrap._find_and_load = find_and_load
    clock.totals["child total (perf_counter)"] = time.perf_counter() - t_start
    Path(out).write_text(json.dumps(clock.totals))
    return status


# --------------------------------------------------------------------------------------------
# parent
# --------------------------------------------------------------------------------------------


def _run(cmd: list[str], env: dict) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr}")
    return wall


def _solver_wall(out_dir: Path) -> float:
    return json.loads((out_dir / "summary.json").read_text())["solver"]["wall_time"]


def _import_top(cmd: list[str], env: dict, n: int = 12) -> list[tuple[str, float, float]]:
    """The slowest imports of a run (-X importtime): (module, self s, cumulative s)."""
    proc = subprocess.run([sys.executable, "-X", "importtime", *cmd[1:]], env=env,
                          capture_output=True, text=True)
    rows = []
    total = 0.0
    by_pkg: dict[str, float] = {}
    for line in proc.stderr.splitlines():
        if not line.startswith("import time:") or "self [us]" in line:
            continue
        self_us, cum_us, name = line.removeprefix("import time:").split("|")
        total += int(self_us) / 1e6
        top = name.strip().split(".")[0]
        by_pkg[top] = by_pkg.get(top, 0.0) + int(self_us) / 1e6
        if not name.startswith("  "):  # a top-level import of the run (one blank)
            rows.append((name.strip(), int(self_us) / 1e6, int(cum_us) / 1e6))
    rows.sort(key=lambda r: -r[2])
    pk = sorted(by_pkg.items(), key=lambda kv: -kv[1])[:n]
    return rows[:n], pk, total


def main() -> None:
    if sys.argv[1:2] == ["--child"]:  # the instrumented run: --child JSON run ARGS...
        sys.exit(child(sys.argv[2], sys.argv[3:]))
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="paper")
    p.add_argument("--duration", type=float, default=0.01, help="simulated time [s]")
    p.add_argument("--method", action="append", default=None,
                   help="solver method(s) (default: adaptive-modal and ida)")
    p.add_argument("--repeat", type=int, default=5, help="runs per measurement (median)")
    p.add_argument("--cold-repeat", type=int, default=2, help="cold runs (each from empty "
                   "caches; median)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--src", default=str(HERE.parent / "src"),
                   help="the roughvib sources to measure (default: this checkout's src/; e.g. "
                        "an export of an earlier commit, for a before/after comparison)")
    a = p.parse_args()
    methods = a.method or ["adaptive-modal", "ida"]
    # as a user runs it: this checkout's sources, byte-code cached (the sandbox sets
    # PYTHONDONTWRITEBYTECODE, which makes every import of roughvib compile its sources)
    env0 = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env0["PYTHONPATH"] = str(Path(a.src).resolve())
    base = Path(tempfile.mkdtemp(prefix="bench_fixed_cost_"))
    report = {"src": env0["PYTHONPATH"], "load_average_before": os.getloadavg(),
              "cpus": os.cpu_count(),
              "python": sys.version.split()[0], "runs": {}}
    t_py = [_run([sys.executable, "-c", "pass"], env0) for _ in range(a.repeat)]
    t_np = [_run([sys.executable, "-c", "import numpy"], env0) for _ in range(a.repeat)]
    report["python -c pass"] = statistics.median(t_py)
    report["python -c 'import numpy'"] = statistics.median(t_np)
    print(f"load average {report['load_average_before']}, interpreter start "
          f"{statistics.median(t_py):.3f} s, with numpy {statistics.median(t_np):.3f} s")
    for method in methods:
        sets = ["--set", f"output.duration={a.duration}", "--set", f"solver.method={method}"]
        for s in a.set:
            sets += ["--set", s]
        out = base / f"run-{method}"
        args = ["run", a.scene, *sets, "--out", str(out), "--no-progress", "--quiet"]
        cmd = [sys.executable, "-m", "roughvib", *args]
        rec = {}
        cold_wall, cold_fixed = [], []
        for i in range(a.cold_repeat):
            env = {**env0, "NUMBA_CACHE_DIR": str(base / f"numba-{method}-{i}"),
                   "ROUGHVIB_CACHE_DIR": str(base / f"rv-{method}-{i}")}
            w = _run(cmd, env)
            cold_wall.append(w)
            cold_fixed.append(w - _solver_wall(out))
        env = {**env0, "NUMBA_CACHE_DIR": str(base / f"numba-{method}-0"),
               "ROUGHVIB_CACHE_DIR": str(base / f"rv-{method}-0")}
        warm_wall, warm_fixed, solver = [], [], []
        for _ in range(a.repeat):
            w = _run(cmd, env)
            warm_wall.append(w)
            solver.append(_solver_wall(out))
            warm_fixed.append(w - solver[-1])
        rec["cold wall"] = statistics.median(cold_wall)
        rec["cold fixed cost"] = statistics.median(cold_fixed)
        rec["warm wall"] = statistics.median(warm_wall)
        rec["warm fixed cost"] = statistics.median(warm_fixed)
        rec["warm fixed cost min..max"] = (min(warm_fixed), max(warm_fixed))
        rec["solver wall_time"] = statistics.median(solver)
        parts: dict[str, list[float]] = {}
        walls = []
        for i in range(a.repeat):
            js = base / f"child-{method}-{i}.json"
            walls.append(_run([sys.executable, str(Path(__file__).resolve()), "--child",
                               str(js), *args], env))
            for k, v in json.loads(js.read_text()).items():
                parts.setdefault(k, []).append(v)
        med = {k: statistics.median(v) for k, v in parts.items()}
        med["unattributed (interpreter start/exit, arguments)"] = (
            statistics.median(walls) - med.pop("child total (perf_counter)"))
        rec["instrumented wall"] = statistics.median(walls)
        rec["breakdown"] = dict(sorted(med.items(), key=lambda kv: -kv[1]))
        top, pkgs, imp_total = _import_top(cmd, env)
        rec["importtime total self"] = imp_total
        rec["importtime by package"] = pkgs
        rec["importtime top-level imports"] = top
        report["runs"][method] = rec
        print(f"\n== {a.scene}, {a.duration} s, {method} "
              f"(median of {a.repeat} warm, {a.cold_repeat} cold runs)")
        print(f"  cold: wall {rec['cold wall']:.2f} s, fixed cost {rec['cold fixed cost']:.2f} s")
        print(f"  warm: wall {rec['warm wall']:.2f} s, fixed cost {rec['warm fixed cost']:.2f} s "
              f"(min {min(warm_fixed):.2f}, max {max(warm_fixed):.2f}), solver "
              f"{rec['solver wall_time']:.3f} s")
        print(f"  instrumented warm run: wall {rec['instrumented wall']:.2f} s")
        for k, v in rec["breakdown"].items():
            print(f"    {k:<52} {v:7.3f} s")
        print(f"  -X importtime: {imp_total:.2f} s of module code in all; by package:")
        print("    " + ", ".join(f"{k} {v:.2f}" for k, v in pkgs))
        print("  slowest top-level imports (cumulative): "
              + ", ".join(f"{n} {c:.2f}" for n, _, c in top[:8]))
    report["load_average_after"] = os.getloadavg()
    print(f"\nload average after: {report['load_average_after']}")
    print(json.dumps(report, indent=1, default=str))


if __name__ == "__main__":
    main()
