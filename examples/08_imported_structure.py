"""
A structure of your own: a cantilever strip from its modes
==========================================================

The structure under the block is a component (docs: structures). Besides the simply supported
plate it can be any linear structure whose modes you have, from a finite-element model or a
modal test, written to a file in the exchange format: natural frequencies [Hz], node
coordinates (x, y) [m] and mass-normalised vertical mode shapes [1/sqrt(kg)] at the nodes.

Here the modes are computed in a few lines of numpy: a steel strip 300 x 60 x 3 mm, clamped at
x = 0 and free at x = 0.3 m, as an Euler-Bernoulli beam (bending along x only; a strip this
narrow has its first torsional mode far above the bending modes used here). The block sits
near the free end. The run is short: 0.15 s with the modes to 5 kHz.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import roughvib

L, b, h = 0.30, 0.06, 0.003            # strip length, width, thickness [m]
E, rho = 2.1e11, 7850.0                 # steel [Pa], [kg/m^3]
mass = rho * L * b * h                  # [kg]

# %%
# Clamped-free beam modes: beta_r L solves cos(bL) cosh(bL) = -1 (1.8751, 4.6941, ...,
# about (2r - 1) pi / 2 above), omega_r = beta_r^2 sqrt(E I / (rho A)), and the shape
# cosh(bx) - cos(bx) - s (sinh(bx) - sin(bx)) with s = (cosh bL + cos bL) / (sinh bL + sin bL),
# written with exponentials so that it stays accurate for the higher modes. Its mean square
# over the length is 1, so dividing by sqrt(mass) makes it mass-normalised.
from scipy.optimize import brentq  # noqa: E402

roots = [brentq(lambda z: np.cos(z) * np.cosh(z) + 1.0, (r - 0.5) * np.pi - 1.0,
                (r - 0.5) * np.pi + 1.0) for r in range(1, 13)]
beta = np.array(roots) / L
omega = beta**2 * np.sqrt(E * h**2 / (12.0 * rho))
frequency = omega / (2 * np.pi)


def beam_shape(bx: np.ndarray, bl: float) -> np.ndarray:
    s = (np.cosh(bl) + np.cos(bl)) / (np.sinh(bl) + np.sin(bl))
    hyper = 0.5 * ((1 - s) * np.exp(bx) + (1 + s) * np.exp(-bx))  # cosh - s sinh
    return hyper - np.cos(bx) + s * np.sin(bx)


x = np.linspace(0.0, L, 601)
y = np.linspace(0.0, b, 5)
X, Y = np.meshgrid(x, y, indexing="ij")
nodes = np.column_stack([X.ravel(), Y.ravel()])
shapes = np.array([beam_shape(br * nodes[:, 0], br * L) for br in beta]) / np.sqrt(mass)

# check the normalisation: the modal mass int rho h phi^2 dA is 1 kg (trapezoidal rule)
line = np.array([beam_shape(br * x, br * L) for br in beta]) / np.sqrt(mass)
modal_mass = rho * h * b * np.sum(0.5 * (line[:, 1:] ** 2 + line[:, :-1] ** 2) * np.diff(x),
                                  axis=1)
print("frequencies [Hz]:", np.round(frequency[:6], 1), "...")
print("modal masses [kg]:", np.round(modal_mass[:6], 5), "...")

fig, ax = plt.subplots(figsize=(8, 3))
for r in range(4):
    ax.plot(x, line[r], label=f"{frequency[r]:.0f} Hz")
ax.axvspan(0.22, 0.26, color="0.85", label="block")
ax.set_xlabel("x [m] (clamped at 0, free at 0.3)")
ax.set_ylabel("shape [1/√kg]")
ax.legend(loc="upper left", fontsize="small")
fig.tight_layout()

folder = Path(tempfile.mkdtemp())
np.savez(folder / "strip.npz", frequency=frequency, nodes=nodes, shapes=shapes)

# %%
# The scene names the file (relative paths start at the scene file's folder); the plate's
# length and width only bound where the block and the observer may sit, and
# ``plate.loss_factor`` gives the modes' damping (the file has no ``damping_ratio``).
scene = roughvib.load_scene("paper", {
    "plate.kind": "imported", "plate.modes_file": str(folder / "strip.npz"),
    "plate.length": L, "plate.width": b, "plate.max_frequency": 5000.0,
    "plate.block_position": [0.24, 0.03], "plate.observation_position": [0.29, 0.03],
    "output.duration": 0.15, "output.transient": 0.0, "output.progress": False})
result = roughvib.simulate(scene)
print(result.summary["model"]["structure"])

# %%
# The strip's response at its tip and the block's vertical acceleration.
ds = result.dataset
fig, ax = plt.subplots(figsize=(8, 3.5))
ax.plot(ds["time"], ds["plate_vertical_acceleration"], lw=0.5, label="strip tip")
ax.plot(ds["time"], ds["block_vertical_acceleration"], lw=0.5, label="block")
ax.set_xlabel("time [s]")
ax.set_ylabel("vertical acceleration [m/s²]")
ax.legend(loc="upper right")
fig.tight_layout()
