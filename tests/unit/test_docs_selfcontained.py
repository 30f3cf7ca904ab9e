"""The documentation and the code point only at what the repository holds.

The developers' own notes (the model brief, the IDA notes, the style guide) are not part of
the repository; a user cannot follow a reference to them. What a user needs is in docs/ in our
own words (docs/theory.md), so no file under docs/, src/, tests/, benchmarks/ or examples/ may
name those notes again.

The pages a user reads state what holds now: no issue numbers a user never saw, no dated
measurement diaries, no "this session" (the history is in git).
"""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
THIS = Path(__file__).name  # this file names the patterns it looks for
SUFFIXES = {".py", ".md", ".rst", ".toml", ".txt", ".cfg", ".html", ".css", ".js"}
FORBIDDEN = re.compile(
    r"physics\.md|ida[-_ ]notes|design\.md|/work/|shared/(physics|ida|design)|"
    r"model brief|\bthe brief\b|\bbrief's\b|\(brief:",
    flags=re.IGNORECASE)


def _files():
    for top in ("src", "docs", "tests", "benchmarks", "examples"):
        for path in sorted((ROOT / top).rglob("*")):
            parts = set(path.relative_to(ROOT).parts)
            if path.is_file() and path.suffix in SUFFIXES and path.name != THIS and not parts & {
                    "_build", "generated", "auto_examples", "__pycache__"}:
                yield path


def test_no_reference_to_files_outside_the_repository():
    hits = []
    for path in _files():
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if FORBIDDEN.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not hits, "references to notes outside the repository:\n" + "\n".join(hits)


def test_the_check_sees_the_sources_and_the_pages():
    names = {p.relative_to(ROOT).as_posix() for p in _files()}
    assert {"docs/theory.md", "src/roughvib/scene/core.py", "src/roughvib/cli/report.py",
            "src/roughvib/scenes/paper.toml", "tests/physics/test_plate.py",
            "benchmarks/bench_paper.py", "examples/01_quickstart.py"} <= names
    assert FORBIDDEN.search("see physics.md §2.4") and FORBIDDEN.search("ida-notes §3")
    assert not FORBIDDEN.search("roughvib sweep v.toml --out /shared/runs/velocity")


#: what only a development diary says: an issue number, a work session, a day's date
DIARY = re.compile(
    r"\bissues? ?-?\d+|(?<![\w&])#\d+\b|\bsessions?\b|\btonight\b|\byesterday\b|"
    r"\bthis round\b|\b20\d\d-\d\d-\d\d\b",
    flags=re.IGNORECASE)


def _pages():
    """README, the pages, the included fragments and the gallery's scripts and header."""
    yield ROOT / "README.md"
    for pattern in ("docs/*.md", "docs/*.rst", "docs/_fragments/*.md", "docs/figures/*.md",
                    "examples/*.py", "examples/*.rst"):
        yield from sorted(ROOT.glob(pattern))


def test_pages_hold_no_issue_numbers_or_diary_dates():
    hits = []
    for path in _pages():
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if DIARY.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not hits, "state the current facts, not their history:\n" + "\n".join(hits)


def test_the_diary_check_sees_the_pages_and_the_patterns():
    names = {p.relative_to(ROOT).as_posix() for p in _pages()}
    assert {"README.md", "docs/performance.md", "docs/paper-comparison.md",
            "docs/_fragments/presets_measured.md", "examples/02_reference_run.py"} <= names
    for diary in ("Where issue 28 stood", "fixed in #28", "measured tonight",
                  "this session's changes", "on 2026-11-26", "the issue-25 case"):
        assert DIARY.search(diary), diary
    for fact in ("0.1429–0.4286 s", "a 2-core Intel Xeon (family 6, model 207)",
                 "`&#160;`", "IEC 61260-1", "the `paper-100mms` scene"):
        assert not DIARY.search(fact), fact
