"""
Validating a run against a measured record
==========================================

A laboratory records the plate acceleration with its own instrument: another sample rate,
integer samples scaled to the recorder's input range, and an electrical noise floor.
``roughvib validate`` compares such a record with a run band by band. This example makes a
stand-in for a measurement from a run's own plate signal: resampled to 96 kHz, with white
noise of 3e-5 m/s^2 rms added, written as a 24-bit WAV file whose full scale is 10 m/s^2. Then
it validates the record and draws the comparison (the paper's Figs. 14/15 style). The run is
the paper scene for 0.3 s: a run-in of one excitation period (1/7 s) and one period analysed.
"""

import tempfile
import wave
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from scipy.signal import resample_poly

import roughvib
from roughvib.analysis.spectra import add_noise_floor
from roughvib.api import validate
from roughvib.views.validation import plot_validation

folder = Path(tempfile.mkdtemp())
scene = roughvib.load_scene("paper", {"output.duration": 0.3, "output.progress": False})
roughvib.simulate(scene).save(folder / "run")

# %%
# The stand-in measurement: the plate signal at 96 kHz plus noise, 24-bit integer samples.
# One full-scale unit (a sample of 2**23) is 10 m/s^2: that is the ``--scale`` of the record.
plate = roughvib.load_result(folder / "run").dataset["plate_vertical_acceleration"].values
measured = add_noise_floor(resample_poly(plate, 24, 25), 96000, 3e-5, seed=1)
full_scale = 10.0  # m/s^2
codes = np.round(measured / full_scale * 2**23).astype(np.int64)
with wave.open(str(folder / "plate_96k.wav"), "wb") as w:
    w.setnchannels(1)
    w.setsampwidth(3)  # 24 bit
    w.setframerate(96000)
    w.writeframes(b"".join(int(c).to_bytes(3, "little", signed=True) for c in codes))

# %%
# ``roughvib validate RUN plate_96k.wav --signal plate --scale 10 --noise-rms 3e-5`` does the
# same as this call: it writes ``RUN/validation/plate_96k/`` (bands.csv, validation.png,
# validation.json) and prints one line.
(v,) = validate(folder / "run", [folder / "plate_96k.wav"], signal="plate", scale=full_scale,
                noise_rms=3e-5)
print(v.summary_line())
print(sorted(p.name for p in (folder / "run" / "validation" / "plate_96k").iterdir()))

# %%
# The band table: in the bands well above the floor the record reads the run's levels (the
# same signal, another rate: the differences are those of the resampling filter); at high
# frequency the plate's response falls below the noise, and those bands are marked.
print(v.table.to_string(index=False, float_format=lambda x: f"{x:.2f}"))

# %%
# The figure ``validation.png`` holds: third-octave levels with the noise floor, and the
# narrow band of both.
plot_validation(v)
plt.tight_layout()
plt.show()
