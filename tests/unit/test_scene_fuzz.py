"""Scene fuzzing (issue 8, first part): any value of any type for any key either validates
(and the scene assembles) or stops with a one-line SceneError; never another exception."""

import dataclasses

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import roughvib
from roughvib.model.system import assemble
from roughvib.physics.surface.field import input_band
from roughvib.scene import _SECTIONS, SceneError

KEYS = [f"{sec}.{f.name}" for sec, cls in _SECTIONS.items() for f in dataclasses.fields(cls)]

values = st.one_of(
    st.none(), st.booleans(), st.integers(-10**6, 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-1e3, 1e3), st.floats(1e-9, 1.0), st.text(max_size=12),
    st.sampled_from(["none", "auto", "modal", "rigid", "cubic", "coulomb", "prescribed"]),
    st.lists(st.floats(0.0, 0.5), max_size=3),
)

# keep assembled scenes cheap: few modes, short profile, short run
#: a short run of few modes on the paper's 50 um band (the default tail to 0.2 um takes an FFT
#: of millions of points per example)
CHEAP = {"plate.max_frequency": 2e3, "output.duration": 0.002,
         "roughness.shortest_wavelength": 50e-6}


@pytest.mark.short_run
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(st.sampled_from(KEYS), values, min_size=1, max_size=3))
def test_random_overrides_validate_or_fail_with_one_line(overrides):
    over = {**CHEAP, **overrides}
    try:
        scene = roughvib.load_scene("paper", over)
    except SceneError as exc:
        assert "\n" not in str(exc) and str(exc)
        return
    try:
        if scene.plate.kind == "modal" and scene.plate.max_frequency > 5e3:
            return  # valid; too many modes to assemble inside a fuzz loop
        if scene.roughness.trace_length > 0.5 or input_band(scene).spacing < 1e-6:
            return  # valid; profile too long to build inside a fuzz loop
        assemble(scene)
    except SceneError as exc:
        assert "\n" not in str(exc) and str(exc)
