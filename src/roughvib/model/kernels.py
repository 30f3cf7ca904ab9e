"""Numba kernels of the hybrid DAE: residual, sparse Jacobian values, root functions, outputs.

Kernels see raw float64/int64 arrays only (never a dataclass). They run unchanged with
``NUMBA_DISABLE_JIT=1``. All share one argument tail, built once by
:func:`roughvib.model.system.assemble` and documented here::

    off     int64 [iq, idq, iz, ivz, ix, ivx, iF, iE, R, K, iL] (StateLayout.offsets)
    fp      float64 scalars, indices FP_* below
    omega2  (R,) squared modal angular frequencies [rad^2/s^2]
    cdamp   (R,) 2 zeta_r omega_r [1/s]
    phi     (R, K) mode shapes at the contacts [-]
    phi_obs (R,) mode shapes at the observation point [-]
    stiff   (K,) contact spring stiffness [N/m]
    cres    (K, K) residual compliance of the truncated modes [m/N]
    spos    (K,) profile coordinates of the contacts at x = 0 [m]
    prof    (ncell, deg+1) profile interpolant (roughvib.physics.surface.interp)
    reg     int64 regime [b, latch s, phase (1 stick, 0 slip), closed_0..closed_K-1]; b is the
            friction-law branch (feldmann) or the slip direction +1/-1, 0 = stick (coulomb)
    rf      float64 regime data [v_ext (latch's running velocity extremum), dwell end time]
    work    float64 scratch, length >= 5 K

The residual is ``res = yp - f(y)`` for differential rows, so ``yp = -res(t, y, 0)`` gives the
consistent derivative. Closed contact k: ``F_k / s_k - (z - w_k + h(s_k + x)) = 0`` with the
plate displacement ``w_k = sum_r phi_rk q_r + sum_j C_kj F_j``; open contact: ``F_k / s_k = 0``.
No Heaviside, no max(): contact state and friction branch are regimes switched by roots.

Set-valued Coulomb law (``iL >= 0``): the friction force lambda is algebraic. In stick
``lambda = T_exc - r2 v`` so that v' = 0 exactly (index 1); in slip b ``lambda = b mu_k(b v)
F_N`` with the Stribeck-type kinetic coefficient of :func:`coulomb_kinetic`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from roughvib.physics.friction import feldmann_mu
from roughvib.physics.surface.interp import profile_eval

FP_MASS = 0
FP_GRAV = 1
FP_R1 = 2
FP_R2 = 3
FP_T0 = 4
FP_OMEGA = 5
FP_MU_SLIP = 6
FP_MU_STICK = 7
FP_A1 = 8
FP_A2 = 9
FP_VH = 10
FP_EPS = 11
FP_VSTICK = 12
FP_PV = 13      # prescribed: constant velocity [m/s]
FP_PA = 14      # prescribed: amplitude [m]
FP_PW = 15      # prescribed: angular frequency [rad/s]
FP_MMODAL = 16  # modal mass [kg]
FP_S0 = 17      # profile: first node [m]
FP_DX = 18      # profile: spacing [m]
FP_VSTRIB = 19  # coulomb: Stribeck velocity [m/s], 0 = constant kinetic coefficient
FP_HYST = 20    # coulomb: relative switching hysteresis of the break-away [-]
N_FP = 21

REG_B = 0
REG_S = 1
REG_PHASE = 2
REG_CLOSED = 3

#: output columns of :func:`outputs` before the per-contact blocks
OUT_NAMES = ("block_vertical_displacement", "block_vertical_velocity",
             "block_vertical_acceleration", "plate_vertical_acceleration",
             "block_tangential_displacement", "block_tangential_velocity", "friction_force",
             "normal_force", "friction_coefficient")
N_OUT_FIXED = len(OUT_NAMES)


@njit(cache=True)
def prescribed_motion(t, fp):
    """Prescribed tangential motion x(t) = v t + A sin(w t) and its velocity ([m], [m/s])."""
    w = fp[FP_PW]
    return fp[FP_PV] * t + fp[FP_PA] * math.sin(w * t), fp[FP_PV] + fp[FP_PA] * w * math.cos(w * t)


@njit(cache=True)
def block_parameters(fp):
    """The block and Feldmann-law scalars the fixed-step loops use, unpacked once.

    Returns
    -------
    m, g, r1, r2, mu_slip, mu_stick, a1, a2, v_h, eps, v_stick : float
        Mass [kg], gravity [m/s^2], dampers [N s/m], friction coefficients [-], law
        parameters a1, a2 [s/m], hysteresis, latch and stick velocities [m/s].
    """
    return (fp[FP_MASS], fp[FP_GRAV], fp[FP_R1], fp[FP_R2], fp[FP_MU_SLIP], fp[FP_MU_STICK],
            fp[FP_A1], fp[FP_A2], fp[FP_VH], fp[FP_EPS], fp[FP_VSTICK])


@njit(cache=True)
def tangential_kinematics(t, y, off, fp):
    """Tangential block position and velocity: states, or the prescribed motion.

    Returns
    -------
    x, vx : float
        [m], [m/s].
    """
    ix = off[4]
    if ix >= 0:
        return y[ix], y[off[5]]
    return prescribed_motion(t, fp)


@njit(cache=True)
def coulomb_kinetic(v, mu_slip, mu_stick, vs):
    """Kinetic coefficient mu_k(v) = mu_slip + (mu_stick - mu_slip) exp(-v / vs), v >= 0.

    Returns (mu_k, dmu_k/dv); ``vs <= 0`` gives the constant mu_slip.
    """
    if vs <= 0.0:
        return mu_slip, 0.0
    e = math.exp(-v / vs)
    return mu_slip + (mu_stick - mu_slip) * e, -(mu_stick - mu_slip) * e / vs


@njit(cache=True)
def coulomb_friction(t, y, off, fp, reg):
    """Algebraic friction force lambda [N] of the set-valued law for the current regime."""
    ivx, iF, K = off[5], off[6], off[9]
    vx = y[ivx]
    b = reg[REG_B]
    if b == 0:
        return fp[FP_T0] * math.cos(fp[FP_OMEGA] * t) - fp[FP_R2] * vx
    fsum = 0.0
    for k in range(K):
        fsum += y[iF + k]
    muk, _ = coulomb_kinetic(b * vx, fp[FP_MU_SLIP], fp[FP_MU_STICK], fp[FP_VSTRIB])
    return b * muk * fsum


@njit(cache=True)
def _plate_at_contacts(y, off, phi, cres, w):
    """w[k] = sum_r phi[r, k] q_r + sum_j cres[k, j] F_j (plate displacement at contact k)."""
    iq, iF, R, K = off[0], off[6], off[8], off[9]
    for k in range(K):
        w[k] = 0.0
    for r in range(R):
        q = y[iq + r]
        for k in range(K):
            w[k] += phi[r, k] * q
    for k in range(K):
        acc = 0.0
        for j in range(K):
            acc += cres[k, j] * y[iF + j]
        w[k] += acc


@njit(cache=True)
def compressions(t, y, off, fp, phi, cres, spos, prof, work):
    """Spring compressions (positive = in contact) and profile slope/curvature at the contacts.

    Fills ``work[0:K]`` with compression [m], ``work[K:2K]`` with z'(s_k + x) [-] and
    ``work[2K:3K]`` with z''(s_k + x) [1/m]; uses ``work[3K:4K]`` as scratch.
    """
    K = off[9]
    iz = off[2]
    x, _ = tangential_kinematics(t, y, off, fp)
    wk = work[3 * K:4 * K]
    _plate_at_contacts(y, off, phi, cres, wk)
    z = y[iz]
    for k in range(K):
        h, dh, d2h = profile_eval(prof, fp[FP_S0], fp[FP_DX], spos[k] + x)
        work[k] = z - wk[k] + h
        work[K + k] = dh
        work[2 * K + k] = d2h


@njit(cache=True)
def residual(t, y, yp, res, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof,
             reg, rf, work):
    """DAE residual ``res = F(t, y, yp)`` of the current regime (see module docstring)."""
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = (off[0], off[1], off[2], off[3], off[4], off[5],
                                               off[6], off[7], off[8], off[9])
    m = fp[FP_MASS]
    M = fp[FP_MMODAL]
    fsum = 0.0
    for k in range(K):
        fsum += y[iF + k]
    # plate modes
    pdiss = 0.0
    for r in range(R):
        q = y[iq + r]
        dq = y[idq + r]
        f = 0.0
        for k in range(K):
            f += phi[r, k] * y[iF + k]
        res[iq + r] = yp[iq + r] - dq
        res[idq + r] = yp[idq + r] + cdamp[r] * dq + omega2[r] * q - f / M
        pdiss += cdamp[r] * dq * dq
    # block, vertical (positive down)
    vz = y[ivz]
    res[iz] = yp[iz] - vz
    res[ivz] = yp[ivz] - (fp[FP_GRAV] - fp[FP_R1] * vz / m - fsum / m)
    # tangential
    x, vx = tangential_kinematics(t, y, off, fp)
    texc = 0.0
    fric = 0.0
    iL = off[10]
    if ix >= 0:
        texc = fp[FP_T0] * math.cos(fp[FP_OMEGA] * t)
        res[ix] = yp[ix] - vx
        if iL >= 0:
            fric = y[iL]
            res[iL] = fric - coulomb_friction(t, y, off, fp, reg)
        else:
            xx = vx + reg[REG_S] * fp[FP_VH]
            mu, _ = feldmann_mu(xx, reg[REG_B], fp[FP_MU_SLIP], fp[FP_MU_STICK], fp[FP_A1],
                                fp[FP_A2])
            fric = mu * fsum
        res[ivx] = yp[ivx] - (texc - fric - fp[FP_R2] * vx) / m
    # contacts (algebraic)
    compressions(t, y, off, fp, phi, cres, spos, prof, work)
    rough_power = 0.0
    for k in range(K):
        if reg[REG_CLOSED + k] == 1:
            res[iF + k] = y[iF + k] / stiff[k] - work[k]
        else:
            res[iF + k] = y[iF + k] / stiff[k]
        rough_power += y[iF + k] * work[K + k] * vx
    # energy audit integrals
    if ix >= 0:
        res[iE] = yp[iE] - texc * vx
        res[iE + 1] = yp[iE + 1] - fric * vx
        res[iE + 2] = yp[iE + 2] - fp[FP_R2] * vx * vx
    else:
        res[iE] = yp[iE]
        res[iE + 1] = yp[iE + 1]
        res[iE + 2] = yp[iE + 2]
    res[iE + 3] = yp[iE + 3] - fp[FP_R1] * vz * vz
    res[iE + 4] = yp[iE + 4] - M * pdiss
    res[iE + 5] = yp[iE + 5] - rough_power


def jacobian_pattern(off: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of the Jacobian entries, in the order of :func:`jacobian_values`.

    Plain Python: it runs once per solver set-up. Any change here must be mirrored in
    :func:`jacobian_values` (the unit tests compare both with a finite-difference Jacobian).
    """
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = (int(v) for v in off[:10])
    rows: list[int] = []
    cols: list[int] = []

    def add(r: int, c: int) -> None:
        rows.append(r)
        cols.append(c)

    for r in range(R):
        add(iq + r, iq + r)
        add(iq + r, idq + r)
        add(idq + r, iq + r)
        add(idq + r, idq + r)
        for k in range(K):
            add(idq + r, iF + k)
    add(iz, iz)
    add(iz, ivz)
    add(ivz, ivz)
    for k in range(K):
        add(ivz, iF + k)
    iL = int(off[10])
    if ix >= 0:
        add(ix, ix)
        add(ix, ivx)
        add(ivx, ivx)
        if iL >= 0:
            add(ivx, iL)
        else:
            for k in range(K):
                add(ivx, iF + k)
    for k in range(K):
        for j in range(K):
            add(iF + k, iF + j)
        add(iF + k, iz)
        for r in range(R):
            add(iF + k, iq + r)
        if ix >= 0:
            add(iF + k, ix)
    if iL >= 0:
        add(iL, iL)
        add(iL, ivx)
        for k in range(K):
            add(iL, iF + k)
    # energy rows
    add(iE, iE)
    if ix >= 0:
        add(iE, ivx)
    add(iE + 1, iE + 1)
    if ix >= 0:
        add(iE + 1, ivx)
        if iL >= 0:
            add(iE + 1, iL)
        else:
            for k in range(K):
                add(iE + 1, iF + k)
    add(iE + 2, iE + 2)
    if ix >= 0:
        add(iE + 2, ivx)
    add(iE + 3, iE + 3)
    add(iE + 3, ivz)
    add(iE + 4, iE + 4)
    for r in range(R):
        add(iE + 4, idq + r)
    add(iE + 5, iE + 5)
    for k in range(K):
        add(iE + 5, iF + k)
    if ix >= 0:
        add(iE + 5, ix)
        add(iE + 5, ivx)
    return np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64)


@njit(cache=True)
def jacobian_values(t, y, yp, cj, vals, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres,
                    spos, prof, reg, rf, work):
    """Values of dF/dy + cj dF/dyp in the order of :func:`jacobian_pattern`."""
    _iq, idq, _iz, ivz, ix, _ivx, iF, _iE, R, K = (off[0], off[1], off[2], off[3], off[4], off[5],
                                               off[6], off[7], off[8], off[9])
    m = fp[FP_MASS]
    M = fp[FP_MMODAL]
    fsum = 0.0
    for k in range(K):
        fsum += y[iF + k]
    x, vx = tangential_kinematics(t, y, off, fp)
    compressions(t, y, off, fp, phi, cres, spos, prof, work)
    p = 0
    for r in range(R):
        vals[p] = cj
        vals[p + 1] = -1.0
        vals[p + 2] = omega2[r]
        vals[p + 3] = cj + cdamp[r]
        p += 4
        for k in range(K):
            vals[p] = -phi[r, k] / M
            p += 1
    vals[p] = cj
    vals[p + 1] = -1.0
    vals[p + 2] = cj + fp[FP_R1] / m
    p += 3
    for _k in range(K):
        vals[p] = 1.0 / m
        p += 1
    mu = 0.0
    dmu = 0.0
    texc = 0.0
    iL = off[10]
    if ix >= 0:
        texc = fp[FP_T0] * math.cos(fp[FP_OMEGA] * t)
        vals[p] = cj
        vals[p + 1] = -1.0
        if iL >= 0:
            vals[p + 2] = cj + fp[FP_R2] / m
            vals[p + 3] = 1.0 / m
            p += 4
        else:
            xx = vx + reg[REG_S] * fp[FP_VH]
            mu, dmu = feldmann_mu(xx, reg[REG_B], fp[FP_MU_SLIP], fp[FP_MU_STICK], fp[FP_A1],
                                  fp[FP_A2])
            vals[p + 2] = cj + (dmu * fsum + fp[FP_R2]) / m
            p += 3
            for _k in range(K):
                vals[p] = mu / m
                p += 1
    for k in range(K):
        closed = reg[REG_CLOSED + k] == 1
        for j in range(K):
            v = cres[k, j] if closed else 0.0
            if j == k:
                v += 1.0 / stiff[k]
            vals[p] = v
            p += 1
        vals[p] = -1.0 if closed else 0.0
        p += 1
        for r in range(R):
            vals[p] = phi[r, k] if closed else 0.0
            p += 1
        if ix >= 0:
            vals[p] = -work[K + k] if closed else 0.0
            p += 1
    if iL >= 0:
        b = reg[REG_B]
        vals[p] = 1.0
        if b == 0:
            vals[p + 1] = fp[FP_R2]
            p += 2
            for _k in range(K):
                vals[p] = 0.0
                p += 1
        else:
            muk, dmuk = coulomb_kinetic(b * vx, fp[FP_MU_SLIP], fp[FP_MU_STICK], fp[FP_VSTRIB])
            vals[p + 1] = -dmuk * fsum
            p += 2
            for _k in range(K):
                vals[p] = -b * muk
                p += 1
    # energy rows
    vals[p] = cj
    p += 1
    if ix >= 0:
        vals[p] = -texc
        p += 1
    vals[p] = cj
    p += 1
    if ix >= 0:
        if iL >= 0:
            vals[p] = -y[iL]
            vals[p + 1] = -vx
            p += 2
        else:
            vals[p] = -(dmu * fsum * vx + mu * fsum)
            p += 1
            for _k in range(K):
                vals[p] = -mu * vx
                p += 1
    vals[p] = cj
    p += 1
    if ix >= 0:
        vals[p] = -2.0 * fp[FP_R2] * vx
        p += 1
    vals[p] = cj
    vals[p + 1] = -2.0 * fp[FP_R1] * y[ivz]
    vals[p + 2] = cj
    p += 3
    for r in range(R):
        vals[p] = -2.0 * M * cdamp[r] * y[idq + r]
        p += 1
    vals[p] = cj
    p += 1
    s1 = 0.0
    s2 = 0.0
    for k in range(K):
        vals[p] = -work[K + k] * vx
        p += 1
        s1 += y[iF + k] * work[K + k]
        s2 += y[iF + k] * work[2 * K + k]
    if ix >= 0:
        vals[p] = -s2 * vx
        vals[p + 1] = -s1
        p += 2
    return p


@njit(cache=True)
def scatter(vals, perm, jj):
    """jj[i] = vals[perm[i]]: COO-ordered values into the solver's CSC data array."""
    for i in range(perm.size):
        jj[i] = vals[perm[i]]


@njit(cache=True)
def events(t, y, ev, off, fp, phi, cres, spos, prof, reg, rf, work):
    """Root functions, each a *margin* that is positive while the current regime holds.

    ``ev[0:K]``: contact k closed -> compression F_k/s_k (lift-off at 0); open -> minus the
    compression (touch-down at 0). Feldmann law: ``ev[K]`` friction branch b * X,
    ``ev[K+1]`` latch margin eps - s (v - v_ext), ``ev[K+2]`` phase margin (slip:
    v^2 - v_st^2, stick: v_st^2 - v^2). Coulomb law, stick: ``ev[K]`` break-away margin
    mu_stick F_N (1 + eps_h) - ``|lambda|``, ``ev[K+1]`` the same without hysteresis (counts the
    hysteresis holds; constant 1 when eps_h = 0), ``ev[K+2]`` dwell timer t_dwell_end - t;
    slip b: ``ev[K]`` = b v.
    All are watched for downward crossings only; prescribed motion disables the last three
    (constant 1).
    """
    ix, iF, K = off[4], off[6], off[9]
    compressions(t, y, off, fp, phi, cres, spos, prof, work)
    for k in range(K):
        if reg[REG_CLOSED + k] == 1:
            ev[k] = work[k]
        else:
            ev[k] = -work[k]
    iL = off[10]
    if ix >= 0 and iL >= 0:
        vx = y[off[5]]
        b = reg[REG_B]
        if b == 0:
            fsum = 0.0
            for k in range(K):
                fsum += y[iF + k]
            lam = abs(y[iL])
            ev[K] = fp[FP_MU_STICK] * fsum * (1.0 + fp[FP_HYST]) - lam
            # the bare threshold counts the holds of a hysteresis; without one it is ev[K]
            ev[K + 1] = fp[FP_MU_STICK] * fsum - lam if fp[FP_HYST] > 0.0 else 1.0
            ev[K + 2] = rf[1] - t
        else:
            ev[K] = b * vx
            ev[K + 1] = 1.0
            ev[K + 2] = 1.0
    elif ix >= 0:
        vx = y[off[5]]
        xx = vx + reg[REG_S] * fp[FP_VH]
        ev[K] = reg[REG_B] * xx
        ev[K + 1] = fp[FP_EPS] - reg[REG_S] * (vx - rf[0])
        vs2 = fp[FP_VSTICK] * fp[FP_VSTICK]
        if reg[REG_PHASE] == 1:
            ev[K + 2] = vs2 - vx * vx
        else:
            ev[K + 2] = vx * vx - vs2
    else:
        ev[K] = 1.0
        ev[K + 1] = 1.0
        ev[K + 2] = 1.0
    _ = iF


@njit(cache=True)
def outputs(t, y, out, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, reg, rf,
            work):
    """One row of the stored outputs (columns ``OUT_NAMES``, then F_k, then xi_rough_k)."""
    iq, idq, iz, ivz, ix, iF, R, K = (off[0], off[1], off[2], off[3], off[4], off[6], off[8],
                                      off[9])
    m = fp[FP_MASS]
    M = fp[FP_MMODAL]
    # an open contact carries exactly zero force: report the regime, not the Newton round-off
    fk = work[4 * K:5 * K]
    fsum = 0.0
    for k in range(K):
        fk[k] = y[iF + k] if reg[REG_CLOSED + k] == 1 else 0.0
        fsum += fk[k]
    vz = y[ivz]
    acc = 0.0
    for r in range(R):
        f = 0.0
        for k in range(K):
            f += phi[r, k] * fk[k]
        acc += phi_obs[r] * (f / M - cdamp[r] * y[idq + r] - omega2[r] * y[iq + r])
    x, vx = tangential_kinematics(t, y, off, fp)
    mu = np.nan
    fr = np.nan
    if ix >= 0 and off[10] >= 0:
        fr = y[off[10]]
        mu = fr / fsum if fsum > 0.0 else np.nan
        if reg[REG_B] == 0:
            vx = 0.0  # stick holds the velocity at zero: report the regime, not round-off
    elif ix >= 0:
        xx = vx + reg[REG_S] * fp[FP_VH]
        mu, _ = feldmann_mu(xx, reg[REG_B], fp[FP_MU_SLIP], fp[FP_MU_STICK], fp[FP_A1],
                            fp[FP_A2])
        fr = mu * fsum
    out[0] = y[iz]
    out[1] = vz
    out[2] = fp[FP_GRAV] - fp[FP_R1] * vz / m - fsum / m
    out[3] = acc
    out[4] = x
    out[5] = vx
    out[6] = fr
    out[7] = fsum
    out[8] = mu
    n0 = N_OUT_FIXED
    for k in range(K):
        out[n0 + k] = fk[k]
        h, _, _ = profile_eval(prof, fp[FP_S0], fp[FP_DX], spos[k] + x)
        out[n0 + K + k] = -h
