"""`roughvib compare` on a tiny scene with a small budget: CSV, table, figure, failed rows,
presets, a budget that bounds the reference."""

import time

import pandas as pd
import pytest

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


def test_the_budget_bounds_the_whole_study_and_the_last_line_says_why_runs_are_missing(
        tmp_path, monkeypatch):
    """The reference, the warm-ups, every run (measured in the worker, so its measurement is
    bounded too) and the figure share one deadline: the study ends EXIT_MARGIN before the
    budget, a run going at the deadline is stopped, the ones after it are skipped. A fake
    worker and a fake clock stand for the processes and the time: nothing here waits."""
    import roughvib.studies.compare as cmp
    from roughvib.scene import load_scene

    now = [100.0]
    monkeypatch.setattr(cmp.time, "perf_counter", lambda: now[0])
    jobs = []

    class Worker:
        def run(self, job, timeout):
            jobs.append((job, timeout, now[0]))
            kind, scene = job[0], job[1]
            if kind == "plot":
                cost, info = 2.0, {"status": "success"}
            elif job[2]:  # the reference (saved)
                cost, info = 10.0, {"status": "success"}
            elif job[4] is None:  # a warm-up
                cost, info = 0.5, {"status": "success"}
            else:
                s = scene.resolved_solver()
                cost = 1.0 if s.method != "ida" else 4.0 * (1e-3 / s.rtol) ** 0.5
                if s.method == "adaptive-modal" and s.rtol < 1e-4:
                    cost = 100.0  # far beyond its predicted cost: stopped at the deadline
                info = {"status": "success", "block_band_db": 0.1}
                if s.method == "newmark" and s.step == 5e-5:
                    info = {"status": "newton_failure", "message": "Newton did not converge"}
            if not timeout > 0:
                return {"status": "over_budget", "wall_time": 0.0}
            if cost > timeout:
                now[0] += timeout
                return {"status": "over_budget", "wall_time": timeout}
            now[0] += cost
            return {**info, "wall_time": cost}

        def close(self):
            pass

    monkeypatch.setattr(cmp, "_Worker", Worker)
    scene = load_scene("paper", {"output.duration": 0.01})
    budget = 60.0
    table = cmp.run_study(scene, tmp_path / "wp", budget=budget, progress=False,
                          started=now[0] - 1.0)  # the CLI's imports took 1 s
    end = 100.0 - 1.0 + budget
    assert now[0] <= end - cmp.EXIT_MARGIN
    runs = [(j, t, t0) for j, t, t0 in jobs if j[0] == "run" and j[4] is not None]
    ref_dir = str(tmp_path / "wp" / "reference")
    assert all(j[4] == (ref_dir, scene.period, scene.output.transient) for j, _, _ in runs)
    # every job may run to its deadline at the latest: the runs' leaves the figure its reserve
    runs_end = end - cmp.EXIT_MARGIN - cmp.FIGURE_RESERVE
    assert all(t0 + t <= runs_end + 1e-9 for _, t, t0 in runs)
    (_, t_plot, t0_plot), = [x for x in jobs if x[0][0] == "plot"]
    assert t0_plot + t_plot == pytest.approx(end - cmp.EXIT_MARGIN)
    status = table["status"].value_counts().to_dict()
    assert status["newton_failure"] == 1 and status["skipped"] >= 1
    assert status["over_budget"] == 1 and status["success"] >= 5
    stopped = table.index[table["status"] == "over_budget"][0]
    assert (table["status"].iloc[stopped + 1:] == "skipped").all()  # nothing after it
    line = cmp.outcome_line(table)
    assert line == (f"{status['success']} of {len(table)} runs succeeded; {status['skipped']} "
                    f"skipped and 1 stopped for the budget; 1 failed (newton_failure)")
    md = (tmp_path / "wp" / "work_precision.md").read_text()
    assert line in md and "figure was not drawn" not in md


def test_the_outcome_line_counts_each_way_a_run_ends():
    t = pd.DataFrame({"status": ["success"] * 3 + ["skipped"] * 2 + ["over_budget",
                                                                     "newton_failure",
                                                                     "newton_failure",
                                                                     "error"]})
    from roughvib.studies.compare import outcome_line

    assert outcome_line(t) == ("3 of 9 runs succeeded; 2 skipped and 1 stopped for the budget; "
                               "3 failed (2 newton_failure, error)")
    assert outcome_line(t[t["status"] == "success"]) == "3 of 3 runs succeeded"


def test_the_budget_counts_from_the_process_start_only_for_a_command_line(monkeypatch,
                                                                          tmp_path):
    """The console script's budget counts its imports (the process's start, from /proc); a
    call of main() from Python (a test, a notebook) counts from the call, not from whenever
    the calling process started."""
    import sys

    import roughvib.cli as cli
    import roughvib.studies.compare as cmp

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cli, "_process_age", lambda: 1000.0)
    seen = []

    def study(*a, started=None, **k):
        seen.append(time.perf_counter() - started)
        return pd.DataFrame({"method": ["ida"], "status": ["skipped"], "wall_time": [None],
                             **{m: [None] for m in cmp.METRICS}})

    monkeypatch.setattr(cmp, "run_study", study)
    assert main(["compare", "paper", "--out", "wp", "--no-progress"]) == 0
    monkeypatch.setattr(sys, "argv", ["roughvib", "compare", "paper", "--out", "wp",
                                      "--no-progress"])
    assert main() == 0
    assert seen[0] < 100.0 <= 1000.0 <= seen[1] < 1100.0
