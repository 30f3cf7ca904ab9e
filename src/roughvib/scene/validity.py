"""Legal scene values outside the model's validity: :func:`~roughvib.scene.validity_warnings`.
"""

from __future__ import annotations

import math

from roughvib.scene.core import Scene

#: a plate thicker than this fraction of its smaller side is no thin (Kirchhoff) plate
THIN_PLATE_RATIO = 0.1
#: thin-plate theory holds for bending wavelengths longer than this many plate thicknesses
BENDING_WAVELENGTH_THICKNESSES = 6.0
#: relative shortfall of the analysis window against one excitation period that counts as
#: rounding, not as a short window: a period typed to 7 or more digits (the docs write two
#: periods at 7 Hz as 0.2857142857 s) passes. The metrics' whole-period window counts each
#: output sample as one step long, so a window short by less than one output step still
#: holds the period; 1e-6 of a period is below one step for any grid of fewer than 1e6
#: samples per period, so the tolerance never hides a window that misses a sample.
PERIOD_ROUNDING = 1e-6


def validity_warnings(scene: Scene) -> list[str]:
    """Legal scene values outside the model's validity, as one-line messages.

    * a plate thicker than 1/10 of its smaller side: Kirchhoff (thin-plate) theory does not
      hold;
    * plate modes whose bending wavelength is shorter than 6 plate thicknesses: thin-plate
      theory, which neglects shear and rotary inertia, overestimates their frequencies;
    * ``output.transient`` not shorter than ``output.duration``: the metrics include the
      run-in;
    * an analysis window (after the run-in) shorter than one excitation period: the rms
      values are no cycle averages, and a calibrated target velocity is missed.

    Parameters
    ----------
    scene : Scene

    Returns
    -------
    list of str
        Empty when nothing applies.
    """
    out = []
    plt = scene.plate
    side = min(plt.length, plt.width)
    if plt.kind == "modal":
        if plt.thickness > THIN_PLATE_RATIO * side:
            out.append(f"plate.thickness {plt.thickness} m is more than {THIN_PLATE_RATIO:g} x "
                       f"the plate's smaller side ({side} m): Kirchhoff (thin-plate) theory "
                       f"does not hold, so the plate modes are not those of this plate")
        else:
            # bending wavenumber k = 2 pi / (6 h) at omega = k^2 sqrt(B / m'')
            k = 2 * math.pi / (BENDING_WAVELENGTH_THICKNESSES * plt.thickness)
            f6 = k**2 * plt.wave_speed_factor / (2 * math.pi)
            if f6 < plt.max_frequency:
                out.append(f"plate modes above {f6:.4g} Hz have bending wavelengths shorter than "
                           f"{BENDING_WAVELENGTH_THICKNESSES:g} x plate.thickness "
                           f"({plt.thickness} m): thin-plate theory overestimates their "
                           f"frequencies (no shear, no rotary inertia); lower "
                           f"plate.max_frequency to {f6:.4g} Hz or read those bands with care, "
                           f"got {plt.max_frequency} Hz")
    out_ = scene.output
    exc = scene.excitation
    window = out_.duration - out_.transient
    if window <= 0:
        out.append(f"output.transient ({out_.transient:.6g} s) is not shorter than "
                   f"output.duration ({out_.duration:.6g} s): the metrics are taken over the "
                   f"whole record, run-in included")
        window = out_.duration
    periodic = exc.frequency > 0 and (exc.kind == "force" or exc.amplitude > 0)
    if periodic and window < scene.period * (1.0 - PERIOD_ROUNDING):
        target = (" and miss excitation.target_rms_velocity, which is calibrated for whole "
                  "cycles") if exc.kind == "force" and exc.target_rms_velocity else ""
        out.append(f"the analysis window ({window:.6g} s) is shorter than one excitation period "
                   f"({scene.period:.6g} s): the rms values and levels average over part of a "
                   f"cycle{target}; make output.duration - output.transient at least one period")
    return out
