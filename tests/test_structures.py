"""Friction structures beyond LuGre (Iurian et al. 2005's survey): Dahl and Maxwell-slip built from native
LuGre elements, their MuJoCo elements against Radau, the per-joint sums every consumer reads (ground truth,
privileged observation, drift) bit-identical across the single env, the vector env and a copy, and the
phenomena of §1.3 that follow from their equations."""

import numpy as np
import pytest
from conftest import lockstep

from frictiongym.agents.classical import Southward
from frictiongym.agents.evaluation.evaluate import run_episode
from frictiongym.agents.lab import radau
from frictiongym.agents.reproduce import friction_phenomena as phen
from frictiongym.agents.reproduce.kang1998 import EPISODE
from frictiongym.envs.friction import KANG_STICK_BAND, MAXWELL_SLIP_LENGTHS, elements, joint_levels
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.vector import ServoVectorEnv

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")  # scipy numerical Jacobian (stiff Radau)

DRIFT = {"friction_drift": {"drift": [-0.5, 0.5], "step": [-0.5, -0.4], "step_at_s": [0.5, 1.5]}}


def test_maxwell_slip_shares_lugres_stiffness_damping_and_static_curve():
    p = plant_spec("kang_robot").drive_friction
    els = elements("maxwell_slip", p)
    assert sum(e.sigma0 for e in els) == pytest.approx(p.sigma0, rel=1e-12)
    assert sum(e.sigma1 for e in els) == pytest.approx(p.sigma1, rel=1e-12)
    assert joint_levels("maxwell_slip", p) == (p.fc, p.fs, p.bias)  # quarters of the levels sum exactly
    # presliding lengths F_s,k/σ0,k spread as MAXWELL_SLIP_LENGTHS (ratios), over a decade and more
    lengths = [e.fs / e.sigma0 for e in els]
    assert np.allclose(
        np.array(lengths) / lengths[1], np.array(MAXWELL_SLIP_LENGTHS) / MAXWELL_SLIP_LENGTHS[1]
    )
    for v in (0.3 * p.vs, p.vs, 5 * p.vs):  # the same steady-state friction as LuGre at every speed
        assert radau.steady_state(p, v, "maxwell_slip") == pytest.approx(p.steady_state(v), rel=1e-12)


def test_dahl_is_lugre_without_the_stribeck_drop():
    p = plant_spec("kang_robot").drive_friction
    (e,) = elements("dahl", p)
    assert (e.fc, e.fs, e.sigma0) == (p.fc, p.fc, p.sigma0)
    assert joint_levels("dahl", p) == (p.fc, p.fc, p.bias)
    assert radau.steady_state(p, 0.5 * p.vs, "dahl") == pytest.approx(
        radau.steady_state(p, 20 * p.vs, "dahl") + p.sigma2 * 19.5 * p.vs, rel=1e-12
    )


@pytest.mark.parametrize("structure", ["dahl", "maxwell_slip", "kang"])
@pytest.mark.parametrize(
    ("plant", "joint"),
    [("kang_robot", "rotor"), pytest.param("m220", "drive", marks=pytest.mark.slow)],  # all: the report
)
def test_native_elements_match_radau(structure, plant, joint):
    spec = plant_spec(plant, friction_model=structure)
    for d in (1, -1):
        r = radau.breakaway(spec, joint, d)
        assert r["simulated"] == pytest.approx(r["reference"], rel=0.02)
    r = radau.presliding(spec, joint)
    assert r["simulated"] == pytest.approx(r["reference"], rel=0.02)
    r = radau.sliding(spec, joint, 0.5 * spec.drive_friction.vs)
    assert r["simulated"] == pytest.approx(r["reference"], rel=0.02)


def test_maxwell_slip_env_with_drift_is_bit_identical_single_vector_and_copy():
    """The flexible servo has two frictional joints, so each joint's three further elements are summed
    into the right joint; drift scales all eight elements."""
    kw = {"randomize": True, "episode_s": 2.0, "overrides": {**DRIFT, "friction_model": "maxwell_slip"}}
    keys = ("qpos", "friction_torque", "nonlinear_friction_torque", "bristle", "static_level")
    core = lockstep("flexible_speed_reversal", kw, keys, copy_at=30)[0].core
    assert len(core.elem_act) == 8 and len(core.fric_act) == 2
    # the friction torque is every element's force on its joint, less the first element's σ2·v
    b, m = core.backend, core.model
    for j, dof in enumerate(core.fric_dofs):
        acts = [a for a, i, _ in core.idx.elements if i == j]
        assert len(acts) == 4
        by_hand = sum(b.force[a] for a in acts) - m.actuator_damping[acts[0]] * b.qvel[dof]
        assert core.ground_truth(0)["friction_torque"][j] == pytest.approx(by_hand, rel=1e-12, abs=1e-15)
    # drift writes each element's share of the level: a quarter each
    lam = core.drift[0, core.k[0] - 1]
    fc0 = core.params[0].friction[0].fc
    for a, i, _ in core.idx.elements:
        if i == 0:
            assert m.actuator_biasprm[a, 3] == pytest.approx(0.25 * fc0 * lam, rel=1e-14)


def test_privileged_spring_force_sums_the_elements():
    kw = {
        "randomize": True,
        "overrides": {"friction_model": "maxwell_slip", "observation": {"privileged": True}},
    }
    v = ServoVectorEnv("kang_regulation", 1, **kw)
    v.reset(seed=3)
    for _ in range(5):
        o, *_ = v.step(np.array([[0.2]], dtype=np.float32))
    core = v.core
    _, _, act, _ = core.backend.state()
    unit = core.sc.action_scale * core.sc.spec.actuator_gain
    spring = sum(
        e.sigma0 * act[0, adr]
        for e, adr in zip(elements("maxwell_slip", core.params[0].friction[0]), core.bristle_adr, strict=True)
    )
    assert o[0, -1] == pytest.approx(np.float32(spring / unit), rel=1e-6)


def test_lag_sign_follows_the_bristle_damping():
    """F = g + (u - 1)(g - σ1·v) while z lags the Stribeck drop (u = σ0·z/g): the presets' critically
    damped bristles (σ1·v > g) give lower friction accelerating; a light σ1 gives the survey's lag."""
    spec = phen.rig_spec("lugre")
    assert phen.lag("lugre", spec, 10.0)["width"] < -0.05
    p = spec.drive_friction
    vbar = 1.5 * p.vs
    light = phen.rig_spec("lugre", phen.LIGHT_SIGMA1 * float(p.g(vbar)) / vbar)
    assert phen.lag("lugre", light, 10.0)["width"] > 0.01
    assert abs(phen.lag("dahl", phen.rig_spec("dahl"), 10.0)["width"]) < 1e-3  # g constant: no lag


def test_maxwell_slip_breakaway_rises_as_the_force_rate_falls_and_dahls_does_not():
    ms, dahl = phen.rig_spec("maxwell_slip"), phen.rig_spec("dahl")
    assert phen.breakaway("maxwell_slip", ms, 0.2) - phen.breakaway("maxwell_slip", ms, 20.0) > 0.05
    assert abs(phen.breakaway("dahl", dahl, 0.2) - phen.breakaway("dahl", dahl, 20.0)) < 0.01


def test_kangs_model_drops_within_its_stick_band():
    p = plant_spec("kang_robot").drive_friction
    (e,) = elements("kang", p)
    assert (e.fc, e.fs, e.vs) == (p.fc, p.fs, KANG_STICK_BAND * p.vs)
    assert radau.steady_state(p, 0.05 * p.vs, "kang") == pytest.approx(
        -(p.fc + p.sigma2 * 0.05 * p.vs) + p.bias
    )


def test_southwards_sampled_limit_cycle_is_larger_on_kangs_model_than_on_lugre():
    """Seed 001 §3.1: the limit cycle comes from the friction's drop at zero speed under sample-and-hold;
    LuGre spreads the drop over v_s = 1 deg/s, the paper's model makes it at once."""
    amp = {
        m: run_episode(Southward(), EPISODE, control_period_s=0.02, overrides={"friction_model": m}).metrics[
            "limit_cycle_amp"
        ]
        for m in ("lugre", "kang")
    }
    assert amp["kang"] > 2 * amp["lugre"] > 0


def test_an_episode_pinning_a_structure_runs_on_it_and_designs_on_the_scenarios_own():
    """The sim-to-real structural axis: Episode(..., (("friction_model", m),)) builds the env with that
    structure (the same episode as the scenario override gives, bit for bit) while the controller is
    designed on the scenario's own plant; the pin survives the engine's CSV round trip."""
    from frictiongym.agents.classical import PD
    from frictiongym.agents.evaluation import engine
    from frictiongym.agents.evaluation.evaluate import EnvCache
    from frictiongym.envs.suites import Episode

    e = Episode("kang_regulation", 5, False, (("friction_model", "coulomb"),))
    assert e.options() is None and e.overrides() == {"friction_model": "coulomb"}
    cache = EnvCache()
    pinned = run_episode(PD(), e, envs=cache)
    assert cache.scenario(e).spec.friction_model == "coulomb"
    direct = run_episode(PD(), Episode("kang_regulation", 5, False), overrides={"friction_model": "coulomb"})
    np.testing.assert_equal(pinned.metrics, direct.metrics)  # nan-aware, exact
    assert pinned.metrics["iae"] != run_episode(PD(), Episode("kang_regulation", 5, False)).metrics["iae"]
    job = engine.Job("PD", e.scenario, e.seed, e.randomize, engine.params_text(e))
    assert job.episode == e


def test_the_coulomb_structures_ground_truth_holds_its_frictionloss_force():
    """Coulomb + viscous is MuJoCo's frictionloss constraint: its torque (efc_force of the FRICTION_DOF
    row) is part of the friction the ground truth reports, alike in the single and the vector env (so the
    Oracle cancels it): -F_c + b while the drive accelerates forward under a constant command (the soft
    constraint's force saturates at its level), bias alone at rest."""
    kw = {"randomize": True, "episode_s": 1.0, "overrides": {"friction_model": "coulomb"}}
    v, s = (
        ServoVectorEnv("m220_reversal_tracking", 2, nthread=2, **kw),
        ServoEnv("m220_reversal_tracking", **kw),
    )
    v.reset(seed=5)
    s.reset(seed=5)
    p = s.core.params[0].friction[0]
    for k in range(s.scenario.episode_steps - 1):
        a = np.full((2, 1), 0.3 if k < 100 else -0.3, dtype=np.float32)
        v.step(a)
        s.step(a[0])
        gv, gs = v.ground_truth(), s.ground_truth()
        assert np.array_equal(gv["nonlinear_friction_torque"][0], gs["nonlinear_friction_torque"])
        if 40 <= k < 100:  # accelerating forward, far from standstill
            assert gs["qvel"][0] > 0.1
            assert gs["nonlinear_friction_torque"][0] == pytest.approx(-p.fc + p.bias, rel=1e-6)


def test_the_reference_only_structures_follow_their_equations():
    """Seed 000 §1.4.3: the reset integrator holds up to σ0(1 + a)z1 = F_s, then slides; §1.4.5:
    Bliman-Sorine's friction while sliding one way is F_c + σ2·v whatever the speed's history (its
    steady state is Coulomb's; rate independent)."""
    spec = phen.rig_spec("reset_integrator")
    p = spec.drive_friction
    assert phen.breakaway("reset_integrator", spec, 2.0) == pytest.approx(1.0, abs=0.02)
    r = radau.reference_friction_along(
        "bliman_sorine", p, lambda t: p.vs * (1.5 + np.sin(2 * np.pi * 10 * t)), 0.3, h=1e-4
    )
    settled = slice(1000, None)  # after 0.1 s, many presliding lengths of travel
    np.testing.assert_allclose(
        r["friction"][settled], -(p.fc + p.sigma2 * r["v"][settled]) + p.bias, rtol=1e-6, atol=1e-9
    )


def test_coulomb_model_keeps_the_viscous_term():
    """3 N·m on Kang's rotor with Coulomb + viscous (σ2 = 0.86 N·m·s/rad): steady speed
    (3 - T_C+)/σ2 ≈ 2.0 rad/s, reached within 10 s (it was 14 rad/s without the viscous term)."""
    sim = PlantSim("kang_robot", friction_model="coulomb")
    sim.reset()
    for _ in range(500):
        r = sim.step(3.0)
    p = sim.spec.drive_friction
    assert r.qvel[0] == pytest.approx((3.0 - p.levels()["coulomb_pos"]) / p.sigma2, rel=0.02)
