"""The public entry points in one place: run a scene, continue a run, read results, run the
studies and write the reports.

Nothing is implemented here; each name is re-exported from the stage that owns it
(docs/architecture.md), so that ``from roughvib.api import ...`` keeps working when code moves
between stages. ``import roughvib`` offers the most used of them lazily.

Each name is imported from its stage on first use: ``from roughvib.api import simulate``
loads the solver stack but not the studies and reports (scipy.signal, dask, matplotlib),
which would add a second or more of imports to every run.
"""

from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the names and where they live (imported on first use, see __getattr__)
    from roughvib.records import export_run, read_record
    from roughvib.results import Result, load_result
    from roughvib.scene import Scene, SceneError, builtin_scenes, load_scene
    from roughvib.simulation import energy_audit, resume, simulate
    from roughvib.studies.compare import run_study
    from roughvib.studies.sweep import builtin_sweeps, load_sweep, run_sweep, sweep_report
    from roughvib.views.report import write_report
    from roughvib.views.surface_report import write_surface_report
    from roughvib.views.validation import validate

__all__ = ["Result", "Scene", "SceneError", "builtin_scenes", "builtin_sweeps", "energy_audit",
           "export_run", "load_result", "load_scene", "load_sweep", "read_record", "resume",
           "run_study", "run_sweep", "simulate", "sweep_report", "validate", "write_report",
           "write_surface_report"]

_OWNER = {
    "Result": "roughvib.results", "load_result": "roughvib.results",
    "Scene": "roughvib.scene", "SceneError": "roughvib.scene",
    "builtin_scenes": "roughvib.scene", "load_scene": "roughvib.scene",
    "energy_audit": "roughvib.simulation", "resume": "roughvib.simulation",
    "simulate": "roughvib.simulation",
    "run_study": "roughvib.studies.compare",
    "builtin_sweeps": "roughvib.studies.sweep", "load_sweep": "roughvib.studies.sweep",
    "run_sweep": "roughvib.studies.sweep", "sweep_report": "roughvib.studies.sweep",
    "write_report": "roughvib.views.report",
    "write_surface_report": "roughvib.views.surface_report",
    "export_run": "roughvib.records", "read_record": "roughvib.records",
    "validate": "roughvib.views.validation",
}


def __getattr__(name: str):
    if name not in _OWNER:
        raise AttributeError(f"module 'roughvib.api' has no attribute {name!r}")
    value = getattr(import_module(_OWNER[name]), name)
    globals()[name] = value  # later look-ups do not come here
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
