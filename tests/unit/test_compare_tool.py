"""`roughvib compare` on a tiny scene with a small budget: CSV, table, figure, failed rows."""

import pandas as pd

from roughvib.cli import main

TINY = ["--set", "output.duration=0.01", "--set", "plate.max_frequency=2000",
        "--set", "excitation.force_amplitude=0.915",
        "--set", "excitation.target_rms_velocity=none", "--set", "output.transient=0",
        "--set", "contact.velocity_factor=false"]  # no velocity target to scale with


def test_compare_writes_csv_table_and_figure(tmp_path, capsys):
    out = tmp_path / "wp"
    code = main(["compare", "paper", "--out", str(out), "--budget", "60", "--no-progress",
                 "--rtols", "1e-4,1e-6", "--steps", "1e-4,1e-5,2.5e-6",
                 "--methods", "ida,adaptive-modal,exact-modal,newmark", *TINY])
    assert code == 0
    table = pd.read_csv(out / "work_precision.csv")
    assert set(table["method"]) == {"ida", "adaptive-modal", "exact-modal", "newmark"}
    assert len(table) == 2 + 2 + 3 + 3
    assert set(table[table["method"] == "adaptive-modal"]["setting_name"]) == {"rtol"}
    ok = table[table["status"] == "success"]
    assert len(ok) >= 8
    # errors shrink along each ladder (finest vs coarsest run of each method)
    for m, g in ok.groupby("method"):
        g = g.sort_values("setting", ascending=False)  # coarsest setting first
        assert g["velocity_rel_rms"].iloc[-1] < g["velocity_rel_rms"].iloc[0], m
    # a step longer than the output step still gives band errors below its Nyquist
    coarse = ok[(ok["method"] == "exact-modal") & (ok["setting"] == 1e-4)]
    assert coarse["block_band_db_100_20k"].notna().all()
    assert (out / "work_precision.md").read_text().startswith("# Work-precision")
    assert (out / "work_precision.png").stat().st_size > 10_000
    assert (out / "reference" / "result.nc").exists()
    assert "runs succeeded" in capsys.readouterr().out


def test_compare_failed_run_is_a_row(tmp_path):
    # a step that does not divide the output step makes those runs fail; the study goes on
    out = tmp_path / "wp2"
    code = main(["compare", "paper", "--out", str(out), "--budget", "60", "--no-progress",
                 "--rtols", "1e-5", "--steps", "3e-6", "--methods", "ida,newmark", *TINY])
    assert code == 0
    table = pd.read_csv(out / "work_precision.csv")
    bad = table[table["method"] == "newmark"]
    assert (bad["status"] == "error").all()
    assert bad["message"].str.contains("solver.step must divide output.step").all()
    assert (table[table["method"] == "ida"]["status"] == "success").all()
