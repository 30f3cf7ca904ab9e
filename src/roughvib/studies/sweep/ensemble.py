"""Roughness ensembles: many draws of a random surface, their mean and spread.

A run on synthetic roughness is one draw (``roughness.seed``) of a random surface, and the
levels of different draws differ by more than the solver error. An *ensemble* is a sweep in
which a ``*.seed`` key varies: :func:`seed_sweep` makes one from a scene (``roughvib run SCENE
--seeds N``), and :func:`ensemble_tables` reduces the case directories of any such sweep to the
mean and spread over the seeds, per group of the other varied keys:

* the total block and plate levels (mean, standard deviation, min, max);
* per run, the contact count, micro-contacts, total stiffness, the spring-mass and the
  measured (transmissibility) contact resonance, lift-offs and the loudest bands;
* the third-octave band spectra of block and plate (IEC 61260-1 filter bank, as in the run
  report):
  mean, standard deviation, min and max of the band levels in dB.

The sweep report (:mod:`roughvib.studies.sweep.report`) shows these tables and the figure of
:func:`roughvib.views.ensemble.ensemble_figure`.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from roughvib.scene import SceneError, load_scene
from roughvib.studies.sweep.spec import CASES_DIR, SUCCESS, Sweep, load_sweep

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

__all__ = ["EnsembleTables", "case_row", "ensemble_tables", "seed_sweep"]

SEED_KEY = "roughness.seed"
#: summary level columns: (name, column of sweep.csv)
LEVELS = (("block", "block_vertical_acceleration_level_db_re_1e-6"),
          ("plate", "plate_vertical_acceleration_level_db_re_1e-6"))


def seed_sweep(scene: str | os.PathLike, seeds: int,
               overrides: dict[str, Any] | None = None) -> Sweep:
    """The ensemble of a scene over ``roughness.seed`` = 1 ... seeds, as a sweep.

    Parameters
    ----------
    scene : str or path
        Built-in scene name or scene file (the sweep's base).
    seeds : int
        Number of draws (>= 2). Seed 1 is the scene's default draw.
    overrides : dict, optional
        Fixed values for every case (dotted keys), e.g. ``{"solver.method": "adaptive-modal"}``.

    Returns
    -------
    Sweep
        Named ``<scene name>-seeds``; grid ``roughness.seed = [1, ..., seeds]``.

    Raises
    ------
    SceneError
        seeds < 2, an unknown scene or key, a scene whose roughness is not synthetic, or
        ``roughness.seed`` among the overrides.
    """
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 2:
        raise SceneError(f"--seeds must be an integer >= 2 (an ensemble of draws), got "
                         f"{seeds!r}")
    overrides = dict(overrides or {})
    if SEED_KEY in overrides:
        raise SceneError(f"--seeds varies {SEED_KEY} itself; do not also set it, got "
                         f"{SEED_KEY}={overrides[SEED_KEY]!r}")
    base = load_scene(scene, overrides)
    if base.roughness.kind != "synthetic":
        raise SceneError(f"--seeds needs random roughness: roughness.kind must be 'synthetic', "
                         f"got {base.roughness.kind!r}")
    src = str(scene)
    if Path(src).is_file():
        src = str(Path(src).resolve())
    return load_sweep({"name": f"{base.name}-seeds",
                       "description": f"{base.name}: ensemble over roughness seeds 1-{seeds}",
                       "base": src, "set": overrides,
                       "grid": {SEED_KEY: list(range(1, seeds + 1))}})


@dataclass(frozen=True)
class EnsembleTables:
    """Mean and spread of an ensemble (see :func:`ensemble_tables`).

    Attributes
    ----------
    runs : pandas.DataFrame
        One row per successful case: ``case``, ``group``, the seed, the levels, ``v_rms``,
        ``contacts``, ``micro_contacts``, ``stiffness_total`` [N/m], ``resonance_spring_mass``
        and ``resonance_transmissibility`` [Hz], ``lift_offs``, ``loudest_block``,
        ``loudest_plate`` [Hz].
    levels : pandas.DataFrame
        Per group and level (block, plate): ``n``, ``mean``, ``std`` (ddof = 1), ``min``,
        ``max``, ``range`` [dB re 1e-6 m/s^2].
    bands : pandas.DataFrame
        Per group, level and third-octave band centre [Hz]: ``n``, ``mean``, ``std``, ``min``,
        ``max`` of the band level [dB re 1e-6 m/s^2].
    seed_key : str
    group_keys : list of str
        The other varied keys; ``group`` is their values joined, or ``"all"``.
    """

    runs: pd.DataFrame
    levels: pd.DataFrame
    bands: pd.DataFrame
    seed_key: str
    group_keys: list[str]


def _spread(values) -> dict[str, float]:
    import numpy as np

    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"n": 0, "mean": math.nan, "std": math.nan, "min": math.nan, "max": math.nan}
    return {"n": int(v.size), "mean": float(v.mean()),
            "std": float(v.std(ddof=1)) if v.size > 1 else math.nan,
            "min": float(v.min()), "max": float(v.max())}


def case_row(result) -> tuple[dict[str, Any], Any]:
    """Per-run numbers of one successful run and its band spectra: what
    :func:`ensemble_tables` takes from each case.

    A sweep's worker computes it from the result it holds in memory (``run_sweep(...,
    case_rows=True)``), so that the client need not load every case again; the result read
    back from the case directory gives the same numbers (its files hold the same float64
    values; tested).

    Parameters
    ----------
    result : Result
        A successful run.

    Returns
    -------
    tuple
        ``(row, (centres, block_db, plate_db))``: a dict of per-run numbers (rms velocity,
        contacts, micro-contacts, total stiffness [N/m], spring-mass and transmissibility
        resonance [Hz], lift-offs, loudest bands [Hz]) and the third-octave band centres [Hz]
        with the block and plate band levels [dB re 1e-6 m/s^2], each of shape (B,).
    """
    from roughvib.analysis import figures_data as fd

    sp = fd.acceleration_spectra(result)
    cr = fd.contact_resonance(result, spectra=sp)
    s = result.summary
    mo = s.get("model", {})
    c = mo.get("contact", {})
    m = s.get("metrics", {})
    row = {"v_rms": m.get("block_tangential_velocity_rms"),
           "contacts": mo.get("contacts"),
           "micro_contacts": c.get("micro_contacts"),
           "stiffness_total": mo.get("contact_stiffness_total"),
           "resonance_spring_mass": cr.spring_mass,
           "resonance_transmissibility": cr.transmissibility_peak,
           "lift_offs": int(s.get("events_by_kind", {}).get("lift_off", 0)),
           "loudest_block": cr.block_maximum, "loudest_plate": cr.plate_maximum}
    return row, (sp.centres, sp.band_db["block"], sp.band_db["plate"])


def _run_row(case_dir: Path) -> tuple[dict[str, Any], Any]:
    """:func:`case_row` of a case directory (its result loaded and checked)."""
    from roughvib.results import load_result

    return case_row(load_result(case_dir))


def ensemble_tables(directory: str | os.PathLike, *,
                    rows: Mapping[str, Any] | None = None) -> EnsembleTables | None:
    """Mean and spread over the seeds of a sweep directory.

    Parameters
    ----------
    directory : path
        A sweep directory (``sweep.json``, ``sweep.csv``, ``cases/``).
    rows : mapping, optional
        :func:`case_row` of cases by case name, as the workers computed them
        (:attr:`SweepRun.rows <roughvib.studies.sweep.run.SweepRun>`); the other successful
        cases are read from their directories.

    Returns
    -------
    EnsembleTables or None
        None when no ``*.seed`` key varies over at least two successful cases.
    """
    import numpy as np
    import pandas as pd

    d = Path(directory)
    meta = json.loads((d / "sweep.json").read_text())
    table = pd.read_csv(d / "sweep.csv", keep_default_na=False,
                        na_values=[""]).astype({"status": str})
    ok = table[table["status"] == SUCCESS]
    seed_key = next((k for k in meta.get("seed_keys", [])
                     if k in ok.columns and ok[k].nunique() >= 2), None)
    if seed_key is None:
        return None
    group_keys = [k for k in meta.get("varied_keys", [])
                  if k != seed_key and k in ok.columns and ok[k].astype(str).nunique() >= 2]
    given = dict(rows or {})
    rows, band_rows = [], []
    for _, r in ok.iterrows():
        group = ", ".join(f"{k}={r[k]}" for k in group_keys) or "all"
        pre = given.get(r["case"])
        extra, (fc, bb, bp) = pre if pre is not None else _run_row(d / CASES_DIR / r["case"])
        rows.append({"case": r["case"], "group": group, seed_key: r[seed_key],
                     "block_db": r[LEVELS[0][1]], "plate_db": r[LEVELS[1][1]], **extra})
        for which, lev in (("block", bb), ("plate", bp)):
            band_rows += [{"group": group, "level": which, "centre": float(f), "db": float(x)}
                          for f, x in zip(fc, lev, strict=True) if np.isfinite(x)]
    runs = pd.DataFrame(rows)
    lev_rows = [{"group": g, "level": which, **_spread(sub[f"{which}_db"])}
                for g, sub in runs.groupby("group", sort=False) for which, _ in LEVELS]
    levels = pd.DataFrame(lev_rows)
    levels["range"] = levels["max"] - levels["min"]
    bands = pd.DataFrame(band_rows)
    if len(bands):
        bands = pd.DataFrame([{"group": g, "level": w, "centre": f, **_spread(sub["db"])}
                              for (g, w, f), sub in bands.groupby(["group", "level", "centre"],
                                                                 sort=False)])
    return EnsembleTables(runs=runs, levels=levels, bands=bands, seed_key=seed_key,
                          group_keys=group_keys)


def _g(v: Any, fmt: str = ".4g") -> str:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return "n/a" if not math.isfinite(f) else format(f, fmt)


def _band_cell(t, f: float) -> str:
    """``mean ± std`` of band ``f`` in a per-band table indexed by centre ('' if absent)."""
    if f not in t.index:
        return ""
    r = t.loc[f]
    return f"{_g(r['mean'], '.1f')} ± {_g(r['std'], '.1f')}"


def ensemble_blocks(ens: EnsembleTables, rep: Path) -> list[tuple[str, Any]]:
    """The ensemble section of the sweep report; writes its CSV files and figure.

    Parameters
    ----------
    ens : EnsembleTables
    rep : Path
        The report directory: ``ensemble_levels.csv``, ``ensemble_runs.csv``,
        ``ensemble_bands.csv`` and ``ensemble.png`` go there.

    Returns
    -------
    list of (kind, payload)
        Blocks for :mod:`roughvib.views.sweep_report`.

    Raises
    ------
    roughvib.rundir.WriteError
        A file cannot be written (a full disk): one line naming it.
    """
    from roughvib.analysis.spectra import nominal_centre
    from roughvib.rundir import writing
    from roughvib.views.ensemble import ensemble_figure

    for name, frame in (("levels", ens.levels), ("runs", ens.runs), ("bands", ens.bands)):
        with writing(rep / f"ensemble_{name}.csv") as fh:  # complete or not at all
            frame.to_csv(fh, index=False, float_format="%.6g")
    blocks: list[tuple[str, Any]] = [
        ("h2", "Ensemble over roughness seeds: mean and spread"),
        ("p", f"Each case is one draw of the random surface (`{ens.seed_key}`); the spread "
              f"over the draws is the uncertainty of a single run's levels. std: sample "
              f"standard deviation (ddof = 1); levels in dB re 1e-6 m/s². Files: "
              f"`ensemble_levels.csv`, `ensemble_runs.csv`, `ensemble_bands.csv`."),
        ("table", (["group", "level", "n", "mean [dB]", "std [dB]", "min [dB]", "max [dB]",
                    "range [dB]"],
                   [[r["group"], r["level"], str(r["n"]), _g(r["mean"], ".1f"),
                     _g(r["std"], ".2f"), _g(r["min"], ".1f"), _g(r["max"], ".1f"),
                     _g(r["range"], ".1f")] for _, r in ens.levels.iterrows()])),
    ]
    if len(ens.bands):
        ensemble_figure(ens.bands, rep / "ensemble.png")
        blocks.append(("img", "ensemble.png"))
    blocks.append(("p", "Per run: contact points N and micro-contacts n_c of the statistical "
                        "model, total contact stiffness, the rigid-plate spring-mass resonance "
                        "sqrt(s_closed/m)/2π and the peak of the measured block/contact-base "
                        "transmissibility, lift-offs, loudest third-octave bands."))
    blocks.append(("table", (
        ["case", "group", "seed", "block dB", "plate dB", "N", "n_c", "s_total N/m",
         "f spring-mass Hz", "f transmissibility Hz", "lift-offs", "loudest block Hz",
         "loudest plate Hz"],
        [[r["case"], r["group"], _g(r[ens.seed_key]), _g(r["block_db"], ".1f"),
          _g(r["plate_db"], ".1f"), _g(r["contacts"]), _g(r["micro_contacts"], ".3g"),
          _g(r["stiffness_total"]), _g(r["resonance_spring_mass"], ".0f"),
          _g(r["resonance_transmissibility"], ".0f"), _g(r["lift_offs"]),
          _g(r["loudest_block"], ".0f"), _g(r["loudest_plate"], ".0f")]
         for _, r in ens.runs.iterrows()])))
    for g in dict.fromkeys(ens.bands["group"]) if len(ens.bands) else []:
        sub = ens.bands[ens.bands["group"] == g]
        piv = {w: sub[sub["level"] == w].set_index("centre") for w in ("block", "plate")}
        centres = sorted(set(piv["block"].index) | set(piv["plate"].index))

        blocks.append(("p", f"Third-octave band levels, {g}: mean ± std over the seeds "
                            f"[dB re 1e-6 m/s²]."))
        blocks.append(("table", (["band centre [Hz]", "block", "plate"],
                                 [[_g(nominal_centre(f), "g"),
                                   _band_cell(piv["block"], f),
                                   _band_cell(piv["plate"], f)] for f in centres])))
    return blocks
