"""Parameter studies ("sweeps") on local worker processes or dask.distributed: resumable, one
result directory per case.

The package is split by responsibility: :mod:`.spec` (the sweep file, its cases and their names,
the layout of a sweep directory), :mod:`.run` (running the cases as tasks and publishing their
directories), :mod:`.pool` (the local pool of worker processes), :mod:`.tables` (the sweep table
and dataset, the slope fits) and :mod:`.report` (the data of the sweep report, rendered by
:mod:`roughvib.views.sweep_report`). The command-line handlers live in
:mod:`roughvib.cli.sweep`.

A sweep file (TOML) names a base scene and the values to vary::

    name = "velocity"
    base = "paper"                        # built-in scene name or a scene file (relative to here)

    [set]                                 # fixed overrides for every case
    "output.duration" = 0.2

    [grid]                                # product of all lists (dimensions of sweep.nc)
    "excitation.target_rms_velocity" = [0.01, 0.02, 0.04, 0.1]
    "roughness.seed" = [1, 2, 3]

    [[case]]                              # and/or a list of cases (the "case" dimension)
    "block.mass" = 0.221

Keys are the dotted scene keys of ``roughvib run --set``; ``[grid.excitation]`` tables with plain
keys work as well. With both ``[grid]`` and ``[[case]]`` every case is run at every grid point.

``run_sweep(sweep, DIR)`` writes::

    DIR/sweep.json         what was swept (base, fixed values, grid, cases)
    DIR/cases/<case>/      one result directory per case (result.nc, events.csv, summary.json,
                           scene.toml as written by Result.save, plus case.json)
    DIR/sweep.csv          one row per case: varied values, status, message, wall time, metrics
    DIR/sweep.nc           the metrics on the sweep's dimensions (xarray, units attributes)

A case directory is written under a temporary name and renamed when complete, so a sweep killed
at any moment loses only the cases in flight. Re-running skips the cases whose summary.json says
``success`` and re-runs failed and missing ones. A case's name is readable values plus a hash of
the base scene and the case's values (``target_rms_velocity-0.01__seed-2__1a2b3c4d5e``, nothing a
shell needs quoted; the exact values are in case.json), so it stays the same when the grid is
extended and changes when the base scene or the fixed values change. Case directories named the
way roughvib 0.1 named them (``target_rms_velocity=0.01,seed=2-...``) are renamed on resuming.

Each case is one task. Without a scheduler address (or client) the cases run on a local pool of
worker processes with one thread each (:class:`.pool.LocalPool`, no Dask); with one, each case is
one Dask task on that cluster. numba, OpenMP and BLAS are limited to one thread per worker so
that the workers do not oversubscribe the cores.
"""

from roughvib.studies.sweep.report import sweep_report
from roughvib.studies.sweep.run import THREAD_ENV, SweepRun, run_sweep
from roughvib.studies.sweep.spec import Case, Sweep, builtin_sweeps, case_name, load_sweep
from roughvib.studies.sweep.tables import collect_table, scene_key_units

__all__ = [
    "Case",
    "Sweep",
    "SweepRun",
    "THREAD_ENV",
    "builtin_sweeps",
    "case_name",
    "collect_table",
    "load_sweep",
    "run_sweep",
    "scene_key_units",
    "sweep_report",
]
