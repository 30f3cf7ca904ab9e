"""
A measured roughness profile
============================

Instead of the synthetic profile, a scene can read a measured one from a text file
(``roughness.kind = "file"``): one height per line at ``roughness.spacing``, or two columns
``x, z``, or several columns of parallel traces that roughvib span-averages across the block
width (docs: surfaces). This example writes a small two-column file itself, standing in for a
profilometer trace: 9 000 points at 10 µm (90 mm: the 40 mm block, its stroke and a margin),
heights in micrometres. Then it inspects the surface as ``roughvib surface`` does and runs a
short simulation on it: one excitation period (1/7 s) with the plate modes cut at 5 kHz, to
keep the example short.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import roughvib
from roughvib.views.figures import plot_wavenumber
from roughvib.views.surface_report import write_surface_report

# A stand-in for a measurement: random-phase waves from 50 µm to 5 mm wavelength, amplitudes
# falling with wavenumber, scaled to 0.35 µm rms (the paper scene's input roughness).
rng = np.random.default_rng(7)
x_um = np.arange(9000) * 10.0
k = 2 * np.pi / rng.uniform(50.0, 5000.0, size=60)  # rad/um
phase = rng.uniform(0, 2 * np.pi, size=60)
z_um = np.sum(k[:, None] ** -1.3 * np.cos(k[:, None] * x_um + phase[:, None]), axis=0)
z_um *= 0.35 / z_um.std()

folder = Path(tempfile.mkdtemp())
trace = folder / "trace.csv"
with trace.open("w") as f:
    f.write("# stylus trace, x and z in micrometres\nx, z\n")
    for xi, zi in zip(x_um, z_um, strict=True):
        f.write(f"{xi:.1f}, {zi:.5f}\n")
print(trace.read_text().splitlines()[:5])

# %%
# The scene reads the file; the heights and x are in micrometres (``roughness.units``).
scene = roughvib.load_scene("paper", {"roughness.kind": "file", "roughness.path": str(trace),
                                      "roughness.units": "um",
                                      "output.duration": 1 / 7, "output.transient": 0.0,
                                      "plate.max_frequency": 5000.0,
                                      "output.progress": False})

# %%
# What ``roughvib surface`` writes: the profile with the chosen contact points (the highest
# maxima under the block; the paper scene derives their number from the surface statistics,
# ``contact.points = "auto"``), its wavenumber spectra and the contact statistics.
paths = write_surface_report(scene, folder / "surface")
print(sorted(p.name for p in paths.values()))
fig, ax = plt.subplots(figsize=(10, 6))
ax.imshow(plt.imread(paths["profile_png"]))
ax.set_axis_off()

# %%
# A short run on the measured surface, and the wavenumber spectra of the whole profile and of
# the stretch the first contact scans.
result = roughvib.simulate(scene)
print(result.status, f"block acceleration rms "
      f"{float(np.sqrt((result.dataset['block_vertical_acceleration'] ** 2).mean())):.3g} m/s^2")
plot_wavenumber(result)
plt.show()
