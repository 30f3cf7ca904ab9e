"""The source study: each variant changes its one source and keeps what the run resolved."""

import numpy as np
import pandas as pd
import pytest

import roughvib
from roughvib.cli import main
from roughvib.studies.sources import source_study, source_variants

#: a rigid base (no modes): five runs in seconds
CHEAP = {"plate.kind": "rigid", "output.duration": 2.0 / 7.0, "output.progress": False}


def test_the_variants_change_one_key_each_and_only_where_it_applies():
    paper = roughvib.load_scene("paper")
    names = [v.name for v in source_variants(paper)]
    assert names == ["as is", "tail", "contact filter", "stick-slip", "friction moment"]
    by = {v.name: v.scene for v in source_variants(paper)}
    assert by["tail"].roughness.shortest_wavelength == 50e-6
    assert by["contact filter"].contact.filter == "none"
    assert by["friction moment"].contact.friction_moment is True
    slide = by["stick-slip"].excitation
    assert slide.kind == "prescribed" and slide.velocity == 0.0
    assert slide.amplitude == pytest.approx(np.sqrt(2) * 0.01 / slide.omega)
    # a prescribed sliding has no stick-slip and no friction; the paper's band no tail
    pres = paper.with_overrides({"excitation.kind": "prescribed", "excitation.velocity": 0.01,
                                 "excitation.target_rms_velocity": "none",
                                 "roughness.shortest_wavelength": 50e-6})
    assert [v.name for v in source_variants(pres)] == ["as is", "contact filter"]
    # no solver integrates the moment of a dynamic law's force: no such variant
    lugre = paper.with_overrides({"friction.law": "lugre"})
    assert [v.name for v in source_variants(lugre)] == ["as is", "tail", "contact filter",
                                                        "stick-slip"]


@pytest.mark.short_run
def test_a_study_holds_the_run_as_it_is_and_its_variants(tmp_path, capsys):
    bands, runs = source_study(roughvib.load_scene("paper", CHEAP))
    assert list(runs["variant"]) == ["as is", "tail", "contact filter", "stick-slip"]
    assert (runs["status"] == "success").all()
    base = bands[bands["variant"] == "as is"]
    held = np.isfinite(base["level_db"])
    assert held.sum() > 20 and np.all(base["change_db"][held] == 0.0)
    # the surface below 50 um is the high bands' input: without it they fall far
    tail = bands[(bands["variant"] == "tail") & (bands["band_hz"] >= 2000.0)]
    assert tail["change_db"].max() < -20.0
    # the filter takes short wavelengths out: without it the high bands rise
    filt = bands[(bands["variant"] == "contact filter") & (bands["band_hz"] >= 4000.0)]
    assert filt["change_db"].min() > 0.0
    # the sinusoidal sliding does not stick
    slide = runs.set_index("variant").loc["stick-slip"]
    assert slide["stick_fraction"] < 0.05 < runs.set_index("variant").loc["as is",
                                                                           "stick_fraction"]
    # the command writes its files, and does not replace them without --overwrite
    out = tmp_path / "src"
    sets = [x for k, v in CHEAP.items() if k != "output.progress"
            for x in ("--set", f"{k}={v}")]
    assert main(["sources", "paper", "--out", str(out), "--no-progress", *sets]) == 0
    for name in ("sources.csv", "sources_runs.csv", "sources.png"):
        assert (out / name).is_file()
    assert len(pd.read_csv(out / "sources_runs.csv")) == 4
    assert main(["sources", "paper", "--out", str(out), "--no-progress", *sets]) == 2
    assert "--overwrite" in capsys.readouterr().err


@pytest.mark.short_run
def test_a_study_of_a_run_directory_lands_beside_it_and_in_its_report(tmp_path, capsys):
    """``roughvib sources DIR`` reruns DIR's scene.toml into DIR; the report of DIR then has a
    source section whose run as it is reproduces the run's overall levels (the same scene,
    deterministic), and says so when a study of another scene lies there."""
    from roughvib.views.report import write_report

    run = tmp_path / "run"
    sets = [x for k, v in CHEAP.items() if k != "output.progress"
            for x in ("--set", f"{k}={v}")]
    assert main(["run", "paper", "--out", str(run), "--no-progress", *sets]) == 0
    assert main(["sources", str(run), "--no-progress"]) == 0
    html = write_report(run).read_text()
    section = html[html.index("Where the band energy comes from"):]
    assert "fig-sources" in section and "made for another scene" not in section
    # a study of another scene (a heavier block) in the same directory is flagged
    assert main(["sources", str(run), "--no-progress", "--overwrite",
                 "--set", "block.mass=1.0"]) == 0
    html = write_report(run, overwrite=True).read_text()
    assert "made for another scene" in html
    # a scene without --out, and a directory that is not a run, are refused in one line
    assert main(["sources", "paper", "--no-progress"]) == 2
    (tmp_path / "empty").mkdir()
    assert main(["sources", str(tmp_path / "empty"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "--out is required" in err[-2] and "without scene.toml" in err[-1]
