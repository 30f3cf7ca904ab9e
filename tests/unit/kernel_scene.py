"""The small scene the kernel unit tests evaluate (shared by conftest and the tests)."""

#: Overrides of the built-in ``paper`` scene: plate modes to 3 kHz (18 modes), a short
#: record and a fixed force amplitude (no run-in calibration).
SMALL_SCENE = {"plate.max_frequency": 3e3, "output.duration": 0.01,
               "excitation.force_amplitude": 0.9, "excitation.target_rms_velocity": "none"}
