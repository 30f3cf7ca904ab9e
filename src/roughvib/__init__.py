"""roughvib: roughness-induced vibration of a tangentially oscillating mass on a plate.

Public API (see docs/quickstart.md)::

    import roughvib
    scene = roughvib.load_scene("paper", **{"output.duration": 0.1})
    result = roughvib.simulate(scene)
    result.save("runs/x")
"""

from roughvib.scene import Scene, SceneError, builtin_scenes, load_scene

__all__ = ["Scene", "SceneError", "builtin_scenes", "load_scene"]
__version__ = "0.1.0"
