"""Radiated sound of the plate: modal velocities from the contact forces, band levels of the
plate's mean-square velocity, of the radiated sound power and of the radiation efficiency.

The plate is linear and the only forces on it are the normal contact forces at the fixed contact
points (the friction forces act in the plate's plane and do not bend it), so the modal
coordinates of a run follow exactly from the stored ``contact_force`` and the plate's initial
state: each mode is a damped oscillator driven by sum_k phi_r(x_k) F_k(t) / M. The forces are
known on the output grid; between samples they are taken as linear (first-order hold, whose
sinc^2 filtering of the force is undone in the band levels) and each mode is propagated exactly
over each step (:func:`modal_response`). That this reproduces the solver's own modal states is
checked against the plate acceleration the solver stored (``plate_vertical_acceleration``, a
sum over the same modal states): tests/physics/test_radiation.py and docs/radiation.md give
the measured agreement.

With the modal velocities dq_r(t):

* the plate's space-averaged mean-square velocity is <v^2> = (1/4) sum_r dq_r^2 (orthogonal
  shapes sin sin with mean square 1/4), band by band from each mode's own spectrum;
* the radiated power, neglecting the coupling between modes, is
  W = rho0 c0 S sum_r sigma_r(f) <v_r^2>, with each mode's bin power weighted by its radiation
  efficiency at the bin's frequency (:func:`roughvib.physics.radiation.modal_radiation_efficiency`),
  so a mode driven off resonance radiates with the efficiency of the frequency it moves at;
* the band radiation efficiency is sigma = W / (rho0 c0 S <v^2>).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from roughvib.analysis.spectra import nominal_centre, third_octave_bands
from roughvib.physics.plate import PlateModes, mode_shapes, plate_modes
from roughvib.physics.radiation import (
    AIR_DENSITY,
    SHAPE_MEAN_SQUARE,
    SOUND_SPEED,
    modal_pressure,
    modal_radiation_efficiency,
    mutual_radiation_efficiency,
)
from roughvib.scene import Plate

__all__ = [
    "RADIATION_COLUMNS",
    "SOUND_POWER_REF",
    "VELOCITY_REF",
    "RadiationBands",
    "check_radiating_plate",
    "cross_modal_check",
    "microphone_bands",
    "modal_response",
    "radiation_bands",
]

#: reference of the sound power level [W] (1 pW)
SOUND_POWER_REF = 1e-12
#: reference of the velocity level [m/s] (1 nm/s, ISO 1683)
VELOCITY_REF = 1e-9
#: reference of the sound pressure level [Pa]
PRESSURE_REF = 2e-5
# frequencies per third-octave band at which the microphones' transfer functions are computed
# (linear interpolation in between, after removing the delay to the plate centre; 16 change
# the paper run's levels by at most 0.05 dB)
_PRESSURE_PER_BAND = 8
#: columns of ``radiation.csv``
RADIATION_COLUMNS = ("band_hz", "sound_power_db", "mean_square_velocity_db",
                     "radiation_efficiency_db")
# modes propagated and transformed at once (memory: samples x chunk floats, 3 arrays)
_CHUNK = 48
# frequencies per third-octave band at which the modal efficiencies are computed (log-log
# interpolation in between)
_SIGMA_PER_BAND = 6



# rows and columns of a mode's first-order-hold step matrix [Phi | Gamma_0 | Gamma_1], (2, 4):
# rows the state (q, dq), columns Phi's two, then the weights of the inputs u_k and u_k+1
ROW_Q, ROW_DQ = 0, 1
COL_PHI_Q, COL_PHI_DQ, COL_GAMMA0, COL_GAMMA1 = 0, 1, 2, 3
# the input and its slope in the augmented state (q, dq, u, u') of _foh_expm
AUG_U, AUG_DU = 2, 3
#: the row of the initial state in the sampled modal histories (T, R)
FIRST_SAMPLE = 0

def check_radiating_plate(plate: Plate) -> None:
    """Refuse, in one line, a plate whose radiation is not defined here.

    Radiation is computed for the built-in simply supported plate (``plate.kind = "modal"``;
    a ``kind`` of ``"simply_supported"`` is accepted as the same plate). A rigid plate does not
    vibrate, and an imported structure has no radiating surface this module knows of.

    Raises
    ------
    ValueError
        ``output.radiation needs the built-in simply supported plate (plate.kind = "modal"),
        got plate.kind = '...'``.
    """
    kind = getattr(plate, "kind", "simply_supported")
    if kind not in ("modal", "simply_supported"):
        raise ValueError(f"output.radiation needs the built-in simply supported plate "
                         f"(plate.kind = \"modal\"), got plate.kind = {kind!r}")


def _foh_matrices(modes: PlateModes, dt: float) -> np.ndarray:
    """Exact one-step propagation of each mode under a force linear within the step.

    Returns ``(R, 2, 4)``: [Phi | Gamma_0 | Gamma_1] with x_(k+1) = Phi x_k + Gamma_0 u_k +
    Gamma_1 u_(k+1), x = (q, dq), u the modal force per modal mass [m/s^2]: the step maps of
    the adaptive exact-modal solver (:func:`roughvib.solvers.adaptive_modal.step_maps`, tested
    against scipy's expm), and the matrix exponential for a critically damped mode (zeta = 1,
    ``plate.loss_factor`` = 2), which those maps do not take.
    """
    from roughvib.solvers.adaptive_modal import step_maps

    w = modes.omega
    z = modes.damping_ratio
    R = len(modes)
    under = np.sqrt(np.clip(1.0 - z * z, 0.0, None)) > 5e-7  # distinct complex eigenvalues
    mats = np.empty((R, 2, 4))
    idx = np.flatnonzero(under)
    if idx.size:
        P, g0, g1 = np.empty((idx.size, 2, 2)), np.empty((idx.size, 2)), np.empty((idx.size, 2))
        step_maps(np.ascontiguousarray(w[idx] ** 2),
                  np.ascontiguousarray(2.0 * z[idx] * w[idx]), float(dt), P, g0, g1)
        mats[idx, :, COL_PHI_Q:COL_PHI_DQ + 1] = P
        mats[idx, :, COL_GAMMA0] = g0
        mats[idx, :, COL_GAMMA1] = g1
    for r in np.flatnonzero(~under):  # critically damped: no distinct eigenvalues
        mats[r] = _foh_expm(w[r], z[r], dt)
    return mats


def _foh_expm(w: float, z: float, h: float) -> np.ndarray:
    """[Phi | Gamma_0 | Gamma_1] of one mode by the matrix exponential of the oscillator
    augmented by the force and its slope."""
    from scipy.linalg import expm

    aug = np.zeros((4, 4))
    aug[ROW_Q, ROW_DQ] = 1.0
    aug[ROW_DQ, ROW_Q] = -w * w
    aug[ROW_DQ, ROW_DQ] = -2.0 * z * w
    aug[ROW_DQ, AUG_U] = 1.0   # input u enters the acceleration
    aug[AUG_U, AUG_DU] = 1.0   # u' = (u_1 - u_0) / h, constant within the step
    E = expm(aug * h)
    # the augmented state is (q, dq, u, u'): its first two rows and columns are Phi, the input
    # columns give the first-order hold's Gamma_0 (weight of u_k) and Gamma_1 (of u_k+1)
    mat = np.empty((2, 4))
    mat[:, COL_PHI_Q:COL_PHI_DQ + 1] = E[ROW_Q:ROW_DQ + 1, COL_PHI_Q:COL_PHI_DQ + 1]
    mat[:, COL_GAMMA0] = E[ROW_Q:ROW_DQ + 1, AUG_U] - E[ROW_Q:ROW_DQ + 1, AUG_DU] / h
    mat[:, COL_GAMMA1] = E[ROW_Q:ROW_DQ + 1, AUG_DU] / h
    return mat


@njit(cache=True)
def _propagate(u, mats, q0, dq0, q, dq):  # pragma: no cover - compiled; tested without JIT
    """Step the modes over the samples: u (T, R) input, mats (R, 2, 4), fills q, dq (T, R)."""
    T, R = u.shape
    for r in range(R):
        a = q0[r]
        b = dq0[r]
        q[FIRST_SAMPLE, r] = a
        dq[FIRST_SAMPLE, r] = b
        p00, p01 = mats[r, ROW_Q, COL_PHI_Q], mats[r, ROW_Q, COL_PHI_DQ]
        p10, p11 = mats[r, ROW_DQ, COL_PHI_Q], mats[r, ROW_DQ, COL_PHI_DQ]
        g00, g01 = mats[r, ROW_Q, COL_GAMMA0], mats[r, ROW_Q, COL_GAMMA1]
        g10, g11 = mats[r, ROW_DQ, COL_GAMMA0], mats[r, ROW_DQ, COL_GAMMA1]
        for t in range(T - 1):
            na = p00 * a + p01 * b + g00 * u[t, r] + g01 * u[t + 1, r]
            nb = p10 * a + p11 * b + g10 * u[t, r] + g11 * u[t + 1, r]
            a = na
            b = nb
            q[t + 1, r] = a
            dq[t + 1, r] = b


def modal_response(force: ArrayLike, contact_xy: ArrayLike, dt: float, modes: PlateModes, *,
                   q0: ArrayLike | None = None, dq0: ArrayLike | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Modal displacements and velocities of the plate driven by the contact forces.

    Parameters
    ----------
    force : array_like, shape (T, K)
        Normal contact forces on the plate at the output samples [N] (``contact_force``).
    contact_xy : array_like, shape (K, 2)
        Plate coordinates of the contacts [m].
    dt : float
        Sample spacing [s].
    modes : PlateModes
        The modes to follow (any subset of the plate's modes).
    q0, dq0 : array_like, shape (R,), optional
        Initial modal displacements [m] and velocities [m/s]; by default the static
        equilibrium under the first sample of the forces (the initial state every roughvib
        solver starts from) at rest.

    Returns
    -------
    q, dq : ndarray, shape (T, R)
        Modal displacements [m] and velocities [m/s] (shapes of maximum 1, so q_r is the
        amplitude of mode r at its antinode).

    Notes
    -----
    Mode r obeys q'' + 2 zeta_r omega_r q' + omega_r^2 q = sum_k phi_r(x_k) F_k(t) / M; with
    F linear between samples each step is the exact solution. The only approximation is the
    force between samples: below the Nyquist frequency the first-order hold passes the
    force's spectrum times sinc^2(f dt) (-0.29 dB at 10 kHz, -1.16 dB at 20 kHz for
    dt = 1e-5 s), which :func:`radiation_bands` undoes.
    """
    F = np.asarray(force, dtype=float)
    xy = np.asarray(contact_xy, dtype=float)
    if F.ndim != 2 or xy.shape != (F.shape[1], 2):
        raise ValueError(f"force must be (T, K) and contact_xy (K, 2), got {F.shape} and "
                         f"{xy.shape}")
    x, y = xy.T
    phi = mode_shapes(modes, x, y)  # (R, K)
    u = np.ascontiguousarray(F @ phi.T) / modes.modal_mass
    if q0 is None:
        q0 = u[0] / modes.omega**2
    if dq0 is None:
        dq0 = np.zeros(len(modes))
    q = np.empty_like(u)
    dq = np.empty_like(u)
    _propagate(u, _foh_matrices(modes, dt), np.asarray(q0, dtype=float),
               np.asarray(dq0, dtype=float), q, dq)
    return q, dq


@dataclass(frozen=True)
class RadiationBands:
    """Third-octave band levels of the plate's vibration and radiated sound.

    Attributes
    ----------
    centre : ndarray, shape (B,)
        Exact band centres [Hz]; ``band_hz`` are the nominal labels.
    band_hz : ndarray, shape (B,)
    mean_square_velocity : ndarray, shape (B,)
        Space- and time-averaged mean-square normal velocity of the plate [(m/s)^2].
    sound_power : ndarray, shape (B,)
        Radiated sound power, all radiating sides [W].
    radiation_efficiency : ndarray, shape (B,)
        W / (rho0 c0 sides S <v^2>) [-].
    sides : int
        Radiating sides (1 or 2).
    n_modes : int
        Modes summed.

    NaN marks a band the record is too short to resolve (fewer than 4 FFT bins, Hann window).
    """

    centre: np.ndarray
    band_hz: np.ndarray
    mean_square_velocity: np.ndarray
    sound_power: np.ndarray
    radiation_efficiency: np.ndarray
    sides: int
    n_modes: int

    def levels(self) -> dict[str, np.ndarray]:
        """The columns of ``radiation.csv``: band_hz, sound power level [dB re 1 pW], mean-square
        velocity level [dB re (1e-9 m/s)^2] and radiation efficiency [dB re 1]."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return {
                "band_hz": self.band_hz,
                "sound_power_db": 10.0 * np.log10(self.sound_power / SOUND_POWER_REF),
                "mean_square_velocity_db": 10.0 * np.log10(self.mean_square_velocity
                                                           / VELOCITY_REF**2),
                "radiation_efficiency_db": 10.0 * np.log10(self.radiation_efficiency),
            }

    def total_sound_power(self) -> float:
        """Sum of the resolved bands' sound power [W]."""
        return float(np.nansum(self.sound_power))



def _window_spectrum(window: slice, samples: int, dt: float, who: str
                     ) -> tuple[int, int, np.ndarray, np.ndarray]:
    """Start and stop of the analysis window in a record of ``samples``, its Hann taper
    (normalised to unit mean square) and the frequencies of its FFT bins [Hz]; ``who`` begins
    the refusal of a window shorter than 8 samples."""
    stop = window.stop if window.stop is not None else samples
    start = window.start or 0
    n = stop - start
    if n < 8:
        raise ValueError(f"{who} an analysis window of >= 8 samples, got {n}")
    taper = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)
    taper /= math.sqrt(np.mean(taper**2))
    return start, stop, taper, np.fft.rfftfreq(n, dt)

def radiation_bands(force: ArrayLike, contact_xy: ArrayLike, dt: float, plate: Plate,
                    window: slice, *, q0: ArrayLike | None = None,
                    dq0: ArrayLike | None = None, sides: int = 1,
                    air_density: float = AIR_DENSITY, sound_speed: float = SOUND_SPEED,
                    fmin: float = 50.0, fmax: float = 20e3) -> RadiationBands:
    """Band levels of the mean-square velocity and radiated power of a run's plate.

    Parameters
    ----------
    force : array_like, shape (T, K)
        Contact forces on the plate over the whole run [N] (from t = 0, the initial state).
    contact_xy : array_like, shape (K, 2)
        Contact positions [m].
    dt : float
        Output step [s].
    plate : Plate
        The run's plate (``kind`` must be the built-in simply supported plate).
    window : slice
        Samples analysed (e.g. whole excitation periods after the run-in).
    q0, dq0 : array_like, shape (R,), optional
        Initial modal state of all the plate's modes (``plate_modes(plate)`` order); see
        :func:`modal_response`.
    sides : {1, 2}
        Radiating sides.
    air_density, sound_speed : float
        rho0 [kg/m^3] and c0 [m/s].
    fmin, fmax : float
        Range of the nominal band centres [Hz] (bands above the Nyquist frequency dropped).

    Returns
    -------
    RadiationBands

    Notes
    -----
    All modes of the run (``plate.max_frequency``) are summed. Each modal velocity is tapered
    by a periodic Hann window of unit mean square over ``window`` (the convention of the run
    report's band spectra) and transformed; bin j of mode r contributes
    (1/4) P_r(f_j) to <v^2> and rho0 c0 S sides sigma_r(f_j) (1/4) P_r(f_j) to W, sigma_r
    interpolated (log-log) between 6 frequencies per band. P_r is divided by the power gain
    sinc^4(f dt) of the first-order hold of the force between samples (:func:`modal_response`),
    which otherwise lowers the levels by 0.3 dB at 10 kHz and 1.2 dB at 20 kHz. Cross-modal
    coupling is neglected (see docs/radiation.md for its measured size).
    """
    check_radiating_plate(plate)
    if sides not in (1, 2):
        raise ValueError(f"output.radiating_sides must be 1 or 2, got {sides}")
    fs = 1.0 / dt
    fc, lo, hi = third_octave_bands(fmin, fmax)
    keep = hi <= 0.5 * fs * (1.0 + 1e-12)
    fc, lo, hi = fc[keep], lo[keep], hi[keep]
    modes = plate_modes(plate)
    R = len(modes)
    q0 = None if q0 is None else np.asarray(q0, dtype=float)
    dq0 = None if dq0 is None else np.asarray(dq0, dtype=float)
    F = np.asarray(force, dtype=float)
    start, stop, taper, f = _window_spectrum(window, F.shape[0], dt, "radiation needs")
    F = F[:stop]
    n = stop - start
    band_of = np.searchsorted(hi, f, side="right")  # bin j in band i when lo_i <= f_j < hi_i
    in_band = (f >= lo[0]) & (f < hi[-1])
    nbins = np.bincount(band_of[in_band], minlength=fc.size)
    hold = _hold_power_gain(f[in_band], dt)
    # modal efficiencies on a log grid covering the bands
    grid = np.geomspace(lo[0], hi[-1], _SIGMA_PER_BAND * fc.size + 1)
    S = plate.length * plate.width
    log_sigma = np.log(np.maximum(modal_radiation_efficiency(
        modes.n, modes.m, plate.length, plate.width, grid, sound_speed), 1e-300))
    lg, lf = np.log(grid), np.log(f[in_band])
    idx = band_of[in_band]
    v2 = np.zeros(fc.size)
    wsum = np.zeros(fc.size)
    for r0 in range(0, R, _CHUNK):
        sub = _subset(modes, slice(r0, r0 + _CHUNK))
        _, dq = modal_response(F, contact_xy, dt, sub,
                               q0=None if q0 is None else q0[r0:r0 + _CHUNK],
                               dq0=None if dq0 is None else dq0[r0:r0 + _CHUNK])
        x = dq[start:stop].T
        x = (x - x.mean(axis=1, keepdims=True)) * taper
        X = np.fft.rfft(x, axis=1)
        p = (X.real**2 + X.imag**2) / float(n) ** 2
        p[:, 1:] *= 2.0  # one-sided; the bands never hold DC, and fs/2 lies above them
        p = p[:, in_band] / hold
        sig = np.exp(np.stack([np.interp(lf, lg, ls) for ls in log_sigma[r0:r0 + _CHUNK]]))
        v2 += np.bincount(idx, weights=SHAPE_MEAN_SQUARE * p.sum(axis=0), minlength=fc.size)
        wsum += np.bincount(idx, weights=SHAPE_MEAN_SQUARE * (sig * p).sum(axis=0),
                            minlength=fc.size)
    power = air_density * sound_speed * S * sides * wsum
    with np.errstate(invalid="ignore", divide="ignore"):
        eff = wsum / v2
    bad = nbins < 4
    v2[bad] = power[bad] = eff[bad] = np.nan
    return RadiationBands(centre=fc, band_hz=nominal_centre(fc), mean_square_velocity=v2,
                          sound_power=power, radiation_efficiency=eff, sides=sides,
                          n_modes=R)


def cross_modal_check(force: ArrayLike, contact_xy: ArrayLike, dt: float, plate: Plate,
                      window: slice, bands: ArrayLike, *, q0: ArrayLike | None = None,
                      dq0: ArrayLike | None = None, mode_factor: float = 4.0,
                      points_per_band: int = 5, sound_speed: float = SOUND_SPEED
                      ) -> dict[str, np.ndarray]:
    """Radiated power of a run in a few bands with and without the coupling between modes.

    The full power of one side is rho0 c0 S / 4 sum_j sum_(r,s) sigma_rs(f_j) Re C_rs(f_j),
    C_rs the one-sided cross power of the modal velocities in FFT bin j (same Hann taper as
    :func:`radiation_bands`) and sigma_rs the mutual radiation efficiencies
    (:func:`roughvib.physics.radiation.mutual_radiation_efficiency`, linear interpolation
    between ``points_per_band`` frequencies across the band); the diagonal terms alone give
    the power :func:`radiation_bands` reports.

    Parameters
    ----------
    force, contact_xy, dt, plate, window, q0, dq0
        As :func:`radiation_bands`.
    bands : array_like, shape (B,)
        Nominal third-octave centres to check [Hz].
    mode_factor : float
        Modes up to ``mode_factor`` times the band's upper edge are summed (both sums use the
        same modes).
    points_per_band : int
        Frequencies at which sigma_rs is computed in each band.
    sound_speed : float
        c0 [m/s].

    Returns
    -------
    dict
        ``band_hz``; ``diagonal`` and ``full``, the power of one side divided by rho0 c0
        [m^2 (m/s)^2]; ``ratio_db`` = 10 log10(full / diagonal); ``modes``, the number of
        modes summed per band.
    """
    bands = np.atleast_1d(np.asarray(bands, dtype=float))
    modes = plate_modes(plate)
    F = np.asarray(force, dtype=float)
    stop = window.stop if window.stop is not None else F.shape[0]
    start = window.start or 0
    n = stop - start
    taper = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)
    taper /= math.sqrt(np.mean(taper**2))
    f = np.fft.rfftfreq(n, dt)
    S = plate.length * plate.width
    out = {"band_hz": bands, "diagonal": np.zeros(bands.size), "full": np.zeros(bands.size),
           "modes": np.zeros(bands.size, dtype=int)}
    for i, b in enumerate(bands):
        lo, hi = b * 10.0 ** (-1.0 / 20.0), b * 10.0 ** (1.0 / 20.0)
        keep = modes.frequency <= mode_factor * hi
        sub = _subset(modes, keep)
        _, dq = modal_response(F[:stop], contact_xy, dt, sub,
                               q0=None if q0 is None else np.asarray(q0)[keep],
                               dq0=None if dq0 is None else np.asarray(dq0)[keep])
        x = dq[start:stop].T
        x = (x - x.mean(axis=1, keepdims=True)) * taper
        X = np.fft.rfft(x, axis=1)
        sel = (f >= lo) & (f < hi)
        Xb = X[:, sel] / (float(n) * np.sinc(f[sel] * dt) ** 2)
        fg = np.linspace(lo, hi, points_per_band)
        sig = np.stack([mutual_radiation_efficiency(sub.n, sub.m, plate.length, plate.width,
                                                    fj, sound_speed) for fj in fg])
        full = diag = 0.0
        for j, fj in enumerate(f[sel]):
            k = min(int(np.searchsorted(fg, fj, side="right")) - 1, points_per_band - 2)
            t = (fj - fg[k]) / (fg[k + 1] - fg[k])
            s_j = (1.0 - t) * sig[k] + t * sig[k + 1]
            c = 2.0 * np.real(np.outer(np.conj(Xb[:, j]), Xb[:, j]))  # one-sided cross power
            full += float(np.sum(s_j * c))
            diag += float(np.sum(np.diag(s_j) * np.diag(c)))
        out["full"][i] = SHAPE_MEAN_SQUARE * S * full
        out["diagonal"][i] = SHAPE_MEAN_SQUARE * S * diag
        out["modes"][i] = len(sub)
    out["ratio_db"] = 10.0 * np.log10(out["full"] / out["diagonal"])
    return out


def microphone_bands(force: ArrayLike, contact_xy: ArrayLike, dt: float, plate: Plate,
                     window: slice, points: ArrayLike, *, q0: ArrayLike | None = None,
                     dq0: ArrayLike | None = None, air_density: float = AIR_DENSITY,
                     sound_speed: float = SOUND_SPEED, fmin: float = 50.0,
                     fmax: float = 5000.0, mode_factor: float = 4.0,
                     per_band: int = _PRESSURE_PER_BAND) -> tuple[np.ndarray, np.ndarray]:
    """Third-octave sound pressure levels at field points above the baffled plate.

    Parameters
    ----------
    force, contact_xy, dt, plate, window, q0, dq0, air_density, sound_speed
        As :func:`radiation_bands`.
    points : array_like, shape (M, 3)
        Microphones [x, y, z] [m], z > 0.
    fmin, fmax : float
        Range of the nominal band centres [Hz].
    mode_factor : float
        Modes up to ``mode_factor`` times the highest band's upper edge are summed.
    per_band : int
        Frequencies per band at which the transfer functions are computed.

    Returns
    -------
    band_hz : ndarray, shape (B,)
        Nominal band centres [Hz].
    levels : ndarray, shape (M, B)
        Sound pressure levels [dB re 20 uPa]; NaN for a band with fewer than 4 FFT bins.

    Notes
    -----
    The pressure is the coherent sum p(f) = sum_r G_r(x, f) V_r(f) over the modes (cross-modal
    terms included), G_r from the Rayleigh integral
    (:func:`roughvib.physics.radiation.modal_pressure`), V_r the Hann-tapered spectrum of the
    modal velocity with the first-order hold undone. G_r exp(+i k R_c), R_c the distance to
    the plate centre, is smooth in frequency (it changes over c0 / (plate diagonal)); it is
    computed at ``per_band`` frequencies per band and interpolated linearly to the FFT bins.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    check_radiating_plate(plate)
    fs = 1.0 / dt
    fc, lo, hi = third_octave_bands(fmin, fmax)
    keep = hi <= 0.5 * fs * (1.0 + 1e-12)
    fc, lo, hi = fc[keep], lo[keep], hi[keep]
    modes = plate_modes(plate)
    use = modes.frequency <= mode_factor * hi[-1]
    sub = _subset(modes, use)
    F = np.asarray(force, dtype=float)
    start, stop, taper, f = _window_spectrum(window, F.shape[0], dt, "microphones need")
    n = stop - start
    in_band = (f >= lo[0]) & (f < hi[-1])
    fb = f[in_band]
    idx = np.searchsorted(hi, fb, side="right")
    nbins = np.bincount(idx, minlength=fc.size)
    grid = np.geomspace(lo[0], hi[-1], per_band * fc.size + 1)
    centre = np.array([plate.length / 2.0, plate.width / 2.0, 0.0])
    rc = np.linalg.norm(pts - centre, axis=1)  # (M,)
    # patches: a tenth of the shortest acoustic wavelength, an eighth of the shortest half wave
    spacing = min(sound_speed / hi[-1] / 10.0,
                  min(plate.length / sub.n.max(), plate.width / sub.m.max()) / 8.0)
    G = modal_pressure(sub.n, sub.m, plate.length, plate.width, pts, grid,
                       air_density=air_density, sound_speed=sound_speed,
                       spacing=spacing)  # (M, R, Fg)
    kg = 2.0 * math.pi * grid / sound_speed
    kb = 2.0 * math.pi * fb / sound_speed
    G = G * np.exp(1j * kg[None, None, :] * rc[:, None, None])
    _, dq = modal_response(F[:stop], contact_xy, dt, sub,
                           q0=None if q0 is None else np.asarray(q0)[use],
                           dq0=None if dq0 is None else np.asarray(dq0)[use])
    x = dq[start:stop].T
    x = (x - x.mean(axis=1, keepdims=True)) * taper
    V = np.fft.rfft(x, axis=1)[:, in_band] / (float(n) * np.sinc(fb * dt) ** 2)  # (R, bins)
    levels = np.empty((pts.shape[0], fc.size))
    for i in range(pts.shape[0]):
        Gi = np.array([np.interp(fb, grid, g.real) + 1j * np.interp(fb, grid, g.imag)
                       for g in G[i]])  # (R, bins)
        P = np.sum(Gi * V, axis=0) * np.exp(-1j * kb * rc[i])
        power = np.bincount(idx, weights=2.0 * np.abs(P) ** 2, minlength=fc.size)
        with np.errstate(divide="ignore"):
            levels[i] = 10.0 * np.log10(power / PRESSURE_REF**2)
    levels[:, nbins < 4] = np.nan
    return nominal_centre(fc), levels


def _hold_power_gain(f: np.ndarray, dt: float) -> np.ndarray:
    """Power gain sinc(f dt)^4 of the first-order hold at frequencies f [Hz].

    A force known at samples k dt and taken as linear in between has, below the Nyquist
    frequency, the spectrum of the force times sinc^2(f dt) (sinc(x) = sin(pi x) / (pi x)):
    the hold is a triangle of width 2 dt. Dividing the modal power by sinc^4 undoes it for a
    force whose content lies below the Nyquist frequency; 1.16 dB at 20 kHz for dt = 1e-5 s.
    """
    return np.sinc(f * dt) ** 4


def _subset(modes: PlateModes, sl: slice) -> PlateModes:
    return PlateModes(n=modes.n[sl], m=modes.m[sl], omega=modes.omega[sl],
                      modal_mass=modes.modal_mass, damping_ratio=modes.damping_ratio[sl],
                      length=modes.length, width=modes.width)
