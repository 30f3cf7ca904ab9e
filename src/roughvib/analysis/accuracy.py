"""The accuracy contract and the measurement of one run against another.

A run is *reference grade* when, against a converged solution of the same scene (docs/accuracy.md):

* the third-octave band levels of block and plate vertical acceleration, 100 Hz to 50 kHz,
  agree within 1 dB in every band whose reference level lies within 80 dB of the strongest
  reference band of that signal, over the scene's analysis window;
* event times (stick, slip, lift-off, touch-down) agree within 1e-6 s after one-to-one
  matching, and no event is left without a partner;
* the tangential velocity's relative rms error over the window is below 1e-4;
* the run's own energy audit closes to 1e-6 (relative residual).

:func:`measure_accuracy` measures all of these for a run against a reference run and returns a
plain dict (JSON-ready) with a verdict; ``roughvib run --verify`` writes it as the
``accuracy`` section of summary.json and the work-precision study (``roughvib compare``) takes
its columns from it, so both use the same numbers.

A band that carries power in the reference but none in the tested run (level -inf dB) is the
largest possible error (``inf``), never a skipped band.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from roughvib.analysis.compare import band_levels, common_grid, match_events, relative_rms_error
from roughvib.analysis.levels import whole_period_window

__all__ = ["CONTRACT", "Contract", "analysis_window", "band_deviations", "contract_ratio",
           "measure_accuracy", "verdict_line"]

#: the two signals whose band levels the contract covers: name in the report -> variable
SIGNALS = {"block": "block_vertical_acceleration", "plate": "plate_vertical_acceleration"}
_REF_ACC = 1e-6  # dB reference of the reported band levels [m/s^2]


@dataclass(frozen=True)
class Contract:
    """Limits of the accuracy contract (docs/accuracy.md).

    Attributes
    ----------
    band_db : float
        Largest band-level deviation [dB] in a checked band.
    dynamic_range_db : float
        Bands whose reference level lies more than this below the strongest reference band of
        the same signal are not checked [dB].
    f_min, f_max : float
        Nominal centre frequencies of the first and last third-octave band [Hz]; bands whose
        upper edge lies above the Nyquist frequency of the output grid are left out (at the
        1e-5 s output step the last band is the 40 kHz band, 35.5-44.7 kHz).
    event_dt : float
        Largest event-time deviation after one-to-one matching [s].
    velocity_rel_rms : float
        Largest relative rms deviation of the tangential velocity [-].
    energy_rel_residual : float
        Largest relative residual of the run's own energy audit [-].
    """

    band_db: float = 1.0
    dynamic_range_db: float = 80.0
    f_min: float = 100.0
    f_max: float = 50e3
    event_dt: float = 1e-6
    velocity_rel_rms: float = 1e-4
    energy_rel_residual: float = 1e-6


CONTRACT = Contract()
#: what refining the input's representation (its grid and tail limit) may move: every band
#: within 60 dB of the strongest by at most 0.5 dB (docs/accuracy.md, "The representation")
REPRESENTATION = Contract(band_db=0.5, dynamic_range_db=60.0)


def analysis_window(t: np.ndarray, period: float, transient: float) -> slice:
    """The scene's analysis window on grid ``t``: whole excitation periods after the run-in.

    A run shorter than its run-in is analysed over the whole record, and a scene without a
    finite period over everything after the run-in (as the run summary does).
    """
    if transient >= t[-1]:
        transient = 0.0
    return whole_period_window(t, period if math.isfinite(period) else 0.0, transient)


def band_deviations(x: np.ndarray, x_ref: np.ndarray, fs: float, *,
                    contract: Contract = CONTRACT) -> dict:
    """Third-octave band levels of a signal against a reference, with the contract's checks.

    Parameters
    ----------
    x, x_ref : ndarray, shape (n,)
        The tested and the reference signal on the same uniform grid [m/s^2].
    fs : float
        Sampling rate [Hz].
    contract : Contract
        Frequency range and dynamic range of the check.

    Returns
    -------
    dict
        ``centres`` [Hz], ``level_db`` and ``reference_db`` [dB re 1e-6 m/s^2] and
        ``deviation_db`` [dB] per band (arrays, Hann-windowed record); ``checked`` (bool array:
        reference band within ``dynamic_range_db`` of the strongest); ``worst_band_hz`` and
        ``worst_deviation_db`` (signed; ``±inf`` when a checked band is empty in one of the
        records), NaN when no band is checked.
    """
    fc, level, level_ref = band_levels(x, x_ref, fs, fmin=contract.f_min, fmax=contract.f_max,
                                       window="hann", ref_value=_REF_ACC)
    with np.errstate(invalid="ignore"):
        dev = level - level_ref
    finite_ref = np.isfinite(level_ref)
    checked = np.zeros(fc.size, bool)
    if finite_ref.any():
        checked = finite_ref & (level_ref >= np.max(level_ref[finite_ref])
                                - contract.dynamic_range_db)
    # a checked band the tested run lost (-inf) or that is NaN counts as the largest error
    dev = np.where(checked & ~np.isfinite(dev), np.where(dev > 0, np.inf, -np.inf), dev)
    worst_hz = worst = float("nan")
    if checked.any():
        i = np.flatnonzero(checked)[int(np.argmax(np.abs(dev[checked])))]
        worst_hz, worst = float(fc[i]), float(dev[i])
    return {"centres": fc, "level_db": level, "reference_db": level_ref, "deviation_db": dev,
            "checked": checked, "worst_band_hz": worst_hz, "worst_deviation_db": worst}


def _finite_or_none(v: float) -> float | None | str:
    """JSON-safe number: NaN -> None, ±inf -> "inf"/"-inf" (summary.json stays strict JSON)."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return None
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return v


def measure_accuracy(result, reference, *, period: float, transient: float,
                     contract: Contract = CONTRACT, reference_label: str = "") -> dict:
    """Measure a run against a reference run of the same scene and judge it by the contract.

    Parameters
    ----------
    result, reference : roughvib.results.Result
        Successful runs of the same scene; output grids that are integer multiples of each
        other (the coarser one is used, never an interpolation).
    period, transient : float
        The scene's excitation period and run-in [s] (:func:`analysis_window`).
    contract : Contract
        The limits (default: ``CONTRACT``).
    reference_label : str
        How the reference was made (written into the report).

    Returns
    -------
    dict
        JSON-ready: ``reference``, ``contract``, ``window`` [s], ``bands`` (per signal:
        ``worst_band_hz``, ``deviation_db``, ``bands_checked``, ``strongest_band_db``,
        ``per_band`` list of ``[centre Hz, reference dB, deviation dB]`` of the checked
        bands), ``events`` (``matched``, ``unmatched``, ``max_dt`` [s]),
        ``velocity_rel_rms``, ``energy_rel_residual`` (the run's) and
        ``reference_energy_rel_residual``, ``verdict`` (``"pass"`` or ``"fail"``) and
        ``failures`` (one sentence per broken limit).
    """
    ds, dr = result.dataset, reference.dataset
    sa, sr, dt = common_grid(ds["time"].values, dr["time"].values)
    t = ds["time"].values[sa]
    win = analysis_window(t, period, transient)
    tw = t[win]
    fails: list[str] = []
    bands = {}
    for name, var in SIGNALS.items():
        b = band_deviations(ds[var].values[sa][win], dr[var].values[sr][win], 1.0 / dt,
                            contract=contract)
        chk = b["checked"]
        per_band = [[float(f), float(r), _finite_or_none(float(d))] for f, r, d in
                    zip(b["centres"][chk], b["reference_db"][chk], b["deviation_db"][chk],
                        strict=True)]
        worst = b["worst_deviation_db"]
        bands[name] = {"worst_band_hz": _finite_or_none(b["worst_band_hz"]),
                       "deviation_db": _finite_or_none(worst),
                       "bands_checked": int(chk.sum()),
                       "strongest_band_db": _finite_or_none(
                           float(np.max(b["reference_db"][chk])) if chk.any() else math.nan),
                       "per_band": per_band}
        if not math.isnan(worst) and abs(worst) > contract.band_db:
            fails.append(f"{name} band {_hz(b['worst_band_hz'])} off by {worst:+.3g} dB "
                         f"(limit {contract.band_db:g} dB)")
    dts, unmatched = match_events(result.events, reference.events)
    max_dt = float(np.max(np.abs(dts))) if dts.size else 0.0
    if max_dt > contract.event_dt:
        fails.append(f"event times off by up to {max_dt:.3g} s (limit {contract.event_dt:g} s)")
    if unmatched:
        fails.append(f"{unmatched} event(s) without a partner in the other run")
    v = relative_rms_error(ds["block_tangential_velocity"].values[sa][win],
                           dr["block_tangential_velocity"].values[sr][win])
    if not math.isnan(v) and v > contract.velocity_rel_rms:
        fails.append(f"tangential velocity rel. rms deviation {v:.3g} (limit "
                     f"{contract.velocity_rel_rms:g})")
    energy = _audit_residual(result)
    if energy is None:  # the paper scheme keeps no audit: the item cannot be shown to hold
        fails.append("the run has no energy audit (its method keeps none)")
    elif not energy <= contract.energy_rel_residual:
        fails.append(f"energy audit residual {energy:.3g} (limit "
                     f"{contract.energy_rel_residual:g})")
    return {
        "reference": reference_label,
        "contract": asdict(contract),
        "window": [float(tw[0]), float(tw[-1])],
        "bands": bands,
        "events": {"matched": int(dts.size), "unmatched": int(unmatched),
                   "max_dt": max_dt},
        "velocity_rel_rms": _finite_or_none(v),
        "energy_rel_residual": energy,
        "reference_energy_rel_residual": _audit_residual(reference),
        "verdict": "fail" if fails else "pass",
        "failures": fails,
    }


def measure_representation(result, refined, *, period: float, transient: float,
                           refinement: str = "") -> dict:
    """Band levels of a run against the same run on a refined input representation.

    Parameters
    ----------
    result, refined : roughvib.results.Result
        A run and the same scene, solver and force on a finer grid and a shorter tail limit.
    period, transient : float
        As for :func:`measure_accuracy`.
    refinement : str
        What was refined (for the report).

    Returns
    -------
    dict
        ``refinement``, ``contract`` (:data:`REPRESENTATION`), ``bands`` (as
        :func:`measure_accuracy`'s), ``verdict`` and ``failures``.
    """
    ds, dr = result.dataset, refined.dataset
    sa, sr, dt = common_grid(ds["time"].values, dr["time"].values)
    win = analysis_window(ds["time"].values[sa], period, transient)
    fails: list[str] = []
    bands = {}
    for name, var in SIGNALS.items():
        b = band_deviations(ds[var].values[sa][win], dr[var].values[sr][win], 1.0 / dt,
                            contract=REPRESENTATION)
        worst = b["worst_deviation_db"]
        bands[name] = {"worst_band_hz": _finite_or_none(b["worst_band_hz"]),
                       "deviation_db": _finite_or_none(worst),
                       "bands_checked": int(b["checked"].sum())}
        if not math.isnan(worst) and abs(worst) > REPRESENTATION.band_db:
            fails.append(f"{name} band {_hz(b['worst_band_hz'])} moves by {worst:+.3g} dB on "
                         f"the refined input (limit {REPRESENTATION.band_db:g} dB)")
    return {"refinement": refinement, "contract": asdict(REPRESENTATION), "bands": bands,
            "verdict": "fail" if fails else "pass", "failures": fails}


def _audit_residual(result) -> float | None:
    """|relative residual| of a run's energy audit; None where the run keeps no audit."""
    value = (result.summary.get("energy_audit") or {}).get("relative_residual")
    if value is None or not math.isfinite(float(value)):
        return None
    return abs(float(value))


def contract_ratio(acc: dict) -> float:
    """The largest ratio of a measured deviation to its contract limit (<= 1: within the
    contract), from :func:`measure_accuracy`'s dict; inf for a lost band or an event without
    a partner, NaN if nothing was measured."""
    c = acc["contract"]
    ratios = []
    for b in acc["bands"].values():
        d = b["deviation_db"]
        if isinstance(d, str):
            return math.inf
        if d is not None:
            ratios.append(abs(d) / c["band_db"])
    if acc["events"]["unmatched"]:
        return math.inf
    ratios.append(acc["events"]["max_dt"] / c["event_dt"])
    if acc["velocity_rel_rms"] is not None:
        ratios.append(acc["velocity_rel_rms"] / c["velocity_rel_rms"])
    if acc["energy_rel_residual"] is None:  # no audit: the item cannot be shown to hold
        return math.inf
    ratios.append(acc["energy_rel_residual"] / c["energy_rel_residual"])
    return max(ratios) if ratios else math.nan


def _hz(f: float) -> str:
    return f"{f / 1e3:.3g} kHz" if f >= 1e3 else f"{f:.3g} Hz"


def verdict_line(acc: dict) -> str:
    """One line: the verdict, what it was measured against and the largest deviations."""
    if "bands" not in acc:
        return f"{acc['verdict'].upper()}: " + "; ".join(acc.get("failures", []))
    b = acc["bands"]
    parts = [f"{n} {_num(b[n]['deviation_db'], '+.2g')} dB @ {_hz_or(b[n]['worst_band_hz'])}"
             for n in SIGNALS if n in b]
    ev = acc["events"]
    parts.append(f"events {ev['max_dt']:.2g} s" + (f" ({ev['unmatched']} unmatched)"
                                                  if ev["unmatched"] else ""))
    parts.append(f"velocity {_num(acc['velocity_rel_rms'], '.2g')}")
    parts.append(f"energy {_num(acc['energy_rel_residual'], '.2g')}")
    if (rep := acc.get("representation")) and "bands" in rep:
        worst = max((rep["bands"][n] for n in SIGNALS if n in rep["bands"]),
                    key=lambda d: abs(d["deviation_db"] or 0.0))
        parts.append(f"refined input {_num(worst['deviation_db'], '+.2g')} dB @ "
                     f"{_hz_or(worst['worst_band_hz'])}")
    head = "PASS" if acc["verdict"] == "pass" else "FAIL"
    return f"{head} against {acc['reference']}: " + ", ".join(parts)


def _num(v, fmt: str) -> str:
    if v is None:
        return "n/a"
    if isinstance(v, str):
        return v
    return format(v, fmt)


def _hz_or(f) -> str:
    return "n/a" if f is None else _hz(float(f))
