"""Numba kernels of the hybrid DAE: residual, root functions, outputs (the Jacobian:
:mod:`roughvib.model.jacobian`).

Kernels see raw float64/int64 arrays only (never a dataclass). They run unchanged with
``NUMBA_DISABLE_JIT=1``. All share one argument tail, built once by
:func:`roughvib.model.system.assemble` and documented here::

    off     int64 header, positions OFF_* (roughvib.model.layout, StateLayout.offsets): state
            offsets iq, idq, iz, ivz, ix, ivx, iF, iE, the sizes R, K, the friction-force
            state iL, the friction-law id (roughvib.physics.friction.LAW_*) and the start
            of the friction moment's slopes in fp (-1: no moment)
    fp      float64 scalars, positions FP_* below; from N_FP on, the packed kinetic curve
            of the table law (roughvib.physics.friction.law_table), empty otherwise; then,
            from off[OFF_IPSI], the friction moment's lever-scaled slopes (K x R)
    omega2  (R,) squared modal angular frequencies [rad^2/s^2]
    cdamp   (R,) 2 zeta_r omega_r [1/s]
    phi     (R, K) mode shapes at the contacts [-]
    phi_obs (R,) mode shapes at the observation point [-]
    stiff   (K,) contact spring stiffness [N/m]
    cres    (K, K) residual compliance of the truncated modes [m/N]
    spos    (K,) profile coordinates of the contacts at x = 0 [m]
    prof    (ncell, deg+1) profile interpolant (roughvib.physics.surface.interp)
    reg     int64 regime, positions REG_*: b, latch s, phase (1 stick, 0 slip), then
            closed_0..closed_K-1; b is the friction-law branch (feldmann) or the slip
            direction +1/-1, 0 = stick (set-valued laws)
    rf      float64 regime data, positions RF_*: the latch's running velocity extremum, the
            end time of a dwell hold
    work    float64 scratch, length work_size(K) (at least 5 K)

The residual is ``res = yp - f(y)`` for differential rows, so ``yp = -res(t, y, 0)`` gives the
consistent derivative. Closed contact k: ``F_k / s_k - (z - w_k + h(s_k + x)) = 0`` with the
plate displacement ``w_k = sum_r phi_rk q_r + sum_j C_kj F_j``; open contact: ``F_k / s_k = 0``.
No Heaviside, no max(): contact state and friction branch are regimes switched by roots.

Set-valued laws (``coulomb``, ``table``: the kernels branch on the law id
``off[OFF_LAW]``): the friction force lambda is algebraic. In stick ``lambda = T_exc - r2 v``
so that v' = 0 exactly (index 1); in slip b ``lambda = b mu_k(b v) F_N`` with the law's kinetic
coefficient (``roughvib.physics.friction.kinetic_coefficient``).

Friction moment (``contact.friction_moment``, ``off[OFF_IPSI] >= 0``): the friction force
T_k = c F_k that the block exerts on the plate at contact k (along +x, the block's x; c = mu
for the Feldmann law, lambda / F_N for the set-valued laws) acts on the plate's top surface,
hp/2 above the mid-plane. With w positive down (the direction of the contact force on the
plate) Kirchhoff's in-plane displacement of the top surface is u = +(hp/2) dw/dx, so the
generalised force on mode r is ``g_r = sum_k Psi_rk T_k`` with ``Psi = (hp/2) dphi/dx``
(packed in ``fp`` from ``off[OFF_IPSI]``, contact-major); it adds to ``phi F`` in the modal
rows. The friction law keeps the block's velocity as the slip velocity. The power
``sum_k T_k u'_k`` it puts into the plate is taken from the friction's: the friction
dissipation integrates ``sum_k T_k (v - u'_k)``, so the energy audit closes unchanged.

Outputs are named, each with its unit and description, in one table
(:mod:`roughvib.model.variables`, re-exported here: ``OUTPUTS``, the columns ``OUT_*``);
:func:`write_output_row` is the one function that writes a row, by name, for every solver
(:func:`outputs` from a state of the DAE, the fixed-step loops from their schemes' values), and
:func:`out_force_column` / :func:`out_roughness_column` give the column of a per-contact output:
no other code computes a column number.
"""

from __future__ import annotations

import math

import cffi
import numpy as np
from numba import carray, njit, types
from numba.core.errors import TypingError
from numba.extending import overload

from roughvib.model.layout import (
    E_EXCITATION,  # noqa: F401  (E_*, N_ENERGY: re-exported for the solvers)
    E_FRICTION,
    E_PLATE_DAMPING,
    E_ROUGHNESS,
    E_TANGENTIAL_DAMPING,
    E_VERTICAL_DAMPING,
    N_ENERGY,  # noqa: F401
    OFF_IDQ,
    OFF_IE,
    OFF_IF,
    OFF_IL,
    OFF_IPSI,
    OFF_IQ,
    OFF_IS,
    OFF_IVX,
    OFF_IVZ,
    OFF_IX,
    OFF_IZ,
    OFF_K,
    OFF_LAW,
    OFF_R,
)
from roughvib.model.variables import (  # noqa: F401  (the outputs, re-exported)
    CONTACT_OUTPUTS,
    N_OUT_FIXED,
    OUT_AZ,
    OUT_C_FORCE,
    OUT_C_ROUGHNESS,
    OUT_FRICTION,
    OUT_MU,
    OUT_NAMES,
    OUT_NORMAL,
    OUT_PLATE_ACC,
    OUT_VX,
    OUT_VZ,
    OUT_X,
    OUT_Z,
    OUTPUTS,
    contact_column,
    n_output_columns,
    output_columns,
)
from roughvib.physics.friction import (
    KIND_DYNAMIC,
    dynamic_law,
    is_set_valued,
    kinetic_coefficient,
    law_kind,
    single_valued_mu,
)
from roughvib.physics.friction.regime import N_ROOTS
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
#: the scalar slots of the friction laws' own keys (``friction.parameters``) by key name: a
#: law's key of this name is packed here (0 where the scene's law has no such key); FP_EPS is
#: derived, max(latch_velocity, hysteresis_velocity)
FP_LAW_KEYS = {"a1": FP_A1, "a2": FP_A2, "hysteresis_velocity": FP_VH,
               "stribeck_velocity": FP_VSTRIB, "switching_hysteresis": FP_HYST}

REG_B = 0
REG_S = 1
REG_PHASE = 2
REG_CLOSED = 3

RF_VEXT = 0    # the latch's running velocity extremum [m/s]
RF_DWELL = 1   # end of the current dwell hold [s]
N_RF = 2

# the friction law's root functions follow the K contact roots: ev[K + ROOT_*]
ROOT_BRANCH = 0  # feldmann: branch b X; set-valued: break-away margin (stick), b v (slip)
ROOT_LATCH = 1   # feldmann: latch margin; set-valued: threshold without hysteresis (stick)
ROOT_PHASE = 2   # feldmann: stick/slip phase margin; set-valued: dwell timer (stick)
N_LAW_ROOTS = N_ROOTS  # every law's three roots (roughvib.physics.friction.regime)

# the outputs (names, units, descriptions, columns) are declared in roughvib.model.variables;
# their columns are re-exported here for the kernels and the solvers
_contact_column = njit(cache=True, inline="always")(contact_column)


@njit(cache=True)
def out_force_column(k, K):
    """Output column of the contact force F_k [N] (contact k of K)."""
    return _contact_column(OUT_C_FORCE, k, K)


@njit(cache=True)
def out_roughness_column(k, K):
    """Output column of the roughness displacement -h(s_k + x) [m] at contact k of K."""
    return _contact_column(OUT_C_ROUGHNESS, k, K)


def work_size(K: int) -> int:
    """Length of the kernels' float scratch ``work`` with K contacts (at least 5 K)."""
    return 5 * K + 8


@njit(cache=True, inline="always")  # every solver's output row, as fast as if written there
def write_output_row(out, tangential, z, vz, az, plate_acc, x, vx, friction, normal, mu, force,
                     height):
    """Write one output row, every output by name: the one writer of output columns.

    Every solver calls it with the quantities of its scheme at an output time (``outputs``
    computes them from a state of the DAE); a new output (``roughvib.model.variables``) is
    a new argument here. Without a tangential state (prescribed motion) there is no
    friction model: the friction force and coefficient are NaN.

    Parameters
    ----------
    out : ndarray, shape (n_output_columns(K),)
        The row, written in place.
    tangential : bool
        Whether the block's tangential motion is a state (a friction model).
    z, vz, az : float
        Block vertical displacement [m], velocity [m/s], acceleration [m/s^2] (positive
        down).
    plate_acc : float
        Plate acceleration at the observation point [m/s^2] (positive down).
    x, vx : float
        Block tangential displacement [m] and velocity [m/s].
    friction : float
        Friction force on the block [N].
    normal : float
        Total normal contact force [N].
    mu : float
        Friction coefficient, friction force / normal force [-].
    force : ndarray, shape (K,)
        Contact forces [N].
    height : ndarray, shape (K,)
        Profile height h(s_k + x) at the contacts [m] (positive up); the output is the
        roughness displacement -h (positive down).
    """
    K = force.size
    out[OUT_Z] = z
    out[OUT_VZ] = vz
    out[OUT_AZ] = az
    out[OUT_PLATE_ACC] = plate_acc
    out[OUT_X] = x
    out[OUT_VX] = vx
    out[OUT_FRICTION] = friction if tangential else np.nan
    out[OUT_NORMAL] = normal
    out[OUT_MU] = mu if tangential else np.nan
    for k in range(K):
        out[out_force_column(k, K)] = force[k]
        out[out_roughness_column(k, K)] = -height[k]


@njit(cache=True, inline="always")
def runtime_int(value):
    """``value`` as a run-time int64 [-], for a constant passed to a compiled function.

    numba types a module constant (or a literal) at a call site as ``Literal[int]`` and
    compiles the called function once per literal value, next to its ``int64`` version: a
    large callee (a solver step with everything inlined) then compiles two or more times.
    Passing ``runtime_int(SLOT)`` instead keeps one specialisation.
    """
    return int(value)


def unowned(a):
    """A view of the C-contiguous array ``a`` without a memory record, for a compiled loop.

    numba keeps a reference count in each array's memory record: every compiled function
    that is not inlined increments and decrements it for each array it is passed (and for
    each view it takes) with an atomic instruction. On the ``paper`` scene those counts were
    59 % of the default solve's compiled time on an Intel Xeon (``perf``; 23 %
    on an earlier one). A view made by ``numba.carray`` over ``a``'s buffer (cffi's
    ``from_buffer``, as numba supports it) has no record: the counting calls on it return at
    once. The solver loops (adaptive-modal's two, the fixed-step schemes') take such views of
    their arrays at entry and pass them down; the arithmetic is the same, so are the results.

    The view does not keep ``a`` alive: use it only while the caller holds ``a`` (within
    the call that made it), never return or store it. Compiled callers get the view (numba
    ``overload``, inlined; an array that is not C-contiguous is a typing error, since the
    view is laid out in C order); called from Python, or with ``NUMBA_DISABLE_JIT=1``, this
    returns ``a`` itself (plain Python counts no references).

    Parameters
    ----------
    a : ndarray
        C-contiguous, any shape and numeric dtype.

    Returns
    -------
    ndarray
        The same memory, shape and dtype as ``a``.
    """
    return a


#: the cffi instance whose ``from_buffer`` numba compiles to the array's data pointer
_FFI = cffi.FFI()


@overload(unowned, inline="always")
def _unowned_compiled(a):
    if not isinstance(a, types.Array) or a.layout != "C":
        raise TypingError(f"unowned() takes a C-contiguous array, got {a}")

    def impl(a):
        return carray(_FFI.from_buffer(a), a.shape)
    return impl


@njit(cache=True, inline="always")
def runtime_bool(value):
    """``value`` as a run-time bool, for a constant passed to a compiled function (as
    :func:`runtime_int`: ``Literal[bool]`` arguments compile the callee once more each)."""
    return bool(value)


@njit(cache=True)
def state_offsets(off):
    """The state offsets and sizes of the header ``off``.

    Returns
    -------
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K : int
        First plate.q, plate.dq, block.z, block.vz, block.x, block.vx (-1 for prescribed
        motion), first contact.force and energy integral; number of modes and contacts.
    """
    return (off[OFF_IQ], off[OFF_IDQ], off[OFF_IZ], off[OFF_IVZ], off[OFF_IX], off[OFF_IVX],
            off[OFF_IF], off[OFF_IE], off[OFF_R], off[OFF_K])


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
    ix = off[OFF_IX]
    if ix >= 0:
        return y[ix], y[off[OFF_IVX]]
    return prescribed_motion(t, fp)


@njit(cache=True)
def kinetic(v, off, fp):
    """The set-valued law's kinetic coefficient at sliding speed v >= 0 and its slope.

    Returns
    -------
    mu_k : float
        [-].
    dmu_k_dv : float
        [s/m].
    """
    return kinetic_coefficient(off[OFF_LAW], v, fp[FP_MU_SLIP], fp[FP_MU_STICK], fp[FP_VSTRIB],
                               fp[N_FP:])


@njit(cache=True)
def set_valued(off):
    """Whether the scene's friction law is set-valued (friction force an algebraic state)."""
    return is_set_valued(off[OFF_LAW])


@njit(cache=True)
def dynamic(off):
    """Whether the scene's friction law is dynamic (internal states ``friction.state``)."""
    return law_kind(off[OFF_LAW]) == KIND_DYNAMIC


@njit(cache=True)
def velocity_law(vx, off, fp, reg):
    """A single-valued law's coefficient in the current regime and its slope in v.

    Returns
    -------
    mu : float
        [-].
    dmu_dv : float
        [s/m].
    """
    return single_valued_mu(off[OFF_LAW], vx + reg[REG_S] * fp[FP_VH], reg[REG_B],
                            fp[FP_MU_SLIP], fp[FP_MU_STICK], fp[FP_A1], fp[FP_A2])


@njit(cache=True)
def dynamic_friction(vx, y, off, fp, reg):
    """A dynamic law's coefficient, its state's rate and their partial derivatives, for the
    velocity's sign ``b = reg[REG_B]`` of the current regime.

    Returns
    -------
    mu, zdot, dmu_dv, dmu_dz, dzdot_dv, dzdot_dz : float
        ``roughvib.physics.friction.dynamic_law``'s, z the law's state ``friction.state``.
    """
    return dynamic_law(off[OFF_LAW], vx, y[off[OFF_IS]], float(reg[REG_B]), fp[FP_MU_SLIP],
                       fp[FP_MU_STICK], fp[N_FP:])


@njit(cache=True)
def set_valued_friction(t, y, off, fp, reg):
    """Algebraic friction force lambda [N] of the set-valued law for the current regime."""
    ivx, iF, K = off[OFF_IVX], off[OFF_IF], off[OFF_K]
    vx = y[ivx]
    b = reg[REG_B]
    if b == 0:
        return fp[FP_T0] * math.cos(fp[FP_OMEGA] * t) - fp[FP_R2] * vx
    fsum = 0.0
    for k in range(K):
        fsum += y[iF + k]
    muk, _ = kinetic(b * vx, off, fp)
    return b * muk * fsum


@njit(cache=True)
def moment_on(off):
    """Whether the friction force's moment drives the plate (``contact.friction_moment``)."""
    return off[OFF_IPSI] >= 0


@njit(cache=True)
def moment_arm(r, y, off, fp):
    """P_r = sum_k Psi_rk F_k [N/sqrt(kg)]: mode r's moment per unit friction coefficient."""
    ip, iF, R, K = off[OFF_IPSI], off[OFF_IF], off[OFF_R], off[OFF_K]
    acc = 0.0
    for k in range(K):
        acc += fp[ip + k * R + r] * y[iF + k]
    return acc


@njit(cache=True)
def surface_velocity(k, y, off, fp):
    """u'_k = sum_r Psi_rk q'_r [m/s]: tangential velocity of the plate's top surface at
    contact k (along the block's x)."""
    ip, idq, R = off[OFF_IPSI], off[OFF_IDQ], off[OFF_R]
    acc = 0.0
    base = ip + k * R
    for r in range(R):
        acc += fp[base + r] * y[idq + r]
    return acc


@njit(cache=True)
def moment_share(t, y, off, fp, reg):
    """The friction force on the plate per unit contact force, T_k = c F_k, and c's derivatives.

    Feldmann law: ``c = mu(v)`` (the law's coefficient in the current regime); set-valued
    laws: ``c = lambda / F_N`` (``F_N = sum_k F_k``; 0 when it is not positive): the friction
    force is shared among the contacts in proportion to their normal forces.

    Returns
    -------
    c : float
        [-].
    dc_dv, dc_dlambda, dc_dF : float
        Derivatives by the block's tangential velocity [s/m], by lambda [1/N] and by each
        contact force F_j [1/N].
    """
    iF, K = off[OFF_IF], off[OFF_K]
    fsum = 0.0
    for k in range(K):
        fsum += y[iF + k]
    if set_valued(off):
        if not fsum > 0.0:
            return 0.0, 0.0, 0.0, 0.0
        lam = y[off[OFF_IL]]
        return lam / fsum, 0.0, 1.0 / fsum, -lam / (fsum * fsum)
    if dynamic(off):  # refused when the scene is loaded (roughvib.solvers.registry)
        raise ValueError("contact.friction_moment: not integrated for a dynamic friction law")
    _, vx = tangential_kinematics(t, y, off, fp)
    mu, dmu = velocity_law(vx, off, fp, reg)
    return mu, dmu, 0.0, 0.0


@njit(cache=True)
def moment_power(y, off, fp):
    """W = sum_k F_k u'_k [N m/s]: the moment's power into the plate is ``c W`` [W]."""
    iF, K = off[OFF_IF], off[OFF_K]
    acc = 0.0
    for k in range(K):
        acc += y[iF + k] * surface_velocity(k, y, off, fp)
    return acc


#: the floating-point liberties of the sums over the modes: reassociation (so that a sum
#: vectorises), no signed zeros, fused multiply-add; never "no NaN / no inf", so that a
#: non-finite value still reaches the solvers' checks
SUM_FASTMATH = {"reassoc", "nsz", "contract"}


@njit(cache=True, fastmath=SUM_FASTMATH)
def vdot(a, b):
    """sum_r a[r] b[r] of two equally long vectors, summed in whatever order vectorises."""
    acc = 0.0
    for r in range(a.size):
        acc += a[r] * b[r]
    return acc


@njit(cache=True, fastmath=SUM_FASTMATH)
def weighted_square_sum(c, v):
    """sum_r c[r] v[r]^2 of two equally long vectors, summed in whatever order vectorises."""
    acc = 0.0
    for r in range(c.size):
        acc += c[r] * v[r] * v[r]
    return acc


#: contacts whose sums over the modes run side by side (:func:`column_sums`): a column of a
#: row-major (R, K) matrix read alone is a strided pass, and its sum one long chain of
#: dependent additions; four chains side by side in one pass over the rows cost about a
#: third as much
COLUMN_GROUP = 4


@njit(cache=True, inline="always")
def column_group(A, v, i0, k0, n):
    """``(s0, s1, s2, s3)``: s_j = sum_r A[r, k0 + j] v[i0 + r] for the ``n`` (1 to
    ``COLUMN_GROUP``) columns from k0 (the rest repeat column k0 + n - 1), side by side in
    one pass over the rows, each in its own accumulator. Inlined: the caller's floating-point
    liberties apply (none: each sum in the order of the rows, the same operations to the bit
    as one column after the other). A single column is summed alone (four copies of it would
    cost more than the one chain)."""
    if n == 1:
        s = 0.0
        for r in range(A.shape[0]):
            s += A[r, k0] * v[i0 + r]
        return s, s, s, s
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    a3 = 0.0
    k1 = k0 + min(1, n - 1)
    k2 = k0 + min(2, n - 1)
    k3 = k0 + min(3, n - 1)
    for r in range(A.shape[0]):
        vr = v[i0 + r]
        a0 += A[r, k0] * vr
        a1 += A[r, k1] * vr
        a2 += A[r, k2] * vr
        a3 += A[r, k3] * vr
    return a0, a1, a2, a3


@njit(cache=True)
def column_sums(A, v, i0, out):
    """out[k] = sum_r A[r, k] v[i0 + r] (A (R, K) row-major, out (K,)), each sum in the order
    of the rows and without reassociation (bit for bit the plain loop), ``COLUMN_GROUP``
    columns at a time (:func:`column_group`)."""
    K = A.shape[1]
    for k0 in range(0, K, COLUMN_GROUP):
        n = min(COLUMN_GROUP, K - k0)
        s = column_group(A, v, i0, k0, n)
        for j in range(n):
            out[k0 + j] = s[j]


@njit(cache=True)
def _plate_at_contacts(y, off, phi, cres, w):
    """w[k] = sum_r phi[r, k] q_r + sum_j cres[k, j] F_j (plate displacement at contact k).

    Each sum over the modes runs in a local accumulator, in the order of the modes
    (:func:`column_sums`): IDA's residual goes through here, and its runs stay what they
    were to the last bit (a vectorised order changed where an extreme scene's IDA run stalls;
    ``tests/physics/test_extremes.py``)."""
    iq, iF, K = off[OFF_IQ], off[OFF_IF], off[OFF_K]
    column_sums(phi, y, iq, w[:K])
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
    K = off[OFF_K]
    iz = off[OFF_IZ]
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
    iq, idq, iz, ivz, ix, ivx, iF, iE, R, K = state_offsets(off)
    m = fp[FP_MASS]
    M = fp[FP_MMODAL]
    fsum = 0.0
    for k in range(K):
        fsum += y[iF + k]
    moment = ix >= 0 and moment_on(off)
    cm = 0.0
    if moment:
        cm, _, _, _ = moment_share(t, y, off, fp, reg)
    # plate modes
    pdiss = 0.0
    for r in range(R):
        q = y[iq + r]
        dq = y[idq + r]
        f = 0.0
        for k in range(K):
            f += phi[r, k] * y[iF + k]
        if moment:
            f += cm * moment_arm(r, y, off, fp)
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
    iL = off[OFF_IL]
    if ix >= 0:
        texc = fp[FP_T0] * math.cos(fp[FP_OMEGA] * t)
        res[ix] = yp[ix] - vx
        if set_valued(off):
            fric = y[iL]
            res[iL] = fric - set_valued_friction(t, y, off, fp, reg)
        elif dynamic(off):
            mu, zdot, _, _, _, _ = dynamic_friction(vx, y, off, fp, reg)
            fric = mu * fsum
            res[off[OFF_IS]] = yp[off[OFF_IS]] - zdot
        else:
            mu, _ = velocity_law(vx, off, fp, reg)
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
        pm = cm * moment_power(y, off, fp) if moment else 0.0
        res[iE + E_FRICTION] = yp[iE + E_FRICTION] - (fric * vx - pm)
        res[iE + E_TANGENTIAL_DAMPING] = yp[iE + E_TANGENTIAL_DAMPING] - fp[FP_R2] * vx * vx
    else:
        res[iE] = yp[iE]
        res[iE + E_FRICTION] = yp[iE + E_FRICTION]
        res[iE + E_TANGENTIAL_DAMPING] = yp[iE + E_TANGENTIAL_DAMPING]
    res[iE + E_VERTICAL_DAMPING] = yp[iE + E_VERTICAL_DAMPING] - fp[FP_R1] * vz * vz
    res[iE + E_PLATE_DAMPING] = yp[iE + E_PLATE_DAMPING] - M * pdiss
    res[iE + E_ROUGHNESS] = yp[iE + E_ROUGHNESS] - rough_power


@njit(cache=True)
def scatter(vals, perm, jj):
    """jj[i] = vals[perm[i]]: COO-ordered values into the solver's CSC data array."""
    for i in range(perm.size):
        jj[i] = vals[perm[i]]


@njit(cache=True)
def follow_latch_extremum(v, reg, rf):
    """Move the latch's running velocity extremum ``rf[RF_VEXT]`` with a new sample ``v``
    [m/s] (the running maximum after a minimum, ``reg[REG_S] < 0``, else the running minimum),
    as the solvers do at their output times; returns the extremum."""
    if reg[REG_S] < 0:
        if v > rf[RF_VEXT]:
            rf[RF_VEXT] = v
    elif v < rf[RF_VEXT]:
        rf[RF_VEXT] = v
    return rf[RF_VEXT]


@njit(cache=True)
def latch_margin(y, off, fp, reg, rf):
    """The Feldmann law's latch margin ``eps - s (v - v_ext)`` [m/s] (``events``' entry
    ``K + ROOT_LATCH``): the only margin that depends on the running extremum ``rf[RF_VEXT]``,
    so the only one to renew when a grid point has moved that extremum."""
    return fp[FP_EPS] - reg[REG_S] * (y[off[OFF_IVX]] - rf[RF_VEXT])


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
    ix, iF, K = off[OFF_IX], off[OFF_IF], off[OFF_K]
    compressions(t, y, off, fp, phi, cres, spos, prof, work)
    for k in range(K):
        if reg[REG_CLOSED + k] == 1:
            ev[k] = work[k]
        else:
            ev[k] = -work[k]
    iL = off[OFF_IL]
    if ix >= 0 and set_valued(off):
        vx = y[off[OFF_IVX]]
        b = reg[REG_B]
        if b == 0:
            fsum = 0.0
            for k in range(K):
                fsum += y[iF + k]
            lam = abs(y[iL])
            ev[K + ROOT_BRANCH] = fp[FP_MU_STICK] * fsum * (1.0 + fp[FP_HYST]) - lam
            # the bare threshold counts the holds of a hysteresis; without one it is ev[K]
            ev[K + ROOT_LATCH] = fp[FP_MU_STICK] * fsum - lam if fp[FP_HYST] > 0.0 else 1.0
            ev[K + ROOT_PHASE] = rf[RF_DWELL] - t
        else:
            ev[K + ROOT_BRANCH] = b * vx
            ev[K + ROOT_LATCH] = 1.0
            ev[K + ROOT_PHASE] = 1.0
    elif ix >= 0:
        vx = y[off[OFF_IVX]]
        if dynamic(off):  # the velocity's sign, no latch
            ev[K + ROOT_BRANCH] = reg[REG_B] * vx
            ev[K + ROOT_LATCH] = 1.0
        else:
            xx = vx + reg[REG_S] * fp[FP_VH]
            ev[K + ROOT_BRANCH] = reg[REG_B] * xx
            ev[K + ROOT_LATCH] = latch_margin(y, off, fp, reg, rf)
        vs2 = fp[FP_VSTICK] * fp[FP_VSTICK]
        if reg[REG_PHASE] == 1:
            ev[K + ROOT_PHASE] = vs2 - vx * vx
        else:
            ev[K + ROOT_PHASE] = vx * vx - vs2
    else:
        ev[K + ROOT_BRANCH] = 1.0
        ev[K + ROOT_LATCH] = 1.0
        ev[K + ROOT_PHASE] = 1.0
    _ = iF


@njit(cache=True, fastmath=SUM_FASTMATH)
def observed_acceleration(q, dq, fk, phi, phi_obs, omega2, cdamp, psi, cm, M):
    """Plate acceleration at the observation point [m/s^2]: sum_r phi_obs_r q''_r, with
    q''_r = f_r / M - c_r q'_r - w_r^2 q_r and the modal force f_r = sum_k phi_rk F_k (plus
    ``cm sum_k Psi_rk F_k`` with the friction moment: ``psi`` its K x R slopes, contact-major,
    or empty). Summed in whatever order vectorises (round-off only): the free part in one pass
    over the modes, then the contacts' forces times their gains ``sum_r phi_obs_r phi_rk``,
    four contacts to a pass (:func:`column_group`; one loop over the modes with the
    contacts' sum inside does not vectorise, and a pass per contact reads a column of phi
    with a stride)."""
    R = q.size
    K = fk.size
    inv_m = 1.0 / M
    acc = 0.0
    for r in range(R):
        acc -= phi_obs[r] * (cdamp[r] * dq[r] + omega2[r] * q[r])
    for k0 in range(0, K, COLUMN_GROUP):  # the contacts' gains sum_r phi_obs_r phi_rk
        n = min(COLUMN_GROUP, K - k0)
        g = column_group(phi, phi_obs, 0, k0, n)
        for j in range(n):
            acc += g[j] * fk[k0 + j] * inv_m
    if psi.size > 0:
        for k in range(K):
            fm = cm * fk[k] * inv_m
            for r in range(R):
                acc += phi_obs[r] * psi[k * R + r] * fm
    return acc


@njit(cache=True)
def outputs(t, y, out, off, fp, omega2, cdamp, phi, phi_obs, stiff, cres, spos, prof, reg, rf,
            work):
    """One row of the stored outputs at a state y of the DAE at t [s], written into ``out``
    by :func:`write_output_row` (the columns of ``roughvib.model.variables``). Uses
    ``work[3K:5K]`` as scratch (the profile heights and the contact forces)."""
    iq, idq, iz, ivz, ix, _ivx, iF, _iE, R, K = state_offsets(off)
    m = fp[FP_MASS]
    M = fp[FP_MMODAL]
    # an open contact carries exactly zero force: report the regime, not the Newton round-off
    fk = work[4 * K:5 * K]
    fsum = 0.0
    for k in range(K):
        fk[k] = y[iF + k] if reg[REG_CLOSED + k] == 1 else 0.0
        fsum += fk[k]
    vz = y[ivz]
    moment = ix >= 0 and moment_on(off)
    cm = 0.0
    if moment:
        cm, _, _, _ = moment_share(t, y, off, fp, reg)
    acc = observed_acceleration(y[iq:iq + R], y[idq:idq + R], fk, phi, phi_obs, omega2, cdamp,
                                fp[off[OFF_IPSI]:] if moment else fp[:0], cm, M)
    x, vx = tangential_kinematics(t, y, off, fp)
    mu = np.nan
    fr = np.nan
    if ix >= 0 and set_valued(off):
        fr = y[off[OFF_IL]]
        mu = fr / fsum if fsum > 0.0 else np.nan
        if reg[REG_B] == 0:
            vx = 0.0  # stick holds the velocity at zero: report the regime, not round-off
    elif ix >= 0 and dynamic(off):
        mu, _, _, _, _, _ = dynamic_friction(vx, y, off, fp, reg)
        fr = mu * fsum
    elif ix >= 0:
        mu, _ = velocity_law(vx, off, fp, reg)
        fr = mu * fsum
    height = work[3 * K:4 * K]
    for k in range(K):
        h, _, _ = profile_eval(prof, fp[FP_S0], fp[FP_DX], spos[k] + x)
        height[k] = h
    az = fp[FP_GRAV] - fp[FP_R1] * vz / m - fsum / m
    write_output_row(out, ix >= 0, y[iz], vz, az, acc, x, vx, fr, fsum, mu, fk, height)
