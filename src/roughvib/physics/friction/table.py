"""The set-valued ``table`` law: a kinetic curve read from a CSV file (docs/friction.md).

Stick is the set-valued regime shared with ``coulomb``; in slip the coefficient is the
monotone cubic Hermite (PCHIP) interpolant of the table (:func:`table_kinetic`), packed for the
kernels by :func:`law_table`.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from numba import njit

from roughvib.scene import FRICTION_LAWS, SANE_BOUNDS, Friction, SceneError

__all__ = ["LAW_ID", "TAB_HEAD", "TAB_N", "law_table", "load_friction_table", "pchip_slopes",
           "table_kinetic"]

#: the law's id in the kernels (``off[OFF_LAW]``; ``roughvib.physics.friction.laws``)
LAW_ID = 2

#: positions in the packed table of the ``table`` law (:func:`law_table`): the row count, then
#: the velocities, the coefficients and the PCHIP slopes, ``TAB_HEAD + 3 n`` floats in all
TAB_N = 0
TAB_HEAD = 1


@njit(cache=True)
def table_kinetic(v, tab):
    """Kinetic coefficient of a tabulated curve: monotone cubic Hermite (PCHIP) interpolation.

    Parameters
    ----------
    v : float
        Sliding speed [m/s]. Below 0 (a Newton iterate) the first interval's tangent is
        continued linearly; beyond the last row the last coefficient holds (slope 0).
    tab : ndarray
        Packed table of :func:`law_table`.

    Returns
    -------
    mu_k : float
        [-].
    dmu_k_dv : float
        [s/m].
    """
    n = int(tab[TAB_N])
    iv = TAB_HEAD
    im = TAB_HEAD + n
    isl = TAB_HEAD + 2 * n
    if v <= tab[iv]:
        return tab[im] + tab[isl] * (v - tab[iv]), tab[isl]
    if v >= tab[iv + n - 1]:
        return tab[im + n - 1], 0.0
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if tab[iv + mid] <= v:
            lo = mid
        else:
            hi = mid
    h = tab[iv + hi] - tab[iv + lo]
    s = (v - tab[iv + lo]) / h
    y0 = tab[im + lo]
    y1 = tab[im + hi]
    d0 = tab[isl + lo]
    d1 = tab[isl + hi]
    s2 = s * s
    s3 = s2 * s
    h00 = 2.0 * s3 - 3.0 * s2 + 1.0
    h10 = s3 - 2.0 * s2 + s
    h01 = -2.0 * s3 + 3.0 * s2
    h11 = s3 - s2
    mu = h00 * y0 + h10 * h * d0 + h01 * y1 + h11 * h * d1
    dmu = ((6.0 * s2 - 6.0 * s) * (y0 - y1) / h + (3.0 * s2 - 4.0 * s + 1.0) * d0
           + (3.0 * s2 - 2.0 * s) * d1)
    return mu, dmu

def pchip_slopes(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Slopes of the monotone piecewise cubic Hermite interpolant (Fritsch and Carlson 1980).

    Interior nodes: 0 where the secant slopes change sign or one is 0, else their weighted
    harmonic mean (Fritsch and Butland 1984), which keeps the interpolant monotone on every
    interval where the data are, so it never overshoots the data. End nodes: the one-sided
    three-point estimate, set to 0 if its sign differs from the first secant and limited to
    three times it (the same shape-preserving rule).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Strictly increasing nodes, n >= 2.
    y : ndarray, shape (n,)
        Values.

    Returns
    -------
    ndarray, shape (n,)
        dy/dx at the nodes.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    h = np.diff(x)
    delta = np.diff(y) / h
    n = x.size
    slope = np.zeros(n)
    if n == 2:
        slope[:] = delta[0]
        return slope
    for k in range(1, n - 1):
        a, b = delta[k - 1], delta[k]
        if a * b > 0.0:
            w1 = 2.0 * h[k] + h[k - 1]
            w2 = h[k] + 2.0 * h[k - 1]
            slope[k] = (w1 + w2) / (w1 / a + w2 / b)

    def end(h0: float, h1: float, d0: float, d1: float) -> float:
        e = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1)
        if e * d0 <= 0.0:
            return 0.0
        if d0 * d1 < 0.0 and abs(e) > abs(3.0 * d0):
            return 3.0 * d0
        return e

    slope[0] = end(*h[:2], *delta[:2])
    slope[-1] = end(*h[::-1][:2], *delta[::-1][:2])
    return slope


#: what a friction table may hold (its values are read as the keys they stand for are): a
#: coefficient in the sane range of friction.mu_slip / mu_stick, a sliding speed in that of
#: the coulomb law's stribeck_velocity
_, _TABLE_MU_MAX, _ = SANE_BOUNDS["friction.mu_stick"]
_TABLE_V_MAX = FRICTION_LAWS["coulomb"].keys["stribeck_velocity"].highest
#: the steepest slope |d mu / d v| of a friction table [s/m]: that of the steepest Feldmann
#: curve within the keys' sane ranges (a coefficient step of 10 decaying at a2 = 1e8 s/m); a
#: step of 0.05 within 1e-300 m/s made the solver divide by zero
_A2_MAX = FRICTION_LAWS["feldmann"].keys["a2"].highest
_TABLE_SLOPE_MAX = _TABLE_MU_MAX * _A2_MAX


def _table_text(path: Path, where: str) -> str:
    """The text of a friction table: UTF-8, a leading byte-order mark dropped (as the scene,
    sweep and roughness files); one line naming the file otherwise."""
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise SceneError(f"{where} must be a readable CSV file, got {err.strerror or err}"
                         ) from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise SceneError(f"{where} must be UTF-8 text (save it as UTF-8 CSV), got byte "
                         f"0x{raw[exc.start]:02x} at byte {exc.start} on line {line}") from None


def _table_header(rows: list[list[str]], text: str, where: str) -> tuple[int, int]:
    """Columns of ``velocity`` and ``mu`` in the header row; a header that names both but not
    as separate comma-separated columns is refused for its separator."""
    header = [c.strip().lower() for c in rows[0]] if rows else []
    if "velocity" in header and "mu" in header:
        return header.index("velocity"), header.index("mu")
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    m = re.search(r"velocity(.+?)mu\b|\bmu(.+?)velocity", first, re.IGNORECASE)
    if m is not None:
        between = m.group(1) if m.group(1) is not None else m.group(2)
        bare = re.sub(r"[\[(][^\])]*[\])]", "", between)  # without units in brackets
        sep = next((c for c in ";\t|" if c in bare), bare.strip() or bare[:1])
        if "," not in between:
            raise SceneError(f"{where} must separate its columns with commas (a CSV file, "
                             f"decimals with a point), got {sep!r} between 'velocity' and 'mu' "
                             f"in the header row")
    raise SceneError(f"{where} must have the columns 'velocity' [m/s] and 'mu' [-] in its "
                     f"header row, got {', '.join(header) or 'no header'}")


def load_friction_table(path: str | Path, mu_stick: float) -> tuple[np.ndarray, np.ndarray]:
    """Read and check a kinetic friction curve: a CSV with columns ``velocity`` and ``mu``.

    Parameters
    ----------
    path : path
        The CSV file: UTF-8 (a leading byte-order mark is allowed), comma-separated, a header
        row, then one row per sample; other columns are ignored.
    mu_stick : float
        The static coefficient [-]; the curve at v = 0 must not exceed it.

    Returns
    -------
    velocity : ndarray, shape (n,)
        Sliding speeds [m/s], strictly increasing from 0.
    mu : ndarray, shape (n,)
        Kinetic coefficients [-].

    Raises
    ------
    SceneError
        One line naming the file and, for a bad value, the row (data rows count from 1; the
        header is line 1 of the file): a missing file, bytes that are not UTF-8, a separator
        other than a comma, a missing column, fewer than two rows, a value that is not a finite
        number, a velocity outside [0, 100] m/s (the sane range of the coulomb law's
        ``stribeck_velocity``) or not increasing, a first velocity other than 0, a
        coefficient outside [0, 10] (the sane range of ``friction.mu_stick``), a slope between
        rows steeper than 1e9 s/m (the steepest Feldmann curve in the sane ranges of
        ``friction.mu_stick`` and the Feldmann law's ``a2``), or a coefficient at v = 0 above
        mu_stick.
    """
    import csv
    import io

    path = Path(path)
    where = f"friction.parameters.table {str(path)!r}"
    text = _table_text(path, where)
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as err:
        raise SceneError(f"{where} must be a CSV file, got {err}") from None
    rows = [r for r in rows if any(c.strip() for c in r)]
    iv, im = _table_header(rows, text, where)
    data = rows[1:]
    if len(data) < 2:
        raise SceneError(f"{where} must have at least 2 data rows, got {len(data)}")
    v = np.empty(len(data))
    mu = np.empty(len(data))
    for i, r in enumerate(data):
        at = f"{where} row {i + 1} (line {i + 2})"
        for col, name, unit, arr in ((iv, "velocity", "m/s", v), (im, "mu", "", mu)):
            cell = r[col].strip() if col < len(r) else ""
            try:
                val = float(cell)
            except ValueError:
                val = math.nan
            if not math.isfinite(val):
                in_unit = f" in {unit}" if unit else ""
                raise SceneError(f"{at}: {name} must be a finite number{in_unit}, got {cell!r}")
            arr[i] = val
        if not 0.0 <= v[i] <= _TABLE_V_MAX:
            raise SceneError(f"{at}: velocity must be in [0, {_TABLE_V_MAX:g}] m/s (the "
                             f"physically sane range of a sliding speed), got {v[i]:g}")
        if i == 0 and v[i] != 0.0:
            raise SceneError(f"{at}: velocity must start at 0 m/s, got {v[i]:g}")
        if i > 0 and not v[i] > v[i - 1]:
            raise SceneError(f"{at}: velocity must increase from row to row, got {v[i]:g} m/s "
                             f"after {v[i - 1]:g} m/s")
        if not 0.0 <= mu[i] <= _TABLE_MU_MAX:
            raise SceneError(f"{at}: mu must be in [0, {_TABLE_MU_MAX:g}] (the physically sane "
                             f"range of a friction coefficient, as friction.mu_stick), got "
                             f"{mu[i]:g}")
        if i > 0 and abs(mu[i] - mu[i - 1]) > _TABLE_SLOPE_MAX * (v[i] - v[i - 1]):
            raise SceneError(f"{at}: mu may change by at most {_TABLE_SLOPE_MAX:g} s/m x the "
                             f"velocity step (the steepest Feldmann curve in the keys' sane "
                             f"ranges), got {mu[i - 1]:g} to {mu[i]:g} over {v[i - 1]:g} to "
                             f"{v[i]:g} m/s")
    if mu[0] > mu_stick:
        raise SceneError(f"{where} row 1 (line 2): mu at velocity 0 must be <= friction.mu_stick "
                         f"({mu_stick:g}), got {mu[0]:g}")
    return v, mu


def law_table(friction: Friction, base_dir: str | Path = ".") -> np.ndarray:
    """The packed kinetic curve the kernels read for the ``table`` law (empty otherwise).

    Layout (positions ``TAB_*``): ``[n, velocity (n), mu (n), slope (n)]`` with the
    :func:`pchip_slopes` of the curve; the path is relative to the scene file's folder.

    Returns
    -------
    ndarray, shape (1 + 3 n,) or (0,)
    """
    if friction.law != "table":
        return np.zeros(0)
    v, mu = load_friction_table(Path(base_dir) / friction.parameters["table"],
                               friction.mu_stick)
    return np.concatenate([[float(v.size)], v, mu, pchip_slopes(v, mu)])

