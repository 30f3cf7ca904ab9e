"""What the run summary tells the user to do next names what the user ran: the scene file or
built-in name and the ``--set`` options, never the scene's ``name``, which need not be a
built-in. Each hinted command is parsed by the real parser and loads the scene that ran."""

from __future__ import annotations

import json
import shlex

import pytest

from roughvib.cli import build_parser, main
from roughvib.cli.args import parse_sets
from roughvib.scene import load_scene, scene_to_dict

SETS = ["output.duration=0.005", "plate.max_frequency=2000", "block.mass=0.3"]


def _hint(out: str) -> str:
    line = next(x for x in out.splitlines() if "seed-to-seed spread:" in x)
    return line.split("seed-to-seed spread: ", 1)[1]


def _scene_of(command: str):
    argv = shlex.split(command)
    assert argv[:2] == ["roughvib", "run"] and argv[-2:] == ["--seeds", "10"]
    args = build_parser().parse_args(argv[1:])
    return load_scene(args.scene or "paper", parse_sets(args.set))


@pytest.mark.parametrize("how", ["file", "builtin"])
def test_the_seed_hint_names_what_the_user_ran(how, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    sets = [w for v in [*SETS, "roughness.seed=4"] for w in ("--set", v)]
    if how == "file":
        (tmp_path / "my scene.toml").write_text('name = "light-block-fast"\n'
                                                '[excitation]\ntarget_rms_velocity = 0.02\n')
        scene_arg = ["my scene.toml"]
    else:
        scene_arg = ["paper-heavy"]
    assert main(["run", *scene_arg, "--out", "r", *sets, "--no-progress"]) == 0
    hint = _hint(capsys.readouterr().out)
    assert "light-block-fast" not in hint
    # the same scene but for the seed, which the ensemble varies (and refuses as a --set)
    ran = load_scene(scene_arg[0], parse_sets(SETS))
    assert "roughness.seed" not in hint
    assert scene_to_dict(_scene_of(hint)) == scene_to_dict(ran)
    # the run directory keeps it, for the report
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["run_command"] + " --seeds 10" == hint


def test_a_rigid_base_has_no_plate_level_line(tmp_path, monkeypatch, capsys):
    """'plate accel 0 m/s^2 rms (n/a re 1e-6 m/s^2)' for a base that cannot move: the line
    says there is no plate motion instead; a plate with modes keeps its level."""
    monkeypatch.chdir(tmp_path)
    sets = [w for v in SETS for w in ("--set", v)]
    assert main(["run", "paper", "--out", "rigid", "--set", "plate.kind=rigid", *sets,
                 "--no-progress"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("plate accel"))
    assert line == "plate accel      none: the rigid base (no modes) does not move"
    summary = json.loads((tmp_path / "rigid" / "summary.json").read_text())
    assert summary["model"]["modes"] == 0
    assert summary["metrics"]["plate_vertical_acceleration_rms"] == 0.0  # what it replaces
    assert main(["run", "paper", "--out", "modal", *sets, "--no-progress"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("plate accel"))
    assert line.endswith("dB re 1e-6 m/s^2)") and "n/a" not in line
