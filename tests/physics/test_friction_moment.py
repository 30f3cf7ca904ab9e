"""The friction force's moment on the plate (``contact.friction_moment``, the paper's extension
(v)): closed form of one mode, reciprocity of force and moment, IDA against adaptive-modal with
the energy audit, the unchanged model without it, and the refusals."""

import math
import warnings

import numpy as np
import pytest

import roughvib
from roughvib.model import kernels as kn
from roughvib.model.system import assemble
from roughvib.physics.friction import feldmann_mu
from roughvib.scene import ModelValidityWarning, SceneError
from roughvib.solvers import adaptive_modal as am
from roughvib.solvers.adaptive_modal import solve_adaptive_modal

SMALL = {"plate.max_frequency": 3e3, "output.duration": 0.01, "output.transient": 0.0,
         "excitation.force_amplitude": 0.9, "excitation.target_rms_velocity": "none"}


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    warnings.simplefilter("ignore", ModelValidityWarning)


#: the paper's kinematic input: the band to 50 um on its 10 um grid, no contact filter
PAPER_INPUT = {"roughness.shortest_wavelength": 50e-6, "roughness.spacing": 10e-6,
               "contact.filter": "none"}

def _scene(name="paper", **kw):
    return roughvib.load_scene(name, {**SMALL, **kw})


def _slip_state(system, v, forces):
    """The static state with the block sliding at v [m/s] and the given contact forces."""
    y, _ = system.static_equilibrium()
    lay = system.layout
    y = y.copy()
    y[lay.slice("plate.q")] = 0.0
    y[lay.slice("plate.dq")] = 0.0
    y[lay.index("block.vx")] = v
    y[lay.slice("contact.force")] = forces
    reg, rf = system.new_regime_arrays()
    reg[kn.REG_B] = 1
    reg[kn.REG_S] = 1
    reg[kn.REG_CLOSED:] = 1
    return y, reg, rf


def _mu(system, v):
    fp = system.fp
    return feldmann_mu(v + fp[kn.FP_VH], 1, fp[kn.FP_MU_SLIP], fp[kn.FP_MU_STICK],
                       fp[kn.FP_A1], fp[kn.FP_A2])[0]


def test_one_mode_static_response_to_the_friction_moment_is_the_closed_form():
    """Only the (1,1) mode kept; the block slides at 5 mm/s on one contact carrying F. Its
    friction mu F acts on the plate's top surface, hp/2 above the mid-plane, along +x: with w
    positive down, the mode's static deflection is q = (phi F + (hp/2) phi_x mu F) / w11^2,
    phi = 2/sqrt(rho hp a b) sin(pi x/a) sin(pi y/b) (mass-normalised). At that deflection the
    IDA residual's modal row is at rest, and the adaptive-modal solver's moment force is the
    same term."""
    base = _scene("paper-handset")
    p = base.plate
    a, b, hp = p.length, p.width, p.thickness
    bend = p.youngs_modulus * hp**3 / (12 * (1 - p.poisson_ratio**2))
    w11 = math.pi**2 * ((1 / a) ** 2 + (1 / b) ** 2) * math.sqrt(bend / (p.density * hp))
    scene = _scene("paper-handset", **{"plate.max_frequency": 1.05 * w11 / (2 * math.pi),
                                       "plate.residual_compliance": False,
                                       "contact.points": 1, "contact.friction_moment": True})
    system = assemble(scene)
    assert system.n_modes == 1 and system.n_contacts == 1
    x, yc = system.contact_xy[0]
    amp = 2.0 / math.sqrt(p.density * hp * a * b)
    phi = amp * math.sin(math.pi * x / a) * math.sin(math.pi * yc / b)
    phi_x = amp * math.pi / a * math.cos(math.pi * x / a) * math.sin(math.pi * yc / b)
    F, v = 2.0, 5e-3
    mu = _mu(system, v)
    q_static = (phi * F + 0.5 * hp * phi_x * mu * F) / w11**2
    # the moment is a sizeable part of this mode's drive at the contact (not a no-op)
    assert abs(0.5 * hp * phi_x * mu) > 1e-3 * abs(phi)
    y, reg, rf = _slip_state(system, v, [F])
    lay = system.layout
    iq, idq = lay.slice("plate.q").start, lay.slice("plate.dq").start
    res = np.zeros_like(y)
    for q, expect in ((q_static, 0.0), (0.0, -q_static * w11**2)):
        y[iq] = q
        kn.residual(0.0, y, np.zeros_like(y), res, *system.kernel_args(reg, rf))
        # res = yp + c dq + w^2 q - u: zero at the static deflection, -u at q = 0
        assert res[idq] == pytest.approx(expect, abs=1e-12 * abs(q_static) * w11**2)
    # the adaptive-modal solver's modal force of the moment: mu (hp/2) phi_x F / M
    u = np.full(1, np.nan)
    am._moment_force(np.array([F]), mu, 1.0, system.off, system.fp, u)
    assert u[0] == pytest.approx(0.5 * hp * phi_x * mu * F, rel=1e-12)
    # a moment-free scene drives the mode by phi F alone
    plain = assemble(scene.with_overrides({"contact.friction_moment": False}))
    y[iq] = 0.0
    kn.residual(0.0, y, np.zeros_like(y), res, *plain.kernel_args(reg, rf))
    assert res[idq] == pytest.approx(-phi * F, rel=1e-12)


def test_force_and_moment_receptances_are_reciprocal():
    """Rotation at a contact A (dw/dx) from a unit force at the observation point B equals the
    displacement at B from a unit moment at A, at any frequency: the moment's modal force is
    taken from the IDA residual (the packed, lever-scaled slopes of all ten contacts), the
    rotation from central differences of the plate's displacement field."""
    scene = _scene("paper-handset", **{"contact.friction_moment": True})
    system = assemble(scene)
    K = system.n_contacts
    assert K == 10
    hp = scene.plate.thickness
    v = 5e-3
    mu = _mu(system, v)
    lay = system.layout
    idq = lay.slice("plate.dq")
    obs = np.array([scene.plate.observation_position])
    phi_b = system.structure.shapes(obs)[:, 0]
    omega2, cdamp = system.omega2, system.cdamp
    for k in range(K):
        forces = np.zeros(K)
        forces[k] = 1.0
        y, reg, rf = _slip_state(system, v, forces)
        res = np.zeros_like(y)
        kn.residual(0.0, y, np.zeros_like(y), res, *system.kernel_args(reg, rf))
        # modal force per unit moment at contact k: (total - contact part) / (mu hp/2)
        g = (-res[idq] - system.phi[:, k]) / (mu * 0.5 * hp)
        xa = system.contact_xy[k]
        d = 1e-7
        shift = np.array([[d, 0.0]])
        slope_fd = (system.structure.shapes(xa + shift)[:, 0]
                    - system.structure.shapes(xa - shift)[:, 0]) / (2 * d)
        for f in (50.0, 700.0, 2500.0):
            w = 2 * math.pi * f
            h = 1.0 / (omega2 - w * w + 1j * w * cdamp)
            disp_from_moment = np.sum(phi_b * g * h)
            rot_from_force = np.sum(slope_fd * phi_b * h)
            scale = np.sum(np.abs(slope_fd * phi_b * h))
            assert abs(disp_from_moment - rot_from_force) < 1e-6 * scale
            # and to round-off against the structure's own slopes
            exact = np.sum(system.structure.slopes(xa[None, :])[:, 0] * phi_b * h)
            assert abs(disp_from_moment - exact) < 1e-12 * scale


def test_ida_and_adaptive_modal_agree_with_the_moment_and_the_audit_closes():
    """0.02 s of the paper scene with modes to 5 kHz (stick, break-away, slip): both solvers
    integrate the moment; plate acceleration and events agree, and both energy audits close
    (the moment's power moves from the friction's dissipation into the plate)."""
    # the paper's input (its 50 um band, no contact filter): the moment's share of the plate's
    # motion is then large enough for "it matters" to be a sharp check
    ov = {"plate.max_frequency": 5e3, "output.duration": 0.02, "output.transient": 0.0,
          "contact.friction_moment": True, **PAPER_INPUT}
    runs = {m: roughvib.simulate(roughvib.load_scene("paper", {**ov, "solver.method": m}),
                                 progress=False)
            for m in ("adaptive-modal", "ida")}
    off = roughvib.simulate(roughvib.load_scene(
        "paper", {**ov, "contact.friction_moment": False}), progress=False)
    acc = {m: r.dataset["plate_vertical_acceleration"].values for m, r in runs.items()}
    ref = acc["ida"]
    rms = np.sqrt(np.mean(ref**2))
    assert np.sqrt(np.mean((acc["adaptive-modal"] - ref) ** 2)) < 1e-2 * rms
    # the moment matters here (so the agreement is not that of two runs without it)
    a_off = off.dataset["plate_vertical_acceleration"].values
    assert np.sqrt(np.mean((a_off - ref) ** 2)) > 0.5 * rms
    ev = {m: r.events for m, r in runs.items()}
    assert list(ev["ida"]["kind"]) == list(ev["adaptive-modal"]["kind"])
    assert np.max(np.abs(ev["ida"]["time"].values - ev["adaptive-modal"]["time"].values)) < 1e-6
    for r in runs.values():
        audit = r.summary["energy_audit"]
        assert abs(audit["relative_residual"]) < 1e-6
        assert audit["friction_dissipation"] > 0


def test_without_the_moment_nothing_changes():
    """Off (the default): no packed slopes and the Jacobian pattern of before. A zero lever
    with the moment on gives the adaptive-modal run of the moment-free model bit for bit (every
    moment term is an exact zero added) with the same step: the trapezoidal one, which the
    moment runs with (the Hermite step, the default where it applies, has no moment terms)."""
    scene = _scene("paper-handset", **{"output.duration": 0.004})
    assert scene.contact.friction_moment is False
    plain = assemble(scene)
    on = assemble(scene.with_overrides({"contact.friction_moment": True}))
    assert plain.off[kn.OFF_IPSI] == -1
    assert plain.fp.size == kn.N_FP
    R, K = on.n_modes, on.n_contacts
    assert on.off[kn.OFF_IPSI] == kn.N_FP and on.fp.size == kn.N_FP + R * K
    rows0, _ = plain.jacobian_pattern()
    rows1, _ = on.jacobian_pattern()
    assert rows1.size == rows0.size + 2 * R  # the modal rows' friction column, the power's dq
    zero = assemble(scene.with_overrides({"contact.friction_moment": True}))
    zero.fp[kn.N_FP:] = 0.0
    ra = solve_adaptive_modal(plain, progress=False, hermite=False)
    rb = solve_adaptive_modal(zero, progress=False)
    assert np.array_equal(ra.outputs, rb.outputs)
    assert np.array_equal(ra.y_final, rb.y_final)


def _setvalued_moment_pair(folder, law, max_frequency):
    """The paper's drive and roughness on modes to ``max_frequency`` [Hz], a Stribeck law
    (analytic ``coulomb`` or sampled into a ``table``) and the friction moment, 0.08 s: slip,
    stick at 0.030 s, break-away at 0.062 s. Runs adaptive-modal and IDA, each at its
    reference preset, and the same scene without the moment."""
    from dataclasses import replace

    from roughvib.physics.friction import coulomb_kinetic

    mu_st, mu_sl, vs = 0.3856, 0.30, 2e-3
    over = {"plate.max_frequency": max_frequency, "output.duration": 0.08,
            "excitation.force_amplitude": 0.91536, "excitation.target_rms_velocity": "none",
            "contact.velocity_factor": False, "output.progress": False,
            "friction.law": law, "friction.mu_stick": mu_st, "friction.mu_slip": mu_sl,
            "contact.friction_moment": True, **PAPER_INPUT}
    if law == "table":
        v = np.linspace(0.0, 12 * vs, 241)
        mu = [coulomb_kinetic(x, mu_sl, mu_st, vs)[0] for x in v]
        np.savetxt(folder / "stribeck.csv", np.column_stack([v, mu]), delimiter=",",
                   header="velocity,mu", comments="")
        over["friction.table"] = "stribeck.csv"
    else:
        over["friction.stribeck_velocity"] = vs
    base = replace(roughvib.load_scene("paper", over), base_dir=str(folder))
    runs = {m: roughvib.simulate(base.with_overrides({"solver.method": m}))
            for m in ("adaptive-modal", "ida")}
    runs["off"] = roughvib.simulate(base.with_overrides({"contact.friction_moment": False}))
    return base, runs


def _assert_setvalued_moment_pair(base, runs):
    """adaptive-modal against IDA with the moment and a set-valued law: every item of the
    accuracy contract, the same stick/slip sequence with a stick phase and a break-away, the
    block held at v = 0 in stick, both energy audits closed; and the moment matters here."""
    from roughvib.analysis.accuracy import measure_accuracy

    am, ida = runs["adaptive-modal"], runs["ida"]
    for r in (am, ida):
        assert r.ok, r.summary["message"]
        audit = r.summary["energy_audit"]
        assert abs(audit["relative_residual"]) < 1e-6, audit
    kinds = [k for k in am.events["kind"] if k in ("stick", "slip")]
    assert kinds == [k for k in ida.events["kind"] if k in ("stick", "slip")]
    assert "stick" in kinds and kinds.count("slip") >= 2
    t = am.dataset["time"].values
    ev = [(k, x) for k, x in zip(am.events["kind"], am.events["time"], strict=True)
          if k in ("stick", "slip")]
    stick = [(x, ev[i + 1][1] if i + 1 < len(ev) else t[-1]) for i, (k, x) in enumerate(ev)
             if k == "stick"]
    v = am.dataset["block_tangential_velocity"].values
    for t0, t1 in stick:
        assert np.all(v[(t > t0 + 1e-5) & (t < t1 - 1e-5)] == 0.0)
    acc = measure_accuracy(am, ida, period=base.period, transient=base.output.transient)
    assert acc["verdict"] == "pass", acc["failures"]
    assert acc["events"]["matched"] >= 3 and acc["events"]["unmatched"] == 0
    a = {k: r.dataset["plate_vertical_acceleration"].values for k, r in runs.items()}
    rms = np.sqrt(np.mean(a["ida"] ** 2))
    assert np.sqrt(np.mean((a["off"] - a["ida"]) ** 2)) > 0.3 * rms


def test_adaptive_modal_integrates_the_moment_with_a_set_valued_law(tmp_path):
    """Coulomb's law with a Stribeck curve: in stick the moment's share is lambda / F_N (the
    holding force shared by the contacts' normal forces), in slip b mu_k(|v|). adaptive-modal
    against IDA (modes to 1.5 kHz), and ``auto`` picks adaptive-modal for the pair."""
    base, runs = _setvalued_moment_pair(tmp_path, "coulomb", 1.5e3)
    assert base.resolved_solver().method == "adaptive-modal"
    _assert_setvalued_moment_pair(base, runs)


@pytest.mark.slow
@pytest.mark.parametrize("law", ["coulomb", "table"])
def test_adaptive_modal_moment_with_set_valued_laws_to_3_khz(tmp_path, law):
    """As above with modes to 3 kHz, for the analytic law and the same curve as a table."""
    _assert_setvalued_moment_pair(*_setvalued_moment_pair(tmp_path, law, 3e3))


@pytest.mark.parametrize("method", ["exact-modal", "newmark", "moreau", "paper"])
def test_fixed_step_schemes_refuse_the_moment(method):
    """Refused when the scene is loaded, by the solver registry's rule, in one line naming
    solver.method, the key that rules the solver out and what would run the scene (moreau
    with a set-valued law, the only one it runs)."""
    law = "coulomb" if method == "moreau" else "feldmann"
    with pytest.raises(SceneError, match=rf"^solver.method = '{method}' cannot run this scene: "
                                         rf"contact.friction_moment = true, and {method} does "
                                         rf"not integrate the friction force's moment on the "
                                         rf"plate; use ida or adaptive-modal$"):
        _scene(**{"contact.friction_moment": True, "solver.method": method,
                  "friction.law": law})


def test_prescribed_motion_and_bad_values_are_refused():
    with pytest.raises(SceneError, match="needs excitation.kind = 'force'"):
        _scene(**{"contact.friction_moment": True, "excitation.kind": "prescribed",
                  "excitation.velocity": 0.01, "excitation.force_amplitude": "none"})
    with pytest.raises(SceneError, match=r"^contact.friction_moment must be true or false, "
                                         r"got 'yes'$"):
        _scene(**{"contact.friction_moment": "yes"})


@pytest.mark.parametrize("method", ["newmark", "paper"])
def test_fixed_step_solvers_refuse_a_system_with_the_moment(method):
    """Called directly (not through a scene, which refuses the pair), the fixed-step loops and
    the paper's scheme still refuse a system that carries the moment, in one line."""
    from roughvib.solvers.fixed_step import solve_fixed_step
    from roughvib.solvers.paper_scheme import solve_paper_scheme

    system = assemble(_scene("paper-handset", **{"contact.friction_moment": True}))
    system.scene = _scene("paper-handset", **{"solver.method": method})
    solve = solve_paper_scheme if method == "paper" else solve_fixed_step
    with pytest.raises(SceneError, match=rf"^contact.friction_moment = true needs solver.method "
                                         rf"'ida' or 'adaptive-modal', got '{method}'$"):
        solve(system, progress=False)
