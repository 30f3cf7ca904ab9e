"""A measured record against a run: band levels side by side, their difference, the noise floor.

This module owns the numbers of a validation (:func:`compare_record`); the files and the figure
are made by :mod:`roughvib.views.validation`. The measured record and the run's signal (plate or
block vertical acceleration) are reduced the same way:

* **the same window length**: the run's analysis window (whole excitation periods after the
  run-in, :func:`roughvib.analysis.figures_data.analysis_window`) and as many samples of the
  record as cover the same time at the record's own rate. The record's window starts where the
  run's does (the run-in skipped), or at ``start``; a record too short for that gives its last
  window-length; a record shorter than the run's window gives its whole number of periods,
  and the run's window is cut to the same length.
* **the same band method**: every band level here comes from one private function,
  ``_band_levels`` (the method of the run's spectra), so a difference between the two columns
  is a difference between the signals, not between two estimators.

The record and the run may have different sample rates. Each side gets the bands its own rate
allows; a band present on one side only (above the lower Nyquist frequency), or with too few
averaging time in the window (bandwidth x time < 4), is left out of the comparison and named in
``left_out``.

Levels in dB re 1e-6 m/s^2; differences measured - simulated [dB]; frequencies in Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from roughvib.records import Record, RecordError
from roughvib.results import Result

__all__ = ["SIGNALS", "Validation", "compare_record", "noise_rms_band_levels",
           "validation_velocity_exponent"]

#: --signal -> dataset variable
SIGNALS = {"plate": "plate_vertical_acceleration", "block": "block_vertical_acceleration"}

REFERENCE = 1e-6  # m/s^2, the reference of every level here


def _band_levels(signal: np.ndarray, fs: float, settle: float = 0.0
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Third-octave band centres [Hz] and levels [dB re 1e-6 m/s^2] of one record.

    The single place where this module computes band levels, by the method of the run's
    spectra (the report's band table and Fig. 14): the IEC 61260-1 filter bank of
    :func:`roughvib.analysis.bands.band_levels`, run from the record's first sample and
    averaged after ``settle`` seconds, so that record and run are reduced alike.
    """
    from roughvib.analysis.bands import band_levels

    bl = band_levels(signal, fs, method="filter", settle=settle, reference=REFERENCE)
    return bl.exact_hz, bl.level_db


def _band_index(fc: np.ndarray) -> np.ndarray:
    """Integer k of the base-10 band (centre 1000 * 10**(k/10) Hz) of each centre."""
    return np.rint(10.0 * np.log10(np.asarray(fc, dtype=float) / 1000.0)).astype(int)


def noise_rms_band_levels(centres: np.ndarray, rms: float, fs: float) -> np.ndarray:
    """Third-octave band levels of white noise of a given rms [dB re 1e-6 m/s^2].

    White noise of mean square ``rms**2`` spread evenly from 0 to ``fs/2`` puts
    ``rms**2 (f_hi - f_lo) / (fs/2)`` into a band with edges ``f_c 10**(∓1/20)``.

    Parameters
    ----------
    centres : ndarray, shape (n_bands,)
        Exact band centres [Hz].
    rms : float
        Noise rms [m/s^2], > 0.
    fs : float
        Sample rate of the noisy record [Hz].

    Returns
    -------
    ndarray, shape (n_bands,)
        Levels [dB re 1e-6 m/s^2].
    """
    if not (rms > 0 and math.isfinite(rms)):
        raise ValueError(f"noise rms must be > 0 m/s^2, got {rms}")
    fc = np.asarray(centres, dtype=float)
    width = fc * (10.0 ** (1.0 / 20.0) - 10.0 ** (-1.0 / 20.0))
    return 10.0 * np.log10(rms**2 * width / (fs / 2.0) / REFERENCE**2)


def _nominal(fc) -> np.ndarray:
    from roughvib.analysis.spectra import nominal_centre

    return np.atleast_1d(nominal_centre(np.asarray(fc, dtype=float)))


def _hz(f: float) -> str:
    return f"{f / 1000:g} kHz" if f >= 1000 else f"{f:g} Hz"


def _energy_sum(levels: np.ndarray) -> float:
    if levels.size == 0:
        return math.nan
    return float(10.0 * np.log10(np.sum(10.0 ** (levels / 10.0))))


@dataclass(frozen=True)
class Validation:
    """A record compared with a run (:func:`compare_record`).

    Attributes
    ----------
    signal : str
        ``plate`` or ``block``.
    record : str
        The record's file.
    table : pandas.DataFrame
        One row per compared band: ``band_hz`` (nominal centre), ``simulated_db``,
        ``measured_db``, ``difference_db`` (measured - simulated), ``noise_db`` (the noise
        floor's band level, NaN without one) and ``at_noise_floor`` (the measurement within
        ``margin_db`` of the floor; NA without one). Levels in dB re 1e-6 m/s^2.
    left_out : list of (float, str)
        Nominal centre [Hz] and reason of every band not compared.
    overall_simulated_db, overall_measured_db, overall_difference_db : float
        Energetic sums of the compared bands [dB re 1e-6 m/s^2] and their difference [dB].
        Not the run summary's level of the signal, which is the rms of the whole signal over
        the window (``info["simulated_broadband_db"]``): the band filters' skirts overlap, so a
        sum of bands counts some power twice (0.07 dB more on ``paper-100mms``'s block).
    window_s : float
        Length of the compared windows [s].
    run_window : tuple of float
        Start and end of the run's samples [s].
    record_window : tuple of float
        Start and end of the record's samples, from its first sample [s].
    fs_run, fs_record : float
        Sample rates [Hz].
    frequency_run, psd_run, frequency_record, psd_record : ndarray
        Welch narrow-band densities [Hz], [dB re (1e-6 m/s^2)^2/Hz] of both windows.
    noise : str
        What the noise floor is (empty without one).
    margin_db : float
        The noise-floor margin [dB].
    notes : list of str
        What differs from a like-for-like comparison (a shorter window, a rate).
    info : dict
        Record and run details (units, channel, run id, scene, friction velocity).
    """

    signal: str
    record: str
    table: pd.DataFrame
    left_out: list
    overall_simulated_db: float
    overall_measured_db: float
    overall_difference_db: float
    window_s: float
    run_window: tuple
    record_window: tuple
    fs_run: float
    fs_record: float
    frequency_run: np.ndarray
    psd_run: np.ndarray
    frequency_record: np.ndarray
    psd_record: np.ndarray
    noise: str = ""
    margin_db: float = 6.0
    notes: list = field(default_factory=list)
    info: dict = field(default_factory=dict)

    def _clear(self) -> np.ndarray:
        """Which compared bands lie above the noise floor (all of them without a floor)."""
        t = self.table
        return (~t["at_noise_floor"].fillna(False).to_numpy(dtype=bool) if self.noise
                else np.ones(len(t), dtype=bool))

    def summary_line(self) -> str:
        """One line: the overall difference, the bands compared and what was left out."""
        t = self.table
        worst = ""
        clear = self._clear()
        if clear.any():
            d = np.where(clear, np.abs(t["difference_db"].to_numpy()), -1.0)
            i = int(np.argmax(d))
            worst = (f", largest {t['difference_db'].iloc[i]:+.1f} dB at "
                     f"{_hz(float(t['band_hz'].iloc[i]))}"
                     f"{' (of the bands above the noise floor)' if self.noise else ''}")
        span = (f"{len(t)} bands {_hz(float(t['band_hz'].iloc[0]))}-"
                f"{_hz(float(t['band_hz'].iloc[-1]))}" if len(t) else "no band")
        floor = ""
        if self.noise:
            floor = f"; {int(t['at_noise_floor'].sum())} at the noise floor"
        out = ""
        if self.left_out:
            out = "; left out: " + ", ".join(f"{_hz(f)} ({why})" for f, why in self.left_out)
        diff = round(self.overall_difference_db, 2) + 0.0  # no "-0.00"
        broadband = self.info.get("simulated_broadband_db")
        other = (f"; the run summary's {broadband:.1f} dB is the broadband rms"
                 if isinstance(broadband, float) and math.isfinite(broadband) else "")
        return (f"{self.signal} vs {self.record}: overall {diff:+.2f} dB "
                f"(measured {self.overall_measured_db:.1f}, simulated "
                f"{self.overall_simulated_db:.1f} dB re 1e-6 m/s^2, energy sums of the bands "
                f"compared{other}) over {span}{worst}{floor}{out}")

    def to_summary(self) -> dict:
        """The JSON-able summary (``validation.json``)."""
        return {
            "signal": self.signal, "record": self.record,
            "overall_simulated_db": self.overall_simulated_db,
            "overall_measured_db": self.overall_measured_db,
            "overall_difference_db": self.overall_difference_db,
            "bands_compared": int(len(self.table)),
            # over the bands above the noise floor, as the summary line's largest difference
            "max_abs_difference_db": (
                float(np.max(np.abs(self.table["difference_db"].to_numpy()[self._clear()])))
                if self._clear().any() else None),
            "bands_at_noise_floor": (int(self.table["at_noise_floor"].sum())
                                     if self.noise else None),
            "left_out": [{"band_hz": f, "reason": why} for f, why in self.left_out],
            "window_s": self.window_s, "run_window_s": list(self.run_window),
            "record_window_s": list(self.record_window),
            "fs_run_hz": self.fs_run, "fs_record_hz": self.fs_record,
            "noise": self.noise, "margin_db": self.margin_db, "notes": list(self.notes),
            "summary": self.summary_line(), **self.info,
        }


def _record_window(record: Record, n_want: int, i_run: int, period: float,
                   start: float | None) -> tuple[int, int, list[str]]:
    """First sample and length of the record's window, and notes."""
    n, fs, notes = record.signal.size, record.fs, []
    if start is not None:
        if not (start >= 0 and math.isfinite(start)):
            raise RecordError(f"{record.path}: --start must be >= 0 s, got {start}")
        i0 = int(round(start * fs))
    elif i_run + n_want <= n:
        i0 = i_run
    else:
        i0 = max(0, n - n_want)
        if i0 < i_run:
            notes.append(f"the record is too short to skip the run's run-in: its window starts "
                         f"at {i0 / fs:.4g} s")
    avail = n - i0
    if avail >= n_want:
        return i0, n_want, notes
    n_per = math.floor(avail / fs / period + 1e-9) if math.isfinite(period) else 0
    if n_per < 1:
        where = f" from --start {start} s" if start is not None else ""
        raise RecordError(f"{record.path}: record of {avail / fs:.4g} s{where} is shorter than "
                          f"one excitation period ({period:.4g} s)")
    length = int(round(n_per * period * fs))
    notes.append(f"the record holds {n_per} whole period(s) from its window start: both windows "
                 f"cut to {length / fs:.4g} s")
    return i0, length, notes


def compare_record(result: Result, record: Record, *, signal: str = "plate",
                   start: float | None = None, fmax: float | None = None,
                   noise: Record | None = None, noise_rms: float | None = None,
                   margin_db: float = 6.0, resolution: float = 25.0) -> Validation:
    """Compare a measured acceleration record with a run's plate or block acceleration.

    Parameters
    ----------
    result : Result
        A complete run.
    record : Record
        The measurement (:func:`roughvib.records.read_record`), in m/s^2.
    signal : {'plate', 'block'}
        Which of the run's vertical accelerations the record measured.
    start : float, optional
        Start of the record's window, from its first sample [s]. Default: the run's window
        start (its run-in skipped), or the record's last window-length if it is too short.
    fmax : float, optional
        Highest band to compare [Hz] (default: the run's highest band). The record must be
        sampled at least at twice it.
    noise : Record, optional
        A record of the measuring chain's noise (the same channel without excitation); its
        band levels are the floor.
    noise_rms : float, optional
        Instead of ``noise``: the rms of a white noise floor from 0 to the record's Nyquist
        frequency [m/s^2].
    margin_db : float
        A band is ``at_noise_floor`` when the measured level is less than this above the
        floor [dB], > 0.
    resolution : float
        Bin spacing of the narrow-band spectra [Hz].

    Returns
    -------
    Validation

    Raises
    ------
    RecordError
        One line naming the file: a record shorter than one excitation period, or sampled at
        less than twice the highest band.
    ValueError
        A bad option (signal, margin, both noise options), or a run without a complete
        record.
    """
    from roughvib.analysis.spectra import narrowband_psd

    _check_options(result, signal, margin_db, noise, noise_rms)
    w = _windows(result, record, signal, start)
    fs_run, fs_rec = w.fs_run, record.fs
    a, n_run = w.run_start, w.n_run
    # the filters run from each signal's first sample and average over the window only
    fc_s, l_s = _band_levels(w.x_run[:a + n_run], fs_run, settle=a / fs_run)
    ok_s = np.isfinite(l_s)
    top = float(_nominal(fc_s[ok_s][-1])[0]) if ok_s.any() else fs_run / 2
    fmax = top if fmax is None else float(fmax)
    if not fmax > 0:
        raise ValueError(f"fmax must be > 0 Hz, got {fmax}")
    if fs_rec < 2.0 * fmax:
        raise RecordError(f"{record.path}: sample rate {fs_rec:g} Hz is below 2 x the highest "
                          f"band ({fmax:g} Hz); give --fmax below {fs_rec / 2:g} Hz to compare "
                          f"the bands under the record's Nyquist frequency")
    fc_m, l_m = _band_levels(record.signal[:w.i0 + w.n_rec], fs_rec, settle=w.i0 / fs_rec)
    k_s, k_m = _band_index(fc_s), _band_index(fc_m)
    sim = dict(zip(k_s.tolist(), l_s, strict=True))
    mea = dict(zip(k_m.tolist(), l_m, strict=True))
    noise_levels, noise_text = _noise_floor(noise, noise_rms, w.n_rec, fc_m, k_m, fs_rec)
    table, left_out = _band_table(sim, mea, k_s, k_m, fmax, fs_run, fs_rec, noise_levels,
                                  noise_text, margin_db)
    o_s = _energy_sum(table["simulated_db"].to_numpy())
    o_m = _energy_sum(table["measured_db"].to_numpy())
    notes = w.notes
    if abs(fs_rec - fs_run) > 1e-9 * fs_run:
        notes.append(f"record sampled at {fs_rec:g} Hz, run at {fs_run:g} Hz")
    xs = w.x_run[a:a + n_run]
    xm = record.signal[w.i0:w.i0 + w.n_rec]
    f_s, p_s = narrowband_psd(xs, fs_run, resolution=resolution, ref=REFERENCE)
    f_m, p_m = narrowband_psd(xm, fs_rec, resolution=resolution, ref=REFERENCE)
    return Validation(
        signal=signal, record=record.path, table=table, left_out=left_out,
        overall_simulated_db=o_s, overall_measured_db=o_m, overall_difference_db=o_m - o_s,
        window_s=w.window_s, run_window=(float(w.t[a]), float(w.t[a + n_run - 1])),
        record_window=(w.i0 / fs_rec, (w.i0 + w.n_rec - 1) / fs_rec), fs_run=fs_run,
        fs_record=fs_rec, frequency_run=f_s, psd_run=p_s, frequency_record=f_m,
        psd_record=p_m, noise=noise_text, margin_db=margin_db, notes=notes,
        info=_validation_info(result, record, signal))


def _check_options(result: Result, signal: str, margin_db: float, noise: Record | None,
                   noise_rms: float | None) -> None:
    """Refuse a bad option of :func:`compare_record` or a run without a complete record
    (``ValueError``, one line)."""
    if signal not in SIGNALS:
        raise ValueError(f"signal must be one of {', '.join(SIGNALS)}, got {signal!r}")
    if not (margin_db > 0 and math.isfinite(margin_db)):
        raise ValueError(f"margin_db must be > 0 dB, got {margin_db}")
    if noise is not None and noise_rms is not None:
        raise ValueError("give either a noise record or a noise rms, not both")
    if not result.ok:
        raise ValueError(f"the run did not complete (status {result.status}): nothing to "
                         f"compare")


@dataclass(frozen=True)
class _Windows:
    """The compared windows of a run and a record (:func:`_windows`)."""

    t: np.ndarray        #: the run's output times [s]
    fs_run: float        #: the run's sample rate [Hz]
    x_run: np.ndarray    #: the run's signal [m/s^2], all of it
    run_start: int       #: first sample of the run's window
    n_run: int           #: samples of the run's window
    window_s: float      #: length of both windows [s]
    i0: int              #: first sample of the record's window
    n_rec: int           #: samples of the record's window
    notes: list          #: what differs from a like-for-like comparison


def _windows(result: Result, record: Record, signal: str, start: float | None) -> _Windows:
    """The run's analysis window and the record's window of the same length (cut to the
    record's whole periods where it is shorter; the module docstring).

    Raises
    ------
    RecordError
        The record (from ``start`` [s]) is shorter than one excitation period.
    """
    from roughvib.analysis import figures_data as fd

    period = fd.scene_of(result).period
    ds = result.dataset
    t = ds["time"].values
    fs_run = 1.0 / float(t[1] - t[0])
    win = fd.analysis_window(result)
    fs_rec = record.fs
    if math.isfinite(period) and record.duration < period * (1.0 - 1e-9):
        raise RecordError(f"{record.path}: record of {record.duration:.4g} s is shorter than "
                          f"one excitation period ({period:.4g} s)")
    x_run = np.asarray(ds[SIGNALS[signal]].values, dtype=float)
    n_run = win.stop - win.start
    window_s = n_run / fs_run
    i_run = int(round((t[win.start] - t[0]) * fs_rec))
    i0, n_rec, notes = _record_window(record, int(round(window_s * fs_rec)), i_run, period,
                                      start)
    if n_rec < int(round(window_s * fs_rec)):
        n_run = int(round(n_rec / fs_rec * fs_run))
        window_s = n_rec / fs_rec
    return _Windows(t=t, fs_run=fs_run, x_run=x_run, run_start=win.start, n_run=n_run,
                    window_s=window_s, i0=i0, n_rec=n_rec, notes=notes)


def _noise_floor(noise: Record | None, noise_rms: float | None, n_rec: int, fc_m: np.ndarray,
                 k_m: np.ndarray, fs_rec: float) -> tuple[dict[int, float], str]:
    """The noise floor's band levels [dB re 1e-6 m/s^2] by band index (of a noise record's
    first ``n_rec`` samples, or of white noise at ``noise_rms`` [m/s^2] in the record's bands
    ``fc_m`` [Hz], indices ``k_m``) and what it is (empty, with no levels, without one)."""
    if noise is not None:
        xn = noise.signal[:min(noise.signal.size, n_rec)]
        fc_n, l_n = _band_levels(xn, noise.fs)
        return (dict(zip(_band_index(fc_n).tolist(), l_n, strict=True)),
                f"record {noise.path} ({xn.size / noise.fs:.4g} s)")
    if noise_rms is not None:
        l_n = noise_rms_band_levels(fc_m, noise_rms, fs_rec)
        return (dict(zip(k_m.tolist(), l_n, strict=True)),
                f"white noise {noise_rms:g} m/s^2 rms (0 to {fs_rec / 2:g} Hz)")
    return {}, ""


def _left_out_reason(k: int, ls, lm, k_s: np.ndarray, k_m: np.ndarray, k_max: int,
                     fmax: float, fs_run: float, fs_rec: float) -> str | None:
    """Why band k is not compared (levels ``ls`` of the run, ``lm`` of the record [dB], None
    where a side has no such band), "" for a band to skip silently (below the window's
    resolution on both sides), None for a band to compare."""
    if k > k_max:
        if ls is not None and np.isfinite(ls):
            return f"above the highest band compared, {fmax:g} Hz"
        return ""
    if lm is None:
        return (f"above the record's Nyquist frequency {_hz(fs_rec / 2)}"
                if k > k_m.max() else "not in the record's bands")
    if ls is None:
        return (f"above the run's Nyquist frequency {_hz(fs_run / 2)}"
                if k > k_s.max() else "not in the run's bands")
    if not (np.isfinite(ls) and np.isfinite(lm)):
        if np.isnan(ls) and np.isnan(lm):
            return ""  # below the window's resolution on both sides: not a band here
        return ("too few FFT bins in the window" if (np.isnan(ls) or np.isnan(lm))
                else "no power")
    return None


def _band_table(sim: dict, mea: dict, k_s: np.ndarray, k_m: np.ndarray, fmax: float,
                fs_run: float, fs_rec: float, noise_levels: dict, noise_text: str,
                margin_db: float) -> tuple[pd.DataFrame, list]:
    """The compared bands (the rows of :attr:`Validation.table`) and the left-out bands
    (nominal centre [Hz], reason), from the run's and the record's levels by band index
    [dB re 1e-6 m/s^2]."""
    k_max = int(_band_index(np.array([fmax]))[0])
    rows, left_out = [], []
    for k in sorted(set(sim) | set(mea)):
        f_nom = float(_nominal(1000.0 * 10.0 ** (k / 10.0))[0])
        ls, lm = sim.get(k), mea.get(k)
        why = _left_out_reason(k, ls, lm, k_s, k_m, k_max, fmax, fs_run, fs_rec)
        if why is not None:
            if why:
                left_out.append((f_nom, why))
            continue
        ln = noise_levels.get(k, math.nan)
        rows.append({"band_hz": f_nom, "simulated_db": float(ls), "measured_db": float(lm),
                     "difference_db": float(lm - ls), "noise_db": float(ln),
                     "at_noise_floor": (bool(lm - ln < margin_db) if np.isfinite(ln)
                                        else pd.NA) if noise_text else pd.NA})
    table = pd.DataFrame(rows, columns=["band_hz", "simulated_db", "measured_db",
                                        "difference_db", "noise_db", "at_noise_floor"])
    if noise_text:
        table["at_noise_floor"] = table["at_noise_floor"].astype("boolean")
    return table, left_out


def _validation_info(result: Result, record: Record, signal: str) -> dict:
    """:attr:`Validation.info`: the record's units and channel, the run's id, scene,
    friction velocity ``v_rms`` [m/s] and the summary's broadband level of the signal
    [dB re 1e-6 m/s^2]."""
    m = result.summary.get("metrics", {})
    return {"record_units": record.units, "record_units_from": record.units_from,
            "record_channel": record.channel, "run_id": result.summary.get("run_id"),
            "scene": result.summary.get("scene"),
            "v_rms": m.get("block_tangential_velocity_rms"),
            # the summary's level: the rms of the whole signal over the run's window, not a
            # sum of bands (the filters' overlapping skirts count some power twice)
            "simulated_broadband_db": m.get(f"{SIGNALS[signal]}_level_db_re_1e-6")}


def validation_velocity_exponent(summaries: list[dict]) -> dict:
    """Velocity exponents of measured and simulated overall levels over several validations.

    Parameters
    ----------
    summaries : list of dict
        :meth:`Validation.to_summary` of validations of runs at different friction velocities
        (``v_rms`` [m/s]), at least two distinct ones, all of the same signal.

    Returns
    -------
    dict
        ``measured`` and ``simulated`` -> ``{"db_per_doubling", "exponent", "stderr"}``
        (power basis, :func:`roughvib.analysis.levels.velocity_exponent`), and ``points``:
        the (v_rms, measured, simulated) triples.
    """
    from roughvib.analysis.levels import velocity_exponent

    v = [s.get("v_rms") for s in summaries]
    if any(x is None for x in v):
        raise ValueError("a velocity exponent needs each run's friction velocity (v_rms)")
    out = {"points": [(float(a), s["overall_measured_db"], s["overall_simulated_db"])
                      for a, s in zip(v, summaries, strict=True)]}
    for key in ("measured", "simulated"):
        fit = velocity_exponent(v, [s[f"overall_{key}_db"] for s in summaries])
        out[key] = fit._asdict()
    return out
