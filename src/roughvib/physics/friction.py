"""Friction law of the paper (Eq. 10) with the latched hysteresis, and a tangential-only model.

This module owns

* the numba kernels of the regularised Feldmann law (docs/theory.md): the branch expression
  :func:`feldmann_mu` (the event-driven solver keeps the branch ``b`` as a discrete state and
  switches it at ``x = 0``), the law itself :func:`feldmann_mu_law` (``b = sign(x)``), and the
  latched hysteresis sign :func:`latch_update` / :func:`latch_margin` (docs/theory.md);
* a plain-Python reference :func:`mu_reference` written from the two-branch form of Eq. 10;
* the tangential-only reference model (block under a constant normal force,
  no roughness), integrated with the trapezoidal rule and a scalar Newton iteration per step
  (:func:`simulate_tangential`), and the calibration of the force amplitude T0 to a target rms
  velocity (:func:`calibrate_force_amplitude`; :func:`calibrated_force_amplitude` keeps each
  result in the on-disk cache of ``roughvib._cache``).

Conventions (docs/theory.md): the friction force on the block is ``-mu(v + s v_h) F_N``, with
``s = +1`` after a velocity maximum (decelerating branch) and ``s = -1`` after a velocity minimum
(accelerating branch). All kernels take floats, ints and arrays only and run unchanged with
``NUMBA_DISABLE_JIT=1``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit

from roughvib._cache import cached_values, code_fingerprint
from roughvib.scene import SANE_BOUNDS, Friction, SceneError
from roughvib.solvers import registry

__all__ = [
    "LAWS",
    "LAW_COULOMB",
    "LAW_FELDMANN",
    "LAW_TABLE",
    "FrictionLaw",
    "calibrate_force_amplitude",
    "coulomb_kinetic",
    "kinetic_coefficient",
    "law_table",
    "load_friction_table",
    "pchip_slopes",
    "table_kinetic",
    "calibrated_force_amplitude",
    "feldmann_mu",
    "feldmann_mu_d2",
    "feldmann_mu_law",
    "latch_margin",
    "latch_update",
    "law_parameters",
    "mu_reference",
    "rms_over_periods",
    "simulate_tangential",
]


# --------------------------------------------------------------------------------------------
# the friction-law component: ids, registry, kinetic curves
# --------------------------------------------------------------------------------------------

#: below this argument ``math.exp`` returns exactly 0.0 (half the smallest subnormal is
#: exp(-745.133)); the C library reaches that 0 through its underflow handler, several times the
#: cost of an exp, and the Feldmann law's steep term exp(-a2 X) underflows whenever the block
#: slides (perf: about 1 % of a default solve)
EXP_ZERO_BELOW = -745.2


@njit(cache=True, inline="always")
def exp_or_zero(arg):
    """``math.exp(arg)``, with the exact 0.0 it underflows to below :data:`EXP_ZERO_BELOW`
    returned without calling it (so the same value to the bit; NaN stays NaN)."""
    if arg < EXP_ZERO_BELOW:
        return 0.0
    return math.exp(arg)


#: ids of the friction laws as the kernels see them (``off[OFF_LAW]``, roughvib.model.layout)
LAW_FELDMANN = 0
LAW_COULOMB = 1
LAW_TABLE = 2

#: positions in the packed table of the ``table`` law (:func:`law_table`): the row count, then
#: the velocities, the coefficients and the PCHIP slopes, ``TAB_HEAD + 3 n`` floats in all
TAB_N = 0
TAB_HEAD = 1


@dataclass(frozen=True)
class FrictionLaw:
    """What a friction law declares (docs/architecture.md, "A friction law").

    Attributes
    ----------
    name : str
        The value of ``friction.law`` that selects it.
    law_id : int
        Its id in the kernels (``LAW_*``).
    set_valued : bool
        True: stick is a regime with the velocity held at zero and the friction force an
        algebraic state, break-away at ``mu_stick F_N`` and the kinetic curve of
        :func:`kinetic_coefficient` in slip. False: a single-valued law of the velocity
        (the Feldmann law with its branch and latch regimes).
    calibration : {"feldmann", "set-valued"}
        The tangential model in which T0 is calibrated to ``excitation.target_rms_velocity``.
    """

    name: str
    law_id: int
    set_valued: bool
    calibration: str

    @property
    def solvers(self) -> tuple[str, ...]:
        """The solver methods that integrate it with a force-driven block, as the solver
        registry says (:meth:`roughvib.solvers.registry.Method.runs_law`)."""
        return tuple(m.name for m in registry.methods() if m.runs_law(self.set_valued))


#: the friction laws by the name a scene uses (``friction.law``)
LAWS = {
    "feldmann": FrictionLaw("feldmann", LAW_FELDMANN, False, "feldmann"),
    # the Coulomb law keeps the calibration it always had (the Feldmann model with the same
    # mu_slip / mu_stick), so that its runs stay bit-identical
    "coulomb": FrictionLaw("coulomb", LAW_COULOMB, True, "feldmann"),
    "table": FrictionLaw("table", LAW_TABLE, True, "set-valued"),
}


@njit(cache=True)
def coulomb_kinetic(v, mu_slip, mu_stick, vs):
    """Kinetic coefficient mu_k(v) = mu_slip + (mu_stick - mu_slip) exp(-v / vs), v >= 0.

    Parameters
    ----------
    v : float
        Sliding speed [m/s].
    mu_slip, mu_stick : float
        Coefficients [-].
    vs : float
        Stribeck velocity [m/s]; ``vs <= 0`` gives the constant mu_slip.

    Returns
    -------
    mu_k : float
        [-].
    dmu_k_dv : float
        [s/m].
    """
    if vs <= 0.0:
        return mu_slip, 0.0
    e = math.exp(-v / vs)
    return mu_slip + (mu_stick - mu_slip) * e, -(mu_stick - mu_slip) * e / vs


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


@njit(cache=True)
def kinetic_coefficient(law, v, mu_slip, mu_stick, vs, tab):
    """Kinetic coefficient of a set-valued law at sliding speed ``v`` >= 0, and its slope.

    Parameters
    ----------
    law : int
        ``LAW_COULOMB`` or ``LAW_TABLE``.
    v : float
        Sliding speed [m/s] (the kernels pass ``b v`` with the slip direction b).
    mu_slip, mu_stick, vs : float
        Coulomb law: :func:`coulomb_kinetic`.
    tab : ndarray
        Table law: :func:`law_table` (ignored otherwise).

    Returns
    -------
    mu_k : float
        [-].
    dmu_k_dv : float
        [s/m].
    """
    if law == LAW_TABLE:
        return table_kinetic(v, tab)
    return coulomb_kinetic(v, mu_slip, mu_stick, vs)


@njit(cache=True)
def is_set_valued(law):
    """Whether the law with id ``law`` has a stick regime with an algebraic friction force."""
    return law == LAW_COULOMB or law == LAW_TABLE


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
#: friction.stribeck_velocity
_, _TABLE_MU_MAX, _ = SANE_BOUNDS["friction.mu_stick"]
_, _TABLE_V_MAX, _ = SANE_BOUNDS["friction.stribeck_velocity"]
#: the steepest slope |d mu / d v| of a friction table [s/m]: that of the steepest Feldmann
#: curve within the keys' sane ranges (a coefficient step of 10 decaying at a2 = 1e8 s/m); a
#: step of 0.05 within 1e-300 m/s made the solver divide by zero
_, _A2_MAX, _ = SANE_BOUNDS["friction.a2"]
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
        number, a velocity outside [0, 100] m/s (the sane range of
        ``friction.stribeck_velocity``) or not increasing, a first velocity other than 0, a
        coefficient outside [0, 10] (the sane range of ``friction.mu_stick``), a slope
        between rows steeper than 1e9 s/m (the steepest Feldmann curve in the sane ranges of
        ``friction.mu_stick`` and ``friction.a2``), or a coefficient at v = 0 above
        mu_stick.
    """
    import csv
    import io

    path = Path(path)
    where = f"friction.table {str(path)!r}"
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
    v, mu = load_friction_table(Path(base_dir) / friction.table, friction.mu_stick)
    return np.concatenate([[float(v.size)], v, mu, pchip_slopes(v, mu)])


# --------------------------------------------------------------------------------------------
# kernels
# --------------------------------------------------------------------------------------------


@njit(cache=True)
def feldmann_mu(x, b, mu_slip, mu_stick, a1, a2):
    """Branch ``b`` of Eq. 10 and its exact derivative.

    ``mu_b(x) = b (mu_slip + (mu_stick - mu_slip) exp(-a1 b x) - mu_stick exp(-a2 b x))``.
    With ``b = sign(x)`` this is the law; the other branch is its smooth continuation through
    ``x = 0`` (both branches give ``mu = 0`` and the same slope there).

    Parameters
    ----------
    x : float
        Shifted relative velocity X = v + s v_h [m/s].
    b : float
        Branch, +1.0 or -1.0.
    mu_slip, mu_stick : float
        Quasi-static kinetic and static coefficients [-].
    a1, a2 : float
        Exponential constants [s/m].

    Returns
    -------
    mu : float
        Friction coefficient [-].
    dmu_dx : float
        d mu / d x [s/m].
    """
    e1 = exp_or_zero(-a1 * b * x)
    e2 = exp_or_zero(-a2 * b * x)
    dmu = mu_stick - mu_slip
    mu = b * (mu_slip + dmu * e1 - mu_stick * e2)
    # b * b = 1: the derivative has the same expression on both branches
    dmu_dx = -a1 * dmu * e1 + a2 * mu_stick * e2
    return mu, dmu_dx


@njit(cache=True)
def feldmann_mu_d2(x, b, mu_slip, mu_stick, a1, a2):
    """:func:`feldmann_mu` and the branch's second derivative (for Newton matrices of
    fourth-order steps, whose tangential rate equation holds ``dmu/dx``).

    Returns
    -------
    mu, dmu_dx, d2mu_dx2 : float
        Friction coefficient [-], its first [s/m] and second [s^2/m^2] derivative in x;
        mu and dmu_dx are those of :func:`feldmann_mu`.
    """
    e1 = exp_or_zero(-a1 * b * x)
    e2 = exp_or_zero(-a2 * b * x)
    dmu = mu_stick - mu_slip
    mu = b * (mu_slip + dmu * e1 - mu_stick * e2)
    dmu_dx = -a1 * dmu * e1 + a2 * mu_stick * e2
    d2mu_dx2 = b * (a1 * a1 * dmu * e1 - a2 * a2 * mu_stick * e2)
    return mu, dmu_dx, d2mu_dx2


@njit(cache=True)
def feldmann_mu_law(x, mu_slip, mu_stick, a1, a2):
    """The law of Eq. 10: :func:`feldmann_mu` on the branch ``b = sign(x)`` (+1 at x = 0).

    The law is C1 at ``x = 0`` (its second derivative jumps there).

    Returns
    -------
    mu : float
        Friction coefficient [-].
    dmu_dx : float
        d mu / d x [s/m].
    """
    b = 1.0 if x >= 0.0 else -1.0
    return feldmann_mu(x, b, mu_slip, mu_stick, a1, a2)


@njit(cache=True)
def latch_update(s, v_ext, v, eps):
    """Advance the latched hysteresis sign by one velocity sample (docs/theory.md).

    ``s = +1`` (after a velocity maximum) tracks the running minimum of the velocity in
    ``v_ext``; ``s = -1`` (after a velocity minimum) tracks the running maximum. The sign flips
    once ``v`` has moved back from the running extremum by more than ``eps``; the extremum then
    restarts at ``v``.

    Parameters
    ----------
    s : float
        Current latch sign, +1.0 or -1.0.
    v_ext : float
        Running extremum of the velocity since the last flip [m/s].
    v : float
        New velocity sample [m/s].
    eps : float
        Flip threshold epsilon_v > 0 [m/s].

    Returns
    -------
    s_new : float
    v_ext_new : float [m/s]
    flipped : bool
    """
    if s > 0.0:
        if v < v_ext:
            v_ext = v
        if v - v_ext > eps:
            return -1.0, v, True
        return 1.0, v_ext, False
    if v > v_ext:
        v_ext = v
    if v_ext - v > eps:
        return 1.0, v, True
    return -1.0, v_ext, False


@njit(cache=True)
def latch_margin(s, v_ext, v, eps):
    """Distance of the latch from its flip: ``eps - s (v - v_ext)`` [m/s].

    Positive while no flip is due; it crosses zero (downward) where :func:`latch_update` flips,
    so an event-driven solver can use it as a root function (``v_ext`` is then the running
    extremum held as a discrete state and updated at the step ends).
    """
    return eps - s * (v - v_ext)


@njit(cache=True)
def _tangential_kernel(t0_amp, mass, r2, normal_force, omega, mu_slip, mu_stick, a1, a2, v_h,
                       eps, dt, n_steps, v_out, x_out):
    """Trapezoidal rule with a scalar Newton iteration on v per step; latch after each step.

    Fills ``v_out`` and ``x_out`` (length n_steps + 1) and returns the number of latch flips and
    the largest Newton iteration count.
    """
    s = -1.0
    v_ext = 0.0
    v0 = 0.0
    x0 = 0.0
    v_out[0] = v0
    x_out[0] = x0
    half = 0.5 * dt
    mu0, _ = feldmann_mu_law(v0 + s * v_h, mu_slip, mu_stick, a1, a2)
    f0 = t0_amp - mu0 * normal_force - r2 * v0
    flips = 0
    max_iter = 0
    tol = 1e-14
    for n in range(n_steps):
        t1 = (n + 1) * dt
        drive1 = t0_amp * math.cos(omega * t1)
        # explicit Euler predictor; the residual is strictly increasing in v1 as long as
        # m + dt/2 (mu' F_N + r2) > 0, which holds for any dt << m / (a1 (mu_stick-mu_slip) F_N)
        v1 = v0 + dt * f0 / mass
        it = 0
        f1 = 0.0
        while True:
            it += 1
            mu1, dmu1 = feldmann_mu_law(v1 + s * v_h, mu_slip, mu_stick, a1, a2)
            f1 = drive1 - mu1 * normal_force - r2 * v1
            res = mass * (v1 - v0) - half * (f0 + f1)
            jac = mass + half * (dmu1 * normal_force + r2)
            dv = res / jac
            v1 -= dv
            if abs(dv) <= tol * (1.0 + abs(v1)) or it >= 50:
                break
        if it > max_iter:
            max_iter = it
        x1 = x0 + half * (v0 + v1)
        s, v_ext, flipped = latch_update(s, v_ext, v1, eps)
        if flipped:
            flips += 1
            mu1, _ = feldmann_mu_law(v1 + s * v_h, mu_slip, mu_stick, a1, a2)
            f1 = drive1 - mu1 * normal_force - r2 * v1
        v_out[n + 1] = v1
        x_out[n + 1] = x1
        v0 = v1
        x0 = x1
        f0 = f1
    return flips, max_iter


@njit(cache=True)
def _tangential_setvalued_kernel(t0_amp, mass, r2, normal_force, omega, law, mu_slip, mu_stick,
                                 vs, tab, dt, n_steps, v_out, x_out):
    """Backward-Euler (Moreau-Jean) steps of the set-valued law; exact stick (v = 0).

    Per step: the free velocity without friction; stick if the friction impulse that holds
    it at zero stays within ``dt mu_stick F_N``, else slip, ``|v1| = |v_free| - c mu_k(|v1|)``
    with ``c = dt F_N / (m + dt r2)`` solved by Newton (safeguarded by bisection). Fills
    ``v_out``, ``x_out`` (length n_steps + 1); returns the number of stick-to-slip switches.
    """
    v0 = 0.0
    x0 = 0.0
    v_out[0] = v0
    x_out[0] = x0
    c = dt * normal_force / (mass + dt * r2)
    breaks = 0
    stuck = True
    for n in range(n_steps):
        t1 = (n + 1) * dt
        vfree = (v0 + dt * t0_amp * math.cos(omega * t1) / mass) / (1.0 + dt * r2 / mass)
        a = abs(vfree)
        if a <= c * mu_stick:
            v1 = 0.0
            stuck = True
        else:
            if stuck:
                breaks += 1
            stuck = False
            lo = 0.0
            hi = a
            w = a
            for _it in range(100):
                mu, dmu = kinetic_coefficient(law, w, mu_slip, mu_stick, vs, tab)
                g = w - a + c * mu
                if g > 0.0:
                    hi = w
                else:
                    lo = w
                dw = g / (1.0 + c * dmu) if 1.0 + c * dmu > 0.0 else 0.5 * (hi - lo)
                w_new = w - dw
                if not (lo < w_new < hi):
                    w_new = 0.5 * (lo + hi)
                if abs(w_new - w) <= 1e-15 + 1e-13 * w_new:
                    w = w_new
                    break
                w = w_new
            v1 = math.copysign(w, vfree)
        x1 = x0 + dt * v1
        v_out[n + 1] = v1
        x_out[n + 1] = x1
        v0 = v1
        x0 = x1
    return breaks


# --------------------------------------------------------------------------------------------
# plain-Python reference
# --------------------------------------------------------------------------------------------


def mu_reference(x: float, mu_slip: float, mu_stick: float, a1: float, a2: float) -> float:
    """Eq. 10 as printed in the paper, two explicit branches (no numba, for tests).

    Parameters
    ----------
    x : float
        X = relative velocity + hysteresis shift [m/s].

    Returns
    -------
    float
        mu(X) [-]; 0 at X = 0.
    """
    if x > 0.0:
        return mu_slip + (mu_stick - mu_slip) * math.exp(-a1 * x) - mu_stick * math.exp(-a2 * x)
    if x < 0.0:
        return -mu_slip - (mu_stick - mu_slip) * math.exp(a1 * x) + mu_stick * math.exp(a2 * x)
    return 0.0


# --------------------------------------------------------------------------------------------
# tangential-only reference model
# --------------------------------------------------------------------------------------------


def law_parameters(friction: Friction) -> tuple[float, float, float, float]:
    """``(mu_slip, mu_stick, a1, a2)`` of a :class:`~roughvib.scene.Friction` as floats."""
    return (float(friction.mu_slip), float(friction.mu_stick), float(friction.a1),
            float(friction.a2))


def simulate_tangential(T0: float, mass: float, r2: float, normal_force: float, omega: float,
                        friction: Friction, duration: float, dt: float = 1e-6,
                        table: np.ndarray | None = None,
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tangential-only block under a constant normal force (docs/theory.md).

    The model is the one the law declares for its calibration (``LAWS[law].calibration``):
    the Feldmann law as described next; a ``set-valued`` law (the ``table`` law) by the
    backward-Euler (Moreau-Jean) step with exact stick, first order in ``dt``.

    ``m v' = T0 cos(omega t) - mu(v + s v_h) F_N - r2 v``, ``x' = v``, from rest at t = 0 with
    the latch on the accelerating branch (``s = -1``, running maximum 0). The regularised law is
    stiff (slope ~ mu_stick a2 F_N), so each step is the trapezoidal rule (second order,
    A-stable) solved for v by Newton; the latch is updated after each step with
    ``friction.effective_latch_velocity``.

    Parameters
    ----------
    T0 : float
        Force amplitude [N].
    mass : float
        Block mass m [kg].
    r2 : float
        Tangential viscous damping [N s/m].
    normal_force : float
        Constant normal force F_N [N] (m g for the paper's block).
    omega : float
        Excitation angular frequency [rad/s].
    friction : Friction
        Law parameters.
    duration : float
        Simulated time [s].
    dt : float, optional
        Fixed step [s]; keep dt well below m / (mu_stick a2 F_N) (~1.3e-5 s for the defaults).
    table : ndarray, optional
        The packed kinetic curve of the ``table`` law (:func:`law_table`).

    Returns
    -------
    t, v, x : ndarray, shape (n + 1,)
        Time [s], velocity [m/s] and displacement [m] on the grid t = k dt,
        n = ceil(duration / dt).
    """
    if not (dt > 0.0 and duration > 0.0):
        raise ValueError(f"dt and duration must be > 0 s, got dt={dt}, duration={duration}")
    if mass <= 0.0:
        raise ValueError(f"mass must be > 0 kg, got {mass}")
    # the grid covers the whole duration (t[-1] >= duration up to round-off)
    n = int(math.ceil(duration / dt - 1e-9))
    v = np.empty(n + 1)
    x = np.empty(n + 1)
    mu_slip, mu_stick, a1, a2 = law_parameters(friction)
    law = LAWS[friction.law]
    if law.calibration == "set-valued":
        tab = np.zeros(0) if table is None else np.asarray(table, dtype=float)
        _tangential_setvalued_kernel(float(T0), float(mass), float(r2), float(normal_force),
                                     float(omega), law.law_id, mu_slip, mu_stick,
                                     float(friction.stribeck_velocity or 0.0), tab, float(dt),
                                     n, v, x)
    else:
        _tangential_kernel(float(T0), float(mass), float(r2), float(normal_force),
                           float(omega), mu_slip, mu_stick, a1, a2,
                           float(friction.hysteresis_velocity),
                           float(friction.effective_latch_velocity), float(dt), n, v, x)
    t = np.arange(n + 1) * dt
    return t, v, x


def rms_over_periods(t: np.ndarray, v: np.ndarray, period: float, transient: float) -> float:
    """Rms of ``v`` over the largest whole number of periods after ``transient``.

    The mean square is the trapezoidal integral of v^2 over [transient, transient + n period],
    the window ends linearly interpolated, so the result is second-order accurate in the grid
    spacing (and independent of how the period falls on the grid).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Increasing times [s].
    v : ndarray, shape (n,)
        Samples [any unit].
    period : float
        Averaging period [s].
    transient : float
        Start of the window [s].

    Returns
    -------
    float
        Rms [unit of v].

    Raises
    ------
    ValueError
        Less than one whole period after ``transient``.
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    if period <= 0.0 or t.size < 2:
        raise ValueError(f"period must be > 0 s and t must have >= 2 samples, got {period}")
    # a window end up to half a grid step past the last sample is clipped to it
    slack = 0.5 * (t[-1] - t[0]) / (t.size - 1)
    n_per = int(math.floor((t[-1] + slack - transient) / period))
    if n_per < 1 or transient < t[0]:
        raise ValueError(f"need at least one whole period ({period} s) between transient "
                         f"({transient} s) and the end ({t[-1]} s)")
    ta = transient
    tb = min(transient + n_per * period, t[-1])
    inside = (t > ta) & (t < tb)
    tt = np.concatenate(([ta], t[inside], [tb]))
    vv = np.concatenate(([np.interp(ta, t, v)], v[inside], [np.interp(tb, t, v)]))
    return float(math.sqrt(np.trapezoid(vv * vv, tt) / (tb - ta)))


def _steady_rms(T0, mass, r2, normal_force, omega, friction, transient_periods, periods, dt,
                table=None):
    period = 2.0 * math.pi / omega
    t, v, _ = simulate_tangential(T0, mass, r2, normal_force, omega, friction,
                                  (transient_periods + periods) * period, dt, table)
    return rms_over_periods(t, v, period, transient_periods * period)


class _Converged(Exception):
    def __init__(self, T0: float) -> None:
        super().__init__(T0)
        self.T0 = T0


def calibrate_force_amplitude(target_rms: float, mass: float, r2: float, normal_force: float,
                              omega: float, friction: Friction, *, transient_periods: int = 3,
                              periods: int = 2, rtol: float = 1e-3, dt: float = 1e-6,
                              table: np.ndarray | None = None) -> float:
    """Force amplitude T0 whose steady-state rms velocity in the tangential model is the target.

    The rms over ``periods`` whole periods after ``transient_periods`` periods of
    :func:`simulate_tangential` increases monotonically with T0, so T0 is the root of
    ``rms(T0) / target - 1`` (Brent's method, stopped once the rms is within ``rtol`` of the
    target).

    Bracket: with V = sqrt(2) target and Z = r2 + i m omega the mass-damper impedance,
    ``T_lo = |Z| V`` is the amplitude the frictionless system needs, and friction only adds
    resistance, so rms(T_lo) <= target. ``T_hi = |Z| V + (4/pi) mu_stick F_N`` adds the largest
    first-harmonic amplitude a friction force bounded by mu_stick F_N can have (describing function
    of a relay). Both ends are checked and widened geometrically if the estimate fails.

    Parameters
    ----------
    target_rms : float
        Target rms velocity [m/s].
    mass, r2, normal_force, omega : float
        As in :func:`simulate_tangential` [kg, N s/m, N, rad/s].
    friction : Friction
    transient_periods, periods : int, optional
        Periods discarded and averaged.
    rtol : float, optional
        Relative tolerance on the rms velocity.
    dt : float, optional
        Time step [s].
    table : ndarray, optional
        The packed kinetic curve of the ``table`` law (:func:`law_table`).

    Returns
    -------
    float
        T0 [N].
    """
    if target_rms <= 0.0:
        raise ValueError(f"target_rms must be > 0 m/s, got {target_rms}")
    # |mu| <= mu_slip + (mu_stick - mu_slip) e^(-a1 |X|) <= mu_stick for every X
    mu_max = max(float(friction.mu_stick), float(friction.mu_slip))
    if table is not None and table.size:
        n_tab = int(table[TAB_N])
        mu_max = max(mu_max, float(np.max(table[TAB_HEAD + n_tab:TAB_HEAD + 2 * n_tab])))

    def g(T0: float) -> float:
        r = _steady_rms(T0, mass, r2, normal_force, omega, friction, transient_periods,
                        periods, dt, table) / target_rms - 1.0
        if abs(r) <= rtol:
            raise _Converged(T0)
        return r

    amp = math.sqrt(2.0) * target_rms
    lo = amp * math.hypot(r2, mass * omega)
    hi = lo + 4.0 / math.pi * mu_max * normal_force
    try:
        g_lo = g(lo)
        while g_lo >= 0.0 and lo > 1e-12 * hi:
            lo *= 0.25
            g_lo = g(lo)
        g_hi = g(hi)
        while g_hi <= 0.0 and hi < 1e6 * lo:
            lo, g_lo = hi, g_hi
            hi *= 1.5
            g_hi = g(hi)
        if not (g_lo < 0.0 < g_hi):
            raise RuntimeError(f"no bracket for target_rms={target_rms} m/s found "
                               f"(T0 in [{lo}, {hi}] N)")
        from scipy.optimize import brentq

        return float(brentq(g, lo, hi, xtol=1e-9 * hi, rtol=1e-12, maxiter=100))
    except _Converged as c:
        return c.T0


def calibrated_force_amplitude(target_rms: float, mass: float, r2: float, normal_force: float,
                               omega: float, friction: Friction,
                               table: np.ndarray | None = None) -> tuple[float, str]:
    """:func:`calibrate_force_amplitude` at its default settings, through the on-disk cache.

    The calibration integrates the tangential model about ten times (about a second); its
    result depends only on the arguments, the friction law's parameters and this module's code,
    so it is stored once per distinct input (``roughvib._cache``: exact floats, keyed by the
    inputs, this file's SHA-256 and the library versions) and read back by later runs.

    Parameters
    ----------
    target_rms, mass, r2, normal_force, omega, friction, table
        As in :func:`calibrate_force_amplitude` [m/s, kg, N s/m, N, rad/s].

    Returns
    -------
    T0 : float
        Force amplitude [N], bit-identical to ``calibrate_force_amplitude(...)``.
    cache : {"hit", "miss", "off"}
        Read from the cache, computed now, or computed with the cache switched off
        (``ROUGHVIB_CACHE=off``).
    """
    mu_slip, mu_stick, a1, a2 = law_parameters(friction)
    inputs = {"target_rms": float(target_rms), "mass": float(mass), "r2": float(r2),
              "normal_force": float(normal_force), "omega": float(omega),
              "mu_slip": mu_slip, "mu_stick": mu_stick, "a1": a1, "a2": a2,
              "hysteresis_velocity": float(friction.hysteresis_velocity),
              "effective_latch_velocity": float(friction.effective_latch_velocity)}
    if LAWS[friction.law].calibration == "set-valued":
        # keys only a set-valued calibration has: the Feldmann law's cache keys stay as they were
        inputs["law"] = friction.law
        inputs["stribeck_velocity"] = float(friction.stribeck_velocity or 0.0)
        if table is not None and table.size:
            import hashlib

            inputs["table_sha256"] = hashlib.sha256(
                np.ascontiguousarray(table, dtype=float).tobytes()).hexdigest()

    def compute() -> dict[str, float]:
        return {"T0": calibrate_force_amplitude(target_rms, mass, r2, normal_force, omega,
                                                friction, table=table)}

    values, status = cached_values("force-calibration", inputs, compute,
                                   code=code_fingerprint([__file__]))
    return values["T0"], status
