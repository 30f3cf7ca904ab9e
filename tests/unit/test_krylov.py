"""Krylov path: the block-elimination preconditioner is the exact inverse of the analytic
Jacobian, and the matrix-free J v equals it, in every regime (model/krylov.py)."""

import numpy as np
import pytest
import scipy.sparse as sp
from kernel_scene import SMALL_SCENE

import roughvib
from roughvib.model import jacobian as jac
from roughvib.model import kernels as kn
from roughvib.model import krylov
from roughvib.model.system import assemble
from roughvib.solvers.base import atol_vector
from roughvib.solvers.ida import _sparsity

#: the scenes here are shorter than the run-in plus one excitation period on purpose
#: (the marker is in tests/conftest.py)
pytestmark = pytest.mark.short_run

CASES = [
    {},
    {"plate.kind": "rigid"},
    {"excitation.kind": "prescribed", "excitation.velocity": 0.01,
     "excitation.force_amplitude": "none"},
    {"contact.points": 1, "roughness.kind": "sinusoid"},
    {"friction.law": "coulomb", "friction.stribeck_velocity": 2e-3},
    {"contact.points": 40},
    {"contact.friction_moment": True},
    {"friction.law": "coulomb", "friction.stribeck_velocity": 2e-3,
     "contact.friction_moment": True},
]


def _scene(**kw):
    return roughvib.load_scene("paper-handset", {**SMALL_SCENE, **kw})


def _states(system, trial, rng):
    """A perturbed equilibrium state and a regime (feldmann branch/latch, coulomb stick/slip,
    a random contact set with at least one contact closed)."""
    y0, _ = system.static_equilibrium()
    n = system.layout.size
    reg, rf = system.new_regime_arrays()
    reg[kn.REG_B] = (-1, 0, 1)[trial] if system.set_valued else (-1, 1, 1)[trial]
    reg[kn.REG_S] = (1, -1, 1)[trial]
    closed = rng.integers(0, 2, system.n_contacts)
    closed[0] = 1
    reg[kn.REG_CLOSED:] = closed
    rf[0] = 1e-3
    y = y0 * (1 + 0.01 * rng.standard_normal(n)) + 1e-9 * rng.standard_normal(n)
    lay = system.layout
    if system.tangential:
        y[lay.index("block.vx")] = 2e-3 * (trial - 1) + 3e-5
        y[lay.index("block.x")] = 1e-4 * trial
    if system.set_valued:
        y[lay.index("friction.force")] = 0.5
    if system.n_modes:  # moving modes (the friction moment's power depends on them)
        y[lay.slice("plate.dq")] += 1e-4 * rng.standard_normal(system.n_modes)
    for name in lay.names:  # energy integrals enter the Jacobian nowhere: any value
        if name.startswith("energy."):
            y[lay.index(name)] = rng.standard_normal()
    return y, reg, rf


def _as_ida_gives(a):
    """A read-only copy of ``a``: IDA hands its iterate and vectors to the callbacks read-only,
    so the kernels run here in the specialisation a run uses (and compile no second one)."""
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def _dense_jacobian(system, t, y, cj, reg, rf):
    n = system.layout.size
    pattern, perm = _sparsity(system)
    vals = np.zeros(perm.size)
    jac.jacobian_values(t, _as_ida_gives(y), _as_ida_gives(np.zeros(n)), cj, vals,
                        *system.kernel_args(reg, rf))
    data = np.zeros(perm.size)
    kn.scatter(vals, perm, data)
    return sp.csc_matrix((data, pattern.indices, pattern.indptr), shape=(n, n)).toarray()


def _psolve(system, t, y, cj, reg, rv, ws, work):
    zv = np.full_like(rv, np.nan)
    krylov.precond_solve(t, _as_ida_gives(y), cj, _as_ida_gives(rv), zv, system.off, system.fp,
                         system.omega2, system.cdamp, system.phi, system.stiff, system.cres,
                         system.input_s, system.prof, reg, work, *ws)
    return zv


def _jv(system, t, y, cj, reg, v):
    out = np.full_like(v, np.nan)
    krylov.jac_vec(t, _as_ida_gives(y), cj, _as_ida_gives(v), out, system.off, system.fp,
                   system.omega2, system.cdamp, system.phi, system.stiff, system.cres,
                   system.input_s, system.prof, reg, np.zeros_like(system.work))
    return out


@pytest.mark.parametrize("overrides", CASES)
def test_preconditioner_inverts_the_jacobian_and_jv_equals_it(overrides):
    system = assemble(_scene(**overrides))
    rng = np.random.default_rng(11)
    n = system.layout.size
    ws = krylov.krylov_workspace(n, system.n_modes, system.n_contacts)
    work = np.zeros_like(system.work)
    # IDA measures corrections in units of the absolute tolerances (its WRMS norm): so do we.
    # J's condition number is ~1e14 in SI units; in these units round-off stays ~1e-12.
    w = atol_vector(system)
    for trial in range(3):
        y, reg, rf = _states(system, trial, rng)
        t = 0.003 + 1e-3 * trial
        for cj in (1e3, 1e5, 1e7):
            J = _dense_jacobian(system, t, y, cj, reg, rf)
            for _ in range(2):
                v = rng.standard_normal(n) * w
                Jv = J @ v
                # J v without forming J: the same matrix as the sparse path's
                scale = np.abs(J) @ np.abs(v) + 1e-300
                assert np.max(np.abs(_jv(system, t, y, cj, reg, v) - Jv) / scale) < 1e-13
                # P^-1 (J v) = v: the preconditioner is J's exact inverse
                z = _psolve(system, t, y, cj, reg, Jv, ws, work)
                assert np.max(np.abs(z - v) / w) < 1e-9


def test_preconditioner_caches_by_cj_and_iterate():
    """Reusing the cached Schur factors gives the answer of a fresh workspace, and a change
    of cj or of the iterate invalidates them."""
    system = assemble(_scene())
    rng = np.random.default_rng(5)
    n = system.layout.size
    y1, reg, _ = _states(system, 1, rng)
    y2 = y1 * (1 + 1e-3 * rng.standard_normal(n))
    rv = rng.standard_normal(n)
    ws = krylov.krylov_workspace(n, system.n_modes, system.n_contacts)
    work = np.zeros_like(system.work)
    seq = [(y1, 1e4), (y1, 1e4), (y1, 3e4), (y2, 3e4), (y1, 1e4)]
    for y, cj in seq:
        fresh = _psolve(system, 0.002, y, cj, reg, rv,
                        krylov.krylov_workspace(n, system.n_modes, system.n_contacts),
                        np.zeros_like(work))
        cached = _psolve(system, 0.002, y, cj, reg, rv, ws, work)
        np.testing.assert_array_equal(cached, fresh)


def test_krylov_kernels_without_jit_match_compiled(run_without_jit):
    system = assemble(_scene())
    rng = np.random.default_rng(2)
    y, reg, _ = _states(system, 2, rng)
    v = rng.standard_normal(y.size)
    n = y.size
    ws = krylov.krylov_workspace(n, system.n_modes, system.n_contacts)
    z = _psolve(system, 0.002, y, 2e4, reg, v, ws, np.zeros_like(system.work))
    jv = _jv(system, 0.002, y, 2e4, reg, v)
    plain = run_without_jit("""
        y, v, reg = inp["y"], inp["v"], inp["reg"]
        ws = krylov.krylov_workspace(y.size, s.n_modes, s.n_contacts)
        z = np.empty_like(v); jv = np.empty_like(v)
        krylov.precond_solve(0.002, y, 2e4, v, z, s.off, s.fp, s.omega2, s.cdamp, s.phi,
                             s.stiff, s.cres, s.input_s, s.prof, reg,
                             np.zeros_like(s.work), *ws)
        krylov.jac_vec(0.002, y, 2e4, v, jv, s.off, s.fp, s.omega2, s.cdamp, s.phi, s.stiff,
                       s.cres, s.input_s, s.prof, reg, np.zeros_like(s.work))
        out.update(z=z, jv=jv)
    """, y=y, v=v, reg=reg)
    np.testing.assert_allclose(plain["z"], z, rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(plain["jv"], jv, rtol=1e-12, atol=1e-300)
