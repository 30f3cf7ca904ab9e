"""Old import paths of the modules that moved when the package took one folder per pipeline
stage (docs/architecture.md), kept for one release.

``import roughvib.plots`` (and the others in :data:`MOVED`) still works: a meta-path finder,
installed by ``roughvib/__init__.py``, answers the old name with the module at its new place
(the same module object, so ``roughvib.plots.FIGURES is roughvib.views.figures.FIGURES``) and
issues a :class:`DeprecationWarning` naming the new path. Nothing inside roughvib uses the old
paths. The command-line handlers (``add_parsers``, ``cmd_*``) that ``report`` and ``sweep``
held moved to :mod:`roughvib.cli` and are not part of the old paths.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings

__all__ = ["MOVED", "install"]

#: old module name -> new module name
MOVED: dict[str, str] = {
    "roughvib.plate": "roughvib.physics.plate",
    "roughvib.friction": "roughvib.physics.friction",
    "roughvib.surface": "roughvib.physics.surface",
    "roughvib.surface.roughness": "roughvib.physics.surface.roughness",
    "roughvib.surface.interp": "roughvib.physics.surface.interp",
    "roughvib.surface.contact": "roughvib.physics.surface.contact",
    "roughvib.plots": "roughvib.views.figures",
    "roughvib.report": "roughvib.views.report",
    "roughvib.surface_report": "roughvib.views.surface_report",
    "roughvib.compare": "roughvib.studies.compare",
    "roughvib.sweep": "roughvib.studies.sweep",
}


def _stacklevel() -> int:
    """Stack level of the first frame outside the import machinery and this module, so that
    the warning names the user's import line (and is shown by default in ``__main__``).
    ``warnings.warn`` skips the frames of ``importlib._bootstrap`` itself, so they do not
    count."""

    def internal(frame) -> bool:
        name = frame.f_code.co_filename
        return "importlib" in name and "_bootstrap" in name

    frame = sys._getframe(1)  # the caller of warnings.warn: level 1
    level = 1
    while frame.f_back is not None and (internal(frame) or frame.f_code.co_filename == __file__):
        frame = frame.f_back
        if not internal(frame):
            level += 1
    return level


class _MovedLoader(importlib.abc.Loader):
    """Loads an old name as the module at its new place."""

    def __init__(self, new: str):
        self.new = new

    def create_module(self, spec):
        warnings.warn(f"{spec.name} moved to {self.new}; the old path will be removed in the "
                      f"next release", DeprecationWarning, stacklevel=_stacklevel())
        module = importlib.import_module(self.new)
        self._spec = module.__spec__
        return module

    def exec_module(self, module) -> None:
        # the import system set __spec__ to the old name's spec; the module keeps its own
        module.__spec__ = self._spec


class _MovedFinder(importlib.abc.MetaPathFinder):
    """Finds the old names of :data:`MOVED`."""

    def find_spec(self, fullname, path=None, target=None):
        new = MOVED.get(fullname)
        if new is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, _MovedLoader(new))


def install() -> None:
    """Put the finder of the old paths first on ``sys.meta_path`` (once).

    First, so that an old submodule name (``roughvib.surface.roughness``) is never found again
    by the path finder under the moved package and loaded a second time, and so that a stale
    directory of an old package left in a checkout cannot shadow it.
    """
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _MovedFinder())
