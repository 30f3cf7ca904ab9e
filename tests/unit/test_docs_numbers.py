"""What the documentation says a run does is what the code does.

The pages quote numbers that a run prints (how many contact points and plate modes the built-in
`paper` scene has, its analysis window) and commands a user copies. They are checked here
against the code, not against numbers copied from an earlier run: the scene is resolved and
assembled, the window computed, every quoted command parsed by the real argument parser.
"""

import re
import shlex
from pathlib import Path

import numpy as np
import pytest

import roughvib
from roughvib.analysis.levels import whole_period_window
from roughvib.cli import build_parser
from roughvib.model.system import assemble
from roughvib.scene import Scene, builtin_scenes

ROOT = Path(__file__).resolve().parents[2]
WORDS = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7,
         "eight": 8, "nine": 9, "ten": 10}
COUNT = r"(\d+|" + "|".join(WORDS) + r")"
#: pages (and the quickstart example) that describe the built-in `paper` scene
PAPER_PAGES = ("README.md", "docs/index.md", "docs/scenes.md", "docs/quickstart.md",
               "examples/01_quickstart.py")


def _number(word: str) -> int:
    return WORDS.get(word.lower(), None) or int(word)


@pytest.fixture(scope="module")
def paper():
    return assemble(roughvib.load_scene("paper", **{"output.progress": False}))


def _paper_lines():
    """Lines that describe the `paper` scene itself (its 0.221 kg block, not another scene)."""
    for name in PAPER_PAGES:
        text = (ROOT / name).read_text(encoding="utf-8")
        # join wrapped prose so that a sentence broken over lines is read whole
        for para in re.split(r"\n\s*\n", text):
            flat = " ".join(para.split())
            for sentence in re.split(r"(?<=[.;|])\s", flat):
                if "0.221 kg" in sentence and "handset" not in sentence:
                    yield name, sentence


def test_contact_counts_stated_for_the_paper_scene_are_the_codes(paper):
    said = []
    for name, sentence in _paper_lines():
        for m in re.finditer(COUNT + r" (?:rough )?contact(?: point)?s?\b", sentence,
                             flags=re.I):
            said.append((name, _number(m.group(1)), sentence))
    assert said, "no page states the paper scene's contact count any more: update this test"
    wrong = [f"{n}: says {k}, the code has {paper.n_contacts}: {s}" for n, k, s in said
             if k != paper.n_contacts]
    assert not wrong, "\n".join(wrong)
    micro = f"{paper.contact['micro_contacts']:.2f}"
    for name, sentence in _paper_lines():
        for m in re.finditer(r"(\d+\.\d+) micro-contacts", sentence):
            assert m.group(1) == micro, f"{name}: says {m.group(1)}, the code has {micro}"


def test_mode_counts_stated_to_50_khz_are_the_codes(paper):
    said = []
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        flat = " ".join(path.read_text(encoding="utf-8").split())
        for m in re.finditer(r"all (\d[\d ]*) (?:plate )?modes (?:up )?to 50 kHz", flat):
            said.append((path.name, int(m.group(1).replace(" ", ""))))
    assert said
    assert paper.scene.plate.max_frequency == pytest.approx(50e3)
    assert {k for _, k in said} == {paper.n_modes}, said


def test_the_analysis_window_quoted_is_the_codes(paper):
    scene = paper.scene
    period = 1.0 / scene.excitation.frequency
    t = scene.output.step * np.arange(
        round(scene.output.duration / scene.output.step) + 1)
    window = whole_period_window(t, period, scene.output.transient)
    lo, hi = f"{t[window][0]:.4f}", f"{t[window][-1] + scene.output.step:.4f}"
    quoted = 0
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for m in re.finditer(r"(0\.\d{4}) ?(?:–|\.\.|-) ?(0\.\d{4}) s",
                             path.read_text(encoding="utf-8")):
            if m.group(1) == "0.1429" or m.group(2) == "0.4286":
                quoted += 1
                assert (m.group(1), m.group(2)) == (lo, hi), (path.name, m.group(0))
    assert quoted


def _commands():
    """Every `roughvib ...` line of a bash block in README.md and docs/*.md."""
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = path.read_text(encoding="utf-8")
        for block in re.findall(r"```(?:bash|console|sh)\n(.*?)```", text, flags=re.S):
            for line in block.replace("\\\n", " ").splitlines():
                line = line.strip().removeprefix("$ ")
                for part in re.split(r"&&|\|(?!\|)|>", line):
                    part = part.split(" #")[0].strip()
                    if part.startswith("roughvib ") or part == "roughvib":
                        yield path.name, part


def test_every_quoted_command_parses(capsys):
    parser = build_parser()
    commands = list(_commands())
    assert len(commands) > 20
    bad = []
    for name, cmd in commands:
        argv = shlex.split(cmd)[1:]
        if "--help" in argv or "-h" in argv or "--version" in argv:
            continue
        try:
            parser.parse_args(argv)
        except SystemExit:
            bad.append(f"{name}: {cmd}: {capsys.readouterr().err.strip().splitlines()[-1]}")
    assert not bad, "\n".join(bad)


def test_scenes_named_in_quoted_run_commands_exist():
    builtins = set(builtin_scenes())
    parser = build_parser()
    for name, cmd in _commands():
        argv = shlex.split(cmd)[1:]
        if argv[:1] != ["run"] or "--help" in argv:
            continue
        scene = parser.parse_args(argv).scene
        if scene and not scene.endswith(".toml"):
            assert scene in builtins, f"{name}: {cmd}: no built-in scene {scene!r}"


def _quickstart_defaults_paragraph() -> str:
    text = (ROOT / "docs" / "quickstart.md").read_text(encoding="utf-8")
    for para in re.split(r"\n\s*\n", text):
        flat = " ".join(para.split())
        if "The defaults are" in flat:
            return flat
    raise AssertionError("docs/quickstart.md no longer says what the defaults are: "
                         "update this test")


def _value(scene, key: str):
    section, name = key.split(".")
    return getattr(getattr(scene, section), name)


def test_the_defaults_the_quickstart_states_are_the_codes():
    """What the quickstart says an empty scene file gives, and what paper-handset changes."""
    para = _quickstart_defaults_paragraph()
    defaults, paper, handset = (Scene(), roughvib.load_scene("paper"),
                                roughvib.load_scene("paper-handset"))
    said = re.search(r"The defaults are the built-in `(\w[\w-]*)` scene", para)
    assert said, para
    assert roughvib.load_scene(said.group(1)).block == defaults.block
    # keys set to "auto" and boolean keys, as `a.b` ... = "auto" and `a.b = true`
    autos = re.search(r"\(((?:`[a-z_]+\.[a-z_]+`(?:, | and )?)+) = \"auto\"", para)
    assert autos, para
    keys = re.findall(r"`([a-z_]+\.[a-z_]+)`", autos.group(1))
    assert len(keys) >= 3
    for key in keys:
        assert _value(defaults, key) == _value(paper, key) == "auto", key
    flags = re.findall(r"`([a-z_]+\.[a-z_]+) = (true|false)`", para)
    assert flags
    for key, word in flags:
        assert _value(defaults, key) is (word == "true"), key
    # the hand-set contact: points, total stiffness, r1, no velocity factor
    hand = re.search(r"`paper-handset` sets the hand-set contact instead \(" + COUNT
                     + r" contact points, ([\d.e]+) N/m, r1 = ([\d.]+) N s/m, no velocity factor\)",
                     para)
    assert hand, para
    assert handset.contact.points == _number(hand.group(1))
    assert handset.contact.stiffness == pytest.approx(float(hand.group(2)))
    assert handset.block.vertical_damping == pytest.approx(float(hand.group(3)))
    assert handset.contact.velocity_factor is False
