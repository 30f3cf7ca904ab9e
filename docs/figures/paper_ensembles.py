"""The roughness ensembles behind docs/paper-comparison.md, and the tables made from them.

Usage (from the repository root)::

    nice -n 10 python docs/figures/paper_ensembles.py run       # the ensembles -> runs/ens/
    python docs/figures/paper_ensembles.py tables               # -> docs/figures/ensembles.md
    python docs/figures/paper_ensembles.py run --only paper-10 --seeds 3   # a quicker look

``run`` is the same as one ``roughvib run SCENE --seeds 10 --set solver.method=adaptive-modal
--out runs/ens/NAME`` per ensemble below (resumable: completed draws are kept). ``tables``
reads the case directories and writes every table of the comparison page, each number as
mean ± standard deviation over the seeds (and the per-run contact count, stiffness and
resonance) to ``docs/figures/ensembles.md`` and ``ensembles.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

#: ensemble name -> (scene, fixed overrides); every run uses adaptive-modal
ENSEMBLES: dict[str, tuple[str, dict]] = {
    "paper-10": ("paper", {}),
    "paper-100": ("paper-100mms", {}),
    "heavy-10": ("paper-heavy", {}),
    "rough-10": ("paper-rough", {}),
    "heavy-100": ("paper-heavy-100mms", {}),
    "rough-100": ("paper-rough-100mms", {}),
    "paper-20": ("paper", {"excitation.target_rms_velocity": 0.02}),
    "paper-40": ("paper", {"excitation.target_rms_velocity": 0.04}),
    "handset-10": ("paper-handset", {}),
    "handset-10-highest": ("paper-handset", {"contact.selection": "highest"}),
}
METHOD = {"solver.method": "adaptive-modal"}


def run(root: Path, seeds: int, only: list[str] | None, workers: int) -> None:
    from roughvib.studies.sweep.ensemble import seed_sweep
    from roughvib.studies.sweep.report import sweep_report
    from roughvib.studies.sweep.run import run_sweep

    for name, (scene, over) in ENSEMBLES.items():
        if only and name not in only:
            continue
        spec = seed_sweep(scene, seeds, {**over, **METHOD})
        out = root / name
        print(f"== {name}: {scene} {over} -> {out}", flush=True)
        r = run_sweep(spec, out, workers=workers, progress=False,
                      log=lambda m: print(m, flush=True))
        print(f"   {len(r.table) - r.failed} of {len(r.table)} succeeded, {r.ran} run now",
              flush=True)
        sweep_report(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["run", "tables"])
    ap.add_argument("--root", default="runs/ens", help="directory of the ensembles")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--only", nargs="*", help="ensemble names (default: all)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(Path(__file__).parent))
    a = ap.parse_args(argv)
    if a.what == "run":
        run(Path(a.root), a.seeds, a.only, a.workers)
    else:
        tables(Path(a.root), Path(a.out))
    return 0


# --------------------------------------------------------------------------------------------
# per-run numbers
# --------------------------------------------------------------------------------------------

def _band_mean(fc, d, lo, hi):
    sel = (fc >= lo * 0.99) & (fc <= hi * 1.01) & np.isfinite(d)
    return (float(np.mean(d[sel])), float(np.min(d[sel])), float(np.max(d[sel]))) \
        if sel.any() else (math.nan,) * 3


def run_numbers(case_dir: Path) -> dict:
    """Everything the comparison page needs from one run (cached in the case directory)."""
    cache = case_dir / "paper_comparison.json"
    if cache.exists() and cache.stat().st_mtime >= (case_dir / "result.nc").stat().st_mtime:
        return json.loads(cache.read_text())
    import roughvib
    from roughvib.analysis import figures_data as fd
    from roughvib.analysis.events import stick_intervals

    r = roughvib.load_result(case_dir)
    s = r.summary
    m, mo = s["metrics"], s["model"]
    c = mo.get("contact", {})
    scene = fd.scene_of(r)
    # the comparison's band numbers were taken with the Hann-tapered FFT band sums, before the
    # reports moved to the IEC 61260-1 filter bank (docs/bands.md); kept so that they reproduce
    sp = fd.acceleration_spectra(r, band_method="fft")
    cr = fd.contact_resonance(r, spectra=sp)
    fc = np.asarray(sp.centres)
    b, p = np.asarray(sp.band_db["block"]), np.asarray(sp.band_db["plate"])
    diff = p - b
    t = r.dataset["time"].values
    win = fd.analysis_window(r)
    t0, t1 = float(t[win][0]), float(t[win][-1])
    sticks = [(max(a, t0), min(bb, t1)) for a, bb in stick_intervals(r.events, float(t[-1]))
              if bb > t0 and a < t1]
    periods = (t1 - t0) * scene.excitation.frequency
    quiet = {}
    if sticks:
        for settle in (0.0, 0.01):
            lv = fd.stick_slip_levels(r, settle=settle)
            quiet[f"settle_{settle}"] = {k: v["stick_minus_slip_db"] for k, v in lv.items()}
    d = {
        "seed": scene.roughness.seed,
        "v_rms": m["block_tangential_velocity_rms"],
        "block_db": m["block_vertical_acceleration_level_db_re_1e-6"],
        "plate_db": m["plate_vertical_acceleration_level_db_re_1e-6"],
        "stick_fraction": m["stick_fraction"],
        "stick_phases_per_period": len(sticks) / periods if periods > 0 else math.nan,
        "mean_stick_s": float(np.mean([bb - a for a, bb in sticks])) if sticks else 0.0,
        "lift_offs": int(s.get("events_by_kind", {}).get("lift_off", 0)),
        "normal_force_min": m["normal_force_min"],
        "contacts": mo["contacts"], "micro_contacts": c.get("micro_contacts"),
        "stiffness": mo["contact_stiffness_total"], "r1": c.get("vertical_damping"),
        "f_spring_mass": cr.spring_mass, "f_transmissibility": cr.transmissibility_peak,
        "t_max": cr.transmissibility_max,
        "loudest_block": cr.block_maximum, "loudest_plate": cr.plate_maximum,
        "crossover": cr.crossover,
        "diff_100_500": _band_mean(fc, diff, 100, 500),
        "diff_1k6_20k": _band_mean(fc, diff, 1600, 20000),
        "diff_above_20k": _band_mean(fc, diff, 25000, 50000),
        "diff_all_above_1k6_positive": bool(np.all(diff[(fc >= 1580) & np.isfinite(diff)] > 0)),
        "quiet": quiet,
        "bands": {"centre": fc.tolist(), "block": b.tolist(), "plate": p.tolist()},
    }
    cache.write_text(json.dumps(d))
    return d


def load_ensemble(root: Path, name: str) -> list[dict]:
    """Per-run numbers of the successful cases of one ensemble, by seed."""
    d = root / name
    if not (d / "sweep.csv").exists():
        return []
    import pandas as pd

    table = pd.read_csv(d / "sweep.csv", keep_default_na=False, na_values=[""])
    rows = [run_numbers(d / "cases" / c)
            for c, st in zip(table["case"], table["status"], strict=True) if st == "success"]
    return sorted(rows, key=lambda x: x["seed"])


# --------------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------------

def ms(values, fmt=".1f") -> str:
    """'mean ± std' (sample std) of finite values, with the count when some are missing."""
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=float)
    if v.size == 0:
        return "n/a"
    sd = f" ± {np.std(v, ddof=1):{fmt}}" if v.size > 1 else ""
    return f"{np.mean(v):{fmt}}{sd}"


def rng(values, fmt=".1f") -> str:
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=float)
    return f"{np.min(v):{fmt}} … {np.max(v):{fmt}}" if v.size else "n/a"


def _md(header, rows) -> str:
    return "\n".join(["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
                      + ["| " + " | ".join(str(c) for c in r) + " |" for r in rows])


def _paired(a: list[dict], b: list[dict], key: str) -> list[float]:
    bb = {x["seed"]: x for x in b}
    return [x[key] - bb[x["seed"]][key] for x in a if x["seed"] in bb]


def _peaks(runs: list[dict]) -> str:
    return ms([r["f_transmissibility"] for r in runs if r["f_transmissibility"]], ".0f")


def tables(root: Path, out: Path) -> None:
    from scipy import stats

    from roughvib.analysis.levels import velocity_exponent

    E = {name: load_ensemble(root, name) for name in ENSEMBLES}
    md: list[str] = ["# Ensemble tables of the paper comparison", "",
                     f"Made by `python docs/figures/paper_ensembles.py tables` from {root}. "
                     "Numbers are mean ± sample standard deviation over the seeds (n given).",
                     ""]
    js: dict = {"n": {k: len(v) for k, v in E.items()}}

    # -- the runs ------------------------------------------------------------------------
    rows = []
    for name, runs in E.items():
        if not runs:
            continue
        rows.append([name, ENSEMBLES[name][0], len(runs),
                     ms([r["v_rms"] * 1e3 for r in runs], ".2f"),
                     ms([r["block_db"] for r in runs]), rng([r["block_db"] for r in runs]),
                     ms([r["plate_db"] for r in runs]), rng([r["plate_db"] for r in runs]),
                     "/".join(sorted({str(r["contacts"]) for r in runs})),
                     ms([r["micro_contacts"] for r in runs if r["micro_contacts"] is not None],
                        ".2f"),
                     ms([r["stiffness"] / 1e6 for r in runs], ".3f"),
                     ms([r["f_spring_mass"] for r in runs], ".0f"),
                     ms([r["f_transmissibility"] for r in runs if r["f_transmissibility"]],
                        ".0f"),
                     ms([r["lift_offs"] for r in runs], ".0f")])
    md += ["## Runs", "", _md(["ensemble", "scene", "n", "v_rms [mm/s]", "block [dB]",
                               "block range", "plate [dB]", "plate range", "N", "n_c",
                               "s_total [1e6 N/m]", "f spring-mass [Hz]",
                               "f transmissibility [Hz]", "lift-offs"], rows), ""]
    md += ["Levels in dB re 1e-6 m/s². N: contact points; n_c: micro-contacts of the "
           "statistical model (blank for the hand-set scenes).", ""]

    # -- per-run contact and resonance ----------------------------------------------------
    for name, runs in E.items():
        if not runs:
            continue
        md += [f"### {name}: per run", "", _md(
            ["seed", "block dB", "plate dB", "N", "s_total N/m", "f spring-mass Hz",
             "f transmissibility Hz", "loudest block Hz", "loudest plate Hz", "lift-offs",
             "stick fraction"],
            [[r["seed"], f"{r['block_db']:.1f}", f"{r['plate_db']:.1f}", r["contacts"],
              f"{r['stiffness']:.4g}", f"{r['f_spring_mass']:.0f}",
              "n/a" if r["f_transmissibility"] is None else f"{r['f_transmissibility']:.0f}",
              f"{r['loudest_block']:.0f}", f"{r['loudest_plate']:.0f}", r["lift_offs"],
              f"{r['stick_fraction']:.3f}"] for r in runs]), ""]

    # -- 1. stick ---------------------------------------------------------------------------
    vel = ["paper-10", "paper-20", "paper-40", "paper-100"]
    md += ["## 1. Stick", "", _md(
        ["ensemble", "stick fraction", "stick phases per period", "mean stick phase [ms]"],
        [[n, ms([r["stick_fraction"] for r in E[n]], ".3f"),
          ms([r["stick_phases_per_period"] for r in E[n]], ".2f"),
          ms([r["mean_stick_s"] * 1e3 for r in E[n]], ".1f")] for n in vel if E[n]]), ""]

    # -- 2. quiet during stick --------------------------------------------------------------
    rows = []
    for n in ("paper-10", "heavy-10", "rough-10", "handset-10"):
        q = [r["quiet"] for r in E[n] if r["quiet"]]
        if q:
            rows.append([n, len(q), ms([x["settle_0.0"]["input_rate"] for x in q]),
                         ms([x["settle_0.0"]["block"] for x in q]),
                         ms([x["settle_0.01"]["block"] for x in q]),
                         ms([x["settle_0.0"]["plate"] for x in q]),
                         ms([x["settle_0.01"]["plate"] for x in q])])
    md += ["## 2. Quiet during stick (stick minus slip, dB)", "", _md(
        ["ensemble", "n", "input rate", "block, whole stick", "block, after 10 ms",
         "plate, whole stick", "plate, after 10 ms"], rows), ""]

    # -- 3. contact resonance ---------------------------------------------------------------
    rows = []
    for n in vel + ["heavy-10", "heavy-100", "rough-10", "rough-100", "handset-10"]:
        if not E[n]:
            continue
        rs = E[n]
        fsm = np.mean([r["f_spring_mass"] for r in rs])
        near = sum(1 for r in rs if 0.7 * r["f_spring_mass"] <= r["loudest_block"]
                   <= 1.4 * r["f_spring_mass"])
        near_p = sum(1 for r in rs if 0.7 * r["f_spring_mass"] <= r["loudest_plate"]
                     <= 1.4 * r["f_spring_mass"])
        rows.append([n, f"{fsm:.0f}", ms([r["f_transmissibility"] for r in rs
                                          if r["f_transmissibility"]], ".0f"),
                     ms([r["t_max"] for r in rs if r["t_max"]], ".1f"),
                     " ".join(f"{r['loudest_block']:.0f}" for r in rs),
                     f"{near}/{len(rs)}",
                     " ".join(f"{r['loudest_plate']:.0f}" for r in rs), f"{near_p}/{len(rs)}"])
    md += ["## 3. Contact resonance", "", _md(
        ["ensemble", "spring-mass [Hz]", "transmissibility peak [Hz]", "|T| at peak",
         "loudest block band per seed [Hz]", "block max within 0.7-1.4 f_c",
         "loudest plate band per seed [Hz]", "plate max within 0.7-1.4 f_c"], rows), ""]

    # -- 4. mass below plate ------------------------------------------------------------------
    rows = []
    for n in vel + ["heavy-10", "rough-10", "handset-10"]:
        rs = E[n]
        if not rs:
            continue
        rows.append([n, ms([r["diff_100_500"][0] for r in rs]),
                     rng([r["diff_100_500"][1] for r in rs] + [r["diff_100_500"][2] for r in rs]),
                     ms([r["diff_1k6_20k"][0] for r in rs]),
                     f"{min(r['diff_1k6_20k'][1] for r in rs):.1f}",
                     ms([r["diff_above_20k"][0] for r in rs]),
                     ms([r["plate_db"] - r["block_db"] for r in rs]),
                     f"{sum(r['diff_all_above_1k6_positive'] for r in rs)}/{len(rs)}"])
    md += ["## 4. Plate minus block band levels (dB)", "", _md(
        ["ensemble", "100-500 Hz mean", "100-500 Hz extremes", "1.6-20 kHz mean",
         "1.6-20 kHz smallest", "25-50 kHz mean", "overall Lp - Lb",
         "runs with every band >= 1.6 kHz plate above block"], rows), ""]

    # -- 5. velocity exponent -----------------------------------------------------------------
    by_seed: dict[int, dict[str, dict]] = {}
    for n in vel:
        for r in E[n]:
            by_seed.setdefault(r["seed"], {})[n] = r
    fits = {"block": [], "plate": []}
    two = {"block": [], "plate": []}
    local = {(w, a, b): [] for w in ("block", "plate")
             for a, b in zip(vel[:-1], vel[1:], strict=True)}
    for _seed, rs in sorted(by_seed.items()):
        if len(rs) < 4:
            continue
        v = [rs[n]["v_rms"] for n in vel]
        for w in ("block", "plate"):
            y = [rs[n][f"{w}_db"] for n in vel]
            fits[w].append(velocity_exponent(v, y).db_per_doubling)
            two[w].append((y[-1] - y[0]) / math.log2(v[-1] / v[0]))
            for i, (a, b) in enumerate(zip(vel[:-1], vel[1:], strict=True)):
                local[(w, a, b)].append((y[i + 1] - y[i]) / math.log2(v[i + 1] / v[i]))
    rows = []
    for w in ("block", "plate"):
        f = np.asarray(fits[w])
        if f.size >= 2:
            half = stats.t.ppf(0.975, f.size - 1) * f.std(ddof=1) / math.sqrt(f.size)
            rows.append([w, f.size, ms(f, ".2f"), f"[{f.mean() - half:.2f}, {f.mean() + half:.2f}]",
                         rng(f, ".1f"), ms(f / (10 * math.log10(2)), ".2f"), ms(two[w], ".2f"),
                         " / ".join(ms(local[(w, a, b)], ".1f")
                                    for a, b in zip(vel[:-1], vel[1:], strict=True))])
    md += ["## 5. Velocity exponent (dB per doubling, per seed over 10/20/40/100 mm/s)", "",
           _md(["level", "seeds", "fit mean ± std", "95 % interval of the mean", "seed range",
                "n (a² ∝ vⁿ)", "two-point 10→100", "local 10→20 / 20→40 / 40→100"], rows), ""]
    js["velocity"] = {w: fits[w] for w in fits}

    # -- 6./7./selection: paired differences ----------------------------------------------
    def pair_rows(pairs):
        out_rows = []
        for label, a, b in pairs:
            if not E[a] or not E[b]:
                continue
            db = _paired(E[a], E[b], "block_db")
            dp = _paired(E[a], E[b], "plate_db")
            out_rows.append([label, len(db), ms(db), rng(db), ms(dp), rng(dp),
                             f"{'/'.join(sorted({str(r['contacts']) for r in E[a]}))} vs "
                             f"{'/'.join(sorted({str(r['contacts']) for r in E[b]}))}",
                             f"{np.mean([r['stiffness'] for r in E[a]]):.3g} vs "
                             f"{np.mean([r['stiffness'] for r in E[b]]):.3g}",
                             f"{_peaks(E[a])} vs {_peaks(E[b])}"])
        return out_rows

    hdr = ["pair (a vs b)", "seeds", "Δ block [dB]", "Δ block range", "Δ plate [dB]",
           "Δ plate range", "N", "s_total [N/m]", "transmissibility peak [Hz]"]
    md += ["## 6. Load (paired by seed, a − b)", "", _md(hdr, pair_rows([
        ("heavy vs paper, 10 mm/s", "heavy-10", "paper-10"),
        ("heavy vs paper, 100 mm/s", "heavy-100", "paper-100")])), ""]
    md += ["## 7. Roughness (paired by seed, a − b)", "", _md(hdr, pair_rows([
        ("rough vs paper, 10 mm/s", "rough-10", "paper-10"),
        ("rough vs paper, 100 mm/s", "rough-100", "paper-100")])), ""]
    md += ["## Contact selection (paired by seed, a − b)", "", _md(hdr, pair_rows([
        ("highest vs separated, hand-set, 10 mm/s", "handset-10-highest", "handset-10"),
        ("module vs hand-set, 10 mm/s", "paper-10", "handset-10")])), ""]
    out.mkdir(parents=True, exist_ok=True)
    (out / "ensembles.md").write_text("\n".join(md) + "\n")
    js["runs"] = {n: [{k: v for k, v in r.items() if k != "bands"} for r in rs]
                  for n, rs in E.items()}
    (out / "ensembles.json").write_text(json.dumps(js, indent=1))
    print(out / "ensembles.md")


if __name__ == "__main__":
    sys.exit(main())
