"""Benchmark: IDA's two Newton linear solvers (``solver.linear_solver``) on the same scenes.

Run on demand, not by the tests:

    python benchmarks/bench_linear_solver.py [--repeat 2]

``sparse``: SuperLU_MT on the analytic arrow-shaped CSC Jacobian (one residual call per Newton
iteration, a Jacobian evaluation and factorisation every few dozen steps). ``gmres``: GMRES with
Krylov dimension 1, the exact block-elimination preconditioner and the analytic J v of
roughvib.model.krylov (per Newton iteration one residual, two preconditioner solves and one J v
call). Cases: the ``paper-handset`` scene (10 contact points, about 400 modes), the same with 40
contacts, and fast prescribed sliding with lift-off events. Prints wall time (minimum over
repeats), steps, residual / Jacobian / Krylov counts, restarts and the energy-audit residual per
case and solver, then one JSON record.
"""

from __future__ import annotations

import argparse
import json
import platform

import roughvib

CASES = {
    "paper 0.05 s": {"output.duration": 0.05},
    "paper, 40 contacts, 0.02 s": {"output.duration": 0.02, "contact.points": 40},
    "sliding 0.3 m/s with lift-off, 0.004 s": {
        "output.duration": 0.004, "excitation.kind": "prescribed",
        "excitation.velocity": 0.3, "excitation.amplitude": 0.0,
        "excitation.target_rms_velocity": "none"},
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=2)
    a = p.parse_args()
    records = []
    for name, over in CASES.items():
        for ls in ("sparse", "gmres"):
            scene = roughvib.load_scene("paper-handset", {**over, "output.progress": False,
                                                          "solver.linear_solver": ls})
            roughvib.simulate(scene.with_overrides({"output.duration": 0.002}))  # JIT warm-up
            best = None
            for _ in range(a.repeat):
                r = roughvib.simulate(scene)
                if best is None or r.summary["solver"]["wall_time"] < best[0]:
                    best = (r.summary["solver"]["wall_time"], r)
            wall, r = best
            st = r.summary["solver"]
            rec = {"case": name, "linear_solver": ls, "wall": wall, "steps": st.get("steps"),
                   "residuals": st["residual_evaluations"],
                   "jacobians": st["jacobian_evaluations"],
                   "krylov_iterations": st.get("linear_iterations"),
                   "restarts": st.get("restarts", 0),
                   "audit": r.summary["energy_audit"]["relative_residual"]}
            records.append(rec)
            print(f"{name:>40} {ls:>6}: {wall:6.2f} s, {rec['steps']} steps, "
                  f"{rec['residuals']} res, {rec['jacobians']} jac, "
                  f"{rec['krylov_iterations']} krylov, {rec['restarts']} restarts, "
                  f"audit {rec['audit']:.1e}")
    print(json.dumps({"benchmark": "linear_solver", "records": records,
                      "machine": platform.platform()}))


if __name__ == "__main__":
    main()
