"""Old import paths (before one layer per folder) keep working for one release, with a warning."""

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import roughvib
from roughvib._compat import MOVED

SRC = Path(roughvib.__file__).parent

#: the public names of the old modules (their __all__ before the move), without the
#: command-line handlers, which moved to roughvib.cli
OLD_PUBLIC = {
    "roughvib.plate": ["PlateModes", "infinite_plate_mobility", "mode_shapes", "plate_modes",
                       "point_mobility", "residual_compliance", "static_compliance",
                       "transfer_mobility"],
    "roughvib.friction": ["calibrate_force_amplitude", "feldmann_mu", "feldmann_mu_law",
                          "latch_margin", "latch_update", "law_parameters", "mu_reference",
                          "rms_over_periods", "simulate_tangential"],
    "roughvib.surface": [],
    "roughvib.surface.roughness": [
        "MeasuredProfile", "Profile", "areal_psd", "band_psd", "build_profile",
        "cbrt2_positions", "functional_filter", "profile_statistics", "read_profile_file",
        "select_contacts", "span_average", "spectral_moments", "synthesize_profile",
        "synthesize_span_averages", "trapezoid_weights", "uniform_positions"],
    "roughvib.surface.interp": ["build_coefficients", "profile_eval", "profile_eval_many"],
    "roughvib.surface.contact": ["GRAVITY", "ContactSolution", "ContactStiffness",
                                 "SummitParameters", "contact_stiffness", "effective_modulus",
                                 "gw_integral", "solve_contact", "summit_parameters",
                                 "velocity_factor"],
    "roughvib.plots": ["FIGURES", "plot_acceleration", "plot_band_comparison", "plot_events",
                       "plot_friction_displacement", "plot_friction_velocity",
                       "plot_friction_velocity_pair", "plot_regime_timeline", "plot_spectra",
                       "plot_tangential_stiffness", "plot_velocity", "plot_velocity_sweep",
                       "plot_wavenumber", "save_figure"],
    "roughvib.report": ["build_report", "write_report"],
    "roughvib.surface_report": ["scan_range", "write_surface_report"],
    "roughvib.compare": ["DEFAULT_RTOLS", "DEFAULT_STEPS", "FIXED_METHODS",
                         "TOLERANCE_METHODS", "crossings", "errors_against", "run_study"],
    "roughvib.sweep": ["Case", "Sweep", "SweepRun", "THREAD_ENV", "builtin_sweeps",
                       "case_name", "collect_table", "load_sweep", "run_sweep",
                       "scene_key_units", "sweep_report"],
}


def test_every_moved_module_is_covered():
    assert set(MOVED) == set(OLD_PUBLIC)


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_path_warns_and_is_the_new_module(old, monkeypatch):
    new = importlib.import_module(MOVED[old])
    monkeypatch.delitem(sys.modules, old, raising=False)  # import it afresh
    with pytest.warns(DeprecationWarning, match=rf"{old} moved to {MOVED[old]}"):
        mod = importlib.import_module(old)
    assert mod is new
    assert sys.modules[old] is new
    assert new.__name__ == MOVED[old] and new.__spec__.name == MOVED[old]  # unchanged
    missing = [n for n in OLD_PUBLIC[old] if not hasattr(mod, n)]
    assert not missing, f"{old} lost {missing}"


def test_from_import_of_an_old_submodule(monkeypatch):
    for name in ("roughvib.surface", "roughvib.surface.interp"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    with pytest.warns(DeprecationWarning, match="roughvib.surface moved"):
        from roughvib.surface import interp
    from roughvib.physics.surface import interp as new

    assert interp is new


def test_unknown_names_are_not_answered():
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("roughvib.no_such_module")


def _imported_names(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module
            yield from (f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            yield from (a.name for a in node.names)


def test_the_package_uses_no_old_path():
    bad = [f"{p.relative_to(SRC)} imports {name}" for p in SRC.rglob("*.py")
           for name in _imported_names(p) if name in MOVED]
    assert not bad, "\n".join(bad)


def test_importing_the_entry_points_does_not_warn():
    code = "import roughvib, roughvib.cli, roughvib.api"
    p = subprocess.run([sys.executable, "-W", "error::DeprecationWarning", "-c", code],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
