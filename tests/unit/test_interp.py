"""Profile interpolants: exactness, continuity order and derivative consistency."""

import numpy as np
import pytest

from roughvib.physics.surface.interp import build_coefficients, profile_eval_many


def test_interpolants_pass_through_nodes_and_reproduce_polynomials():
    dx = 1e-5
    s = np.arange(200) * dx
    rng = np.random.default_rng(0)
    z = rng.standard_normal(200) * 1e-6
    for kind in ("linear", "cubic", "quintic"):
        c = build_coefficients(z, dx, kind)
        zz, _, _ = profile_eval_many(c, 0.0, dx, s[5:-5])
        np.testing.assert_allclose(zz, z[5:-5], rtol=0, atol=1e-18)
    cubic = 1e-3 * (s - 1e-3) ** 3 + 2e-2 * s**2
    c = build_coefficients(cubic, dx, "cubic")
    q = np.linspace(2e-4, 1.8e-3, 333)
    zz, dz, d2z = profile_eval_many(c, 0.0, dx, q)
    np.testing.assert_allclose(zz, 1e-3 * (q - 1e-3) ** 3 + 2e-2 * q**2, atol=1e-16)
    np.testing.assert_allclose(dz, 3e-3 * (q - 1e-3) ** 2 + 4e-2 * q, atol=1e-12)
    np.testing.assert_allclose(d2z, 6e-3 * (q - 1e-3) + 4e-2, atol=1e-8)


@pytest.mark.parametrize("kind,order", [("linear", 2), ("cubic", 4), ("quintic", 6)])
def test_interpolation_error_converges_at_its_order(kind, order):
    lam = 1e-3
    errs = []
    for dx in (lam / 20, lam / 40):
        s = np.arange(int(0.01 / dx) + 1) * dx
        c = build_coefficients(np.sin(2 * np.pi * s / lam), dx, kind)
        q = np.linspace(0.003, 0.007, 2001)
        zz, _, _ = profile_eval_many(c, 0.0, dx, q)
        errs.append(np.max(np.abs(zz - np.sin(2 * np.pi * q / lam))))
    slope = np.log2(errs[0] / errs[1])
    assert abs(slope - order) < 0.3


def test_continuity_of_derivatives_at_nodes():
    dx = 1e-5
    z = np.random.default_rng(1).standard_normal(100)
    nodes = np.arange(10, 90) * dx
    for kind, smooth in (("linear", 0), ("cubic", 2), ("quintic", 2)):
        c = build_coefficients(z, dx, kind)
        left = profile_eval_many(c, 0.0, dx, nodes - 1e-13)
        right = profile_eval_many(c, 0.0, dx, nodes + 1e-13)
        for d in range(smooth + 1):
            tol = 1e-6 * np.max(np.abs(right[d])) + 1e-12 * (1e5 ** d)
            assert np.max(np.abs(left[d] - right[d])) < tol
        if kind == "linear":
            assert np.max(np.abs(left[1] - right[1])) > 1.0  # slope jumps: C0 only
