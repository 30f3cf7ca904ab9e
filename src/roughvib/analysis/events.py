"""Event-log analysis: stick and lift-off intervals, and the per-cycle phase table.

Works on the event table of a :class:`roughvib.results.Result` (or a saved ``events.csv``):
stick phases run from a ``stick`` event to the next ``slip`` event, lift-offs of contact k from
``lift_off`` to the next ``touch_down`` of k. The solvers log the friction phase a run starts in
as a ``stick`` or ``slip`` event at its start, so a stick phase from t = 0 has its own start
event and counts as a phase. A log without that event (a contact that starts open, a log
written before it was added) is recognised from the first event of the pair.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["GUARD_KINDS", "lift_off_intervals", "phase_table", "regime_series",
           "stick_intervals"]

GUARD_KINDS = ("hysteresis_hold", "dwell_hold", "chatter_guard", "event_storm")


def _intervals(times_kinds: list[tuple[float, str]], start: str, end: str, t0: float,
               t_end: float, *, with_origin: bool = False) -> list:
    """Intervals from start to end events; with_origin adds whether a start event opened it."""
    out = []
    t_open = None
    real = True
    first = next(((t, k) for t, k in times_kinds if k in (start, end)), None)
    if first is not None and first[1] == end and first[0] > t0:
        # the run started inside the phase (an end event at t0 says it started outside)
        t_open, real = t0, False
    for t, k in times_kinds:
        if k == start and t_open is None:
            t_open, real = t, True
        elif k == end and t_open is not None:
            out.append((t_open, t, real))
            t_open = None
    if t_open is not None:
        out.append((t_open, t_end, real))
    return out if with_origin else [(a, b) for a, b, _ in out]


def stick_intervals(events: pd.DataFrame, t_end: float, t0: float = 0.0
                    ) -> list[tuple[float, float]]:
    """Stick phases [(start, end)] in seconds, from the ``stick``/``slip`` events."""
    ev = events.sort_values("time", kind="stable")
    tk = [(float(t), str(k)) for t, k in zip(ev["time"], ev["kind"], strict=True)]
    return _intervals(tk, "stick", "slip", t0, t_end)


def lift_off_intervals(events: pd.DataFrame, contact: int, t_end: float, t0: float = 0.0
                       ) -> list[tuple[float, float]]:
    """Lift-off phases of one contact [(start, end)] in seconds."""
    ev = events[events["contact"] == contact].sort_values("time", kind="stable")
    tk = [(float(t), str(k)) for t, k in zip(ev["time"], ev["kind"], strict=True)]
    return _intervals(tk, "lift_off", "touch_down", t0, t_end)


def _overlap(intervals: list[tuple[float, float]], a: float, b: float) -> float:
    return sum(max(0.0, min(e, b) - max(s, a)) for s, e in intervals)


def phase_table(events: pd.DataFrame, t_end: float, period: float, n_contacts: int
                ) -> pd.DataFrame:
    """Per excitation cycle: stick fraction, stick phases, lift-offs per contact, guards.

    Parameters
    ----------
    events : DataFrame
        Event log (columns time, kind, contact).
    t_end : float
        End of the run [s].
    period : float
        Excitation period [s]; ``inf`` or 0 gives one row for the whole run. A piece at the
        end shorter than a thousandth of a period (a record of whole periods ends on the first
        output sample at or after its last period's end) belongs to the last cycle.
    n_contacts : int

    Returns
    -------
    DataFrame
        One row per cycle: ``cycle``, ``start`` and ``end`` [s], ``stick_fraction``,
        ``stick_phases`` (stick events in the cycle), ``mean_stick_duration`` [s] (of those
        phases, whole length), ``lift_offs_k`` (lift-off events of contact k) and
        ``lift_off_time_k`` [s] (time open within the cycle) for each contact k,
        ``guard_activations`` (hysteresis and dwell holds, chatter guards, storms).
    """
    if not math.isfinite(period) or period <= 0:
        edges = np.array([0.0, t_end])
    else:
        n = max(1, int(math.ceil(t_end / period - 1e-3)))
        edges = np.minimum(np.arange(n + 1) * period, t_end)
        edges[-1] = t_end
    ev = events.sort_values("time", kind="stable")
    tk = [(float(t), str(k)) for t, k in zip(ev["time"], ev["kind"], strict=True)]
    sticks_o = _intervals(tk, "stick", "slip", 0.0, t_end, with_origin=True)
    sticks = [(a, b) for a, b, _ in sticks_o]
    lifts_o = []
    for k in range(n_contacts):
        evk = ev[ev["contact"] == k]
        tkk = [(float(t), str(x)) for t, x in zip(evk["time"], evk["kind"], strict=True)]
        lifts_o.append(_intervals(tkk, "lift_off", "touch_down", 0.0, t_end, with_origin=True))
    lifts = [[(a, b) for a, b, _ in lo] for lo in lifts_o]
    guards = events[events["kind"].isin(GUARD_KINDS)]["time"].to_numpy(dtype=float)
    rows = []
    for c in range(edges.size - 1):
        a, b = float(edges[c]), float(edges[c + 1])
        if b <= a:
            continue
        # the last cycle also counts the events at the end of the run (a failed run stops
        # at its last event)
        b_ev = b if c < edges.size - 2 else float(np.nextafter(b, np.inf))
        started = [(s, e) for s, e, real in sticks_o if real and a <= s < b_ev]
        row = {
            "cycle": c, "start": a, "end": b,
            "stick_fraction": _overlap(sticks, a, b) / (b - a),
            "stick_phases": len(started),
            "mean_stick_duration": float(np.mean([e - s for s, e in started]))
            if started else 0.0,
        }
        for k in range(n_contacts):
            row[f"lift_offs_{k}"] = sum(1 for s, _, real in lifts_o[k]
                                        if real and a <= s < b_ev)
            row[f"lift_off_time_{k}"] = _overlap(lifts[k], a, b)
        row["guard_activations"] = int(np.sum((guards >= a) & (guards < b_ev)))
        rows.append(row)
    import pandas as pd

    return pd.DataFrame(rows)


def _step_series(times: np.ndarray, values: np.ndarray, initial: int, grid: np.ndarray
                 ) -> np.ndarray:
    """A piecewise-constant state on ``grid``: ``initial``, then ``values[i]`` from
    ``times[i]`` on (an event at a grid time counts from that sample)."""
    states = np.concatenate([[initial], values]).astype(np.int8)
    return states[np.searchsorted(times, grid, side="right")]


def regime_series(events: pd.DataFrame | list, time: np.ndarray, closed0: np.ndarray,
                  stick0: bool) -> tuple[np.ndarray, np.ndarray]:
    """The contacts' open/closed state and the block's stick flag on a time grid.

    Parameters
    ----------
    events : DataFrame or list
        Event log (columns time, kind, contact), or the solver's event records (attributes
        time, kind, contact; contact -1 for block-level events).
    time : ndarray, shape (n,)
        Output grid [s].
    closed0 : ndarray of int, shape (K,)
        1 where contact k is closed at the start of the run.
    stick0 : bool
        Whether the block starts in stick.

    Returns
    -------
    closed : ndarray of int8, shape (n, K)
        1 while contact k is closed, 0 while it is lifted off: ``closed0`` switched by the
        ``lift_off`` and ``touch_down`` events of contact k.
    stick : ndarray of int8, shape (n,)
        1 in a stick phase: ``stick0`` switched by the ``stick`` and ``slip`` events.
    """
    if isinstance(events, list):  # records: no pandas needed
        t = np.array([r.time for r in events], dtype=float)
        order = np.argsort(t, kind="stable")
        t = t[order]
        kind = np.array([r.kind for r in events], dtype=object)[order]
        contact = np.array([r.contact for r in events], dtype=float)[order]
    else:
        ev = events.sort_values("time", kind="stable")
        t = ev["time"].to_numpy(dtype=float)
        kind = ev["kind"].to_numpy(dtype=object)
        contact = ev["contact"].to_numpy(dtype=float, na_value=-1.0)
    grid = np.asarray(time, dtype=float)
    closed = np.empty((grid.size, len(closed0)), dtype=np.int8)
    for k, c0 in enumerate(closed0):
        sel = (contact == k) & ((kind == "lift_off") | (kind == "touch_down"))
        closed[:, k] = _step_series(t[sel], kind[sel] == "touch_down", int(c0), grid)
    sel = (kind == "stick") | (kind == "slip")
    return closed, _step_series(t[sel], kind[sel] == "stick", int(stick0), grid)
