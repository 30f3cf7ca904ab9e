"""Benchmark: the fixed cost of a run (everything but the integration), by stage and cache state.

Run on demand, not by the tests:

    python benchmarks/bench_fixed_cost.py [--repeat 3] [--duration 0.01]
                                          [--method ida] [--method adaptive-modal]
                                          [--src path/to/other/src]

For each solver method the script runs ``python -m roughvib run paper`` over a short duration
in fresh subprocesses, ``--repeat`` times in each of three cache states:

* **cold**: empty numba and roughvib cache directories (``NUMBA_CACHE_DIR``,
  ``ROUGHVIB_CACHE_DIR`` pointed at new temporary directories): every kernel is compiled and
  every cached preprocessing result computed, as in the first run after an install;
* **new inputs**: numba's cache filled, roughvib's empty: a run of a scene (or a sweep case)
  whose calibration, contact and spline inputs have not been seen before;
* **warm**: both caches filled by an earlier run of the same scene, as in every later run.

Each run is instrumented (this script in ``--child`` mode): each stage is timed with
``time.perf_counter`` (exclusive times: a stage's own time without the stages and imports
nested in it): imports by top-level package, scene load, profile synthesis, contact module,
plate modes, residual compliance, force calibration, numba dispatch and cache loading per
kernel module, integration, dataset, summary, energy audit, saving. "interpreter start +
exit" is the subprocess's wall time minus everything timed inside it (interpreter start-up and
shut-down, argument parsing). The stages are summed into the groups of :data:`GROUPS`, one
printed table.

The headline: fixed cost = subprocess wall time - the integration stage (the solver's own
time without the numba kernels it loads or compiles on its first call; summary.json's solver
``wall_time`` includes them and is printed too). Each figure is the median over ``--repeat``
runs; the load average before and after is printed, because other processes on the machine
inflate the timings. The same difference in CPU seconds (the subprocess's user + system
time minus the integration's) is printed too: it is far less sensitive to such load. A few
uninstrumented warm runs show the instrumentation's own cost, and a ``python -X importtime``
run lists the slowest imports of a warm run. Finally ``--repeat`` further runs in one
process, after a first one, show what a run costs a sweep worker that keeps its imports and
loaded kernels between cases (wall time minus the solver's ``wall_time``).
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

# this folder's module (the script's own directory is on sys.path)
from machine import describe, timed_python

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
        self.cpu: dict[str, float] = {}  # the same for the process's CPU time
        self.stack: list[list] = []  # [label, start, nested time, cpu start, nested cpu]

    def enter(self, label: str) -> None:
        self.stack.append([label, time.perf_counter(), 0.0, time.process_time(), 0.0])

    def leave(self) -> None:
        label, start, nested, cpu_start, cpu_nested = self.stack.pop()
        elapsed = time.perf_counter() - start
        cpu = time.process_time() - cpu_start
        self.totals[label] = self.totals.get(label, 0.0) + elapsed - nested
        self.cpu[label] = self.cpu.get(label, 0.0) + cpu - cpu_nested
        if self.stack:
            self.stack[-1][2] += elapsed
            self.stack[-1][4] += cpu

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
    Path(out + ".cpu").write_text(json.dumps(clock.cpu))  # CPU seconds per stage
    return status


# --------------------------------------------------------------------------------------------
# parent
# --------------------------------------------------------------------------------------------


def _solver_wall(out_dir: Path) -> float:
    return json.loads((out_dir / "summary.json").read_text())["solver"]["wall_time"]


_IN_PROCESS = """
import json, shutil, sys, time
from roughvib.cli import main
args, out, n = json.loads(sys.argv[1]), sys.argv[2], int(sys.argv[3])
fixed = []
for _ in range(n + 1):  # the first run pays the imports and kernel loading
    shutil.rmtree(out, ignore_errors=True)
    t = time.perf_counter()
    assert main(args) == 0
    wall = time.perf_counter() - t
    with open(out + "/summary.json") as fh:
        fixed.append(wall - json.load(fh)["solver"]["wall_time"])
print(json.dumps(fixed[1:]))
"""


def _in_process(args: list[str], out: Path, env: dict, n: int) -> list[float]:
    """Fixed costs of runs 2..n+1 in one process (as in a sweep worker, which keeps its imports
    and loaded kernels between cases): wall time minus the solver's wall_time."""
    proc = subprocess.run([sys.executable, "-c", _IN_PROCESS, json.dumps(args), str(out),
                           str(n)], env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"in-process runs failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _import_top(argv: list[str], env: dict, n: int = 12) -> list[tuple[str, float, float]]:
    """The slowest imports of ``python ARGV`` (-X importtime): (module, self s, cumulative s)."""
    proc = subprocess.run([sys.executable, "-X", "importtime", *argv], env=env,
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


# the groups of the printed table: each label of the instrumented run goes to one
GROUPS = [
    ("interpreter start + exit", lambda k: k.startswith("unattributed")),
    ("imports", lambda k: k.startswith("import ")),
    ("scene load + output directory", lambda k: k in ("scene load + validation",
                                                       "run directory check + lock")),
    ("force calibration (T0)", lambda k: k == "force calibration"),
    ("assembly + preprocessing", lambda k: k in (
        "profile synthesis", "profile checks + validity warnings", "contact module",
        "plate modes + mode shapes", "residual compliance", "profile interpolant",
        "assembly (rest)")),
    ("numba cache load / compilation", lambda k: k.startswith("numba load/compile")),
    ("integration", lambda k: k == "integration"),
    ("result, summary + saving", lambda k: k in (
        "dataset", "event table", "energy audit", "summary (metrics, provenance, scene.toml)",
        "saving files", "printing the summary")),
    ("rest (CLI, simulate glue)", lambda k: True),
]

# cache states measured: (name, fresh numba cache per run, fresh roughvib cache per run)
MODES = [
    ("cold: first run after an install (empty numba and roughvib caches)", True, True),
    ("new inputs (numba cache warm, roughvib cache empty)", False, True),
    ("warm (both caches filled)", False, False),
]


def _grouped(parts: dict[str, float]) -> dict[str, float]:
    out = {name: 0.0 for name, _ in GROUPS}
    for k, v in parts.items():
        for name, match in GROUPS:
            if match(k):
                out[name] += v
                break
    return out


def main() -> None:
    if sys.argv[1:2] == ["--child"]:  # the instrumented run: --child JSON run ARGS...
        sys.exit(child(sys.argv[2], sys.argv[3:]))
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="paper")
    p.add_argument("--duration", type=float, default=0.01, help="simulated time [s]")
    p.add_argument("--method", action="append", default=None,
                   help="solver method(s) (default: ida and adaptive-modal, "
                        "which solver.method = auto runs)")
    p.add_argument("--repeat", type=int, default=3, help="runs per cache state (median)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--warm-only", action="store_true",
                   help="measure only the warm state (a quick check; the caches are filled by "
                        "one unmeasured run first)")
    p.add_argument("--src", default=str(HERE.parent / "src"),
                   help="the roughvib sources to measure (default: this checkout's src/; e.g. "
                        "an export of an earlier commit, for a before/after comparison)")
    a = p.parse_args()
    methods = a.method or ["ida", "adaptive-modal"]
    modes = MODES[-1:] if a.warm_only else MODES
    # as a user runs it: this checkout's sources, byte-code cached (the sandbox sets
    # PYTHONDONTWRITEBYTECODE, which makes every import of roughvib compile its sources)
    env0 = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env0["PYTHONPATH"] = str(Path(a.src).resolve())
    base = Path(tempfile.mkdtemp(prefix="bench_fixed_cost_"))
    report = {"src": env0["PYTHONPATH"], "load_average_before": os.getloadavg(),
              "cpus": os.cpu_count(), "repeat": a.repeat,
              "python": sys.version.split()[0], "runs": {}, "machine": describe()}
    print(report["machine"])
    t_py = [timed_python(["-c", "pass"], env0)["wall"] for _ in range(a.repeat)]
    t_np = [timed_python(["-c", "import numpy"], env0)["wall"] for _ in range(a.repeat)]
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
        argv = ["-m", "roughvib", *args]
        rec = {}
        warm_env = {**env0, "NUMBA_CACHE_DIR": str(base / f"numba-{method}-warm"),
                    "ROUGHVIB_CACHE_DIR": str(base / f"rv-{method}-warm")}
        timed_python(argv, warm_env)  # fills the caches of the warm and new-input runs
        for mode, fresh_numba, fresh_rv in modes:
            walls, fixed, solver, fixed_cpu = [], [], [], []
            parts: dict[str, list[float]] = {}
            for i in range(a.repeat):
                tag = f"{method}-{len(rec)}-{i}"
                env = dict(warm_env)
                if fresh_numba:
                    env["NUMBA_CACHE_DIR"] = str(base / f"numba-{tag}")
                if fresh_rv:
                    env["ROUGHVIB_CACHE_DIR"] = str(base / f"rv-{tag}")
                js = base / f"child-{tag}.json"
                proc = timed_python([str(Path(__file__).resolve()), "--child", str(js),
                                     *args], env)
                w = proc["wall"]
                walls.append(w)
                solver.append(_solver_wall(out))
                got = json.loads(js.read_text())
                got["unattributed"] = w - got.pop("child total (perf_counter)")
                # the solver's wall_time includes the numba kernels it loads (or compiles) on
                # first call: the integration proper is the instrumented stage without them
                fixed.append(w - got.get("integration", 0.0))
                # CPU seconds, much less sensitive to other processes than wall time
                cpu_int = json.loads(Path(str(js) + ".cpu").read_text()).get("integration", 0.0)
                fixed_cpu.append(proc["cpu"] - cpu_int)
                for k, v in _grouped(got).items():
                    parts.setdefault(k, []).append(v)
                for k, v in got.items():
                    parts.setdefault("detail: " + k, []).append(v)
            rec[mode] = {
                "wall": statistics.median(walls), "walls": walls,
                "solver wall_time": statistics.median(solver),
                "fixed cost": statistics.median(fixed), "fixed costs": fixed,
                "fixed cost, CPU": statistics.median(fixed_cpu), "fixed costs, CPU": fixed_cpu,
                "stages": {k: statistics.median(v) for k, v in parts.items()
                           if not k.startswith("detail: ")},
                "detail": dict(sorted(((k.removeprefix("detail: "), statistics.median(v))
                                       for k, v in parts.items() if k.startswith("detail: ")),
                                      key=lambda kv: -kv[1])),
            }
        plain = []  # uninstrumented warm runs: the instrumentation's own cost
        for _ in range(a.repeat):
            w = timed_python(argv, warm_env)["wall"]
            plain.append(w - _solver_wall(out))  # an upper bound of the integration
        rec["warm fixed cost, uninstrumented"] = statistics.median(plain)
        rec["in-process fixed costs"] = _in_process(args, out, warm_env, a.repeat)
        top, pkgs, imp_total = _import_top(argv, warm_env)
        rec["importtime total self"] = imp_total
        rec["importtime by package"] = pkgs
        rec["importtime top-level imports"] = top
        report["runs"][method] = rec
        print(f"\n== {a.scene}, {a.duration} s, {method} (median of {a.repeat} runs each)")
        names = [m for m, _, _ in modes]
        print(f"  {'stage [s]':<34}" + "".join(f"{n.split(':')[0].split(' (')[0]:>14}"
                                               for n in names))
        for g, _ in GROUPS:
            print(f"  {g:<34}" + "".join(f"{rec[n]['stages'][g]:14.3f}" for n in names))
        print(f"  {'wall time':<34}" + "".join(f"{rec[n]['wall']:14.3f}" for n in names))
        print(f"  {'solver wall_time':<34}" + "".join(f"{rec[n]['solver wall_time']:14.3f}"
                                                      for n in names))
        print(f"  {'FIXED COST (wall - integration)':<34}"
              + "".join(f"{rec[n]['fixed cost']:14.3f}" for n in names))
        print(f"  {'fixed cost in CPU seconds':<34}"
              + "".join(f"{rec[n]['fixed cost, CPU']:14.3f}" for n in names))
        print(f"  warm run without instrumentation, wall - solver wall_time: "
              f"{rec['warm fixed cost, uninstrumented']:.3f} s (runs: "
              + ", ".join(f"{x:.2f}" for x in plain) + ")")
        print("  later runs in one process (as in a sweep worker), wall - solver wall_time: "
              + ", ".join(f"{x:.3f}" for x in rec["in-process fixed costs"]) + " s")
        for n in names:
            print(f"  {n}: fixed costs " + ", ".join(f"{x:.2f}" for x in rec[n]["fixed costs"])
                  + " s; CPU " + ", ".join(f"{x:.2f}" for x in rec[n]["fixed costs, CPU"]))
        print("  warm run in detail: " + ", ".join(
            f"{k} {v:.3f}" for k, v in list(rec[names[-1]]["detail"].items())[:14]))
        print(f"  -X importtime: {imp_total:.2f} s of module code in all; by package:")
        print("    " + ", ".join(f"{k} {v:.2f}" for k, v in pkgs))
        print("  slowest top-level imports (cumulative): "
              + ", ".join(f"{n} {c:.2f}" for n, _, c in top[:8]))
    report["load_average_after"] = os.getloadavg()
    print(f"\nload average after: {report['load_average_after']}")
    (base / "report.json").write_text(json.dumps(report, indent=1, default=str))
    print(f"full report: {base / 'report.json'}")


if __name__ == "__main__":
    main()
