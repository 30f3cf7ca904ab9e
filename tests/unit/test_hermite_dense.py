"""Dense output of the Hermite step (roughvib.solvers.hermite_dense): its modal maps against an
independent integration of the forced oscillator and the step's own maps, its interpolants on
polynomials they must reproduce, and the dense state against a Hermite step to the same
time (the two agree to the step's fourth order)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from roughvib.model import kernels as kn
from roughvib.model.system import assemble
from roughvib.scene import load_scene
from roughvib.solvers import adaptive_modal as am
from roughvib.solvers import hermite as hm
from roughvib.solvers import hermite_dense as hd
from roughvib.solvers.checkpoint import start_state
from roughvib.solvers.ida import _atol_vector

# modes from omega tau << 1 (series) to omega tau >> 1 (particular solution), 1 % damping
OMEGA2 = (2 * np.pi * np.array([50.0, 3e3, 2e4, 6e4])) ** 2
CDAMP = 0.02 * np.sqrt(OMEGA2)


def test_dense_maps_at_the_step_end_are_the_steps_maps():
    h = 2e-5
    Pd = np.zeros((hd.N_DMAP, OMEGA2.size))
    Phi = np.zeros((OMEGA2.size, 2, 2))
    H = np.zeros((OMEGA2.size, hm.N_HOLD, 2))
    hd.dense_maps(OMEGA2, CDAMP, h, h, Pd)
    hm.hermite_maps(OMEGA2, CDAMP, h, Phi, H)
    np.testing.assert_array_equal(Pd[hd.DM_QD], Phi[:, hm.MODE_Q, hm.MODE_DQ])
    for row, hold, comp in ((hd.DM_U0Q, hm.HOLD_U0, hm.MODE_Q),
                            (hd.DM_DU0D, hm.HOLD_DU0, hm.MODE_DQ),
                            (hd.DM_U1Q, hm.HOLD_U1, hm.MODE_Q),
                            (hd.DM_DU1D, hm.HOLD_DU1, hm.MODE_DQ)):
        np.testing.assert_allclose(Pd[row], H[:, hold, comp], rtol=1e-13)


@pytest.mark.parametrize("frac", [0.25, 0.5, 0.81])
def test_dense_maps_integrate_the_cubic_forced_oscillator(frac):
    """q(tau) from the maps against DOP853 at rtol 1e-12 of q'' + c q' + w^2 q = u(s), u the
    Hermite cubic of (u0, u0', u1, u1') over h."""
    h = 2e-5
    tau = frac * h
    u0, du0, u1, du1 = 1.0, 3e4, -0.5, 1e4
    s_ = (u1 - u0) / h
    coef = [u0, du0, (3 * s_ - 2 * du0 - du1) / h, (du0 + du1 - 2 * s_) / h ** 2]
    Pd = np.zeros((hd.N_DMAP, OMEGA2.size))
    hd.dense_maps(OMEGA2, CDAMP, h, tau, Pd)
    q0, dq0 = 1e-6, 2e-3
    data = (u0, du0, u1, du1)
    for r in range(OMEGA2.size):
        sol = solve_ivp(lambda s, z, r=r: [z[1], np.polyval(coef[::-1], s) - CDAMP[r] * z[1]
                                           - OMEGA2[r] * z[0]],
                        (0, tau), [q0, dq0], method="DOP853", rtol=1e-12, atol=1e-22)
        q = Pd[hd.DM_QQ, r] * q0 + Pd[hd.DM_QD, r] * dq0 + sum(
            Pd[row, r] * d for row, d in zip((hd.DM_U0Q, hd.DM_DU0Q, hd.DM_U1Q, hd.DM_DU1Q),
                                             data, strict=True))
        dq = Pd[hd.DM_DQ, r] * q0 + Pd[hd.DM_DD, r] * dq0 + sum(
            Pd[row, r] * d for row, d in zip((hd.DM_U0D, hd.DM_DU0D, hd.DM_U1D, hd.DM_DU1D),
                                             data, strict=True))
        assert q == pytest.approx(sol.y[0, -1], rel=1e-10)
        assert dq == pytest.approx(sol.y[1, -1], rel=1e-10)


def test_quintic_interpolant_reproduces_a_quintic():
    rng = np.random.default_rng(3)
    a = rng.normal(size=6)
    p = np.polynomial.Polynomial(a)
    h = 0.3
    for theta in (0.0, 0.2, 0.5, 0.77, 1.0):
        got = hd._quintic(theta, h, p(0), p.deriv()(0), p.deriv(2)(0), p(h), p.deriv()(h),
                          p.deriv(2)(h))
        assert got == pytest.approx(p(theta * h), rel=1e-12, abs=1e-12)


def _paper_start():
    system = assemble(load_scene("paper", {"plate.max_frequency": 20e3}), force_amplitude=0.9)
    reg, rf = system.new_regime_arrays()
    _, y, _ = start_state(system, reg, rf, None, 0, 0)
    y[system.layout.index("block.vz")] = 1e-4  # m/s: the contact force changes at once
    return system, reg, rf, y


def test_dense_state_agrees_with_a_step_to_the_same_time_to_fourth_order():
    """The dense state at the middle of a step of h against a Hermite step of h/2 from the same
    start: both fourth order, so their difference is the steps' local error, ~h^5: it falls
    at least 16x per halving of h from 5e-6 s (measured 19-160x) in the plate modes, the
    contact force and the block's velocities."""
    system, reg, rf, y0 = _paper_start()
    (off, fp, omega2, cdamp, phi, _obs, stiff, cres, spos, prof, _reg, _rf,
     work) = system.kernel_args(reg, rf)
    R, K = system.n_modes, system.n_contacts
    lay = system.layout
    phiT = np.ascontiguousarray(phi.T)
    hs = am.new_hermite_scratch(work, R, K)
    ist = np.zeros(am.N_IST, dtype=np.int64)
    M = fp[kn.FP_MMODAL]
    wts = _atol_vector(system) * 1e-3 + 1e-12 * np.abs(y0)
    dF0 = np.zeros(K)
    am.force_rates(y0, dF0, off, fp, phiT, stiff, cres, spos, prof, reg, hs)
    c0 = np.zeros(hm.carry_size(R, K))
    hm.carried(0.0, y0, dF0, c0, off, fp, omega2, cdamp, phiT, spos, prof, reg)
    parts = {"plate.dq": lay.slice("plate.dq"), "contact.force": lay.slice("contact.force"),
             "block.vz": lay.slice("block.vz"), "block.vx": lay.slice("block.vx")}
    diffs = []
    for h in (5e-6, 2.5e-6, 1.25e-6):
        hp = am.new_hermite_maps(R, K)
        am._hermite_fill(0, h, omega2, cdamp, phi, cres, M, hp, ist)
        am._hermite_fill(1, h / 2, omega2, cdamp, phi, cres, M, hp, ist)
        out = []
        for slot, hstep in ((0, h), (1, h / 2)):
            y1, dF1, c1 = y0.copy(), dF0.copy(), c0.copy()
            hs.iws[hm.IWS_JAC_VALID] = 0
            assert am._hstep(0.0, hstep, y0, dF0, c0, y1, dF1, c1, slot, hp, wts, off, fp,
                             omega2, cdamp, phiT, stiff, spos, prof, reg, hs, ist)
            out.append((y1, dF1, c1))
        (y1, dF1, c1), (yh, _, _) = out
        Pd = np.zeros((hd.N_DMAP, R))
        hd.dense_maps(omega2, cdamp, h, h / 2, Pd)
        yd, dFd = y0.copy(), np.zeros(K)
        hd.dense_state(0.5, h, 0.0, y0, dF0, c0, y1, dF1, c1, Pd, yd, dFd, off, fp, phiT, reg)
        diffs.append({name: np.max(np.abs(yd[sl] - yh[sl])) / np.max(np.abs(yh[sl]))
                      for name, sl in parts.items()})
    for name in parts:
        d = [x[name] for x in diffs]
        assert d[0] / d[1] > 16 and d[1] / d[2] > 16, (name, d)
