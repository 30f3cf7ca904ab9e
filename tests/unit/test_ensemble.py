"""Roughness ensembles: ``roughvib run SCENE --seeds N`` and the ensemble section of a sweep
report. The mean, spread and band spectra are checked against numpy over the case files."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import roughvib
from roughvib.cli import main
from roughvib.physics.surface.contact import contact_stiffness
from roughvib.scene import SceneError
from roughvib.studies.sweep import run as sweep_run
from roughvib.studies.sweep.ensemble import _run_row, ensemble_tables, seed_sweep

distributed = pytest.importorskip("dask.distributed")

FAST = {"output.duration": 0.05, "output.transient": 0.0, "plate.max_frequency": 3000.0,
        "solver.atol_acceleration": 1e-5, "solver.method": "adaptive-modal"}


def test_seed_sweep_is_the_seed_grid_of_the_scene_and_rejects_bad_input():
    spec = seed_sweep("paper", 4, {"output.duration": 0.1})
    assert spec.name == "paper-seeds" and spec.grid == {"roughness.seed": [1, 2, 3, 4]}
    assert spec.fixed == {"output.duration": 0.1}
    assert [c.values["roughness.seed"] for c in spec.cases()] == [1, 2, 3, 4]
    for seeds, over, fragment in ((1, {}, "--seeds must be an integer >= 2"),
                                  (3, {"roughness.seed": 5}, "do not also set it"),
                                  (3, {"roughness.kind": "none"}, "needs random roughness")):
        with pytest.raises(SceneError, match=fragment) as info:
            seed_sweep("paper", seeds, over)
        assert "\n" not in str(info.value)


@pytest.fixture(scope="module")
def ensemble(tmp_path_factory):
    """``roughvib run paper --seeds 3`` on a 1-worker cluster shared with nothing else."""
    out = tmp_path_factory.mktemp("ens") / "paper-seeds"
    mp = pytest.MonkeyPatch()
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None,
                                  env=dict(sweep_run.THREAD_ENV)) as cluster, \
            distributed.Client(cluster) as client:
        real = sweep_run.run_sweep
        runs = []

        def run_sweep(spec, o, **kw):
            runs.append(real(spec, o, **{**kw, "client": client}))
            return runs[-1]

        mp.setattr(sweep_run, "run_sweep", run_sweep)
        args = ["run", "paper", "--seeds", "3", "--out", str(out), "--no-progress"]
        for k, v in FAST.items():
            args += ["--set", f"{k}={v}"]
        import contextlib
        import io

        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            code = main(args)
        mp.undo()
    return out, code, buf.getvalue(), runs[0]


def test_run_seeds_writes_one_case_per_seed_and_the_spread(ensemble):
    out, code, printed, _ = ensemble
    assert code == 0
    table = pd.read_csv(out / "sweep.csv")
    assert sorted(table["roughness.seed"]) == [1, 2, 3]
    assert (table["status"] == "success").all()
    levels = pd.read_csv(out / "report" / "ensemble_levels.csv")
    for which in ("block", "plate"):
        x = table[f"{which}_vertical_acceleration_level_db_re_1e-6"].to_numpy()
        row = levels[levels["level"] == which].iloc[0]
        assert row["n"] == 3
        # the CSV holds 6 significant digits
        assert row["mean"] == pytest.approx(x.mean(), rel=1e-5)
        assert row["std"] == pytest.approx(x.std(ddof=1), rel=1e-5, abs=1e-5)
        assert row["range"] == pytest.approx(np.ptp(x), rel=1e-5, abs=1e-5)
        # the printed summary
        assert f"{which} level  mean {x.mean():6.1f} dB, std {x.std(ddof=1):4.2f} dB" in printed
    html = (out / "report" / "report.html").read_text()
    assert "Ensemble over roughness seeds" in html and "ensemble.png" in html


def test_ensemble_runs_record_contact_and_bands_are_the_mean_over_seeds(ensemble):
    out, _, _, _ = ensemble
    from roughvib.analysis import figures_data as fd

    ens = ensemble_tables(out)
    scene = roughvib.load_scene("paper", FAST)
    cs = contact_stiffness(scene)
    assert list(ens.runs["contacts"]) == [cs.points] * 3
    np.testing.assert_allclose(ens.runs["stiffness_total"], cs.s_total, rtol=1e-12)
    np.testing.assert_allclose(ens.runs["resonance_spring_mass"],
                               math.sqrt(cs.s_total / scene.block.mass) / (2 * math.pi),
                               rtol=1e-12)  # one contact, always closed here
    per_case = [fd.acceleration_spectra(roughvib.load_result(out / "cases" / c))
                for c in ens.runs["case"]]
    bands = pd.read_csv(out / "report" / "ensemble_bands.csv")
    plate = bands[bands["level"] == "plate"].set_index("centre")
    centres = per_case[0].centres
    for j in np.flatnonzero(np.isfinite(per_case[0].band_db["plate"])):
        x = np.array([sp.band_db["plate"][j] for sp in per_case])
        row = plate.loc[plate.index[np.argmin(np.abs(plate.index - centres[j]))]]
        assert row["mean"] == pytest.approx(x.mean(), rel=1e-5, abs=1e-4)
        assert row["std"] == pytest.approx(x.std(ddof=1), rel=1e-5, abs=1e-4)


def test_ensemble_numbers_from_the_workers_are_those_read_back_from_the_cases(ensemble):
    """``--seeds`` takes each case's numbers from the worker that ran it (the result in
    memory), not by loading every case again: they must be exactly what the case files give."""
    out, _, _, run = ensemble
    assert sorted(run.rows) == sorted(pd.read_csv(out / "sweep.csv")["case"])
    handed = ensemble_tables(out, rows=run.rows)
    read = ensemble_tables(out)
    for name in ("runs", "levels", "bands"):
        pd.testing.assert_frame_equal(getattr(handed, name), getattr(read, name),
                                      check_exact=True)
    for case, (row, spectra) in run.rows.items():
        (row2, spectra2) = _run_row(out / "cases" / case)
        assert row == row2
        for a, b in zip(spectra, spectra2, strict=True):
            np.testing.assert_array_equal(a, b)


def test_single_draw_note_only_for_random_surfaces():
    from roughvib.analysis.levels import single_draw_note

    def summary(**prof):
        return {"scene": "my-scene", "model": {"profile": prof}}

    note = single_draw_note(summary(kind="synthetic", seed=7))
    # not made by 'roughvib run' (no run_command): the saved scene, not the scene's name,
    # which need not be a built-in
    assert "roughness.seed = 7" in note and "my-scene" not in note
    assert note.endswith("seed-to-seed spread: roughvib run RUN_DIR/scene.toml --seeds 10")
    ran = {**summary(kind="synthetic", seed=7), "run_command": "roughvib run s.toml --set a=1"}
    assert single_draw_note(ran).endswith("roughvib run s.toml --set a=1 --seeds 10")
    for kind in ("none", "sinusoid", "file"):
        assert single_draw_note(summary(kind=kind)) is None
    assert single_draw_note({}) is None
