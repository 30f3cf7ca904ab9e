"""roughvib: roughness-induced vibration of a tangentially oscillating mass on a plate.

Public API (see docs/quickstart.md)::

    import roughvib
    scene = roughvib.load_scene("paper", **{"output.duration": 0.1})
    result = roughvib.simulate(scene)
    result.save("runs/x")
    ds = result.to_dataset()        # xarray.Dataset, every variable with units
    result.events                   # pandas.DataFrame event log
"""

from roughvib import _compat
from roughvib._version import __version__ as __version__
from roughvib.scene import Scene, SceneError, builtin_scenes, load_scene

__all__ = ["Result", "Scene", "SceneError", "builtin_scenes", "load_result", "load_scene",
           "resume", "simulate"]

_compat.install()  # old import paths (roughvib.plots, roughvib.sweep, ...) for one release


def __getattr__(name):
    # the solver stack (numba, sksundae, xarray) is imported on first use, so that
    # `import roughvib` and scene validation stay fast
    if name in ("simulate", "resume"):
        from roughvib import simulation

        return getattr(simulation, name)
    if name in ("Result", "load_result"):
        from roughvib import results

        return getattr(results, name)
    raise AttributeError(f"module 'roughvib' has no attribute {name!r}")


def __dir__():
    # the lazily imported names are part of the public API: list them too
    return sorted(set(globals()) | set(__all__))
