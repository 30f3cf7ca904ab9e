"""adaptive-modal's Hermite loop: which scenes it covers, and the force rates it starts from.

The loop itself is judged by what it produces: the convergence and reference tests
(tests/convergence), the checkpoint tests and the energy audits of every run."""

import numpy as np
import pytest

from roughvib.model import kernels as kn
from roughvib.model.system import assemble
from roughvib.scene import load_scene
from roughvib.solvers import adaptive_modal as am
from roughvib.solvers import hermite as hm
from roughvib.solvers.base import atol_vector
from roughvib.solvers.checkpoint import start_state

FAST = {"plate.max_frequency": 5000.0, "output.progress": False}


@pytest.mark.parametrize(("over", "covered"), [
    ({}, True),
    ({"friction.law": "coulomb"}, False),          # set-valued: stick holds the block
    ({"contact.friction_moment": True}, False),     # the moment's modal force
    ({"excitation.kind": "prescribed", "excitation.amplitude": 0.0,
      "excitation.velocity": 0.1, "excitation.target_rms_velocity": "none"}, False),
])
def test_the_hermite_step_covers_the_feldmann_law_with_a_force_driven_block(over, covered):
    system = assemble(load_scene("paper", {**FAST, **over}), force_amplitude=0.9)
    assert am.hermite_applies(system) is covered


def test_force_rates_are_the_contact_forces_time_derivative():
    """force_rates (the contact relation's rate solved for dF) against the derivative of the
    contact force along an integration: the one-sided three-point difference of the forces
    after 0, 1 and 2 Hermite steps of 1e-7 s (error ~ (1e-7 s)^2 F'''), from the paper scene's
    start with the block given a vertical velocity (so that the force changes at once)."""
    system = assemble(load_scene("paper", FAST), force_amplitude=0.9)
    reg, rf = system.new_regime_arrays()
    _, y, _ = start_state(system, reg, rf, None, 0, 0)
    lay = system.layout
    y[lay.index("block.vz")] = 1e-4  # m/s: the state stays consistent (vz is free)
    (off, fp, omega2, cdamp, phi, _obs, stiff, cres, spos, prof, _reg, _rf,
     work) = system.kernel_args(reg, rf)
    R, K = system.n_modes, system.n_contacts
    phiT = np.ascontiguousarray(phi.T)
    hp = am.new_hermite_maps(R, K)
    hs = am.new_hermite_scratch(work, R, K)
    ist = np.zeros(am.N_IST, dtype=np.int64)
    h = 1e-7
    am._hermite_fill(0, h, omega2, cdamp, phi, cres, fp[kn.FP_MMODAL], hp, ist)
    wts = atol_vector(system) * 1e-3 + 1e-12 * np.abs(y)
    ys, dFs = [y], []
    dF = np.zeros(K)
    c = np.zeros(hm.carry_size(R, K))
    for i in range(2):
        am.force_rates(ys[-1], dF, off, fp, phiT, stiff, cres, spos, prof, reg, hs)
        dFs.append(dF.copy())
        hm.carried(i * h, ys[-1], dF, c, off, fp, omega2, cdamp, phiT, spos, prof, reg)
        y1, dF1, c1 = ys[-1].copy(), dF.copy(), c.copy()
        assert am._hstep(i * h, h, ys[-1], dF, c, y1, dF1, c1, 0, hp, wts, off, fp, omega2,
                         cdamp, phiT, stiff, spos, prof, reg, hs, ist, am.NEWTON_KEPT)
        ys.append(y1)
        # the step solves the same rate at its end, jointly with the force
        am.force_rates(y1, dF, off, fp, phiT, stiff, cres, spos, prof, reg, hs)
        np.testing.assert_allclose(dF, dF1, rtol=1e-6)
    iF = lay.slice("contact.force")
    F0, F1, F2 = (s[iF] for s in ys)
    fd = (-3 * F0 + 4 * F1 - F2) / (2 * h)
    assert np.all(np.abs(dFs[0]) > 1.0)  # N/s: the force does change
    np.testing.assert_allclose(dFs[0], fd, rtol=1e-5)
