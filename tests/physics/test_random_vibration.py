"""The whole input chain against random-vibration closed forms.

A block on one linear contact spring slides at constant speed V (prescribed) over a rigid base
whose synthetic surface reaches down to 1 um. Passed at speed V, the surface's one-sided
wavenumber spectrum G(k) [m^2/(rad/m)] becomes the input's frequency spectrum

    S_u(f) = G(2 pi f / V) |H(2 pi f a / V)|^2 2 pi / V           [m^2/Hz]

(H the contact filter of spots of radius a, 1 without it), and the block's vertical
acceleration on the spring s with its damper r1 has

    S_a(f) = (2 pi f)^4 |T(f)|^2 S_u(f),   T = s / (s - m w^2 + i w r1).

The expected band powers are integrals of these closed forms over each third-octave band, with
G the model spectrum (``band_psd``), its functional high-pass and its normalisation integrated
here by quadrature; the run's band powers come from the recorded ``block_vertical_acceleration``
and from the second central difference of the recorded ``roughness_input`` (its transfer
function (2 - 2 cos(w dt))^2 / dt^4 is applied to the closed form: the input's displacement
spectrum falls so steeply that a window's leakage would decide its high bands). A finite
record of a random process scatters about the expectation by about 1 / sqrt(B T) in power (B
the bandwidth, T the record): the tolerance of a band is four times that.
"""

import math

import numpy as np
import pytest
from scipy import integrate

import roughvib
from roughvib.analysis.spectra import band_powers, third_octave_bands
from roughvib.api import simulate
from roughvib.physics.surface.field import hertz_filter
from roughvib.physics.surface.roughness import band_psd, functional_gain

V = 0.01          # m/s
S = 3.1e6         # N/m
M = 0.221         # kg
R1 = 83.0         # N s/m
RMS = 0.02e-6     # m: the spring never opens (its static compression is 0.7 um)
SPOT = 5e-6       # m
DURATION, TRANSIENT = 1.05, 0.05   # s: the start transient decays as exp(-r1 t / 2m)
BANDS = (500.0, 6300.0)            # Hz: 50 um ... 1.6 um at 10 mm/s, inside the 1 um tail


def _scene_overrides(filtered: bool) -> dict:
    return {"plate.kind": "rigid", "contact.points": 1, "contact.stiffness": S,
            "contact.velocity_factor": False, "block.vertical_damping": R1,
            "contact.filter": "hertz" if filtered else "none", "contact.spot_radius": SPOT,
            "roughness.rms": RMS, "roughness.shortest_wavelength": 1e-6,
            "excitation.kind": "prescribed", "excitation.velocity": V,
            "excitation.amplitude": 0.0, "excitation.target_rms_velocity": "none",
            "output.duration": DURATION, "output.transient": TRANSIENT,
            "output.progress": False}


@pytest.fixture(scope="module")
def runs():
    out = {}
    for filtered in (False, True):
        r = simulate(roughvib.load_scene("paper", _scene_overrides(filtered)))
        assert r.ok, r.summary["message"]
        assert not (r.events["kind"] == "lift_off").any()
        out[filtered] = r
    return out


def _model_spectrum(scene):
    """G(k) [m^2/(rad/m)] of the run's surface: the model shape times the functional filter,
    normalised by quadrature to the scene's rms (independent of the synthesis' bins)."""
    r, L = scene.roughness, scene.block.length

    def shape(k):
        return band_psd(np.atleast_1d(k), r, shortest=1e-6) \
            * functional_gain(np.atleast_1d(k), r.filter, L) ** 2

    kl, kh = 2 * np.pi / r.longest_wavelength, 2 * np.pi / 1e-6
    edges = np.geomspace(kl, kh, 200)
    var = sum(integrate.quad(lambda k: float(shape(k)[0]), a, b, limit=200)[0]
              for a, b in zip(edges[:-1], edges[1:], strict=True))
    return lambda k: shape(k) * (r.rms**2 / var)


def _expected(g, lower, upper, filtered, acceleration, dt=1e-5):
    out = []
    for lo, hi in zip(lower, upper, strict=True):
        def s_f(f):
            k = 2 * np.pi * f / V
            w = 2 * np.pi * f
            su = float(g(k)[0]) * 2 * np.pi / V
            if filtered:
                su *= float(hertz_filter(k * SPOT)) ** 2
            if acceleration:
                su *= w**4 * abs(S / (S - M * w**2 + 1j * w * R1)) ** 2
            else:  # the second central difference of the input
                su *= ((2 - 2 * math.cos(w * dt)) / dt**2) ** 2
            return su
        out.append(integrate.quad(s_f, lo, hi, limit=200)[0])
    return np.array(out)


def _measured(r, name, lower, upper):
    ds = r.dataset
    t = ds["time"].values
    x = ds[name].values
    x = x[:, 0] if x.ndim == 2 else x
    dt = t[1] - t[0]
    if name == "roughness_input":
        x = np.concatenate([[np.nan], (x[2:] - 2 * x[1:-1] + x[:-2]) / dt**2, [np.nan]])
    sel = (t >= TRANSIENT) & np.isfinite(x)
    return band_powers(x[sel], 1.0 / dt, lower, upper, window="hann")


def _bands():
    centre, lower, upper = third_octave_bands(BANDS[0] / 1.1, BANDS[1] * 1.1)
    return centre, lower, upper


@pytest.mark.parametrize("filtered", [False, True], ids=["no-filter", "hertz-filter"])
@pytest.mark.parametrize("name,acceleration", [("roughness_input", False),
                                               ("block_vertical_acceleration", True)])
def test_band_powers_follow_the_random_vibration_closed_form(runs, filtered, name,
                                                             acceleration):
    r = runs[filtered]
    centre, lower, upper = _bands()
    g = _model_spectrum(roughvib.load_scene("paper", _scene_overrides(filtered)))
    want = _expected(g, lower, upper, filtered, acceleration)
    got = _measured(r, name, lower, upper)
    bt = (upper - lower) * (DURATION - TRANSIENT) / 1.5  # Hann: 1.5 x the resolution
    tol_db = 10 * np.log10(1 + 4 / np.sqrt(bt))
    err = 10 * np.log10(got / want)
    bad = {f"{c:g} Hz": f"{e:+.2f} dB (tol {t:.2f})"
           for c, e, t in zip(centre, err, tol_db, strict=True) if abs(e) > t}
    assert not bad, bad


def test_the_filter_divides_each_band_by_its_closed_form(runs):
    """Same seed, same phases: the ratio of the filtered to the unfiltered band powers of the
    input is the band average of H^2 weighted by the spectrum. Both records scatter alike
    where H is smooth across a band; where the band holds a zero of H (q = 4.49, 7.73, ...),
    the bins near it weigh differently in the two, so the tolerance is the band's."""
    centre, lower, upper = _bands()
    g = _model_spectrum(roughvib.load_scene("paper", _scene_overrides(False)))
    ratio_want = (_expected(g, lower, upper, True, False)
                  / _expected(g, lower, upper, False, False))
    ratio_got = (_measured(runs[True], "roughness_input", lower, upper)
                 / _measured(runs[False], "roughness_input", lower, upper))
    err = 10 * np.log10(ratio_got / ratio_want)
    bt = (upper - lower) * (DURATION - TRANSIENT) / 1.5
    tol_db = 10 * np.log10(1 + 4 / np.sqrt(bt))
    assert np.all(np.abs(err) < tol_db), [f"{c:.0f}: {e:+.2f}/{t:.2f}"
                                          for c, e, t in zip(centre, err, tol_db, strict=True)]
    # and the filter matters there: at 6.3 kHz (lambda = 1.6 um, q = 20) it takes > 40 dB
    assert 10 * math.log10(ratio_want[-1]) < -40
