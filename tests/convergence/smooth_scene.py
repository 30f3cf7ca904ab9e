"""The smooth test scene of the convergence tests (shared by their files)."""

#: One contact on a sinusoid, prescribed sliding, modal plate to 3 kHz, no lift-off: smooth and
#: linear, so that fitted orders are the schemes' own.
SMOOTH = {"contact.points": 1, "roughness.kind": "sinusoid", "roughness.amplitude": 0.05e-6,
          "roughness.wavelength": 1e-3, "excitation.kind": "prescribed",
          "excitation.velocity": 0.2, "excitation.amplitude": 0.0,
          "excitation.target_rms_velocity": "none", "plate.max_frequency": 3e3,
          "plate.loss_factor": 0.1, "output.duration": 0.02, "output.step": 2e-4,
          "output.progress": False}
