"""Error metrics between a run and a reference run (work-precision studies).

* :func:`band_levels`, :func:`band_level_errors` — third-octave band levels of two signals and
  their differences [dB], reduced to the largest ``|dB|`` over a frequency range by
  :func:`max_abs_db` (a band lost by the tested signal is an infinite error);
* :func:`relative_rms_error` — rms(x - x_ref) / rms(x_ref) on a common grid;
* :func:`match_events` — one-to-one matching of events of the same kind and contact by time
  (greedy by closeness within a window), returning the time errors and the unmatched count.

The signals of the two runs may be sampled differently (a fixed-step run with a step longer
than the reference's output step): :func:`common_grid` brings both onto the coarser grid by
taking every m-th sample, so the comparison never interpolates.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from roughvib.analysis.spectra import band_powers, third_octave_bands

__all__ = ["band_level_errors", "band_levels", "common_grid", "match_events", "max_abs_db",
           "relative_rms_error"]


def common_grid(t_a: np.ndarray, t_b: np.ndarray) -> tuple[slice, slice, float]:
    """Sample-picking slices that put two uniform grids starting at 0 on the coarser one.

    Returns
    -------
    sel_a, sel_b : slice
        ``x_a[sel_a]`` and ``x_b[sel_b]`` are on the same times.
    dt : float
        The common spacing [s].

    Raises
    ------
    ValueError
        If one spacing is not an integer multiple of the other.
    """
    da = float(t_a[1] - t_a[0])
    db = float(t_b[1] - t_b[0])
    dt = max(da, db)
    ma = dt / da
    mb = dt / db
    if abs(ma - round(ma)) > 1e-6 * ma or abs(mb - round(mb)) > 1e-6 * mb:
        raise ValueError(f"grids of {da:g} s and {db:g} s are not integer multiples")
    ma, mb = int(round(ma)), int(round(mb))
    n = min((t_a.size - 1) // ma, (t_b.size - 1) // mb) + 1
    return slice(0, (n - 1) * ma + 1, ma), slice(0, (n - 1) * mb + 1, mb), dt


def band_levels(x: np.ndarray, x_ref: np.ndarray, fs: float, *, fmin: float = 100.0,
                fmax: float = 50e3, window: str = "hann", ref_value: float = 1e-6
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Third-octave band levels of a signal and of its reference [dB re ``ref_value``].

    Bands are those of :func:`roughvib.analysis.spectra.third_octave_bands` with the upper edge
    below fs/2. Both records are tapered with ``window``
    (:func:`roughvib.analysis.spectra.band_powers`): the Hann default keeps the leakage of loud
    bands out of quiet ones, which with ``"boxcar"`` can mask an error in a band 60 dB below
    its neighbour. A band without power has the level -inf.

    Returns
    -------
    centres : ndarray [Hz]
    level, level_ref : ndarray [dB]
    """
    fc, lo, hi = third_octave_bands(fmin, fmax)
    keep = hi <= fs / 2 * (1 + 1e-12)
    fc, lo, hi = fc[keep], lo[keep], hi[keep]
    pa = band_powers(np.asarray(x, float), fs, lo, hi, window=window)
    pr = band_powers(np.asarray(x_ref, float), fs, lo, hi, window=window)
    with np.errstate(divide="ignore"):
        return (fc, 10.0 * np.log10(pa / ref_value**2), 10.0 * np.log10(pr / ref_value**2))


def band_level_errors(x: np.ndarray, x_ref: np.ndarray, fs: float, *, fmin: float = 100.0,
                      fmax: float = 50e3, window: str = "hann", floor_db: float | None = None,
                      ref_value: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Third-octave band level difference L(x) - L(x_ref) [dB] per band (:func:`band_levels`).

    A band where the reference has no power gives NaN (nothing to compare). A band where the
    reference has power and ``x`` has none gives -inf: the largest possible error, which
    :func:`max_abs_db` reports as inf.

    ``floor_db`` (dB re ``ref_value``, in the signal's unit) also gives NaN for bands whose
    reference level lies below it: the resolution a tolerance promises.

    Returns
    -------
    centres : ndarray [Hz]
    diff_db : ndarray [dB]
    """
    fc, level, level_ref = band_levels(x, x_ref, fs, fmin=fmin, fmax=fmax, window=window,
                                       ref_value=ref_value)
    with np.errstate(invalid="ignore"):
        d = level - level_ref
    d[~np.isfinite(level_ref)] = np.nan
    if floor_db is not None:
        d[level_ref < floor_db] = np.nan
    return fc, d


def max_abs_db(centres: np.ndarray, diff_db: np.ndarray, f_lo: float, f_hi: float) -> float:
    """Largest ``|dB|`` over bands with centres in [f_lo, f_hi]; inf if a band there was lost
    (-inf, see :func:`band_level_errors`); NaN if no band is available."""
    sel = (centres >= f_lo * 0.999) & (centres <= f_hi * 1.001) & ~np.isnan(diff_db)
    return float(np.max(np.abs(diff_db[sel]))) if sel.any() else float("nan")


def relative_rms_error(x: np.ndarray, x_ref: np.ndarray) -> float:
    """rms(x - x_ref) / rms(x_ref) [-] (arrays of equal length on the same grid)."""
    x = np.asarray(x, dtype=float)
    r = np.asarray(x_ref, dtype=float)
    den = float(np.sqrt(np.mean(r * r)))
    return float(np.sqrt(np.mean((x - r) ** 2)) / den) if den > 0 else float("nan")


def match_events(events: pd.DataFrame, reference: pd.DataFrame, *,
                 kinds=("stick", "slip", "lift_off", "touch_down"), window: float = 1e-3
                 ) -> tuple[np.ndarray, int]:
    """Match events one-to-one to the reference by kind, contact and time.

    For each (kind, contact) the pairs are taken greedily in order of increasing ``|dt|``, each
    event used at most once, and only within ``window`` [s].

    Returns
    -------
    dt : ndarray
        Time errors t - t_ref of the matched pairs [s].
    unmatched : int
        Events of either run without a partner.
    """
    errs: list[float] = []
    unmatched = 0
    for kind in kinds:
        a = events[events["kind"] == kind]
        b = reference[reference["kind"] == kind]
        ca = a["contact"].fillna(-1).astype(int).to_numpy() if len(a) else np.array([], int)
        cb = b["contact"].fillna(-1).astype(int).to_numpy() if len(b) else np.array([], int)
        for c in set(ca.tolist()) | set(cb.tolist()):
            ta = a["time"].to_numpy(dtype=float)[ca == c]
            tb = b["time"].to_numpy(dtype=float)[cb == c]
            if ta.size and tb.size:
                d = np.abs(ta[:, None] - tb[None, :])
                order = np.argsort(d, axis=None, kind="stable")
                used_a = np.zeros(ta.size, bool)
                used_b = np.zeros(tb.size, bool)
                for flat in order:
                    i, j = divmod(int(flat), tb.size)
                    if d[i, j] > window:
                        break
                    if not used_a[i] and not used_b[j]:
                        used_a[i] = used_b[j] = True
                        errs.append(float(ta[i] - tb[j]))
                unmatched += int((~used_a).sum() + (~used_b).sum())
            else:
                unmatched += ta.size + tb.size
    return np.array(errs), unmatched
