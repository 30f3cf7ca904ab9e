"""Progress on stderr: a tqdm bar on a terminal, sparse whole lines in a log file."""

import io

import pytest

from roughvib import _progress
from roughvib._progress import LineProgress, NoProgress, progress_bar


class _Tty(io.StringIO):
    def isatty(self):
        return True


class _Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


@pytest.fixture
def clock(monkeypatch):
    c = _Clock()
    monkeypatch.setattr(_progress.time, "monotonic", c)
    return c


def test_terminal_gets_tqdm_and_a_file_gets_lines():
    from tqdm import tqdm

    bar = progress_bar(1.0, desc="x", unit="s", file=_Tty())
    assert isinstance(bar, tqdm)
    bar.close()
    assert isinstance(progress_bar(1.0, desc="x", unit="s", file=io.StringIO()), LineProgress)
    for file in (_Tty(), io.StringIO()):  # disabled: silent on a terminal and in a file
        bar = progress_bar(1.0, desc="x", unit="s", disable=True, file=file, initial=0.25)
        assert isinstance(bar, NoProgress) and (bar.n, bar.total) == (0.25, 1.0)
        bar.update(0.5)
        bar.set_postfix(failed=1)
        bar.refresh()
        bar.close()
        assert bar.n == 0.75 and file.getvalue() == ""


def test_lines_at_tenths_at_most_every_gap_and_after_the_interval(clock):
    out = io.StringIO()
    bar = LineProgress(1.0, desc="roughvib paper", unit="s sim", file=out, value_format=".2f")
    for k in range(1, 101):  # 100 updates in 1 s: too fast for a line per tenth
        clock.t += 0.01
        bar.n = k / 100
        bar.refresh()
    assert out.getvalue() == ""
    bar.close()
    assert out.getvalue() == ("roughvib paper: 1.00/1.00 s sim (100 %), elapsed 0:01, "
                              "about 0:00 left\n")
    bar.update(0)  # nothing after close
    assert out.getvalue().count("\n") == 1

    out = io.StringIO()
    bar = LineProgress(100, desc="sweep s", unit="case", file=out)
    clock.t += 6
    bar.update(5)  # no tenth crossed yet
    clock.t += 6
    bar.set_postfix(failed=1, refresh=False)
    bar.update(6)  # 11 %: a line
    for _ in range(3):  # slow work: a line every 30 s even without a new tenth
        clock.t += 31
        bar.update(1)
    bar.close()
    lines = out.getvalue().splitlines()
    assert [ln.split(":")[1].split("(")[0].strip() for ln in lines] == [
        "11/100 case", "12/100 case", "13/100 case", "14/100 case"]
    assert lines[0] == "sweep s: 11/100 case (11 %), failed=1, elapsed 0:12, about 1:37 left"
