"""Scene description: frozen, validated dataclasses in SI units, TOML load/save.

This package owns the *contract* of a scene file. Every value has a default taken from the
paper scene (docs/theory.md), so an empty TOML file is the paper scene. A bad value raises
:class:`SceneError` (a ``ValueError``) whose message names the field path, the rule, the unit
and the value, e.g. ``plate.thickness must be > 0 m, got -0.003``.

Nothing in here knows how a solver works; what each one runs is asked of the solver registry
(:mod:`roughvib.solvers.registry`, which imports nothing from roughvib), so that a scene a
solver cannot run is refused when it is loaded. Later pipeline stages read these objects and
turn them into flat arrays once.

The modules, by responsibility (every name stays importable from ``roughvib.scene``):

* :mod:`.checks`: :class:`SceneError`, :class:`ModelValidityWarning`, the field checks, the
  upper limits and ``SANE_BOUNDS``;
* :mod:`.bodies`: the sections :class:`Block`, :class:`Plate`, :class:`Contact`,
  :class:`Roughness`;
* :mod:`.forces`: the sections :class:`Friction` and :class:`Excitation`;
* :mod:`.solver_output`: the sections :class:`Solver` and :class:`Output`, the solver methods
  and accuracy presets;
* :mod:`.core`: :class:`Scene` and its plain-dict form;
* :mod:`.files`: TOML out, the built-in scenes, reading files, :func:`load_scene`;
* :mod:`.validity`: :func:`validity_warnings`.
"""

from roughvib.scene.bodies import (
    Block,
    Contact,
    Plate,
    Roughness,
)
from roughvib.scene.checks import (
    _INT_MAX,  # noqa: F401
    _NAME_FORBIDDEN,  # noqa: F401
    MAX_CONTACTS,  # noqa: F401
    MAX_FIXED_STEPS,  # noqa: F401
    MAX_MODES,  # noqa: F401
    MAX_PROFILE_SAMPLES,  # noqa: F401
    NAME_MAX,  # noqa: F401
    SANE_BOUNDS,  # noqa: F401
    ModelValidityWarning,
    SceneError,
    _auto_or_positive,  # noqa: F401
    _boolean,  # noqa: F401
    _check_bounds,  # noqa: F401
    _choice,  # noqa: F401
    _file_name,  # noqa: F401
    _fmt,  # noqa: F401
    _integer,  # noqa: F401
    _nonneg,  # noqa: F401
    _number,  # noqa: F401
    _opt_positive,  # noqa: F401
    _pair,  # noqa: F401
    _positive,  # noqa: F401
    _range,  # noqa: F401
    _set,  # noqa: F401
    _u,  # noqa: F401
    bounds_rule,  # noqa: F401
    user_stacklevel,  # noqa: F401
)
from roughvib.scene.core import (
    _SECTIONS,  # noqa: F401
    _TOP_KEYS,  # noqa: F401
    DESCRIPTION_MAX,  # noqa: F401
    Scene,
    _assign,  # noqa: F401
    replace_section,  # noqa: F401
    scene_from_dict,  # noqa: F401
    scene_to_dict,  # noqa: F401
)
from roughvib.scene.files import (
    _FILE_KINDS,  # noqa: F401
    _toml_value,  # noqa: F401
    builtin_scenes,
    load_scene,
    read_regular_file,  # noqa: F401
    read_toml_file,
    scene_to_toml,
)
from roughvib.scene.forces import (
    FRICTION_LAWS,  # noqa: F401
    LAW_KEYS,  # noqa: F401
    SET_VALUED_LAWS,  # noqa: F401
    Excitation,
    Friction,
    LawDeclaration,  # noqa: F401
    LawKey,  # noqa: F401
    law_key_path,  # noqa: F401
)
from roughvib.scene.solver_output import (
    _TOLERANCE_KEYS,  # noqa: F401
    ACCURACY_LEVELS,
    ACCURACY_PRESETS,
    FIXED_STEP_METHODS,
    SOLVER_METHODS,
    Output,
    Solver,
)
from roughvib.scene.validity import (
    BENDING_WAVELENGTH_THICKNESSES,  # noqa: F401
    PERIOD_ROUNDING,  # noqa: F401
    THIN_PLATE_RATIO,  # noqa: F401
    validity_warnings,
)

__all__ = [
    "Block",
    "Contact",
    "Excitation",
    "Friction",
    "ModelValidityWarning",
    "Output",
    "Plate",
    "Roughness",
    "Scene",
    "SceneError",
    "ACCURACY_LEVELS",
    "ACCURACY_PRESETS",
    "FIXED_STEP_METHODS",
    "SOLVER_METHODS",
    "Solver",
    "builtin_scenes",
    "load_scene",
    "read_toml_file",
    "scene_to_toml",
    "validity_warnings",
]

# The public home of these names is ``roughvib.scene``: the API reference documents them here
# (autodoc takes an object whose ``__module__`` is this package as its member) and error
# messages and reprs name ``roughvib.scene.Scene``. Pickle finds them here too (re-exported).
for _name in __all__:
    _obj = globals()[_name]
    if isinstance(_obj, type) or callable(_obj) and hasattr(_obj, "__code__"):
        if _obj.__module__.startswith(__name__ + "."):
            _obj.__module__ = __name__
del _name, _obj
