"""The LuGre dynamic friction law: closed forms, its scene keys, and a run through the DAE.

Closed forms of the normalised law (Canudas de Wit et al. 1995), written here from the law,
not taken from the code: steady sliding ``mu_ss(v) = g(v) sgn(v) + sigma2 v`` with
``g(v) = mu_c + (mu_s - mu_c) exp(-(v/v_s)^2)``, and small displacements from rest behaving as a
spring of stiffness ``sigma0 F_N`` with the damper ``(sigma1 + sigma2) F_N``.
"""

import math
import pathlib
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import roughvib
from roughvib.physics.friction import LAWS, calibrate_force_amplitude, law_kind, rms_over_periods
from roughvib.physics.friction import lugre as lugre_law
from roughvib.physics.friction.calibration import simulate_tangential
from roughvib.scene import SceneError

MU_C, MU_S = 0.30, 0.40  # the paper's mu_slip, mu_stick (the scene's defaults)


def _g(v, vs):
    return MU_C + (MU_S - MU_C) * math.exp(-(v / vs) ** 2)


def _params(sigma0=1e5, sigma1=100.0, sigma2=0.0, vs=2e-3):
    return lugre_law.pack_parameters({"sigma0": sigma0, "sigma1": sigma1, "sigma2": sigma2,
                                      "stribeck_velocity": vs})


@pytest.mark.parametrize("sigma2", [0.0, 0.5])
@pytest.mark.parametrize("v", [-2e-2, -2e-3, -3e-4, 1e-4, 1e-3, 2.5e-3, 5e-3, 5e-2])
def test_steady_sliding_reaches_the_closed_form(v, sigma2):
    # the bristle state integrated at constant velocity by an independent integrator settles
    # where the law's coefficient is g(v) sgn(v) + sigma2 v and z = g(v) sgn(v) / sigma0
    p = _params(sigma2=sigma2)
    b = math.copysign(1.0, v)

    def rate(_t, z):
        return [lugre_law.bristle_law(v, z[0], b, MU_C, MU_S, p)[1]]

    tau = _g(v, 2e-3) / (1e5 * abs(v))  # the bristles' time constant at this speed
    sol = solve_ivp(rate, (0.0, 40 * tau), [0.0], method="Radau", rtol=1e-11, atol=1e-16)
    z = sol.y[0, -1]
    mu = lugre_law.bristle_law(v, z, b, MU_C, MU_S, p)[0]
    closed = math.copysign(_g(v, 2e-3), v) + sigma2 * v
    assert mu == pytest.approx(closed, rel=1e-8)
    assert z == pytest.approx(math.copysign(_g(v, 2e-3), v) / 1e5, rel=1e-8)
    assert lugre_law.steady_coefficient(v, MU_C, MU_S, sigma2, 2e-3) == pytest.approx(closed,
                                                                                       rel=1e-14)


def test_defaults_give_the_papers_coefficients():
    # sigma2 = 0: steady sliding tends to mu_slip fast and to mu_stick slow
    scene = roughvib.load_scene("paper", {"friction.law": "lugre"})
    par = scene.friction.parameters
    assert par["sigma2"] == 0.0
    fast = lugre_law.steady_coefficient(1.0, scene.friction.mu_slip, scene.friction.mu_stick,
                                        par["sigma2"], par["stribeck_velocity"])
    slow = lugre_law.steady_coefficient(1e-9, scene.friction.mu_slip, scene.friction.mu_stick,
                                        par["sigma2"], par["stribeck_velocity"])
    assert fast == pytest.approx(0.30, abs=1e-12)
    assert slow == pytest.approx(0.40, abs=1e-12)


def test_partial_derivatives_are_exact():
    p = _params(sigma2=0.3)
    rng = np.random.default_rng(5)
    for _ in range(20):
        v = rng.uniform(-5e-3, 5e-3)
        z = rng.uniform(-4e-6, 4e-6)
        b = math.copysign(1.0, v)
        mu, zd, dmv, dmz, dzv, dzz = lugre_law.bristle_law(v, z, b, MU_C, MU_S, p)
        hv, hz = 1e-9, 1e-12
        up = lugre_law.bristle_law(v + hv, z, b, MU_C, MU_S, p)
        dn = lugre_law.bristle_law(v - hv, z, b, MU_C, MU_S, p)
        assert dmv == pytest.approx((up[0] - dn[0]) / (2 * hv), rel=1e-6, abs=1e-6)
        assert dzv == pytest.approx((up[1] - dn[1]) / (2 * hv), rel=1e-6, abs=1e-9)
        up = lugre_law.bristle_law(v, z + hz, b, MU_C, MU_S, p)
        dn = lugre_law.bristle_law(v, z - hz, b, MU_C, MU_S, p)
        assert dmz == pytest.approx((up[0] - dn[0]) / (2 * hz), rel=1e-6)
        assert dzz == pytest.approx((up[1] - dn[1]) / (2 * hz), rel=1e-6, abs=1e-3)


def _presliding_amplitude(T0, m, r2, normal_force, omega, sigma0=1e5, sigma1=100.0,
                          sigma2=0.0):
    # m x'' + (r2 + (sigma1 + sigma2) F_N) x' + sigma0 F_N x = T0 cos(omega t)
    return T0 / abs(sigma0 * normal_force - m * omega**2
                    + 1j * omega * (r2 + (sigma1 + sigma2) * normal_force))


def test_tangential_model_presliding_is_a_spring_of_stiffness_sigma0():
    m, r2, fn, omega = 0.221, 0.5, 0.221 * 9.81, 2 * math.pi * 7
    T0 = 1e-3 * MU_S * fn  # far below break-away: z = x to 1e-3
    scene = roughvib.load_scene("paper", {"friction.law": "lugre"})
    t, v, x = simulate_tangential(T0, m, r2, fn, omega, scene.friction, 2.0 / 7, dt=1e-5)
    last = t > 1.0 / 7
    amp = 0.5 * (x[last].max() - x[last].min())
    assert amp == pytest.approx(_presliding_amplitude(T0, m, r2, fn, omega), rel=2e-3)


@pytest.mark.short_run
def test_dae_presliding_is_a_spring_of_stiffness_sigma0():
    # the whole DAE (IDA) on a rigid base with a nm roughness: the block's tangential
    # displacement amplitude is the closed form's, and it changes with sigma0 as 1 / sigma0
    base = roughvib.load_scene("paper")
    m, r2 = base.block.mass, base.block.tangential_damping
    fn, omega = m * 9.81, 2 * math.pi * base.excitation.frequency
    T0 = 1e-3 * MU_S * fn
    for sigma0 in (1e5, 4e5):
        scene = roughvib.load_scene("paper", {
            "friction.law": "lugre", "friction.parameters.sigma0": sigma0,
            "output.progress": False, "output.duration": 0.3, "output.transient": 0.1,
            "plate.kind": "rigid", "roughness.rms": 1e-9,
            "roughness.shortest_wavelength": 5e-5, "excitation.force_amplitude": T0,
            "excitation.target_rms_velocity": "none"})
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = roughvib.simulate(scene)
        assert r.status == "success"
        ds = r.to_dataset()
        x = ds.block_tangential_displacement.values
        last = ds.time.values > 0.3 - 1 / base.excitation.frequency
        amp = 0.5 * (x[last].max() - x[last].min())
        assert amp == pytest.approx(_presliding_amplitude(T0, m, r2, fn, omega, sigma0),
                                    rel=2e-3)
        assert abs(r.summary["energy_audit"]["relative_residual"]) < 1e-6


def test_calibration_reaches_the_target_rms():
    scene = roughvib.load_scene("paper", {"friction.law": "lugre"})
    m, fn, omega = 0.221, 0.221 * 9.81, 2 * math.pi * 7
    T0 = calibrate_force_amplitude(0.01, m, 0.5, fn, omega, scene.friction, dt=2e-6)
    period = 2 * math.pi / omega
    t, v, _ = simulate_tangential(T0, m, 0.5, fn, omega, scene.friction, 5 * period, dt=2e-6)
    assert rms_over_periods(t, v, period, 3 * period) == pytest.approx(0.01, rel=2e-3)


def test_scene_keys_and_solvers():
    assert LAWS["lugre"].kind == "dynamic" and LAWS["lugre"].states == 1
    assert LAWS["lugre"].solvers == ("ida",)
    scene = roughvib.load_scene("paper", {"friction.law": "lugre"})
    assert scene.resolved_solver().method == "ida"
    with pytest.raises(SceneError, match=r"adaptive-modal runs single-valued or set-valued"):
        roughvib.load_scene("paper", {"friction.law": "lugre",
                                      "solver.method": "adaptive-modal"})
    with pytest.raises(SceneError, match=r"friction.parameters.sigma0 is a key of "
                                         r"friction.law = 'lugre', not of"):
        roughvib.load_scene("paper", {"friction.parameters.sigma0": 2e5})
    with pytest.raises(SceneError, match=r"friction.parameters.sigma1 .* must be in \[0, "):
        roughvib.load_scene("paper", {"friction.law": "lugre",
                                      "friction.parameters.sigma1": -1.0})
    with pytest.raises(SceneError, match=r"friction_moment"):
        roughvib.load_scene("paper", {"friction.law": "lugre",
                                      "contact.friction_moment": True})
    with pytest.raises(SceneError, match=r"gmres"):
        roughvib.load_scene("paper", {"friction.law": "lugre", "solver.method": "ida",
                                      "solver.linear_solver": "gmres"})


def test_unregistered_law_id_raises_in_the_kernels():
    with pytest.raises(ValueError, match="no law is registered"):
        law_kind(len(LAWS) + 7)


def test_the_law_is_named_in_three_source_files_at_most():
    # its module, its registration, the scene's list of laws
    src = pathlib.Path(roughvib.__file__).parent
    files = sorted(str(p.relative_to(src)) for p in src.rglob("*.py")
                   if "lugre" in p.read_text(encoding="utf-8").lower())
    assert files == ["physics/friction/laws.py", "physics/friction/lugre.py",
                     "scene/forces.py"]


@pytest.mark.slow
def test_verify_passes_on_the_paper_scene():
    # the paper scene with the law, shortened to 0.08 s (two stick phases and reversals): the
    # run (IDA, the only solver of a dynamic law) against IDA at 100x tighter tolerances and
    # against the refined input, judged by the accuracy contract (the whole 0.43 s scene
    # passes too: docs/friction.md)
    scene = roughvib.load_scene("paper", {"friction.law": "lugre", "output.progress": False,
                                          "output.duration": 0.08, "output.transient": 0.02})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = roughvib.simulate(scene, verify=True)
    acc = r.summary["accuracy"]
    assert acc["verdict"] == "pass", acc["failures"]
    assert acc["representation"]["verdict"] == "pass"
    assert acc["events"]["matched"] >= 4 and acc["events"]["unmatched"] == 0


def test_the_laws_keys_round_trip_through_the_scene_file(tmp_path):
    from roughvib.scene import scene_to_toml

    scene = roughvib.load_scene("paper", {"friction.law": "lugre",
                                          "friction.parameters.sigma0": 2e5})
    path = tmp_path / "lugre.toml"
    path.write_text(scene_to_toml(scene))
    back = roughvib.load_scene(path)
    assert back.friction.parameters == {"sigma0": 2e5, "sigma1": 100.0, "sigma2": 0.0,
                                        "stribeck_velocity": 2e-3}
    assert back.friction == scene.friction
