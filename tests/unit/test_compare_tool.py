"""`roughvib compare` on a tiny scene with a small budget: CSV, table, figure, failed rows,
presets, a budget that bounds the reference."""

import time

import pandas as pd

from roughvib.cli import main

TINY = ["--set", "output.duration=0.01", "--set", "plate.max_frequency=2000",
        "--set", "excitation.force_amplitude=0.915",
        "--set", "excitation.target_rms_velocity=none", "--set", "output.transient=0",
        "--set", "contact.velocity_factor=false"]  # no velocity target to scale with


#: a step that does not divide the output step (1e-5 s): the fixed-step runs at it fail
BAD_STEP = 3e-6


def test_compare_writes_csv_table_and_figure_and_a_failed_run_is_a_row(tmp_path, capsys):
    """The whole study, with a failed rung in the middle of the fixed-step ladders.

    The failed-row check used to be a study of its own (ida and newmark, no presets); it is
    one more rung here (the same study code, the same scene), which saves a worker process,
    a reference run and the warm-ups (6.9 s measured), and shows in addition that the runs
    after the failed ones still succeed."""
    out = tmp_path / "wp"
    code = main(["compare", "paper", "--out", str(out), "--budget", "300", "--no-progress",
                 "--rtols", "1e-4,1e-6", "--steps", f"1e-4,1e-5,{BAD_STEP},2.5e-6",
                 "--methods", "ida,adaptive-modal,exact-modal,newmark", *TINY])
    assert code == 0
    table = pd.read_csv(out / "work_precision.csv", keep_default_na=False,
                        na_values=[""])
    assert set(table["method"]) == {"ida", "adaptive-modal", "exact-modal", "newmark"}
    # the failed runs are rows with their message; the study went on past them
    bad = table[table["setting"] == BAD_STEP]
    assert set(bad["method"]) == {"exact-modal", "newmark"}
    assert (bad["status"] == "error").all()
    assert bad["message"].str.contains("solver.step must divide output.step").all()
    assert (table[table["setting"] != BAD_STEP]["status"] == "success").all()
    later = table.index > bad.index.max()
    assert (table[later]["status"] == "success").sum() >= 2
    assert set(table[table["method"] == "adaptive-modal"]["setting_name"]) == {"rtol"}
    # each method runs its ladder and its three presets (a preset equal to a rung is one run)
    for m in ("ida", "adaptive-modal", "exact-modal", "newmark"):
        presets = "/".join(table[table["method"] == m]["preset"].fillna("").astype(str))
        for level in ("reference", "standard", "draft"):
            assert level in presets, (m, level)
    ok = table[table["status"] == "success"]
    assert len(ok) >= 14
    # errors shrink along each ladder (finest vs coarsest run of each method)
    for m, g in ok.groupby("method"):
        coarse, fine = g[g["setting"] == g["setting"].max()], g[g["setting"] == g["setting"].min()]
        assert fine["velocity_rel_rms"].max() < coarse["velocity_rel_rms"].min(), m
    # a step longer than the output step still gives band errors below its Nyquist
    coarse = ok[(ok["method"] == "exact-modal") & (ok["setting"] == 1e-4)]
    assert coarse["block_band_db"].notna().all()
    assert set(ok["verdict"]) <= {"pass", "fail"}
    assert (ok["contract_ratio"] > 0).all()
    assert (out / "work_precision.md").read_text().startswith("# Work-precision")
    assert (out / "work_precision.png").stat().st_size > 10_000
    assert (out / "reference" / "result.nc").exists()
    assert "runs succeeded" in capsys.readouterr().out


def test_budget_bounds_the_reference(tmp_path, capsys):
    """A reference that cannot finish within the budget is stopped at the budget, and the
    command says so in one line (exit status 1)."""
    out = tmp_path / "wp3"
    t0 = time.perf_counter()
    code = main(["compare", "paper", "--out", str(out), "--budget", "3", "--no-progress",
                 "--reference-method", "ida", "--methods", "ida",
                 "--set", "output.duration=0.2", "--set", "output.transient=0"])
    spent = time.perf_counter() - t0
    assert code == 1
    err = capsys.readouterr().err
    assert "did not finish within --budget 3 s" in err
    assert spent < 3 + 15  # the budget, plus stopping the child and the imports
