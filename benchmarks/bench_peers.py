"""Benchmark: roughvib's IDA against scipy's solve_ivp (BDF, Radau, LSODA, DOP853) and the
fixed-step schemes, on identical right-hand sides and at matched error.

Run on demand, not by the tests:

    python benchmarks/bench_peers.py [--duration 0.005] [--budget 120] [--error 1e-3]

Scene: the ``paper`` plate and block reduced to one contact (about 400 modes), sliding at a
prescribed 10 mm/s with a 2 kg block so that the contact never opens (scipy's integrators get no
event handling here; the script checks that IDA logs no event). The scipy right-hand side is
roughvib's own model: ``System.consistent(t, y)`` solves the algebraic contact force from the
same numba kernels and returns y' = f(y), so every method integrates the same equations.

Every method runs over a tolerance (or step) ladder within a wall-time budget per run. The
error of a run is the relative rms difference of the plate acceleration at the observation
point from an IDA reference at rtol 1e-10 on the 1e-5 s output grid. Wall time at a common
error level (``--error``) is interpolated log-log between the two runs that bracket it; the
ratios to IDA are printed with a JSON record for docs/performance.md.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time

import numpy as np
from scipy.integrate import solve_ivp

import roughvib
from roughvib.analysis.compare import relative_rms_error
from roughvib.model import kernels as kn
from roughvib.model.regimes import initial_regime
from roughvib.model.system import assemble
from roughvib.solvers.base import atol_vector

SCENE = {"contact.points": 1, "plate.max_frequency": 50.6e3, "block.mass": 2.0,
         "excitation.kind": "prescribed", "excitation.velocity": 0.01,
         "excitation.amplitude": 0.0, "excitation.target_rms_velocity": "none",
         "output.progress": False}
SIGNAL = "plate_vertical_acceleration"


def _ida(scene, rtol):
    s = scene.with_overrides({"solver.rtol": rtol, "solver.atol_acceleration": rtol * 1e-2})
    t0 = time.perf_counter()
    r = roughvib.simulate(s)
    wall = time.perf_counter() - t0
    return r.dataset[SIGNAL].values, wall, len(r.events), r.summary["solver"].get("steps")


def _fixed(scene, method, step):
    s = scene.with_overrides({"solver.method": method, "solver.step": step})
    t0 = time.perf_counter()
    r = roughvib.simulate(s)
    return r.dataset[SIGNAL].values, time.perf_counter() - t0, None, None


def _scipy(scene, method, rtol, budget):
    system = assemble(scene)
    lay = system.layout
    reg, rf = system.new_regime_arrays()
    y0, closed = system.static_equilibrium()
    initial_regime(closed, system.fp, lay.tangential, system.scene.friction.law).pack(reg, rf)
    y0, _ = system.consistent(0.0, y0, reg, rf)
    alg = np.zeros(lay.size, dtype=bool)
    alg[lay.algebraic_indices] = True
    diff = np.flatnonzero(~alg)
    full = y0.copy()
    atol = atol_vector(system)[diff] * (rtol / scene.solver.rtol)
    grid = np.arange(int(round(scene.output.duration / scene.output.step)) + 1) * \
        scene.output.step
    deadline = time.perf_counter() + budget

    def rhs(t, yd):
        if time.perf_counter() > deadline:
            raise TimeoutError
        full[diff] = yd
        _, yp = system.consistent(t, full, reg, rf)
        return yp[diff]

    t0 = time.perf_counter()
    try:
        sol = solve_ivp(rhs, (0.0, grid[-1]), y0[diff], method=method, t_eval=grid,
                        rtol=rtol, atol=atol)
    except TimeoutError:
        return None, time.perf_counter() - t0, None, None
    wall = time.perf_counter() - t0
    if not sol.success:
        return None, wall, None, None
    out = np.empty(kn.N_OUT_FIXED + 2 * system.n_contacts)
    sig = np.empty(grid.size)
    j = kn.OUT_NAMES.index(SIGNAL)
    args = system.kernel_args(reg, rf)
    for i, t in enumerate(grid):
        full[diff] = sol.y[:, i]
        y, _ = system.consistent(t, full, reg, rf)
        kn.outputs(t, y, out, *args)
        sig[i] = out[j]
    return sig, wall, None, sol.nfev


def _at_error(rows, target):
    """Wall time at ``target`` error, log-log between the runs that bracket it."""
    pts = sorted((r["error"], r["wall"]) for r in rows if r["error"] and
                 math.isfinite(r["error"]))
    for (e1, w1), (e2, w2) in zip(pts, pts[1:], strict=False):
        if e1 <= target <= e2:
            f = (math.log(target) - math.log(e1)) / (math.log(e2) - math.log(e1))
            return math.exp(math.log(w1) + f * (math.log(w2) - math.log(w1)))
    return float("nan")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=0.005)
    p.add_argument("--budget", type=float, default=120.0, help="wall seconds per run")
    p.add_argument("--error", type=float, default=1e-3, help="matched error level")
    a = p.parse_args()
    scene = roughvib.load_scene("paper-handset", {**SCENE, "output.duration": a.duration})
    _ida(scene.with_overrides({"output.duration": 0.001}), 1e-6)  # JIT warm-up
    ref, _, n_ev, _ = _ida(scene, 1e-10)
    assert n_ev == 0, "the reduced scene must stay in contact (no events) for the peers"
    ladders = {
        "ida": [1e-4, 1e-5, 1e-6, 1e-7, 1e-8],
        "exact-modal": [1e-5, 5e-6, 2.5e-6, 1.25e-6],
        "newmark": [1e-5, 5e-6, 2.5e-6, 1.25e-6],
        "BDF": [1e-3, 1e-4, 1e-5, 1e-6], "Radau": [1e-3, 1e-4, 1e-5, 1e-6],
        "LSODA": [1e-3, 1e-4, 1e-5, 1e-6, 1e-7], "DOP853": [1e-3, 1e-5, 1e-7, 1e-9],
    }
    table = {}
    print(f"{'method':>12} {'tol/step':>9} {'wall [s]':>9} {'error':>9}")
    for method, ladder in ladders.items():
        rows = []
        for v in ladder:
            if method == "ida":
                sig, wall, _, _ = _ida(scene, v)
            elif method in ("exact-modal", "newmark"):
                sig, wall, _, _ = _fixed(scene, method, v)
            else:
                sig, wall, _, _ = _scipy(scene, method, v, a.budget)
            err = relative_rms_error(sig, ref) if sig is not None else float("nan")
            rows.append({"setting": v, "wall": wall, "error": err})
            print(f"{method:>12} {v:>9.1e} {wall:>9.2f} {err:>9.2e}"
                  + ("  (> budget or failed)" if sig is None else ""))
            if sig is None:
                break
        table[method] = rows
    t_ida = _at_error(table["ida"], a.error)
    print(f"\nwall time at relative rms error {a.error:g} (ratio to IDA):")
    ratios = {}
    for method, rows in table.items():
        t = _at_error(rows, a.error)
        ratios[method] = t / t_ida if math.isfinite(t) else float("nan")
        txt = f"{t:.2f} s, {ratios[method]:.1f}x" if math.isfinite(t) else \
            "not bracketed (error never reached within the ladder/budget)"
        print(f"  {method:>12}: {txt}")
    print(json.dumps({"benchmark": "peers", "duration": a.duration, "error": a.error,
                      "table": table, "ratios": ratios, "machine": platform.platform()}))


if __name__ == "__main__":
    main()
