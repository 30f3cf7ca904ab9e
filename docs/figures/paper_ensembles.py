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

#: the paper's own input: its measured band (to 50 um) on its 10 um grid, linear interpolation,
#: the heights at a point (no contact filter)
PROCEDURE = {"roughness.shortest_wavelength": 50e-6, "roughness.spacing": 10e-6,
             "roughness.interpolation": "linear", "contact.filter": "none"}
#: tolerances tighter than the `reference` preset, for the friction-moment pairs
TIGHT = {"solver.rtol": 1e-6, "solver.atol_acceleration_relative": 1e-6}
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
    # the paper's procedure: its 50 um band on its 10 um grid, linear, no contact filter
    "procedure-10": ("paper", {**PROCEDURE}),
    "procedure-20": ("paper", {**PROCEDURE, "excitation.target_rms_velocity": 0.02}),
    "procedure-40": ("paper", {**PROCEDURE, "excitation.target_rms_velocity": 0.04}),
    "procedure-100": ("paper-100mms", {**PROCEDURE}),
    # point or area coupling
    "area-paper-10": ("paper", {"contact.patch": "area"}),
    "area-heavy-10": ("paper-heavy", {"contact.patch": "area"}),
    "area-paper-100": ("paper-100mms", {"contact.patch": "area"}),
    # a plate ten times as damped as the paper's (quiet during stick)
    "damped-10": ("paper", {"plate.loss_factor": 0.03}),
    # the friction moment, on and off at the same tight tolerances
    "moment-off-10": ("paper", {**TIGHT}),
    "moment-on-10": ("paper", {**TIGHT, "contact.friction_moment": True}),
    "moment-off-100": ("paper-100mms", {**TIGHT}),
    "moment-on-100": ("paper-100mms", {**TIGHT, "contact.friction_moment": True}),
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

#: bumped when run_numbers gains a number, so that older caches are recomputed
CACHE_VERSION = 2
NOISE_RMS = 1e-3  # simulated accelerometer floor on the block [m/s^2 rms], as make_figures.py


def _band_mean(fc, d, lo, hi):
    sel = (fc >= lo * 0.99) & (fc <= hi * 1.01) & np.isfinite(d)
    return (float(np.mean(d[sel])), float(np.min(d[sel])), float(np.max(d[sel]))) \
        if sel.any() else (math.nan,) * 3


def _input_bands(r, win, fs: float) -> np.ndarray:
    """Band levels of the contacts' input acceleration, power mean over the contacts [dB].

    The input's second derivative by central differences, Hann-tapered band sums. The
    differences attenuate the top bands (about 1 dB at 10 kHz); a ratio of two runs in the
    same band is exact.
    """
    from roughvib.analysis.spectra import band_levels

    xi = r.dataset["roughness_input"].values[win]
    acc = np.gradient(np.gradient(xi, 1.0 / fs, axis=0), 1.0 / fs, axis=0)
    _, lev = band_levels(acc, fs, axis=0, window="hann")
    return 10.0 * np.log10(np.mean(10.0 ** (lev / 10.0), axis=1))


def _stick_numbers(r, scene, t) -> dict:
    from roughvib.analysis import figures_data as fd
    from roughvib.analysis.events import stick_intervals

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
    return {"stick_phases_per_period": len(sticks) / periods if periods > 0 else math.nan,
            "mean_stick_s": float(np.mean([bb - a for a, bb in sticks])) if sticks else 0.0,
            "quiet": quiet}


def run_numbers(case_dir: Path) -> dict:
    """Everything the comparison page needs from one run (cached in the case directory)."""
    cache = case_dir / "paper_comparison.json"
    if cache.exists() and cache.stat().st_mtime >= (case_dir / "result.nc").stat().st_mtime:
        d = json.loads(cache.read_text())
        if d.get("version") == CACHE_VERSION:
            return d
    import roughvib
    from roughvib.analysis import figures_data as fd

    r = roughvib.load_result(case_dir)
    s = r.summary
    m, mo = s["metrics"], s["model"]
    c = mo.get("contact", {})
    scene = fd.scene_of(r)
    # Hann-tapered FFT band sums (docs/bands.md): the band numbers of the comparison page
    sp = fd.acceleration_spectra(r, band_method="fft")
    cr = fd.contact_resonance(r, spectra=sp)
    fc = np.asarray(sp.centres)
    b, p = np.asarray(sp.band_db["block"]), np.asarray(sp.band_db["plate"])
    diff = p - b
    t = r.dataset["time"].values
    win = fd.analysis_window(r)
    inp = _input_bands(r, win, 1.0 / float(t[1] - t[0]))
    v = np.abs(r.dataset["block_tangential_velocity"].values[win])
    hurst = scene.roughness.hurst
    d = {
        "version": CACHE_VERSION,
        "seed": scene.roughness.seed,
        "v_rms": m["block_tangential_velocity_rms"],
        # the time means of |v|^(2H) and |v|^(4+2H): how the input grows below and above the
        # contact filter's corner (docs/theory.md, "The input field")
        "v_2h": float(np.mean(v ** (2 * hurst))), "v_4_2h": float(np.mean(v ** (4 + 2 * hurst))),
        "block_db": m["block_vertical_acceleration_level_db_re_1e-6"],
        "plate_db": m["plate_vertical_acceleration_level_db_re_1e-6"],
        "stick_fraction": m["stick_fraction"],
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
        **_stick_numbers(r, scene, t),
        "bands": {"centre": fc.tolist(), "block": b.tolist(), "plate": p.tolist(),
                  "input": inp.tolist()},
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


def _first_case(root: Path, name: str) -> Path | None:
    """The case directory of the lowest successful seed of an ensemble."""
    d = root / name
    if not (d / "sweep.csv").exists():
        return None
    import pandas as pd

    t = pd.read_csv(d / "sweep.csv", keep_default_na=False, na_values=[""])
    t = t[t["status"] == "success"].sort_values("roughness.seed")
    return d / "cases" / t["case"].iloc[0] if len(t) else None


def single_draw(case_dir: Path) -> dict:
    """The numbers the page quotes for the figures of one draw (paper Figs. 3, 5, 8, 9, 14)."""
    import roughvib
    from roughvib.analysis import figures_data as fd
    from roughvib.analysis.spectra import band_levels, nominal_centre

    r = roughvib.load_result(case_dir)
    loop = fd.friction_loop(r, periods=None)
    fig9, k, guard = fd.tangential_stiffness(r)
    st = fig9.stick
    ok = np.isfinite(k)
    stick_k, slip_k = k[ok & st], np.abs(k[ok & ~st])
    dt = float(loop.time[1] - loop.time[0])
    rate = np.abs(np.gradient(loop.friction, dt))
    sp = fd.acceleration_spectra(r, noise_rms=NOISE_RMS)
    fc = np.asarray(sp.centres)
    masked = sp.band_db["block_noisy"] - sp.band_db["block"] > 3.0
    floor = next((float(nominal_centre(fc[i])) for i in range(fc.size)
                  if masked[i:].all()), None)
    x = r.dataset["block_vertical_acceleration"].values[fd.analysis_window(r)]
    fs = 1.0 / dt
    cr, rect = band_levels(x, fs)
    _, hann = fd.tapered_band_levels(x, fs)
    return {
        "normal_force": [float(loop.normal_force.min()), float(loop.normal_force.max())],
        "mu_peak": float(np.max(np.abs(loop.coefficient))),
        "stroke_pp_mm": float(np.ptp(loop.displacement)) * 1e3,
        "stick_dTdx_median_p99_max": [float(np.median(stick_k)),
                                      float(np.percentile(stick_k, 99)), float(stick_k.max())]
        if stick_k.size else None,
        "slip_dTdx_median_p99": [float(np.median(slip_k)), float(np.percentile(slip_k, 99))],
        "v_guard": guard,
        "dTdt_max_median": [float(rate.max()), float(np.median(rate))],
        "noise_floor_from_band": floor,
        "rect_vs_hann": {f"{nominal_centre(f):g}": [float(a), float(h)]
                         for f, a, h in zip(cr, rect, hann, strict=True) if f > 4000},
    }


# --------------------------------------------------------------------------------------------
# table helpers
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


def _paired_bands(a: list[dict], b: list[dict], which: str) -> np.ndarray:
    """Band levels of a minus b, paired by seed: shape (seeds, bands) [dB]."""
    bb = {x["seed"]: x for x in b}
    return np.asarray([np.asarray(x["bands"][which]) - np.asarray(bb[x["seed"]]["bands"][which])
                       for x in a if x["seed"] in bb], dtype=float)


def _peaks(runs: list[dict]) -> str:
    return ms([r["f_transmissibility"] for r in runs if r["f_transmissibility"]], ".0f")


def _nominal(f) -> str:
    from roughvib.analysis.spectra import nominal_centre

    return f"{nominal_centre(f):g}"


def _doublings(a: dict, b: dict) -> float:
    return math.log2(a["v_rms"] / b["v_rms"])


# --------------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------------

#: the ensembles of the page's main tables (per-run tables for these)
MAIN = ["paper-10", "paper-100", "heavy-10", "rough-10", "heavy-100", "rough-100", "paper-20",
        "paper-40", "handset-10", "handset-10-highest"]
VEL = ["paper-10", "paper-20", "paper-40", "paper-100"]
PROC = ["procedure-10", "procedure-20", "procedure-40", "procedure-100"]
#: bands of the per-band velocity slopes [Hz, nominal]
SLOPE_BANDS = (100, 160, 250, 400, 630, 1000, 1600, 2500, 4000, 6300, 10000, 16000, 25000,
               40000)


def _runs_section(E) -> list[str]:
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
    md = ["## Runs", "", _md(["ensemble", "scene", "n", "v_rms [mm/s]", "block [dB]",
                              "block range", "plate [dB]", "plate range", "N", "n_c",
                              "s_total [1e6 N/m]", "f spring-mass [Hz]",
                              "f transmissibility [Hz]", "lift-offs"], rows), ""]
    md += ["Levels in dB re 1e-6 m/s². N: contact points; n_c: micro-contacts of the "
           "statistical model (blank for the hand-set scenes). Overrides of each ensemble: "
           "`ENSEMBLES` in docs/figures/paper_ensembles.py.", ""]
    for name in MAIN:
        runs = E.get(name)
        if not runs:
            continue
        md += [f"### {name}: per run", "", _md(
            ["seed", "block dB", "plate dB", "N", "s_total N/m", "f spring-mass Hz",
             "f transmissibility Hz", "loudest block Hz", "loudest plate Hz", "lift-offs",
             "stick fraction"],
            [[r["seed"], f"{r['block_db']:.1f}", f"{r['plate_db']:.1f}", r["contacts"],
              f"{r['stiffness']:.4g}", f"{r['f_spring_mass']:.0f}",
              "n/a" if r["f_transmissibility"] is None else f"{r['f_transmissibility']:.0f}",
              _nominal(r["loudest_block"]), _nominal(r["loudest_plate"]), r["lift_offs"],
              f"{r['stick_fraction']:.3f}"] for r in runs]), ""]
    return md


def _stick_sections(E) -> list[str]:
    md = ["## 1. Stick", "", _md(
        ["ensemble", "stick fraction", "stick phases per period", "mean stick phase [ms]"],
        [[n, ms([r["stick_fraction"] for r in E[n]], ".3f"),
          ms([r["stick_phases_per_period"] for r in E[n]], ".2f"),
          ms([r["mean_stick_s"] * 1e3 for r in E[n]], ".1f")] for n in VEL if E[n]]), ""]
    rows = []
    for n in ("paper-10", "heavy-10", "rough-10", "handset-10", "damped-10", "procedure-10",
              "moment-off-10", "moment-on-10"):
        q = [r["quiet"] for r in E[n] if r["quiet"]]
        if q:
            rows.append([n, len(q), ms([x["settle_0.0"]["input_rate"] for x in q]),
                         ms([x["settle_0.0"]["block"] for x in q]),
                         ms([x["settle_0.01"]["block"] for x in q]),
                         ms([x["settle_0.0"]["plate"] for x in q]),
                         ms([x["settle_0.01"]["plate"] for x in q])])
    md += ["## 2. Quiet during stick (stick minus slip, dB)", "", _md(
        ["ensemble", "n", "input rate", "block, whole stick", "block, after 10 ms",
         "plate, whole stick", "plate, after 10 ms"], rows), "",
        "damped-10: the plate's loss factor 0.03 instead of 0.003.", ""]
    return md


def _resonance_section(E) -> list[str]:
    rows = []
    for n in VEL + ["heavy-10", "heavy-100", "rough-10", "rough-100", "handset-10"] + PROC:
        if not E[n]:
            continue
        rs = E[n]
        fsm = np.mean([r["f_spring_mass"] for r in rs])
        near = sum(1 for r in rs if 0.7 * r["f_spring_mass"] <= r["loudest_block"]
                   <= 1.4 * r["f_spring_mass"])
        near_p = sum(1 for r in rs if 0.7 * r["f_spring_mass"] <= r["loudest_plate"]
                     <= 1.4 * r["f_spring_mass"])
        rows.append([n, f"{fsm:.0f}", _nominal(fsm), _peaks(rs),
                     ms([r["t_max"] for r in rs if r["t_max"]], ".1f"),
                     " ".join(_nominal(r["loudest_block"]) for r in rs), f"{near}/{len(rs)}",
                     " ".join(_nominal(r["loudest_plate"]) for r in rs), f"{near_p}/{len(rs)}"])
    return ["## 3. Contact resonance", "", _md(
        ["ensemble", "spring-mass f_c [Hz]", "band of f_c [Hz]", "transmissibility peak [Hz]",
         "peak transmissibility", "loudest block band per seed [Hz]",
         "block max within 0.7-1.4 f_c",
         "loudest plate band per seed [Hz]", "plate max within 0.7-1.4 f_c"], rows), ""]


def _plate_block_section(E) -> list[str]:
    rows = []
    for n in VEL + ["heavy-10", "rough-10", "handset-10"] + PROC:
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
    md = ["## 4. Plate minus block band levels (dB)", "", _md(
        ["ensemble", "100-500 Hz mean", "100-500 Hz extremes", "1.6-20 kHz mean",
         "1.6-20 kHz smallest", "25-50 kHz mean", "overall Lp - Lb",
         "runs with every band >= 1.6 kHz plate above block"], rows), ""]
    rows = []
    for hi, lo in (("paper-100", "paper-10"), ("procedure-100", "procedure-10")):
        if not E[hi] or not E[lo]:
            continue
        bb = {x["seed"]: x for x in E[lo]}
        both = [(x, bb[x["seed"]]) for x in E[hi] if x["seed"] in bb]
        rows.append([f"{hi} vs {lo}",
                     ms([a["diff_1k6_20k"][0] - b["diff_1k6_20k"][0] for a, b in both]),
                     ms([a["diff_above_20k"][0] - b["diff_above_20k"][0] for a, b in both]),
                     ms([(a["plate_db"] - a["block_db"]) - (b["plate_db"] - b["block_db"])
                         for a, b in both])])
    md += ["### Plate minus block, 100 mm/s minus 10 mm/s (paired by seed, dB)", "", _md(
        ["pair", "1.6-20 kHz band mean", "25-50 kHz band mean", "overall Lp - Lb"], rows), ""]
    return md


def _exponent_rows(E, series: list[str], label: str) -> tuple[list, dict]:
    from scipy import stats

    from roughvib.analysis.levels import velocity_exponent

    by_seed: dict[int, dict[str, dict]] = {}
    for n in series:
        for r in E[n]:
            by_seed.setdefault(r["seed"], {})[n] = r
    fits, two = {"block": [], "plate": []}, {"block": [], "plate": []}
    pairs = list(zip(series[:-1], series[1:], strict=True))
    local = {(w, a, b): [] for w in ("block", "plate") for a, b in pairs}
    for _seed, rs in sorted(by_seed.items()):
        if len(rs) < len(series):
            continue
        v = [rs[n]["v_rms"] for n in series]
        for w in ("block", "plate"):
            y = [rs[n][f"{w}_db"] for n in series]
            fits[w].append(velocity_exponent(v, y).db_per_doubling)
            two[w].append((y[-1] - y[0]) / math.log2(v[-1] / v[0]))
            for i, (a, b) in enumerate(pairs):
                local[(w, a, b)].append((y[i + 1] - y[i]) / math.log2(v[i + 1] / v[i]))
    rows = []
    for w in ("block", "plate"):
        f = np.asarray(fits[w])
        if f.size >= 2:
            half = stats.t.ppf(0.975, f.size - 1) * f.std(ddof=1) / math.sqrt(f.size)
            rows.append([label, w, f.size, ms(f, ".2f"),
                         f"[{f.mean() - half:.2f}, {f.mean() + half:.2f}]", rng(f, ".1f"),
                         ms(f / (10 * math.log10(2)), ".2f"), ms(two[w], ".2f"),
                         " / ".join(ms(local[(w, a, b)], ".1f") for a, b in pairs)])
    return rows, fits


def _velocity_sections(E, js) -> list[str]:
    rows, fits = _exponent_rows(E, VEL, "physical input")
    rows2, fits2 = _exponent_rows(E, PROC, "the paper's procedure")
    md = ["## 5. Velocity exponent (dB per doubling, per seed over 10/20/40/100 mm/s)", "",
          _md(["input", "level", "seeds", "fit mean ± std", "95 % interval of the mean",
               "seed range", "n (a² ∝ vⁿ)", "two-point 10→100",
               "local 10→20 / 20→40 / 40→100"], rows + rows2), ""]
    js["velocity"] = {w: fits[w] for w in fits}
    js["velocity_procedure"] = {w: fits2[w] for w in fits2}
    # per band, 10 -> 100 mm/s, paired by seed, and what |v|^(2H), |v|^(4+2H) predict
    lo, hi = {r["seed"]: r for r in E["paper-10"]}, {r["seed"]: r for r in E["paper-100"]}
    seeds = sorted(set(lo) & set(hi))
    if not seeds:
        return md
    centres = np.asarray(lo[seeds[0]]["bands"]["centre"])
    labels = [float(_nominal(f)) for f in centres]
    pred = [[10 * math.log10(hi[s][k] / lo[s][k]) / _doublings(hi[s], lo[s]) for s in seeds]
            for k in ("v_2h", "v_4_2h")]
    rows = []
    for fb in SLOPE_BANDS:
        if fb not in labels:
            continue
        i = labels.index(fb)
        rows.append([f"{fb:g}"] + [ms([(hi[s]["bands"][w][i] - lo[s]["bands"][w][i])
                                       / _doublings(hi[s], lo[s]) for s in seeds])
                                   for w in ("input", "block", "plate")])
    md += ["### Band levels, 10 → 100 mm/s (dB per doubling of v_rms, paired by seed)", "",
           f"What a self-affine input predicts for the contacts' input acceleration "
           f"(docs/theory.md, \"The input field\"): below the contact filter's corner "
           f"{ms(pred[0], '.2f')} (the ratio of the time means of |v|^(2H)), above it "
           f"{ms(pred[1], '.2f')} (|v|^(4+2H)).", "",
           _md(["band [Hz]", "input", "block", "plate"], rows), ""]
    return md


def _pair_sections(E) -> list[str]:
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
    md = ["## 6. Load (paired by seed, a − b)", "", _md(hdr, pair_rows([
        ("heavy vs paper, 10 mm/s", "heavy-10", "paper-10"),
        ("heavy vs paper, 100 mm/s", "heavy-100", "paper-100"),
        ("heavy vs paper, 10 mm/s, area", "area-heavy-10", "area-paper-10")])), ""]
    md += ["## 7. Roughness (paired by seed, a − b)", "", _md(hdr, pair_rows([
        ("rough vs paper, 10 mm/s", "rough-10", "paper-10"),
        ("rough vs paper, 100 mm/s", "rough-100", "paper-100")])), ""]
    md += ["## Contact selection (paired by seed, a − b)", "", _md(hdr, pair_rows([
        ("highest vs separated, hand-set, 10 mm/s", "handset-10-highest", "handset-10"),
        ("module vs hand-set, 10 mm/s", "paper-10", "handset-10")])), ""]
    md += ["## The physical input against the paper's procedure (paired by seed, a − b)", "",
           _md(hdr, pair_rows([(f"{a} vs {b}", a, b) for a, b in zip(VEL, PROC, strict=True)])),
           ""]
    return md


def _band_table(E, pairs, which: tuple[str, ...]) -> list[str]:
    """Per-band mean ± std of paired differences, one column per (pair, signal)."""
    cols, header = [], ["band [Hz]"]
    centres = None
    for label, a, b in pairs:
        if not E[a] or not E[b]:
            continue
        for w in which:
            d = _paired_bands(E[a], E[b], w)
            cols.append([ms(d[:, i]) for i in range(d.shape[1])])
            header.append(f"{label}, {w}")
        centres = E[a][0]["bands"]["centre"]
    if centres is None:
        return []
    rows = [[_nominal(f)] + [c[i] for c in cols] for i, f in enumerate(centres)
            if np.isfinite(E[pairs[0][1]][0]["bands"]["block"][i])]
    return [_md(header, rows), ""]


def _coupling_rows(E, pairs) -> list:
    rows = []
    for label, n in pairs:
        rs = E[n]
        if not rs:
            continue
        rows.append([label, ms([r["block_db"] for r in rs]), ms([r["plate_db"] for r in rs]),
                     ms([r["diff_1k6_20k"][0] for r in rs]),
                     ms([r["diff_above_20k"][0] for r in rs]),
                     f"{sum(r['diff_all_above_1k6_positive'] for r in rs)}/{len(rs)}",
                     ms([r["lift_offs"] for r in rs])])
    return rows


def _extension_sections(E) -> list[str]:
    hdr = ["ensemble", "block overall [dB]", "plate overall [dB]",
           "plate − block, 1.6–20 kHz band mean", "plate − block, 25–50 kHz band mean",
           "every band ≥ 1.6 kHz plate above block", "lift-offs per run"]
    md = ["## Point or area contact: area minus point, paired by seed (dB)", ""]
    md += _band_table(E, [("10 mm/s", "area-paper-10", "paper-10"),
                          ("heavy, 10 mm/s", "area-heavy-10", "heavy-10"),
                          ("100 mm/s", "area-paper-100", "paper-100")], ("plate", "block"))
    md += [_md(hdr, _coupling_rows(E, [
        ("paper-10, point", "paper-10"), ("paper-10, area", "area-paper-10"),
        ("heavy-10, point", "heavy-10"), ("heavy-10, area", "area-heavy-10"),
        ("paper-100, point", "paper-100"), ("paper-100, area", "area-paper-100")])), ""]
    rows = []
    for label, a, b in (("area − point, 10 mm/s", "area-paper-10", "paper-10"),
                        ("area − point, 100 mm/s", "area-paper-100", "paper-100"),
                        ("moment on − off, 10 mm/s", "moment-on-10", "moment-off-10"),
                        ("moment on − off, 100 mm/s", "moment-on-100", "moment-off-100")):
        if E[a] and E[b]:
            db, dp = _paired(E[a], E[b], "block_db"), _paired(E[a], E[b], "plate_db")
            rows.append([label, ms(db, ".2f"), rng(db), ms(dp, ".2f"), rng(dp)])
    md += ["## Friction moment: on minus off, paired by seed (dB)", "",
           "Both at solver.rtol 1e-6 and solver.atol_acceleration_relative 1e-6.", ""]
    md += _band_table(E, [("10 mm/s", "moment-on-10", "moment-off-10"),
                          ("100 mm/s", "moment-on-100", "moment-off-100")], ("block", "plate"))
    md += [_md(hdr, _coupling_rows(E, [
        ("moment off, 10 mm/s", "moment-off-10"), ("moment on, 10 mm/s", "moment-on-10"),
        ("moment off, 100 mm/s", "moment-off-100"), ("moment on, 100 mm/s", "moment-on-100")])),
        ""]
    two = []
    for label, a, b in (("moment off", "moment-off-100", "moment-off-10"),
                        ("moment on", "moment-on-100", "moment-on-10")):
        if E[a] and E[b]:
            bb = {x["seed"]: x for x in E[b]}
            two.append([label] + [ms([(x[f"{w}_db"] - bb[x["seed"]][f"{w}_db"])
                                      / _doublings(x, bb[x["seed"]])
                                      for x in E[a] if x["seed"] in bb], ".2f")
                                  for w in ("block", "plate")])
    md += ["### Overall levels, paired by seed", "",
           _md(["pair", "Δ block [dB]", "Δ block range", "Δ plate [dB]", "Δ plate range"], rows),
           "", "### Two-point velocity exponent, 10 → 100 mm/s [dB per doubling]", "",
           _md(["", "block", "plate"], two), ""]
    return md


def _single_draw_section(root: Path, js) -> list[str]:
    md = ["## Single draws (lowest seed)", ""]
    rows = []
    for name in ("paper-10", "paper-100"):
        case = _first_case(root, name)
        if case is None:
            continue
        d = single_draw(case)
        js.setdefault("single", {})[name] = d
        st = d["stick_dTdx_median_p99_max"]
        rows.append([name, f"{d['normal_force'][0]:.2f} … {d['normal_force'][1]:.2f}",
                     f"{d['mu_peak']:.3f}", f"{d['stroke_pp_mm']:.2f}",
                     "n/a" if st is None else f"{st[0]:.2g} / {st[1]:.2g} / {st[2]:.2g}",
                     f"{d['slip_dTdx_median_p99'][0]:.2g} / {d['slip_dTdx_median_p99'][1]:.2g}",
                     f"{d['dTdt_max_median'][0]:.2g} / {d['dTdt_max_median'][1]:.2g}",
                     "none" if d["noise_floor_from_band"] is None
                     else f"{d['noise_floor_from_band']:g}",
                     "; ".join(f"{k}: {a:.1f} / {h:.1f}" for k, (a, h) in
                               d["rect_vs_hann"].items() if k in ("5000", "10000", "20000",
                                                                  "40000"))])
    md += [_md(["ensemble", "F_N range [N]", "peak friction coefficient", "stroke p-p [mm]",
                "stick dT/dx median / 99th percentile / max [N/m]",
                "slip dT/dx magnitude, median / 99th percentile [N/m]",
                "dT/dt magnitude, max / median [N/s]",
                "block + 1e-3 m/s² noise floored from [Hz]",
                "block bands, rectangular / Hann [dB]"], rows), "",
           "dT/dx over the 2.5 periods of the figure (paper Fig. 9b), where |v| exceeds 1e-4 "
           "v_rms; dT/dt over the analysis window. Noise floor: the lowest band from which "
           "every band of the block with the noise is more than 3 dB above the block alone "
           "(the spectra figure's filter bank).", ""]
    return md


def tables(root: Path, out: Path) -> None:
    E = {name: load_ensemble(root, name) for name in ENSEMBLES}
    md: list[str] = ["# Ensemble tables of the paper comparison", "",
                     "Made by `python docs/figures/paper_ensembles.py tables`. "
                     "Numbers are mean ± sample standard deviation over the seeds (n given).",
                     ""]
    js: dict = {"n": {k: len(v) for k, v in E.items()}}
    md += _runs_section(E)
    md += _stick_sections(E)
    md += _resonance_section(E)
    md += _plate_block_section(E)
    md += _velocity_sections(E, js)
    md += _pair_sections(E)
    md += _extension_sections(E)
    md += _single_draw_section(root, js)
    out.mkdir(parents=True, exist_ok=True)
    (out / "ensembles.md").write_text("\n".join(md) + "\n")
    js["runs"] = {n: [{k: v for k, v in r.items() if k != "bands"} for r in rs]
                  for n, rs in E.items()}
    (out / "ensembles.json").write_text(json.dumps(js, indent=1))
    print(out / "ensembles.md")


if __name__ == "__main__":
    sys.exit(main())
