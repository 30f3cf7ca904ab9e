"""The public entry points in one place: run a scene, continue a run, read results, run the
studies and write the reports.

Nothing is implemented here; each name is re-exported from the stage that owns it
(docs/architecture.md), so that ``from roughvib.api import ...`` keeps working when code moves
between stages. ``import roughvib`` offers the most used of them lazily.
"""

from roughvib.results import Result, load_result
from roughvib.scene import Scene, SceneError, builtin_scenes, load_scene
from roughvib.simulation import energy_audit, resume, simulate
from roughvib.studies.compare import run_study
from roughvib.studies.sweep import builtin_sweeps, load_sweep, run_sweep, sweep_report
from roughvib.views.report import write_report
from roughvib.views.surface_report import write_surface_report

__all__ = ["Result", "Scene", "SceneError", "builtin_scenes", "builtin_sweeps", "energy_audit",
           "load_result", "load_scene", "load_sweep", "resume", "run_study", "run_sweep",
           "simulate", "sweep_report", "write_report", "write_surface_report"]
