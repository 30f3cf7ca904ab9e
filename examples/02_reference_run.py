"""
A reference run at the default settings
=======================================

The paper scene with everything at its default: all 393 plate modes to 50 kHz, ``solver.method
= "auto"`` (here the event-driven ``adaptive-modal`` solver) at ``solver.accuracy =
"reference"``, the preset that meets the accuracy contract (docs: accuracy), output on the
1e-5 s grid. Only the duration is cut, from 3/7 s to one excitation period from rest (1/7 s,
no run-in), so that the example runs in a few seconds; a real reference run is ``roughvib run``
(about 0.3 s of solver time for the full 3/7 s, 1-2 s for the whole command once the kernels
are compiled), and ``roughvib run --verify`` also checks it by a second, independent solver.
"""

import matplotlib.pyplot as plt

import roughvib
from roughvib.views.figures import plot_acceleration, plot_spectra

scene = roughvib.load_scene("paper", {"output.duration": 1 / 7, "output.transient": 0.0,
                                      "output.progress": False})
solver = scene.resolved_solver()  # what "auto" and the preset resolve to for this scene
print(f"{scene.name}: {scene.block.mass} kg block, solver {solver.method} "
      f"(accuracy {solver.accuracy!r}: rtol {solver.rtol:g}), "
      f"modes to {scene.plate.max_frequency / 1e3:g} kHz")
result = roughvib.simulate(scene)

# %%
# The summary says how the run went and how well its energy balance closes: the work of the
# excitation and of the roughness input equals the dissipation plus the change of stored
# energy, up to the integration error.
s = result.summary
print(f"status {result.status}, calibrated T0 = {s['force_amplitude']:.4f} N")
print(f"{s['solver']['steps']} steps, {len(result.events)} events, "
      f"solver wall time {s['solver']['wall_time']:.2f} s")
print(f"energy audit: relative residual {s['energy_audit']['relative_residual']:.1e}")

# %%
# The time series live in an :class:`xarray.Dataset` with units on every variable.
ds = result.to_dataset()
print(ds["plate_vertical_acceleration"].attrs["units"], ds.sizes)

# %%
# Block and plate accelerations over the run, and their third-octave spectra (IEC 61260-1
# class 1 filter bank, docs: bands). With one period from rest (1/7 s) the bands too narrow
# to be averaged over the window are left out.
plot_acceleration(result)
plot_spectra(result)
plt.show()
