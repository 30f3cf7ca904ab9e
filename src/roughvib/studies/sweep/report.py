"""The sweep report's data: which studies (velocity, load, roughness) the sweep holds, their
points, groups and slope fits, the tables of cases; rendered by
:mod:`roughvib.views.sweep_report`."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from roughvib.rundir import output_folder, writing
from roughvib.studies.sweep.ensemble import EnsembleTables, ensemble_blocks, ensemble_tables
from roughvib.studies.sweep.spec import SUCCESS, _replace_file
from roughvib.studies.sweep.tables import _fit, _joint_fit
from roughvib.views.sweep_report import render_html, render_markdown, study_figure

__all__ = ["sweep_report"]

#: the columns of ``report/fits.csv``: the study, its x column, the level and the group of
#: cases fitted, then the slope fit (``tables._fit``), ``per_seed`` as space-separated slopes
FIT_COLUMNS = ["study", "x", "quantity", "group", "db_per_doubling", "ci_low", "ci_high",
               "exponent_power", "n_seeds", "n_points", "method", "intercept", "per_seed"]
#: the varied keys a report plots against, with the x quantity of the plot
_STUDIES: tuple[tuple[str, tuple[str, ...], str | None, str], ...] = (
    ("velocity", ("excitation.target_rms_velocity", "excitation.velocity"),
     "block_tangential_velocity_rms", "friction velocity v_rms [m/s]"),
    ("load", ("block.mass",), None, "block mass [kg]"),
    ("roughness", ("roughness.rms",), None, "roughness rms [m]"),
)
_LEVELS = (("block", "block_vertical_acceleration_level_db_re_1e-6"),
           ("plate", "plate_vertical_acceleration_level_db_re_1e-6"))


#: the joint fit's levels: name, column (the radiated power only where the runs computed it)
_JOINT_LEVELS = (*_LEVELS, ("radiated power", "sound_power_level_db_re_1pW"))


def _joint_blocks(ok, varied: list[str], rep: Path) -> list[tuple[str, Any]]:
    """The joint fit L = 20 log10(Ra^a V^b) + c when roughness.rms and a velocity key vary:
    report blocks, and ``report/joint_fit.csv``."""
    import pandas as pd

    vkey = next((k for k in _STUDIES[0][1] if k in varied and ok[k].nunique() >= 2), None)
    if "roughness.rms" not in varied or vkey is None or ok["roughness.rms"].nunique() < 2:
        return []
    vcol = "block_tangential_velocity_rms"
    df = ok[(ok["roughness.rms"] > 0) & (ok[vcol] > 0)]
    rows, table = [], []
    for which, col in _JOINT_LEVELS:
        if col not in df:
            continue
        sub = df[df[col].notna()]
        if len(sub) < 4 or sub["roughness.rms"].nunique() < 2 or sub[vcol].nunique() < 2:
            continue
        f = _joint_fit(sub["roughness.rms"], sub[vcol], sub[col])
        rows.append({"quantity": f"{which} level", "column": col, **f})

        def ci(name, f=f):
            lo, hi = f[f"{name}_low"], f[f"{name}_high"]
            return f"[{_g(lo, '.2f')}, {_g(hi, '.2f')}]" if math.isfinite(lo) else "n/a"

        table.append([f"{which} level", _g(f["a"], ".2f"), ci("a"), _g(f["b"], ".2f"), ci("b"),
                      _g(f["b_db_per_doubling"], ".1f"), _g(f["c"], ".1f"),
                      _g(f["rms_residual"], ".2f"), str(f["n_points"])])
    if not rows:
        return []
    with writing(rep / "joint_fit.csv") as fh:
        pd.DataFrame(rows).to_csv(fh, index=False, float_format="%.6g")
    return [("h2", "Roughness and velocity: joint fit L = 20 log10(Ra^a V^b) + c"),
            ("p", f"Ra = `roughness.rms` [m], V = `{vcol}` (measured) [m/s]; least squares "
                  f"over all successful cases (seeds pooled), 95 % t intervals from the "
                  f"residual scatter. b in dB per doubling of V is 20 log10(2) b = 6.02 b; the "
                  f"paper reads 9 to 12 dB per doubling of the velocity for the block and the "
                  f"plate. Table: `report/joint_fit.csv`."),
            ("table", (["quantity", "a (roughness)", "95 % interval", "b (velocity)",
                        "95 % interval", "b dB/doubling", "c [dB]", "rms residual [dB]", "n"],
                       table))]


def _g(v: Any, fmt: str = ".4g") -> str:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return "" if math.isnan(f) else format(f, fmt)


def sweep_report(directory: str | os.PathLike, *,
                 ensemble: EnsembleTables | None = None) -> Path:
    """Plots and a short report of a finished (or partly finished) sweep.

    For a velocity sweep (``excitation.target_rms_velocity`` or ``excitation.velocity``
    varied) the total block and plate levels are drawn against the measured friction
    velocity (rms tangential block velocity) with the fitted slope in dB per doubling; when a
    ``*.seed`` key varies, the slope is fitted per seed and given as the mean with its 95 %
    confidence interval across seeds. ``block.mass`` (load) and ``roughness.rms`` (roughness)
    get the same treatment. Other varied keys split the points into groups, one fit each.
    Only successful cases are used.

    Parameters
    ----------
    directory : path
        Sweep directory written by :func:`.run_sweep`.
    ensemble : EnsembleTables, optional
        The directory's :func:`.ensemble_tables`, if the caller has them already (they load
        every case that the sweep's workers did not hand over); computed when not given.

    Returns
    -------
    Path
        ``DIR/report/report.md``; next to it ``report.html``, ``fits.csv`` and one PNG per
        study (``velocity.png``, ``load.png``, ``roughness.png``).

    Raises
    ------
    FileNotFoundError
        ``directory`` holds no sweep.csv / sweep.json.
    roughvib.rundir.OutputError
        ``DIR/report`` cannot be made (a file of that name is in its way): one line.
    roughvib.rundir.WriteError
        A file cannot be written (a full disk): one line naming it; each file of the report
        appears complete or not at all.
    """
    import pandas as pd

    d = Path(directory)
    meta, table = _read_sweep(d)
    varied = [k for k in meta.get("varied_keys", []) if k in table.columns]
    seed_keys = [k for k in meta.get("seed_keys", []) if k in table.columns]
    ok = table[table["status"] == SUCCESS]
    rep = output_folder(d / "report")  # a file in its way: one line

    blocks: list[tuple[str, Any]] = []  # (kind, payload): h2, p, table, img
    fit_rows: list[dict] = []
    for study in _STUDIES:
        blocks += _study_blocks(study, ok, varied, seed_keys, rep, fit_rows)
    joint = _joint_blocks(ok, varied, rep)
    blocks += joint
    if not fit_rows and not joint:
        blocks.append(("p", "No velocity, load or roughness key varies over two or more "
                            "successful cases; nothing to fit."))
    # the header also when nothing was fitted (an ensemble of one setting): an empty table
    with writing(rep / "fits.csv") as fh:
        pd.DataFrame(fit_rows, columns=FIT_COLUMNS).to_csv(fh, index=False, float_format="%.6g")

    if (ens := ensemble if ensemble is not None else ensemble_tables(d)) is not None:
        blocks += ensemble_blocks(ens, rep)
    blocks += _case_blocks(table, varied)

    title = f"Sweep report: {meta.get('name', d.name)}"
    descr = str(meta.get("description", "")).strip()
    if descr and not descr.endswith("."):
        descr += "."
    intro = (f"{descr} Base scene `{meta.get('base')}`; "
             f"{len(table)} cases, {len(ok)} succeeded, {len(table) - len(ok)} failed or "
             f"missing. Tables: `sweep.csv`, `sweep.nc`; fits: `report/fits.csv`.").strip()
    _replace_file(rep / "report.md", render_markdown(title, intro, blocks))
    _replace_file(rep / "report.html", render_html(title, intro, blocks, directory=rep))
    return rep / "report.md"


def _read_sweep(d: Path) -> tuple[dict, Any]:
    """A sweep directory's ``sweep.json`` (dict) and ``sweep.csv`` (a DataFrame, the
    ``status`` and ``message`` columns as text).

    Raises
    ------
    FileNotFoundError
        Either file is missing.
    """
    import pandas as pd

    if not (d / "sweep.csv").is_file() or not (d / "sweep.json").is_file():
        raise FileNotFoundError(f"{d} is not a sweep directory (no sweep.csv / sweep.json)")
    meta = json.loads((d / "sweep.json").read_text())
    table = pd.read_csv(d / "sweep.csv", keep_default_na=False,
                        na_values=[""]).astype({"status": str, "message": str})
    return meta, table


def _study_groups(df, keys: tuple[str, ...], varied: list[str], seed_keys: list[str]
                  ) -> list[tuple[str, Any]]:
    """The groups of a study's cases, one fit each: by the other varied keys (not the
    study's, not a seed) that take two or more values, or ``all``."""
    others = [k for k in varied if k not in keys and k not in seed_keys
              and df[k].astype(str).nunique() >= 2]
    if not others:
        return [("all", df)]
    return [(", ".join(f"{k}={v}" for k, v in
                       zip(others, g if isinstance(g, tuple) else (g,), strict=True)), sub)
            for g, sub in df.groupby(others, sort=False)]


def _study_blocks(study_row: tuple, ok, varied: list[str], seed_keys: list[str], rep: Path,
                  fit_rows: list[dict]) -> list[tuple[str, Any]]:
    """One study of :data:`_STUDIES` (velocity, load or roughness): its slope fits of the
    block and plate levels (dB per doubling of x) per group, appended to ``fit_rows``, its
    figure ``rep/<study>.png`` and its report blocks; none if its key does not vary over
    two or more successful cases (``ok``)."""
    study, keys, measured, xlabel = study_row
    key = next((k for k in keys if k in varied and ok[k].nunique() >= 2), None)
    if key is None:
        return []
    df = ok.copy()
    xcol = key
    if measured and measured in df and df[measured].notna().all() \
            and (df[measured] > 0).all():
        xcol = measured
    df = df[df[xcol] > 0]
    seed_col = seed_keys[0] if seed_keys and df[seed_keys[0]].nunique() >= 2 else None
    groups = _study_groups(df, keys, varied, seed_keys)
    fits = {}
    for which, col in _LEVELS:
        for label, sub in groups:
            sub = sub[sub[col].notna()]
            if sub[xcol].nunique() < 2:
                continue
            f = _fit(sub[xcol], sub[col], sub[seed_col] if seed_col else None)
            fits[(which, label)] = f
            fit_rows.append({"study": study, "x": xcol, "quantity": f"{which} level",
                             "group": label, **{k: v for k, v in f.items()
                                                if k != "per_seed"},
                             "per_seed": " ".join(f"{s:.3f}" for s in f["per_seed"])})
    png = rep / f"{study}.png"
    study_figure(study, xlabel if xcol == measured or not measured else
                 f"{key} (target)", groups, xcol, seed_col, fits, png, _LEVELS)
    blocks: list[tuple[str, Any]] = []
    blocks.append(("h2", f"{study.capitalize()}: total levels vs {xlabel.split(' [')[0]}"))
    blocks.append(("p", f"x = `{xcol}`" + (f" (measured; the target `{key}` is in the "
                                             f"table)" if xcol != key else "")
                   + (f"; seeds: `{seed_col}`" if seed_col else "")
                   + f"; {len(df)} successful cases."))
    blocks.append(("img", png.name))
    header = ["quantity", "group", "dB per doubling", "95 % interval",
              "n (a² ∝ x^n)", "how"]
    rows = [[f"{w} level", lab, _g(f["db_per_doubling"], ".2f"),
             f"[{_g(f['ci_low'], '.2f')}, {_g(f['ci_high'], '.2f')}]"
             if math.isfinite(f["ci_low"]) else "n/a",
             _g(f["exponent_power"], ".2f"), f["method"]]
            for (w, lab), f in fits.items()]
    blocks.append(("table", (header, rows)))
    if study == "velocity":
        blocks.append(("p", "The paper reads its velocity study on the power basis: a² ∝ "
                            "v^n with n = 3 to 3.5, i.e. 9 to 10.5 dB per doubling."))
    return blocks


def _case_blocks(table, varied: list[str]) -> list[tuple[str, Any]]:
    """The report's tables of cases: the failed or missing ones with their messages, then
    every case with its varied keys, status, levels [dB re 1e-6 m/s^2], friction velocity
    [m/s], stick fraction and wall time [s]."""
    blocks: list[tuple[str, Any]] = []
    failed = table[table["status"] != SUCCESS]
    if len(failed):
        blocks.append(("h2", f"Failed or missing cases ({len(failed)})"))
        blocks.append(("table", (["case", "status", "message"],
                                 [[r["case"], r["status"], r["message"]]
                                  for _, r in failed.iterrows()])))
    blocks.append(("h2", "Cases"))
    cols = [("block dB", _LEVELS[0][1]), ("plate dB", _LEVELS[1][1]),
            ("v_rms m/s", "block_tangential_velocity_rms"), ("stick", "stick_fraction"),
            ("wall s", "wall_time")]
    blocks.append(("table", (["case", *varied, "status", *(c for c, _ in cols)],
                             [[r["case"], *(_g(r[k]) for k in varied), r["status"],
                               *(_g(r[c]) for _, c in cols)] for _, r in table.iterrows()])))
    return blocks
