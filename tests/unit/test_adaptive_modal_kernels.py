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
from roughvib.solvers.adaptive_modal import SERIES_LIMIT, bump_maps, step_maps


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


def _expm_bump(w, zeta, h):
    """[q, q'](h) from rest under u(t) = t (h - t) / 2, from the exponential of the system
    augmented with the input's Taylor chain u, u', u''."""
    A = np.zeros((5, 5))
    A[0, 1] = 1.0
    A[1, 0] = -w * w
    A[1, 1] = -2 * zeta * w
    A[1, 2] = 1.0
    A[2, 3] = 1.0
    A[3, 4] = 1.0
    return (expm(A * h) @ np.array([0.0, 0.0, 0.0, h / 2, -1.0]))[:2]


@pytest.mark.parametrize("wh", [1e-7, 1e-4, 0.03, 0.5, 0.999, 1.001, 3.0, 40.0, 700.0])
@pytest.mark.parametrize("zeta", [0.0, 0.005, 0.3])
def test_bump_maps_match_the_matrix_exponential(wh, zeta):
    """The first-order hold's error map (embedded error estimate) on both branches."""
    w = 2 * np.pi * 1e4
    h = wh / w
    Phi, G0, G1, G2 = (np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 2)),
                       np.zeros((1, 2)))
    step_maps(np.array([w * w]), np.array([2 * zeta * w]), h, Phi, G0, G1)
    bump_maps(np.array([w * w]), np.array([2 * zeta * w]), h, Phi, G2)
    ref = _expm_bump(w, zeta, h)
    S = np.diag([w, 1.0])
    scale = np.max(np.abs(S @ ref))
    # the closed form subtracts terms of order h^2 / w^2 to get a result of order h^4 / 24
    # near omega h = 1: a few digits go, which an error estimate can spare
    np.testing.assert_allclose(S @ G2[0], S @ ref, rtol=0, atol=1e-9 * scale)


def test_bump_maps_small_omega_limit():
    """omega h -> 0: q'' = u, so q(h) = h^4 / 24 and q'(h) = h^3 / 12 (integrals of the bump)."""
    h = 1e-5
    w = 1e-3 / h
    Phi, G0, G1, G2 = (np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 2)),
                       np.zeros((1, 2)))
    step_maps(np.array([w * w]), np.array([0.0]), h, Phi, G0, G1)
    bump_maps(np.array([w * w]), np.array([0.0]), h, Phi, G2)
    np.testing.assert_allclose(G2[0], [h**4 / 24, h**3 / 12], rtol=1e-6)


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


def test_coulomb_law_is_refused_with_a_one_line_error():
    over = {"solver.method": "adaptive-modal", "friction.law": "coulomb",
            "output.duration": 1e-3, "output.progress": False}
    with pytest.raises(SceneError, match="friction.law"):
        simulate(roughvib.load_scene("paper-handset", over))



def test_error_norm_is_rms_over_the_modes_and_max_over_the_rest():
    from roughvib.solvers.adaptive_modal import _err_norm

    # two modal states (errors 3 and 1 weights), then two block states (0.5 and 2 weights)
    y0 = np.array([1.0, 1.0, 1.0, 1.0])
    atol = np.full(4, 1e-6)
    w = 1e-6 * 1.0 + 1e-6
    yb = y0.copy()
    ya = yb + 3 * w * np.array([3.0, 1.0, 0.5, 2.0])
    assert _err_norm(ya, yb, y0, atol, 1e-6, 2) == pytest.approx(np.sqrt((9 + 1) / 2))
    ya[0] = yb[0]  # modal rms now 1/sqrt(2): the block state's 2 dominates
    assert _err_norm(ya, yb, y0, atol, 1e-6, 2) == pytest.approx(2.0)
    assert _err_norm(ya, yb, y0, atol, 1e-6, 0) == pytest.approx(2.0)  # rigid plate: max
    for pos in range(4):  # a NaN wins wherever it sits, even before finite components
        bad = ya.copy()
        bad[pos] = np.nan
        assert _err_norm(bad, yb, y0, atol, 1e-6, 2) >= 1e300
