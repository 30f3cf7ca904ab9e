"""Kernels of the adaptive exact-modal solver: propagators vs scipy's expm, the small dense
solve, plain-Python parity, and the scenes it refuses."""

import numpy as np
import pytest
from kernel_scene import SMALL_SCENE
from scipy.linalg import expm

import roughvib
from roughvib.api import simulate
from roughvib.model.krylov import lu_factor, lu_solve
from roughvib.scene import SceneError
from roughvib.solvers.adaptive_modal import SERIES_LIMIT, step_maps


def _expm_maps(w, zeta, h):
    """Phi, G0, G1 of one mode from the exponential of the augmented first-order-hold system."""
    A = np.zeros((4, 4))
    A[0, 1] = 1.0
    A[1, 0] = -w * w
    A[1, 1] = -2 * zeta * w
    A[1, 2] = 1.0  # u drives the acceleration
    A[2, 3] = 1.0  # u' constant over the step
    E = expm(A * h)
    return E[:2, :2], E[:2, 2] - E[:2, 3] / h, E[:2, 3] / h


@pytest.mark.parametrize("wh", [1e-7, 1e-4, 0.03, 0.5, 0.999, 1.001, 3.0, 40.0, 700.0])
@pytest.mark.parametrize("zeta", [0.0, 0.005, 0.3])
def test_step_maps_match_the_matrix_exponential(wh, zeta):
    """Both branches (series below omega h = 1, closed form above) against scipy's expm.

    Entries are compared in the units they act in: G0, G1 relative to their largest
    component, Phi relative to 1 (its scale), so that tiny coefficients at omega h -> 0
    (which multiply tiny inputs) are judged by what they contribute.
    """
    w = 2 * np.pi * 1e4
    h = wh / w
    Phi, G0, G1 = np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 2))
    step_maps(np.array([w * w]), np.array([2 * zeta * w]), h, Phi, G0, G1)
    P, g0, g1 = _expm_maps(w, zeta, h)
    # scale the state as [w q, q'] so that Phi's entries are O(1) whatever omega is
    S = np.diag([w, 1.0])
    Si = np.diag([1 / w, 1.0])
    tol = 2e-14 * max(1.0, wh)
    np.testing.assert_allclose(S @ Phi[0] @ Si, S @ P @ Si, rtol=0, atol=tol)
    for got, ref in ((G0[0], g0), (G1[0], g1)):
        scale = np.max(np.abs(S @ ref))
        np.testing.assert_allclose(S @ got, S @ ref, rtol=0, atol=2.5 * tol * scale)


def test_step_maps_are_continuous_across_the_branch_switch():
    w = 3e5
    out = []
    for wh in (SERIES_LIMIT * (1 - 1e-15), SERIES_LIMIT * (1 + 1e-15)):
        Phi, G0, G1 = np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 2))
        step_maps(np.array([w * w]), np.array([0.01 * w]), wh / w, Phi, G0, G1)
        out.append(np.concatenate([Phi.ravel() * [1, w, 1 / w, 1], G0.ravel() * [w * w, w],
                                   G1.ravel() * [w * w, w]]))
    np.testing.assert_allclose(out[0], out[1], rtol=0, atol=2e-14)


def test_step_maps_reproduce_free_decay_and_static_deflection():
    """Closed forms: free decay of q(0) = 1 and the static deflection u / w^2 of a constant
    force held for many periods."""
    w, z = 2 * np.pi * 500.0, 0.02
    h = 0.5  # 250 periods: the transient has decayed by exp(-z w h) = 2e-14
    Phi, G0, G1 = np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 2))
    step_maps(np.array([w * w]), np.array([2 * z * w]), h, Phi, G0, G1)
    assert G0[0, 0] + G1[0, 0] == pytest.approx(1 / w**2, rel=1e-12)
    assert abs(G0[0, 1] + G1[0, 1]) < 1e-12 / w
    h = 1e-3
    step_maps(np.array([w * w]), np.array([2 * z * w]), h, Phi, G0, G1)
    wd = w * np.sqrt(1 - z * z)
    q = np.exp(-z * w * h) * (np.cos(wd * h) + z * w / wd * np.sin(wd * h))
    assert Phi[0, 0, 0] == pytest.approx(q, rel=1e-12)


def test_newton_solve_on_a_leading_block_matches_numpy():
    """The Newton step factors the leading nu x nu block of a (K+1)-square buffer in place."""
    rng = np.random.default_rng(4)
    for n in (1, 2, 5, 11, 41):
        A = rng.standard_normal((n + 2, n + 2))
        A[:n, :n] += np.diag(np.full(n, 0.1))
        b = rng.standard_normal(n + 2)
        tail = b[n:].copy()
        ref = np.linalg.solve(A[:n, :n], b[:n])
        piv = np.zeros(n + 2, dtype=np.int64)
        lu_factor(A[:n, :n], piv[:n])
        lu_solve(A[:n, :n], piv[:n], b[:n])
        np.testing.assert_allclose(b[:n], ref, rtol=1e-10)
        assert np.array_equal(b[n:], tail)


@pytest.mark.short_run
@pytest.mark.parametrize(("R", "K"), [(0, 1), (1, 1), (37, 1), (5, 4), (120, 9)])
def test_the_trapezoidal_steps_scratch_slices_tile_it(R, K):
    """The named slices of implicit_step's float scratch follow each other without gap or
    overlap, in WS_* order, and fill the scratch (3 R + 6 K + 3 long, as before it had
    names)."""
    from roughvib.solvers.adaptive import trapezoidal as tz

    ws = np.arange(float(tz.ws_size(R, K)))
    assert ws.size == 3 * R + 6 * K + 3
    cut = [tz.ws_slice(ws, i, R, K) for i in range(tz.N_WS)]
    np.testing.assert_array_equal(np.concatenate(cut), ws)
    for i, piece in enumerate(cut):
        assert piece.size == tz.ws_length(i, R, K)
        assert piece.size == 0 or piece[0] == tz.ws_start(i, R, K)
    assert [cut[i].size for i in (tz.WS_SQ, tz.WS_SDQ, tz.WS_UM)] == [R] * 3
    assert [cut[i].size for i in (tz.WS_RHS, tz.WS_IDX, tz.WS_NOISE)] == [K + 1] * 3
    assert [cut[i].size for i in (tz.WS_WFREE, tz.WS_F, tz.WS_WM)] == [K] * 3


def test_kernels_without_jit_match_compiled(run_without_jit):
    """The whole solver in plain Python (NUMBA_DISABLE_JIT=1) gives the compiled result."""
    over = {**SMALL_SCENE, "output.duration": 3e-4, "output.progress": False,
            "solver.method": "adaptive-modal"}
    compiled = simulate(roughvib.load_scene("paper-handset", over))
    assert compiled.ok
    plain = run_without_jit(f"""
        r = roughvib.simulate(roughvib.load_scene("paper-handset", {over!r}))
        assert r.ok, r.summary["message"]
        out["plate"] = r.dataset["plate_vertical_acceleration"].values
        out["block"] = r.dataset["block_vertical_acceleration"].values
        out["steps"] = np.array(r.summary["solver"]["steps"])
    """)
    assert int(plain["steps"]) == compiled.summary["solver"]["steps"]
    for key, var in (("plate", "plate_vertical_acceleration"),
                     ("block", "block_vertical_acceleration")):
        ref = compiled.dataset[var].values
        np.testing.assert_allclose(plain[key], ref, rtol=0,
                                   atol=1e-9 * np.max(np.abs(ref)))


@pytest.mark.short_run
def test_a_law_the_registry_does_not_give_the_solver_is_refused_in_one_line(monkeypatch):
    """Every built-in law without internal states runs with adaptive-modal; where the solver
    registry says it does not run a law (here its entry struck down to single-valued laws),
    the scene is refused when it is loaded, and a system assembled before still is when the
    solver is called directly (its own guard reads the laws' solvers from the same
    registry)."""
    from dataclasses import replace

    from roughvib.model.system import assemble
    from roughvib.physics.friction import LAWS
    from roughvib.solvers import registry
    from roughvib.solvers.adaptive_modal import solve_adaptive_modal

    assert all("adaptive-modal" in law.solvers for law in LAWS.values() if law.states == 0)
    over = {"solver.method": "adaptive-modal", "friction.law": "coulomb",
            "output.duration": 1e-3, "output.progress": False}
    system = assemble(roughvib.load_scene("paper-handset", over))
    monkeypatch.setitem(registry._METHODS, "adaptive-modal",
                        replace(registry.get("adaptive-modal"), friction=("single-valued",)))
    assert LAWS["coulomb"].solvers == ("ida", "moreau")
    with pytest.raises(SceneError, match=r"^solver.method = 'adaptive-modal' cannot run this "
                                         r"scene: friction.law = 'coulomb' is set-valued "
                                         r"\(stick held at v = 0\), and adaptive-modal runs "
                                         r"single-valued laws only; use ida or moreau$") as info:
        roughvib.load_scene("paper-handset", over)
    assert "\n" not in str(info.value)
    with pytest.raises(SceneError, match=r"^solver.method = 'adaptive-modal' supports "
                                         r"friction.law = 'feldmann' only \(friction.law = "
                                         r"'coulomb' needs one of 'ida', 'moreau'\), got "
                                         r"'coulomb'$"):
        solve_adaptive_modal(system, progress=False)


@pytest.mark.short_run
@pytest.mark.parametrize("law,branch", [("feldmann", 1), ("feldmann", -1), ("coulomb", 0),
                                        ("coulomb", 1), ("coulomb", -1), ("table", 0),
                                        ("table", 1), ("table", -1)])
def test_derivatives_match_the_residual_for_every_law_and_regime(tmp_path, monkeypatch, law,
                                                                 branch):
    """``derivatives`` (block accelerations, energy powers) against the DAE residual of
    ``kernels.residual`` at a consistent state of every law and regime (stick: branch 0 of a
    set-valued law, where the friction force holds the block and does no work)."""
    from dataclasses import replace

    from roughvib.model import kernels as kn
    from roughvib.model.system import assemble
    from roughvib.solvers.adaptive_modal import D_AX, D_AZ, D_POWER, N_D, derivatives

    monkeypatch.chdir(tmp_path)
    (tmp_path / "curve.csv").write_text("velocity,mu\n0,0.38\n0.002,0.34\n0.01,0.30\n"
                                        "0.1,0.32\n")
    over = {**SMALL_SCENE, "friction.law": law, "contact.velocity_factor": False,
            "output.progress": False}
    if law == "table":
        over["friction.table"] = "curve.csv"
    if law == "coulomb":
        over["friction.stribeck_velocity"] = 3e-3
    scene = replace(roughvib.load_scene("paper", over), base_dir=str(tmp_path))
    system = assemble(scene)
    lay = system.layout
    rng = np.random.default_rng(7)
    y, closed = system.static_equilibrium()
    reg, rf = system.new_regime_arrays()
    reg[kn.REG_B] = branch
    reg[kn.REG_S] = -1
    reg[kn.REG_CLOSED:] = closed
    y[lay.slice("plate.dq")] = 1e-4 * rng.standard_normal(system.n_modes)
    y[lay.index("block.vz")] = 2e-4
    y[lay.index("block.x")] = 3e-4
    y[lay.index("block.vx")] = 0.004 * branch + (0.0007 if law == "feldmann" else 0.0)
    t = 0.0123
    y, yp = system.consistent(t, y, reg, rf)
    off, fp, _omega2, cdamp, _phi, _phi_obs, _stiff, _cres, spos, prof, _r, _f, _w = \
        system.kernel_args(reg, rf)
    d = np.zeros(N_D)
    derivatives(t, y, d, off, fp, cdamp, spos, prof, reg)
    assert d[D_AZ] == pytest.approx(yp[lay.index("block.vz")], rel=1e-14)
    assert d[D_AX] == pytest.approx(yp[lay.index("block.vx")], rel=1e-13, abs=1e-15)
    e = lay.slice("energy.excitation_work").start
    np.testing.assert_allclose(d[D_POWER:D_POWER + kn.N_ENERGY], yp[e:e + kn.N_ENERGY],
                               rtol=1e-13, atol=1e-300)
    if branch == 0:  # stick: held, no acceleration, no work of the drive or the friction
        assert d[D_AX] == 0.0
        assert d[D_POWER + kn.E_FRICTION] == 0.0 and d[D_POWER + kn.E_EXCITATION] == 0.0
    elif law != "feldmann":  # slip: the kinetic curve in the direction of sliding
        fsum = float(np.sum(y[lay.slice("contact.force")]))
        mu_k, _ = kn.kinetic(0.004, off, fp)
        texc = fp[kn.FP_T0] * np.cos(fp[kn.FP_OMEGA] * t)
        expect = (texc - branch * mu_k * fsum - fp[kn.FP_R2] * 0.004 * branch) / fp[kn.FP_MASS]
        assert d[D_AX] == pytest.approx(expect, rel=1e-12)



def test_error_norm_is_rms_over_the_modes_and_max_over_the_rest():
    from roughvib.solvers.adaptive_modal import _err_norm

    # two modal states (errors 3 and 1 weights), then two block states (0.5 and 2 weights)
    y0 = np.array([1.0, 1.0, 1.0, 1.0])
    atol = np.full(4, 1e-6)
    w = 1e-6 * 1.0 + 1e-6
    yb = y0.copy()
    ya = yb + 3 * w * np.array([3.0, 1.0, 0.5, 2.0])
    assert _err_norm(ya, yb, y0, atol, 1e-6, 2, 3.0) == pytest.approx(np.sqrt((9 + 1) / 2))
    ya[0] = yb[0]  # modal rms now 1/sqrt(2): the block state's 2 dominates
    assert _err_norm(ya, yb, y0, atol, 1e-6, 2, 3.0) == pytest.approx(2.0)
    assert _err_norm(ya, yb, y0, atol, 1e-6, 0, 3.0) == pytest.approx(2.0)  # rigid plate: max
    for pos in range(4):  # a NaN wins wherever it sits, even before finite components
        bad = ya.copy()
        bad[pos] = np.nan
        assert _err_norm(bad, yb, y0, atol, 1e-6, 2, 3.0) >= 1e300


def test_error_norm_over_many_modes_weighs_each_by_the_larger_magnitude():
    """The modal sum runs in vectorised order (round-off only): over an odd number of modes it
    equals the formula term by term, with each weight taken from the larger of |y0| and |yb|,
    and a zero weight or an infinite state is still rejected."""
    from roughvib.solvers.adaptive_modal import _err_norm

    rng = np.random.default_rng(7)
    n_modal = 787  # not a multiple of any vector width
    n = n_modal + 3
    y0 = rng.normal(size=n) * 10.0 ** rng.uniform(-9, -3, size=n)
    yb = y0 * rng.uniform(0.1, 10.0, size=n)  # either may be the larger
    atol = np.full(n, 1e-12)
    rtol = 1e-5
    w = rtol * np.maximum(np.abs(y0), np.abs(yb)) + atol
    ya = yb + 3.0 * w * rng.uniform(-2.0, 2.0, size=n)
    e = (ya - yb) / (3.0 * w)
    expect = max(np.sqrt(np.mean(e[:n_modal] ** 2)), np.max(np.abs(e[n_modal:])))
    assert _err_norm(ya, yb, y0, atol, rtol, n_modal, 3.0) == pytest.approx(expect, rel=1e-12)
    zero = atol.copy()
    zero[5] = 0.0
    y0z, ybz = y0.copy(), yb.copy()
    y0z[5] = ybz[5] = 0.0  # weight exactly zero: not a finite error
    assert _err_norm(ya, ybz, y0z, zero, rtol, n_modal, 3.0) >= 1e300
    big = ya.copy()
    big[300] = np.inf
    assert _err_norm(big, yb, y0, atol, rtol, n_modal, 3.0) >= 1e300


@pytest.mark.short_run
@pytest.mark.parametrize("law", ["feldmann", "coulomb"])
def test_extrapolation_is_richardsons_and_keeps_the_energy_integrals(law):
    """The kept state is ``yb + (yb - ya) / 3`` (the two half steps' estimate removed) in every
    state but the energy integrals; in a Coulomb stick the algebraic friction force is the one
    that holds the extrapolated state, not an extrapolated number."""
    from roughvib.model import kernels as kn
    from roughvib.solvers.adaptive_modal import _extrapolate

    system, y, t, (reg, rf) = _consistent_state(law)
    off, fp, _o, _c, phi, _po, _s, cres, spos, prof, _r, _f, work = system.kernel_args(reg, rf)
    rng = np.random.default_rng(3)
    yb = y * (1.0 + 1e-6 * rng.standard_normal(y.size))
    ya = y * (1.0 + 1e-6 * rng.standard_normal(y.size))
    before = yb.copy()
    ge = np.zeros(system.n_contacts + kn.N_LAW_ROOTS)
    armed = np.zeros(ge.size, dtype=np.int64)
    assert _extrapolate(t, ya, yb, np.zeros_like(y), ge, armed, off, fp, phi, cres, spos, prof,
                        reg, rf, work)
    expect = before + (before - ya) / 3.0
    lay = system.layout
    e = lay.slice("energy.excitation_work").start
    energy = slice(e, e + kn.N_ENERGY)
    expect[energy] = before[energy]
    if law == "coulomb":
        il = off[kn.OFF_IL]
        assert yb[il] == kn.set_valued_friction(t, yb, off, fp, reg)
        assert yb[il] != expect[il]  # recomputed, not extrapolated
        expect[il] = yb[il]
    np.testing.assert_array_equal(yb, expect)
    # the margins returned are those of the kept state
    g = np.zeros_like(ge)
    kn.events(t, yb, g, off, fp, phi, cres, spos, prof, reg, rf, work)
    np.testing.assert_array_equal(ge, g)


@pytest.mark.short_run
def test_extrapolation_that_would_cross_an_armed_margin_is_not_made():
    """Sliding forward (Feldmann branch +1, margin v - v_h): half steps that end at a positive
    margin m, and a full step at v + 4 m, extrapolate to a margin of -m / 3. With that root
    armed the half-step result is kept as it is; unarmed, the extrapolation is made."""
    from roughvib.model import kernels as kn
    from roughvib.solvers.adaptive_modal import _extrapolate

    system, y, t, (reg, rf) = _consistent_state("feldmann")
    off, fp, _o, _c, phi, _po, _s, cres, spos, prof, _r, _f, work = system.kernel_args(reg, rf)
    K = system.n_contacts
    ivx = system.layout.index("block.vx")
    g = np.zeros(K + kn.N_LAW_ROOTS)
    kn.events(t, y, g, off, fp, phi, cres, spos, prof, reg, rf, work)
    margin = g[K + kn.ROOT_BRANCH]
    assert margin > 0.0
    ya = y.copy()
    ya[ivx] = y[ivx] + 4.0 * margin
    for armed_branch, made in ((1, False), (0, True)):
        yb = y.copy()
        armed = np.zeros(K + kn.N_LAW_ROOTS, dtype=np.int64)
        armed[K + kn.ROOT_BRANCH] = armed_branch
        ge = np.zeros(K + kn.N_LAW_ROOTS)
        done = _extrapolate(t, ya, yb, np.zeros_like(y), ge, armed, off, fp, phi, cres, spos,
                            prof, reg, rf, work)
        assert done is made
        if made:
            assert ge[K + kn.ROOT_BRANCH] == pytest.approx(-margin / 3.0, rel=1e-9)
            assert yb[ivx] == pytest.approx(y[ivx] - 4.0 * margin / 3.0, rel=1e-12)
        else:
            np.testing.assert_array_equal(yb, y)


def _consistent_state(law):
    """A consistent state of the small scene, sliding forward (Feldmann) or held in a Coulomb
    stick, with the plate moving; returns (system, y, t, (reg, rf))."""
    from roughvib.model import kernels as kn
    from roughvib.model.system import assemble

    over = {**SMALL_SCENE, "friction.law": law, "contact.velocity_factor": False,
            "output.progress": False}
    if law == "coulomb":
        over["friction.stribeck_velocity"] = 3e-3
    system = assemble(roughvib.load_scene("paper", over))
    lay = system.layout
    y, closed = system.static_equilibrium()
    reg, rf = system.new_regime_arrays()
    reg[kn.REG_B] = 1 if law == "feldmann" else 0
    reg[kn.REG_S] = -1
    reg[kn.REG_CLOSED:] = closed
    rng = np.random.default_rng(7)
    y[lay.slice("plate.dq")] = 1e-4 * rng.standard_normal(system.n_modes)
    y[lay.index("block.vz")] = 2e-4
    y[lay.index("block.vx")] = 0.004 if law == "feldmann" else 0.0
    t = 0.0123
    y, _ = system.consistent(t, y, reg, rf)
    return system, y, t, (reg, rf)
