"""IDA's Newton matrix ``J = dF/dy + cj dF/dyp``: its entries declared once, its sparsity
pattern derived from them.

Every entry of the Jacobian is written in one place, :func:`jacobian_entries`, as a call
``p = emit(vals, rows, cols, p, row, col, value)`` with a running cursor ``p``. The function
runs in two passes over the same code:

* the **pattern pass** (:func:`jacobian_pattern`, once per solver set-up) passes ``rows`` and
  ``cols`` arrays: :func:`emit` records each entry's row and column (and its value at the
  pattern's point, which is discarded);
* the **value pass** (:func:`jacobian_values`, every Newton matrix IDA forms) passes
  ``rows = cols = None``: numba compiles :func:`emit` to the single store ``vals[p] = value``
  (the row and column expressions are dead code), as fast as the hand-written cursor was.

So the pattern cannot disagree with the values: an entry is one call, and a new state's
entries go into :func:`jacobian_entries` (its friction entries into
:func:`friction_entries`) and nowhere else. Rules for an entry:

* emit the same (row, column) sequence in every regime: a regime changes an entry's
  value, never whether it exists (an open contact's entries are exact zeros), since the
  pattern is built once for all regimes (the unit tests build it in several and compare);
* never emit one (row, column) twice (:func:`jacobian_pattern` refuses duplicates);
* order is free: IDA receives the values through the permutation to CSC order
  (:func:`roughvib.model.kernels.scatter`).

The friction law's linearisation (its coefficient and slopes, the friction moment's share)
is computed by :func:`friction_terms` only; :func:`friction_entries` turns it into the rows
of the tangential velocity, of the friction state and of the friction power, and the Krylov
kernels (:mod:`roughvib.model.krylov`) read the same :class:`FrictionTerms`, so no law is
differentiated twice.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit, types
from numba.extending import overload

from roughvib.model import kernels as kn
from roughvib.model.layout import (
    E_EXCITATION,
    E_FRICTION,
    E_PLATE_DAMPING,
    E_ROUGHNESS,
    E_TANGENTIAL_DAMPING,
    E_VERTICAL_DAMPING,
    N_ENERGY,
    OFF_IE,
    OFF_IL,
    OFF_IPSI,
    OFF_IS,
    OFF_IX,
)

__all__ = ["FrictionTerms", "emit", "friction_entries", "friction_terms", "jacobian_entries",
           "jacobian_pattern", "jacobian_values"]


def emit(vals, rows, cols, p, row, col, value):
    """Write entry ``p`` of the Jacobian, (row, col, value); return the next cursor ``p + 1``.

    Value pass (``rows`` and ``cols`` None): ``vals[p] = value``. Pattern pass (``rows`` and
    ``cols`` int64 arrays, ``vals`` as long): the row, column and value, where ``p`` is
    within the arrays (beyond them nothing is written, so that a pass with empty arrays
    counts the entries). numba compiles one specialisation per pass (an ``overload`` by the
    type of ``rows``, inlined), so the value pass is a bare store.

    Parameters
    ----------
    vals : ndarray (nnz,)
        Values [units of the residual row per unit of the state column].
    rows, cols : ndarray (nnz,) of int64, or None
        Row and column indices (pattern pass), or None (value pass).
    p : int
        Cursor: the entry's position in COO order.
    row, col : int
        The entry's row (residual) and column (state).
    value : float
        ``dF_row/dy_col + cj dF_row/dyp_col``.

    Returns
    -------
    int
        ``p + 1``.
    """
    if rows is None:
        vals[p] = value
    elif p < rows.size:
        rows[p] = row
        cols[p] = col
        vals[p] = value
    return p + 1


@overload(emit, inline="always")
def _emit_compiled(vals, rows, cols, p, row, col, value):
    if isinstance(rows, types.NoneType):
        def value_pass(vals, rows, cols, p, row, col, value):
            vals[p] = value
            return p + 1
        return value_pass

    def pattern_pass(vals, rows, cols, p, row, col, value):
        if p < rows.size:
            rows[p] = row
            cols[p] = col
            vals[p] = value
        return p + 1
    return pattern_pass


#: The friction law linearised at a state (:func:`friction_terms`): the block's tangential
#: velocity ``vx`` [m/s] and the normal force ``fsum`` = sum_k F_k [N]; the Feldmann law's
#: coefficient ``mu`` [-] and slope ``dmu`` = dmu/dv [s/m] (0 for the other laws); the
#: set-valued friction row ``d lambda + alpha d vx + beta sum_k dF_k`` (``alpha`` [N s/m],
#: ``beta`` [-]; 0 for the Feldmann law); the friction moment's share c of the friction force
#: ``cm`` [-] and its slopes ``dcv`` [s/m], ``dcl`` [1/N], ``dcf`` [1/N]
#: (:func:`roughvib.model.kernels.moment_share`) and its power per unit c ``wm`` [N m/s]
#: (:func:`roughvib.model.kernels.moment_power`), all 0 without the moment. A dynamic law
#: (internal state z, ``friction.state``) gives ``mu`` and ``dmu`` = dmu/dv at fixed z, and
#: ``dmuz`` = dmu/dz [1/m], ``dzv`` = dz'/dv [-], ``dzz`` = dz'/dz [1/s] (0 for the other laws).
FrictionTerms = namedtuple("FrictionTerms", ["vx", "fsum", "mu", "dmu", "alpha", "beta",
                                             "cm", "dcv", "dcl", "dcf", "wm", "dmuz", "dzv",
                                             "dzz"])


@njit(cache=True, inline="always")
def friction_terms(t, y, off, fp, reg):
    """The friction law linearised at (t, y) in regime ``reg``: the one place that
    differentiates the law for the Newton matrix.

    Read by :func:`friction_entries` (IDA's sparse Jacobian) and by the Krylov kernels
    (``precond_solve``, ``jac_vec`` in :mod:`roughvib.model.krylov`), so both linear solvers
    see the same derivatives. A new law adds its coefficients here, in its branch (and, if
    the kernels need new ones, fields of :data:`FrictionTerms`).

    Parameters
    ----------
    t : float
        Time [s].
    y : ndarray (n,)
        State.
    off, fp, reg
        The kernels' header, scalars and regime (:mod:`roughvib.model.kernels`).

    Returns
    -------
    FrictionTerms
        See :data:`FrictionTerms`; all slopes 0 under prescribed tangential motion.
    """
    iF, K = off[kn.OFF_IF], off[kn.OFF_K]
    fsum = 0.0
    for k in range(K):
        fsum += y[iF + k]
    _, vx = kn.tangential_kinematics(t, y, off, fp)
    mu = 0.0
    dmu = 0.0
    alpha = 0.0
    beta = 0.0
    cm = 0.0
    dcv = 0.0
    dcl = 0.0
    dcf = 0.0
    wm = 0.0
    dmuz = 0.0
    dzv = 0.0
    dzz = 0.0
    if off[OFF_IX] >= 0:
        if kn.dynamic(off):
            mu, _, dmu, dmuz, dzv, dzz = kn.dynamic_friction(vx, y, off, fp, reg)
        elif kn.set_valued(off):
            b = reg[kn.REG_B]
            if b == 0:
                alpha = fp[kn.FP_R2]
            else:
                muk, dmuk = kn.kinetic(b * vx, off, fp)
                alpha = -dmuk * fsum
                beta = -b * muk
        else:
            mu, dmu = kn.velocity_law(vx, off, fp, reg)
        if kn.moment_on(off):
            cm, dcv, dcl, dcf = kn.moment_share(t, y, off, fp, reg)
            wm = kn.moment_power(y, off, fp)
    return FrictionTerms(vx, fsum, mu, dmu, alpha, beta, cm, dcv, dcl, dcf, wm, dmuz, dzv, dzz)


@njit(cache=True, inline="always")
def friction_entries(vals, rows, cols, p, t, y, cj, off, fp, reg, ft, M):
    """Emit the friction's entries: the rows of the block's tangential position and
    velocity, of the friction state (set-valued laws), of the friction power, and the
    friction moment's friction column in the modal rows.

    The one function that branches on the law kind for the Jacobian's structure (the law's
    derivatives come from ``ft``, :func:`friction_terms`). Nothing is emitted under prescribed
    tangential motion (no ``block.x``, ``block.vx``). Rows, with ``u`` the friction's
    argument (``vx`` for the Feldmann law, ``lambda`` for the set-valued laws):

    * ``x``: ``cj dx - dvx``;
    * ``vx``: ``(cj + r2/m) dvx`` plus the friction: Feldmann ``(dmu F_N dvx + mu sum_k dF_k)
      / m``, set-valued ``d lambda / m``;
    * ``lambda`` (set-valued): ``d lambda + alpha dvx + beta sum_k dF_k``;
    * the friction power ``E_FRICTION`` (its ``cj`` diagonal is emitted with the other energy
      rows): minus the derivative of ``T v - c W``;
    * with the friction moment, each modal row's ``-P_r dc/du / M`` and the power row's
      modal velocities ``c P_r``.

    **A dynamic law** (internal state z, ``friction.state`` at ``off[OFF_IS]``) shares the
    single-valued rows (its ``mu`` and ``dmu`` at fixed z) and adds, in its branch, the
    ``vx`` row's z column ``dmu/dz F_N / m``, the state's own row ``(cj - dz'/dz) dz -
    dz'/dv dvx`` and the power row's z column; its derivatives come from
    :func:`friction_terms`' dynamic branch (``kernels.dynamic_friction``, the law dispatch).
    The Krylov preconditioner (``precond_solve``) has no elimination of such a state
    (``solver.linear_solver = "gmres"`` is refused with a dynamic law).

    Parameters
    ----------
    vals, rows, cols, p
        The sink and cursor of :func:`emit`.
    t : float
        Time [s].
    y : ndarray (n,)
        State.
    cj : float
        IDA's ``alpha / h`` [1/s].
    off, fp, reg
        The kernels' header, scalars and regime.
    ft : FrictionTerms
        :func:`friction_terms` at (t, y, reg).
    M : float
        Modal mass [kg].

    Returns
    -------
    int
        The cursor after the last entry.
    """
    ix = off[OFF_IX]
    if ix < 0:
        return p
    ivx, iF, iE, iL = off[kn.OFF_IVX], off[kn.OFF_IF], off[OFF_IE], off[OFF_IL]
    idq, R, K = off[kn.OFF_IDQ], off[kn.OFF_R], off[kn.OFF_K]
    m = fp[kn.FP_MASS]
    iEF = iE + E_FRICTION
    moment = kn.moment_on(off)
    vx, fsum, mu, dmu = ft.vx, ft.fsum, ft.mu, ft.dmu
    cm, dcv, dcl, dcf, wm = ft.cm, ft.dcv, ft.dcl, ft.dcf, ft.wm
    p = emit(vals, rows, cols, p, ix, ix, cj)
    p = emit(vals, rows, cols, p, ix, ivx, -1.0)
    if kn.set_valued(off):
        # friction force lambda: an algebraic state
        p = emit(vals, rows, cols, p, ivx, ivx, cj + fp[kn.FP_R2] / m)
        p = emit(vals, rows, cols, p, ivx, iL, 1.0 / m)
        p = emit(vals, rows, cols, p, iL, iL, 1.0)
        p = emit(vals, rows, cols, p, iL, ivx, ft.alpha)
        for k in range(K):
            p = emit(vals, rows, cols, p, iL, iF + k, ft.beta)
        # friction power lambda v - c W
        p = emit(vals, rows, cols, p, iEF, ivx, -y[iL])
        p = emit(vals, rows, cols, p, iEF, iL, -(vx - dcl * wm))
        if moment:
            for k in range(K):
                p = emit(vals, rows, cols, p, iEF, iF + k,
                         cm * kn.surface_velocity(k, y, off, fp) + dcf * wm)
        iu = iL
        dcu = dcl
    else:
        # single-valued (Feldmann) or dynamic law: friction mu(v[, z]) F_N
        p = emit(vals, rows, cols, p, ivx, ivx, cj + (dmu * fsum + fp[kn.FP_R2]) / m)
        for k in range(K):
            p = emit(vals, rows, cols, p, ivx, iF + k, mu / m)
        # friction power mu F_N v - c W
        p = emit(vals, rows, cols, p, iEF, ivx, -(dmu * fsum * vx + mu * fsum - dcv * wm))
        for k in range(K):
            uk = kn.surface_velocity(k, y, off, fp) if moment else 0.0
            p = emit(vals, rows, cols, p, iEF, iF + k, -mu * (vx - uk))
        iS = off[OFF_IS]
        if kn.dynamic(off):
            # the law's state z: mu depends on it, z' = zdot(v, z) (the moment is refused)
            p = emit(vals, rows, cols, p, ivx, iS, ft.dmuz * fsum / m)
            p = emit(vals, rows, cols, p, iS, iS, cj - ft.dzz)
            p = emit(vals, rows, cols, p, iS, ivx, -ft.dzv)
            p = emit(vals, rows, cols, p, iEF, iS, -ft.dmuz * fsum * vx)
        iu = ivx
        dcu = dcv
    if moment:
        # the modal rows' friction column, the power's modal velocities
        for r in range(R):
            pr = kn.moment_arm(r, y, off, fp)
            p = emit(vals, rows, cols, p, idq + r, iu, -pr * dcu / M)
            p = emit(vals, rows, cols, p, iEF, idq + r, cm * pr)
    return p


@njit(cache=True, inline="always")
def jacobian_entries(t, y, yp, cj, vals, rows, cols, off, fp, omega2, cdamp, phi, phi_obs,
                     stiff, cres, spos, prof, reg, rf, work):
    """Every entry of ``J = dF/dy + cj dF/dyp`` at (t, y), through :func:`emit`.

    The one declaration of the Jacobian (module docstring): the modal rows, the vertical
    pair, the friction's rows (:func:`friction_entries`), the contact rows and the energy
    rows. ``rows``/``cols`` None: the value pass; arrays: the pattern pass.

    Returns
    -------
    int
        The number of entries.
    """
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = kn.state_offsets(off)
    m = fp[kn.FP_MASS]
    M = fp[kn.FP_MMODAL]
    ft = friction_terms(t, y, off, fp, reg)
    vx = ft.vx
    kn.compressions(t, y, off, fp, phi, cres, spos, prof, work)
    moment = ix >= 0 and kn.moment_on(off)
    ip = off[OFF_IPSI]
    p = 0
    # plate modes: q' = dq, dq' = -c dq - w^2 q + (phi F + c Psi F) / M
    for r in range(R):
        p = emit(vals, rows, cols, p, iq + r, iq + r, cj)
        p = emit(vals, rows, cols, p, iq + r, idq + r, -1.0)
        p = emit(vals, rows, cols, p, idq + r, iq + r, omega2[r])
        p = emit(vals, rows, cols, p, idq + r, idq + r, cj + cdamp[r])
        if moment:
            pr = kn.moment_arm(r, y, off, fp)
            for k in range(K):
                p = emit(vals, rows, cols, p, idq + r, iF + k,
                         -(phi[r, k] + ft.cm * fp[ip + k * R + r] + ft.dcf * pr) / M)
        else:
            for k in range(K):
                p = emit(vals, rows, cols, p, idq + r, iF + k, -phi[r, k] / M)
    # block, vertical
    p = emit(vals, rows, cols, p, iz, iz, cj)
    p = emit(vals, rows, cols, p, iz, ivz, -1.0)
    p = emit(vals, rows, cols, p, ivz, ivz, cj + fp[kn.FP_R1] / m)
    for k in range(K):
        p = emit(vals, rows, cols, p, ivz, iF + k, 1.0 / m)
    # block, tangential; friction state; friction power
    p = friction_entries(vals, rows, cols, p, t, y, cj, off, fp, reg, ft, M)
    # contacts: F_k / s_k - (z - w_k + h(s_k + x)) when closed, F_k / s_k when open
    for k in range(K):
        closed = reg[kn.REG_CLOSED + k] == 1
        for j in range(K):
            v = cres[k, j] if closed else 0.0
            if j == k:
                v += 1.0 / stiff[k]
            p = emit(vals, rows, cols, p, iF + k, iF + j, v)
        p = emit(vals, rows, cols, p, iF + k, iz, -1.0 if closed else 0.0)
        for r in range(R):
            p = emit(vals, rows, cols, p, iF + k, iq + r, phi[r, k] if closed else 0.0)
        if ix >= 0:
            p = emit(vals, rows, cols, p, iF + k, ix, -work[K + k] if closed else 0.0)
    # energy integrals: yp - power; nothing depends on them
    for i in range(N_ENERGY):
        p = emit(vals, rows, cols, p, iE + i, iE + i, cj)
    if ix >= 0:
        texc = fp[kn.FP_T0] * math.cos(fp[kn.FP_OMEGA] * t)
        p = emit(vals, rows, cols, p, iE + E_EXCITATION, ivx, -texc)
        p = emit(vals, rows, cols, p, iE + E_TANGENTIAL_DAMPING, ivx,
                 -2.0 * fp[kn.FP_R2] * vx)
    p = emit(vals, rows, cols, p, iE + E_VERTICAL_DAMPING, ivz, -2.0 * fp[kn.FP_R1] * y[ivz])
    for r in range(R):
        p = emit(vals, rows, cols, p, iE + E_PLATE_DAMPING, idq + r,
                 -2.0 * M * cdamp[r] * y[idq + r])
    s1 = 0.0
    s2 = 0.0
    for k in range(K):
        p = emit(vals, rows, cols, p, iE + E_ROUGHNESS, iF + k, -work[K + k] * vx)
        s1 += y[iF + k] * work[K + k]
        s2 += y[iF + k] * work[2 * K + k]
    if ix >= 0:
        p = emit(vals, rows, cols, p, iE + E_ROUGHNESS, ix, -s2 * vx)
        p = emit(vals, rows, cols, p, iE + E_ROUGHNESS, ivx, -s1)
    return p


@njit(cache=True)
def jacobian_values(t, y, yp, cj, vals, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres,
                    spos, prof, reg, rf, work):
    """Values of ``dF/dy + cj dF/dyp`` in the order of :func:`jacobian_pattern` (the value
    pass of :func:`jacobian_entries`); returns the number of entries."""
    return jacobian_entries(t, y, yp, cj, vals, None, None, off, fp, omega2, cdamp, phi,
                            phi_obs, stiff, cres, spos, prof, reg, rf, work)


def jacobian_pattern(off: np.ndarray, fp: np.ndarray, omega2: np.ndarray, cdamp: np.ndarray,
                     phi: np.ndarray, phi_obs: np.ndarray, stiff: np.ndarray, cres: np.ndarray,
                     spos: np.ndarray, prof: np.ndarray, reg: np.ndarray, rf: np.ndarray,
                     work: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of the Jacobian's entries, in the order of
    :func:`jacobian_values`: the pattern pass of :func:`jacobian_entries`.

    Runs the entries once to count them and once to record them, at the zero state (the
    values there are discarded; the pattern is the same in every regime), on a copy of
    ``work``.

    Parameters
    ----------
    off ... work
        The kernels' argument tail (``System.kernel_args``).

    Returns
    -------
    rows, cols : ndarray (nnz,) of int64

    Raises
    ------
    AssertionError
        If an entry is emitted twice.
    """
    n = int(off[OFF_IE]) + N_ENERGY  # the energy integrals are the last states
    y = np.zeros(n)
    scratch = np.zeros_like(work)
    args = (off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, reg, rf, scratch)
    empty = np.zeros(0, dtype=np.int64)
    nnz = jacobian_entries(0.0, y, y, 1.0, np.zeros(0), empty, empty.copy(), *args)
    rows = np.zeros(nnz, dtype=np.int64)
    cols = np.zeros(nnz, dtype=np.int64)
    jacobian_entries(0.0, y, y, 1.0, np.zeros(nnz), rows, cols, *args)
    if np.unique(rows * n + cols).size != nnz:
        raise AssertionError("duplicate Jacobian entries in the pattern")
    return rows, cols
