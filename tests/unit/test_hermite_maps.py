"""The Hermite-hold step maps of a mode (roughvib.solvers.hermite) against scipy's expm of the
oscillator driven by a cubic, and against closed forms of the hold."""

import numpy as np
import pytest
from scipy.linalg import expm

from roughvib.solvers.hermite import (
    HERMITE_SERIES_LIMIT,
    HOLD_DU0,
    HOLD_DU1,
    HOLD_U0,
    HOLD_U1,
    N_HOLD,
    hermite_maps,
)


def _expm_hermite(w, zeta, h):
    """Phi and the four hold maps from the exponential of the oscillator driven by a cubic.

    Augmented state [w q, q', v_0 .. v_3] with v_j = h^(j+1) u^(j): the cubic is its own
    Taylor series, so one matrix exponential propagates both; each Hermite datum is mapped to
    the Taylor data. The scaling keeps every entry of the exponentiated matrix O(1) or
    O(omega h) (unscaled, expm's small entries were off by 1e-9 relative at omega h = 1e-3,
    against a 40-digit mpmath exponential).
    """
    wh = w * h
    B = np.zeros((6, 6))
    B[0, 1] = wh
    B[1, 0] = -wh
    B[1, 1] = -2 * zeta * wh
    B[1, 2] = 1.0          # u = v_0 / h drives the acceleration
    B[2, 3] = B[3, 4] = B[4, 5] = 1.0
    E = expm(B)
    unscale = np.diag([1 / w, 1.0])
    maps = np.zeros((N_HOLD, 2))
    for i in range(N_HOLD):
        d = np.zeros(N_HOLD)
        d[i] = 1.0
        u0, du0, u1, du1 = d[HOLD_U0], d[HOLD_DU0], d[HOLD_U1], d[HOLD_DU1]
        s = (u1 - u0) / h
        c2 = (3 * s - 2 * du0 - du1) / h
        c3 = (du0 + du1 - 2 * s) / h ** 2
        taylor = np.array([u0, du0, 2 * c2, 6 * c3]) * h ** np.arange(1, 5)
        maps[i] = unscale @ E[:2, 2:] @ taylor
    return unscale @ E[:2, :2] @ np.diag([w, 1.0]), maps


def _maps(w, zeta, h):
    Phi, H = np.zeros((1, 2, 2)), np.zeros((1, N_HOLD, 2))
    hermite_maps(np.array([w * w]), np.array([2 * zeta * w]), h, Phi, H)
    return Phi[0], H[0]


@pytest.mark.parametrize("wh", [1e-6, 1e-3, 0.3, 1.0, 1.999, 2.001, 3.0, 10.0, 300.0])
@pytest.mark.parametrize("zeta", [0.0, 0.0015, 0.3])
def test_hermite_maps_match_the_matrix_exponential(wh, zeta):
    """Both branches (series up to omega h = 2, particular solution above) against expm, in
    the units each entry acts in: the state scaled [w q, q'], the hold maps relative to the
    largest of them (at large omega h the response is quasi-static, q(h) ~ u(h) / w^2, and
    the maps of u(0), u'(0) and u'(h) are differences of terms of that size: their own
    scale is no measure of what they contribute)."""
    w = 2 * np.pi * 1e4
    h = wh / w
    Phi, H = _maps(w, zeta, h)
    P, Href = _expm_hermite(w, zeta, h)
    S = np.diag([w, 1.0])
    Si = np.diag([1 / w, 1.0])
    tol = 2e-14 * max(1.0, wh)
    np.testing.assert_allclose(S @ Phi @ Si, S @ P @ Si, rtol=0, atol=tol)
    scale = np.max(np.abs(Href @ S))
    np.testing.assert_allclose(H @ S, Href @ S, rtol=0, atol=2.5 * tol * scale)


def test_hermite_maps_are_continuous_across_the_branch_switch():
    w = 3e5
    out = []
    for wh in (HERMITE_SERIES_LIMIT * (1 - 1e-15), HERMITE_SERIES_LIMIT * (1 + 1e-15)):
        Phi, H = _maps(w, 0.0015, wh / w)
        out.append(np.concatenate([H[i] * [w * w, w] for i in range(N_HOLD)]))
    scale = np.max(np.abs(out[0]))
    np.testing.assert_allclose(out[0], out[1], rtol=0, atol=1e-13 * scale)


def test_a_held_cubic_force_is_propagated_exactly():
    """A force that *is* a cubic is held exactly: the maps reproduce the closed-form response
    of an undamped oscillator to u = a + b t + c t^2 + d t^3 from rest, whose particular
    solution is polynomial (q_p = sum_j p_j t^j with w^2 p_j + (j+2)(j+1) p_{j+2} = coeff_j)."""
    w, h = 2 * np.pi * 7e3, 4e-5          # omega h = 1.76: the series branch
    coeff = np.array([0.3, -2.0e3, 5.0e7, -1.0e12])
    p = np.zeros(6)
    for j in range(3, -1, -1):
        p[j] = (coeff[j] - (j + 2) * (j + 1) * p[j + 2]) / w ** 2
    # from rest: q = q_p(t) - q_p(0) cos(w t) - q_p'(0) sin(w t) / w
    q_h = (np.polyval(p[3::-1], h) - p[0] * np.cos(w * h) - p[1] * np.sin(w * h) / w)
    dq_h = (np.polyval(np.polyder(p[3::-1]), h) + p[0] * w * np.sin(w * h)
            - p[1] * np.cos(w * h))
    u = np.polyval(coeff[::-1], [0.0, h])
    du = np.polyval(np.polyder(coeff[::-1]), [0.0, h])
    for wh_shift in (1.0, 3.0):             # and the particular-solution branch
        ww = w * wh_shift
        if wh_shift != 1.0:
            p = np.zeros(6)
            for j in range(3, -1, -1):
                p[j] = (coeff[j] - (j + 2) * (j + 1) * p[j + 2]) / ww ** 2
            q_h = (np.polyval(p[3::-1], h) - p[0] * np.cos(ww * h) - p[1] * np.sin(ww * h) / ww)
            dq_h = (np.polyval(np.polyder(p[3::-1]), h) + p[0] * ww * np.sin(ww * h)
                    - p[1] * np.cos(ww * h))
        Phi, H = _maps(ww, 0.0, h)
        got = (H[HOLD_U0] * u[0] + H[HOLD_DU0] * du[0] + H[HOLD_U1] * u[1]
               + H[HOLD_DU1] * du[1])
        np.testing.assert_allclose(got, [q_h, dq_h], rtol=1e-11,
                                   atol=1e-13 * np.max(np.abs([q_h * ww, dq_h])) / ww)
