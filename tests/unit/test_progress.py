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


# ---- the kernel clock: numba's loading and compiling, and the notice of a cold cache -------

NOTICE = "roughvib: compiling the numba kernels"


def test_the_compile_notice_is_printed_once_and_only_when_asked():
    out = io.StringIO()
    c = _progress.KernelClock(file=out)
    c.compiling()  # not asked (e.g. --no-progress, a sweep case)
    assert out.getvalue() == "" and c.compiled == 1
    with c.notifying(True):
        c.compiling()
        c.compiling()
    assert out.getvalue().count(NOTICE) == 1 and out.getvalue().count("\n") == 1
    assert c.compiled == 3 and c.notify is False


def test_the_clock_adds_up_the_outermost_holds_of_the_lock(monkeypatch):
    t = iter([10.0, 13.0, 20.0, 20.5])
    monkeypatch.setattr(_progress.time, "perf_counter", lambda: next(t))
    c = _progress.KernelClock()
    c.lock_taken()
    c.lock_taken()  # nested: one hold
    c.lock_released()
    c.lock_released()
    c.lock_taken()
    c.lock_released()
    assert c.seconds == pytest.approx(3.0 + 0.5)


_KERNEL_MODULE = '''
import sys
import numba
from roughvib._progress import kernel_clock

@numba.njit(cache=True)
def twice(x):
    return 2 * x

clock = kernel_clock()
with clock.notifying(True):
    twice(3)
print(clock.compiled, clock.seconds > 0)
'''


def test_numba_compiles_announce_themselves_once_and_a_warm_cache_is_silent(tmp_path):
    """A fresh numba cache: the first process compiles the kernel and says so on stderr; the
    second loads it from numba's cache, compiles nothing and says nothing (a warm run)."""
    import os
    import subprocess
    import sys

    (tmp_path / "kmod.py").write_text(_KERNEL_MODULE)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    env.pop("NUMBA_DISABLE_JIT", None)
    runs = [subprocess.run([sys.executable, str(tmp_path / "kmod.py")], env=env, cwd=tmp_path,
                           capture_output=True, text=True, timeout=300) for _ in range(2)]
    cold, warm = runs
    assert cold.returncode == 0 and warm.returncode == 0, cold.stderr + warm.stderr
    assert cold.stderr.count(NOTICE) == 1 and cold.stdout.split() == ["1", "True"]
    assert NOTICE not in warm.stderr and warm.stdout.split() == ["0", "True"]


@pytest.mark.filterwarnings("ignore:.*excitation period:UserWarning")  # a 5 ms window
def test_the_pilot_wall_time_leaves_out_the_kernels_and_the_summary_names_them(
        monkeypatch, tmp_path):
    """The report showed 'pilot solve wall time 83.79 s' next to a solver wall time of 0.26 s:
    the pilot, the run's first solve, held numba's compilation. Here a fake clock stands still
    but for 50 s of a (simulated) compilation and 0.25 s of solving inside the pilot."""
    import time

    import roughvib.simulation as sim
    from roughvib.scene import load_scene

    monkeypatch.chdir(tmp_path)
    now = [1000.0]
    monkeypatch.setattr(time, "perf_counter", lambda: now[0])
    clock = _progress.kernel_clock()
    real_solve = sim._solve
    calls = []

    def solve(system, **kw):
        if not calls:  # the pilot
            clock.lock_taken()
            now[0] += 50.0
            clock.lock_released()
            now[0] += 0.25
        calls.append(system.scene.output.duration)
        return real_solve(system, **kw)

    monkeypatch.setattr(sim, "_solve", solve)
    scene = load_scene("paper", {"output.duration": 0.005, "plate.max_frequency": 2000.0,
                                 "output.transient": 0.0, "output.progress": False})
    res = sim.simulate(scene)
    s = res.summary["solver"]
    assert len(calls) == 2 and s["pilot"]["duration"] == calls[0]
    assert s["pilot"]["wall_time"] == pytest.approx(0.25)
    assert s["pilot"]["kernel_time"] == pytest.approx(50.0)
    k = s["kernels"]
    assert k["pilot"] == pytest.approx(50.0) and k["solve"] == 0.0
    assert k["time"] == pytest.approx(k["preprocessing"] + k["pilot"] + k["solve"])
