"""The machine a benchmark runs on, in one line, printed at the head of the benchmarks.

The same code measures differently on different processors of the same size, with the same
source tree and the same results (the default solve's ratio to the fixed-step floor too). A
figure in docs/performance.md is therefore quoted with this line, so that measurements are
compared on like machines:

    python benchmarks/machine.py

Everything here is read without root and without a network: ``/proc/cpuinfo`` (Linux; absent
elsewhere, then the platform module's name), the processor LLVM compiles numba's kernels for
(``llvmlite.binding.get_host_cpu_name``, public API), the core count and the versions of the
libraries that set the speed of a solve. :func:`timed_python` times one Python process on it,
the way every benchmark here that starts processes does.
"""

from __future__ import annotations

import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

#: the fields of /proc/cpuinfo that name a processor (the first core's)
CPUINFO_FIELDS = ("model name", "cpu family", "model", "stepping", "cpu MHz")


def cpuinfo(path: str | os.PathLike = "/proc/cpuinfo") -> dict[str, str]:
    """The first processor's ``CPUINFO_FIELDS`` from a Linux ``/proc/cpuinfo``.

    Returns
    -------
    dict
        Field name to its text; empty where the file does not exist.
    """
    p = Path(path)
    if not p.is_file():
        return {}
    fields: dict[str, str] = {}
    for line in p.read_text(errors="replace").splitlines():
        if not line.strip():  # the first processor's block ends at the first empty line
            break
        key, _, value = line.partition(":")
        key = key.strip()
        if key in CPUINFO_FIELDS:
            fields[key] = value.strip()
    return fields


def describe() -> str:
    """One line: processor (its family/model/stepping and LLVM's name for it), cores, clock,
    Python and the numerical libraries' versions."""
    import llvmlite.binding as llvm
    import numba
    import numpy
    import scipy

    info = cpuinfo()
    name = info.get("model name") or platform.processor() or platform.machine()
    ident = ", ".join(f"{k.replace('cpu ', '')} {info[k]}"
                      for k in ("cpu family", "model", "stepping") if k in info)
    clock = f" at {float(info['cpu MHz']):.0f} MHz" if "cpu MHz" in info else ""
    return (f"{name} ({ident + '; ' if ident else ''}LLVM target {llvm.get_host_cpu_name()}), "
            f"{os.cpu_count()} cores{clock}; Python {platform.python_version()}, "
            f"numpy {numpy.__version__}, scipy {scipy.__version__}, numba {numba.__version__}")


def timed_python(argv: list[str], env: dict) -> dict:
    """Run ``python ARGV`` (this interpreter, started directly) and time it.

    Returns
    -------
    dict
        ``wall`` [s]; ``cpu``, the process's and its children's user and system time [s]
        (``getrusage(RUSAGE_CHILDREN)``); ``load_before`` and ``load_after``, the one-minute
        load average around it.

    Raises
    ------
    SystemExit
        If the process fails: its command line, exit code and the end of its stderr.
    """
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, *argv], env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"python {' '.join(argv)} failed ({proc.returncode}):\n"
                         f"{proc.stderr[-3000:]}")
    return {"wall": wall, "cpu": r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime,
            "load_before": load0[0], "load_after": os.getloadavg()[0]}


if __name__ == "__main__":
    print(describe())


def measurements(script: str, scenes, repeat: int, processes: int, measure):
    """Yield ``(scene, row)`` for each scene: ``measure(scene, repeat)`` in this process, or,
    with ``processes`` > 0, that many times in fresh processes of ``script`` run with
    ``SCENE --repeat N --json-line`` (each prints its row as one JSON line last)."""
    import json

    for name in scenes:
        for _ in range(max(processes, 1)):
            if not processes:
                yield name, measure(name, repeat)
                continue
            out = subprocess.run([sys.executable, script, name, "--repeat", str(repeat),
                                  "--json-line"], check=True, capture_output=True,
                                 text=True).stdout
            yield name, json.loads(out.strip().splitlines()[-1])


def ratio_line(name: str, ratios, target: float, what: str = "ratio") -> str:
    """One line: the median and range of ``ratios`` and how many are at or below ``target``."""
    import statistics

    return (f"{name}: {what} median {statistics.median(ratios):.2f}, range {min(ratios):.2f}-"
            f"{max(ratios):.2f}, {sum(x <= target for x in ratios)} of {len(ratios)} at or "
            f"below {target}")
