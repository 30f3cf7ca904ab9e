"""The sweep report's data: which studies (velocity, load, roughness) the sweep holds, their
points, groups and slope fits, the tables of cases; rendered by
:mod:`roughvib.views.sweep_report`."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from roughvib.studies.sweep.ensemble import ensemble_blocks, ensemble_tables
from roughvib.studies.sweep.spec import SUCCESS, _replace_file
from roughvib.studies.sweep.tables import _fit
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


def _g(v: Any, fmt: str = ".4g") -> str:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return "" if math.isnan(f) else format(f, fmt)


def sweep_report(directory: str | os.PathLike) -> Path:
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

    Returns
    -------
    Path
        ``DIR/report/report.md``; next to it ``report.html``, ``fits.csv`` and one PNG per
        study (``velocity.png``, ``load.png``, ``roughness.png``).

    Raises
    ------
    FileNotFoundError
        ``directory`` holds no sweep.csv / sweep.json.
    """
    import pandas as pd

    d = Path(directory)
    if not (d / "sweep.csv").is_file() or not (d / "sweep.json").is_file():
        raise FileNotFoundError(f"{d} is not a sweep directory (no sweep.csv / sweep.json)")
    meta = json.loads((d / "sweep.json").read_text())
    table = pd.read_csv(d / "sweep.csv", keep_default_na=False,
                        na_values=[""]).astype({"status": str, "message": str})
    varied = [k for k in meta.get("varied_keys", []) if k in table.columns]
    seed_keys = [k for k in meta.get("seed_keys", []) if k in table.columns]
    ok = table[table["status"] == SUCCESS]
    rep = d / "report"
    rep.mkdir(exist_ok=True)

    blocks: list[tuple[str, Any]] = []  # (kind, payload): h2, p, table, img
    fit_rows = []
    for study, keys, measured, xlabel in _STUDIES:
        key = next((k for k in keys if k in varied and ok[k].nunique() >= 2), None)
        if key is None:
            continue
        df = ok.copy()
        xcol = key
        if measured and measured in df and df[measured].notna().all() \
                and (df[measured] > 0).all():
            xcol = measured
        df = df[df[xcol] > 0]
        seed_col = seed_keys[0] if seed_keys and df[seed_keys[0]].nunique() >= 2 else None
        others = [k for k in varied if k not in keys and k not in seed_keys
                  and df[k].astype(str).nunique() >= 2]
        if others:
            groups = [(", ".join(f"{k}={v}" for k, v in
                                 zip(others, g if isinstance(g, tuple) else (g,), strict=True)),
                       sub) for g, sub in df.groupby(others, sort=False)]
        else:
            groups = [("all", df)]
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
    if not fit_rows:
        blocks.append(("p", "No velocity, load or roughness key varies over two or more "
                            "successful cases; nothing to fit."))
    # the header also when nothing was fitted (an ensemble of one setting): an empty table
    pd.DataFrame(fit_rows, columns=FIT_COLUMNS).to_csv(rep / "fits.csv", index=False,
                                                       float_format="%.6g")

    if (ens := ensemble_tables(d)) is not None:
        blocks += ensemble_blocks(ens, rep)

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
