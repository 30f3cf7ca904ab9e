"""`roughvib compare` on a tiny scene with a small budget: CSV, table, figure, failed rows,
presets, a budget that bounds the reference."""

import time

import pandas as pd

from roughvib.cli import main

TINY = ["--set", "output.duration=0.01", "--set", "plate.max_frequency=2000",
        "--set", "excitation.force_amplitude=0.915",
        "--set", "excitation.target_rms_velocity=none", "--set", "output.transient=0",
        "--set", "contact.velocity_factor=false"]  # no velocity target to scale with


def test_compare_writes_csv_table_and_figure(tmp_path, capsys):
    out = tmp_path / "wp"
    code = main(["compare", "paper", "--out", str(out), "--budget", "300", "--no-progress",
                 "--rtols", "1e-4,1e-6", "--steps", "1e-4,1e-5,2.5e-6",
                 "--methods", "ida,adaptive-modal,exact-modal,newmark", *TINY])
    assert code == 0
    table = pd.read_csv(out / "work_precision.csv", keep_default_na=False,
                        na_values=[""])
    assert set(table["method"]) == {"ida", "adaptive-modal", "exact-modal", "newmark"}
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


def test_compare_failed_run_is_a_row(tmp_path):
    # a step that does not divide the output step makes those runs fail; the study goes on
    out = tmp_path / "wp2"
    code = main(["compare", "paper", "--out", str(out), "--budget", "120", "--no-progress",
                 "--rtols", "1e-5", "--steps", "3e-6", "--methods", "ida,newmark",
                 "--no-presets", *TINY])
    assert code == 0
    table = pd.read_csv(out / "work_precision.csv")
    bad = table[table["method"] == "newmark"]
    assert (bad["status"] == "error").all()
    assert bad["message"].str.contains("solver.step must divide output.step").all()
    assert (table[table["method"] == "ida"]["status"] == "success").all()


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
