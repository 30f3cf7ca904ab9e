"""Kernels of the hybrid DAE: analytic Jacobian vs finite differences, plain-Python parity."""

import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from kernel_scene import SMALL_SCENE

import roughvib
from roughvib.model import jacobian as jac
from roughvib.model import kernels as kn
from roughvib.model.layout import StateLayout
from roughvib.model.system import assemble
from roughvib.physics.structures import export_modes
from roughvib.physics.structures.exchange import write_modes
from roughvib.scene import ModelValidityWarning, Plate
from roughvib.solvers.ida import _sparsity


def _small_scene(**kw):
    return roughvib.load_scene("paper-handset", {**SMALL_SCENE, **kw})


def _read_only(a):
    """A read-only copy of ``a``, as IDA hands y and y' to the Jacobian: the kernel runs in
    the specialisation a run compiles (numba would compile a second one for writable arrays)."""
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def _fd_jacobian(system, t, y, yp, cj, reg, rf):
    n = y.size
    args = system.kernel_args(reg, rf)

    def F(yy, yyp):
        r = np.empty(n)
        kn.residual(t, yy, yyp, r, *args)
        return r

    J = np.zeros((n, n))
    for j in range(n):
        h = 1e-6 * max(1e-6, abs(y[j]))
        e = np.zeros(n)
        e[j] = h
        J[:, j] = (F(y + e, yp) - F(y - e, yp)) / (2 * h)
        hp = 1e-6 * max(1.0, abs(yp[j]))
        e[j] = hp
        J[:, j] += cj * (F(y, yp + e) - F(y, yp - e)) / (2 * hp)
    return J


@pytest.mark.parametrize("overrides", [
    {},
    {"plate.kind": "rigid"},
    {"excitation.kind": "prescribed", "excitation.velocity": 0.01,
     "excitation.force_amplitude": "none"},
    {"contact.points": 1, "roughness.kind": "sinusoid"},
    {"friction.law": "coulomb", "friction.stribeck_velocity": 2e-3},
    {"contact.friction_moment": True},
    {"contact.friction_moment": True, "contact.patch": "area"},
    {"friction.law": "coulomb", "friction.stribeck_velocity": 2e-3,
     "contact.friction_moment": True},
    {"friction.law": "lugre"},
    {"friction.law": "lugre", "friction.parameters.sigma2": 0.5, "plate.kind": "rigid"},
])
@pytest.mark.short_run
def test_analytic_jacobian_matches_finite_differences(overrides):
    _assert_jacobian_matches_finite_differences(_small_scene(**overrides))


@pytest.mark.parametrize("moment", [False, True])
@pytest.mark.short_run
def test_analytic_jacobian_of_the_table_law_matches_finite_differences(tmp_path, moment):
    # a tabulated Stribeck-like curve, read from a file (the set-valued table law)
    table = tmp_path / "curve.csv"
    table.write_text("velocity,mu\n0,0.3856\n0.001,0.35\n0.004,0.31\n0.02,0.30\n0.2,0.29\n")
    scene = _small_scene(**{"friction.law": "table", "friction.table": str(table),
                            "contact.friction_moment": moment})
    assert scene.friction.set_valued
    _assert_jacobian_matches_finite_differences(scene)


@pytest.mark.parametrize("moment", [False, True])
@pytest.mark.short_run
def test_analytic_jacobian_of_imported_modes_matches_finite_differences(tmp_path, moment):
    # the small scene's plate exported (modes to twice its cut: a residual compliance from
    # the file) and imported: shapes and slopes interpolated between scattered nodes
    write_modes(tmp_path / "modes.npz", export_modes(Plate(max_frequency=3e3), grid=(41, 36)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelValidityWarning)
        scene = _small_scene(**{"plate.kind": "imported",
                                "plate.modes_file": str(tmp_path / "modes.npz"),
                                "contact.friction_moment": moment})
        system = assemble(scene)
    assert system.n_modes > 0 and np.any(system.cres)
    _assert_jacobian_matches_finite_differences(scene, system)


def _disagreement(J, rows, cols, vals, n):
    """How far the sparse matrix of (rows, cols, vals) is from J: the largest difference
    relative to its row's largest entry, and 1 where J has an entry outside the pattern."""
    A = sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).toarray()
    declared = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n)).toarray() > 0
    scale = np.maximum(np.abs(J), np.abs(A)).max(axis=1, keepdims=True) + 1e-300
    outside = 1.0 if np.any(J[~declared] != 0.0) else 0.0
    return max(float(np.max(np.abs(A - J) / scale)), outside)


def _assert_jacobian_matches_finite_differences(scene, system=None):
    """The sparse Jacobian (pattern pass and value pass of ``jacobian_entries``, through IDA's
    CSC permutation) equals central differences of the residual in three regimes; the pattern
    is the same in every regime; and the check itself fails for values out of step with the
    pattern (the values reversed)."""
    system = assemble(scene) if system is None else system
    rng = np.random.default_rng(3)
    y0, _ = system.static_equilibrium()
    n = system.layout.size
    rows, cols = system.jacobian_pattern()
    for trial in range(3):
        reg, rf = system.new_regime_arrays()
        # feldmann: branch -1/+1; coulomb: slip-/stick/slip+
        reg[kn.REG_B] = (-1, 0, 1)[trial] if system.set_valued else (-1, 1, 1)[trial]
        reg[kn.REG_S] = (1, -1, 1)[trial]
        reg[kn.REG_CLOSED:] = rng.integers(0, 2, system.n_contacts)
        rf[0] = 1e-3
        y = y0 * (1 + 0.01 * rng.standard_normal(n)) + 1e-9 * rng.standard_normal(n)
        y[system.layout.slice("plate.dq")] += 1e-4 * rng.standard_normal(system.n_modes)
        if system.tangential:
            y[system.layout.index("block.vx")] = 2e-3 * (trial - 1) + 3e-5
            y[system.layout.index("block.x")] = 1e-4 * trial
        if system.set_valued:
            y[system.layout.index("friction.force")] = 0.5  # a realistic value for the FD step
        if system.layout.has("friction.state"):  # a bristle deflection of a few um
            y[system.layout.slice("friction.state")] = 2e-6 * (trial - 1) + 1e-7
        yp = 1e-3 * rng.standard_normal(n)
        cj = 10.0 ** (2 + trial)
        J = _fd_jacobian(system, 0.003, y, yp, cj, reg, rf)
        # the pattern does not depend on the regime it is built in
        rows_reg, cols_reg = jac.jacobian_pattern(*system.kernel_args(reg, rf))
        assert np.array_equal(rows_reg, rows) and np.array_equal(cols_reg, cols)
        pattern, perm = _sparsity(system)
        vals = np.zeros(perm.size)
        nnz = jac.jacobian_values(0.003, _read_only(y), _read_only(yp), cj, vals,
                                  *system.kernel_args(reg, rf))
        assert nnz == rows.size == perm.size
        data = np.zeros(perm.size)
        kn.scatter(vals, perm, data)
        A = sp.csc_matrix((data, pattern.indices, pattern.indptr), shape=(n, n)).toarray()
        scale = np.maximum(np.abs(J), np.abs(A)).max(axis=1, keepdims=True) + 1e-300
        assert np.max(np.abs(A - J) / scale) < 1e-5
        assert np.all(J[pattern.toarray() == 0] == 0.0)
        # the same check on the COO triplets, and that it catches values out of step
        assert _disagreement(J, rows, cols, vals, n) < 1e-5
        assert _disagreement(J, rows, cols, vals[::-1], n) > 1e-2


def test_layout_names_and_sizes():
    lay = StateLayout(n_modes=4, n_contacts=3, tangential=True)
    assert lay.size == 4 + 4 + 2 + 2 + 3 + 6
    assert lay.slice("plate.dq") == slice(4, 8)
    assert lay.index("block.vx") == 11
    assert list(lay.algebraic_indices) == [12, 13, 14]
    presc = StateLayout(n_modes=0, n_contacts=1, tangential=False)
    assert not presc.has("block.x") and presc.index("block.x") == -1
    with pytest.raises(KeyError, match="no state 'plate.w'"):
        lay.slice("plate.w")


@pytest.mark.short_run
def test_static_equilibrium_carries_the_weight():
    system = assemble(_small_scene())
    y, closed = system.static_equilibrium()
    F = y[system.layout.slice("contact.force")]
    assert np.all(F >= 0) and np.all(F[closed == 0] == 0)
    assert F.sum() == pytest.approx(0.221 * 9.81, rel=1e-12)
    # the residual of the consistent static state is zero at rest with no drive
    reg, rf = system.new_regime_arrays()
    reg[kn.REG_CLOSED:] = closed
    reg[kn.REG_B] = 1
    yy, yp = system.consistent(0.0, y, reg, rf)
    assert np.max(np.abs(yp[system.layout.slice("plate.dq")])) < 1e-6
    assert abs(yp[system.layout.index("block.vz")]) < 1e-12


@pytest.mark.short_run
def test_consistent_force_rates_follow_the_contact_law():
    """yp of the contact forces is dF/dt along the motion: the forces that keep the contact
    law at t + d, for the differential states advanced by d yp, differ from those at t by
    d yp_F (central differences, 1e-6 relative). IDA predicts its first step after a restart
    from these; zero rates (as before) failed a tight touch-down (issue 17)."""
    system = assemble(_small_scene(**{"contact.points": 3}))
    y, closed = system.static_equilibrium()
    lay = system.layout
    rng = np.random.default_rng(5)
    y = y.copy()
    for name in ("plate.dq", "block.vz", "block.vx"):  # a moving state
        y[lay.slice(name)] = rng.normal(0.0, 1e-3, lay.slice(name).stop - lay.slice(name).start)
    reg, rf = system.new_regime_arrays()
    reg[kn.REG_CLOSED:] = closed
    reg[kn.REG_B] = 1
    t = 0.003
    yy, yp = system.consistent(t, y, reg, rf)
    iF = lay.slice("contact.force")
    d = 1e-9
    Fd = [system.contact_forces(t + s * d, yy + s * d * yp, closed) for s in (1, -1)]
    fd = (Fd[0] - Fd[1]) / (2 * d)
    assert np.max(np.abs(yp[iF])) > 1.0  # the forces do change
    np.testing.assert_allclose(yp[iF], fd, rtol=1e-6, atol=1e-6 * np.max(np.abs(fd)))


@pytest.mark.short_run
def test_kernels_without_jit_match_compiled(run_without_jit):
    """The residual, the Jacobian's pattern and its values computed with NUMBA_DISABLE_JIT=1
    (``emit`` as plain Python) equal the compiled ones."""
    system = assemble(_small_scene())
    y, closed = system.static_equilibrium()
    y = y * 1.001
    reg, rf = system.new_regime_arrays()
    reg[kn.REG_CLOSED:] = closed
    reg[kn.REG_B] = 1
    reg[kn.REG_S] = -1
    res = np.empty_like(y)
    yp = np.linspace(-1e-3, 1e-3, y.size)
    kn.residual(0.002, y, yp, res, *system.kernel_args(reg, rf))
    rows, cols = system.jacobian_pattern()
    vals = np.zeros(rows.size)
    jac.jacobian_values(0.002, y, yp, 3e4, vals, *system.kernel_args(reg, rf))
    plain = run_without_jit("""
        from roughvib.model import jacobian as jac
        y, yp = inp["y"], inp["yp"]
        res = np.empty_like(y)
        args = s.kernel_args(inp["reg"], np.zeros(2))
        kn.residual(0.002, y, yp, res, *args)
        rows, cols = s.jacobian_pattern()
        vals = np.zeros(rows.size)
        jac.jacobian_values(0.002, y, yp, 3e4, vals, *args)
        out.update(res=res, rows=rows, cols=cols, vals=vals)
    """, y=y, yp=yp, reg=reg)
    np.testing.assert_allclose(plain["res"], res, rtol=1e-12, atol=1e-18)
    np.testing.assert_array_equal(plain["rows"], rows)
    np.testing.assert_array_equal(plain["cols"], cols)
    np.testing.assert_allclose(plain["vals"], vals, rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("n_contacts", [1, 3, 4, 6, 9])  # groups of four and what is left
def test_observed_acceleration_is_the_modal_sum(n_contacts):
    """The plate acceleration at the observation point is sum_r phi_obs_r q''_r with
    q''_r = (Phi F)_r / M - c_r q'_r - w_r^2 q_r (and the friction moment's share
    cm (Psi^T F)_r / M): the kernel against that sum written with NumPy, on random modes."""
    rng = np.random.default_rng(7)
    R, K, M, cm = 57, n_contacts, 0.83, 0.37
    q, dq = rng.normal(size=R) * 1e-9, rng.normal(size=R) * 1e-5
    fk = rng.uniform(1.0, 5.0, size=K)
    phi, phi_obs = rng.normal(size=(R, K)), rng.normal(size=R)
    omega2 = (2 * np.pi * rng.uniform(1e2, 5e4, size=R)) ** 2
    cdamp = 1e-3 * np.sqrt(omega2)
    qdd = phi @ fk / M - cdamp * dq - omega2 * q
    got = kn.observed_acceleration(q, dq, fk, phi, phi_obs, omega2, cdamp, np.zeros(0), 0.0, M)
    assert got == pytest.approx(phi_obs @ qdd, rel=1e-12)
    psi = rng.normal(size=(K, R))  # the moment's slopes, contact-major
    got_m = kn.observed_acceleration(q, dq, fk, phi, phi_obs, omega2, cdamp, psi.ravel(), cm, M)
    assert got_m == pytest.approx(phi_obs @ (qdd + cm * psi.T @ fk / M), rel=1e-12)


@pytest.mark.parametrize("n_columns", [1, 2, 3, 4, 5, 7, 8, 9])
def test_column_sums_are_the_plain_loop_to_the_bit(n_columns):
    """kn.column_sums sums the columns of a row-major (R, K) matrix side by side, four at a
    time. Each sum must still be the plain loop's, in the order of the rows, without
    reassociation: IDA's residual reads the plate's displacement at the contacts through it,
    and a changed last bit changes where an extreme scene's IDA run stalls. Against a Python
    loop (IEEE double, each product and sum rounded in turn), exactly; against NumPy's matrix
    product within round-off. Magnitudes spread over 16 decades make any other order of the
    additions show in the last bits."""
    rng = np.random.default_rng(11)
    R, i0 = 61, 5
    A = rng.normal(size=(R, n_columns)) * 10.0 ** rng.uniform(-8.0, 8.0, size=(R, n_columns))
    v = rng.normal(size=R + i0 + 3)
    out = np.full(n_columns, np.nan)
    kn.column_sums(A, v, i0, out)
    plain = np.zeros(n_columns)
    for k in range(n_columns):
        acc = 0.0
        for r in range(R):
            acc += float(A[r, k]) * float(v[i0 + r])
        plain[k] = acc
    np.testing.assert_array_equal(out, plain)
    scale = np.abs(A).T @ np.abs(v[i0:i0 + R])
    assert np.all(np.abs(out - A.T @ v[i0:i0 + R]) <= 1e-13 * scale)
