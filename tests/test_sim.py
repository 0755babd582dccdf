"""Sampled-data simulation: delay timing, ZOH, sensors, runtime parameters, batch equivalence."""

import mujoco
import numpy as np
import pytest
from mujoco.batch import Batch

from frictiongym.envs.config import ConfigError
from frictiongym.envs.plants.params import EpisodeParams, apply_batch
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.servo_env import ServoEnv


@pytest.mark.parametrize("delay_steps", [0, 1, 7, 40, 79, 80])
def test_command_acts_from_exactly_tk_plus_tau(delay_steps):
    """Up to two control periods of 40 steps (MAX_DELAY_PERIODS: the plant's own delay and the one more
    period a robustness check adds), the command acts exactly the delay after it was given."""
    sim = PlantSim("kang_robot")
    h = sim.spec.timestep
    p = EpisodeParams.nominal(sim.spec)
    sim.reset(EpisodeParams(**{**p.__dict__, "delay": delay_steps * h}))
    sim.step(0.0)  # one control period of zero command
    t_k = sim.data.time
    sim.data.ctrl[sim.idx.drive_ctrl] = 1.0
    first = None
    for _ in range(3 * sim.spec.substeps):
        t_start = sim.data.time
        mujoco.mj_step(sim.model, sim.data)
        if first is None and sim.data.actuator_force[sim.idx.drive] != 0.0:
            first = t_start
    assert first == pytest.approx(t_k + delay_steps * h, abs=1e-12)


def test_a_delay_beyond_two_control_periods_is_refused_naming_the_field():
    spec = PlantSim("kang_robot").spec
    p = EpisodeParams.nominal(spec)
    EpisodeParams(**{**p.__dict__, "delay": 2 * spec.control_period}).validate(spec)
    with pytest.raises(ConfigError, match=r"params\.delay"):
        EpisodeParams(**{**p.__dict__, "delay": 2 * spec.control_period + spec.timestep}).validate(spec)


def test_the_delay_stays_the_same_over_a_long_episode():
    """A command given at step i acts from step i + 3 at every step of 60 s (120,000 steps of 0.5 ms), not
    one step later once the accumulated time's rounding crosses the stored timestamps (it did after 16 s
    when the delay was exactly 3 steps): each step's command is distinct, so the force says which step's
    command acts."""
    sim = PlantSim("kang_robot")
    h = sim.spec.timestep
    p = EpisodeParams.nominal(sim.spec)
    sim.reset(EpisodeParams(**{**p.__dict__, "delay": 3 * h}))
    n = round(60.0 / h)
    given = np.arange(n) % 1000 * 1e-4  # distinct values within the command limit
    acted = np.empty(n)
    for i in range(n):
        sim.data.ctrl[sim.idx.drive_ctrl] = given[i]
        mujoco.mj_step(sim.model, sim.data)
        acted[i] = sim.data.actuator_force[sim.idx.drive]
    np.testing.assert_array_equal(acted[3:], given[:-3] * sim.model.actuator_gear[sim.idx.drive, 0])


def test_command_is_held_over_the_period_and_clipped():
    sim = PlantSim("flexible_servo")
    sim.reset()
    sim.step(25.0)  # beyond ±10 V
    assert sim.data.actuator_force[sim.idx.drive] == pytest.approx(10.0)  # actuator units (V)
    dof = sim.dofs[0]
    assert sim.data.qfrc_actuator[dof] - sim.data.qfrc_actuator[dof] * 0 == pytest.approx(
        10.0 * sim.spec.actuator_gain
        + sim.friction_torque()[0]
        + sim.model.actuator_damping[sim.idx.friction[0]] * -sim.data.qvel[dof],
        rel=1e-9,
    )
    with pytest.raises(ValueError, match="finite"):
        sim.step(float("nan"))


def test_encoder_quantisation_and_seeded_noise():
    sim = PlantSim("m220", {"sensors": {"encoder_drive": {"noise_std_counts": 2.0}}})
    res = sim.spec.sensors[0].resolution
    r = sim.reset(qpos=[1000.4 * res], seed=3)
    assert r.measurement[1] == pytest.approx(
        np.floor(1000.4 * res * sim.spec.kinematic_ratios()["load"] / res) * res
    )
    a = [sim.step(1.0).measurement for _ in range(5)]
    sim.reset(qpos=[1000.4 * res], seed=3)
    b = [sim.step(1.0).measurement for _ in range(5)]
    assert np.array_equal(a, b)
    assert all(np.allclose(np.round(m / res), m / res) for m in a)


def test_tacho_ripple_has_ten_periods_per_revolution_as_wallenborg_measured():
    """Wallenborg 1987 §7.2: the ripple's frequency is 100 rad/s at ω1 = 10 rad/s, ten periods per
    revolution: with an amplitude set and the shaft's speed zero, the reading over one revolution is
    A·sin(10·θ), crossing zero 20 times."""
    from frictiongym.envs.plants import plant_spec
    from frictiongym.envs.sensors import SensorArrays

    spec = plant_spec("flexible_servo", {"sensors": {"tacho1": {"ripple_amplitude_v": 0.05}}})
    sensors = SensorArrays.of(spec, tuple(range(len(spec.joints))))
    i = next(k for k, x in enumerate(spec.sensors) if x.name == "tacho1")
    theta = np.linspace(0.0, 2 * np.pi, 2001)[:-1]
    qpos = np.zeros((len(theta), len(spec.joints)))
    qpos[:, sensors.dofs[i]] = theta
    ripple = sensors.measure(qpos, np.zeros_like(qpos), np.zeros((len(theta), len(spec.sensors))))[:, i]
    assert np.allclose(ripple, 0.05 * np.sin(10 * theta))
    assert np.count_nonzero(np.diff(np.sign(ripple[1:])) != 0) == 19  # 20 crossings, the first at θ = 0


def test_runtime_parameters_change_the_physics_without_recompiling():
    sim = PlantSim("kang_robot", friction_model="none")
    p = EpisodeParams.nominal(sim.spec)
    sim.reset(p)
    v1 = sim.step(1.0).qvel[0]
    sim.reset(EpisodeParams(**{**p.__dict__, "inertia": (2 * p.inertia[0],)}))
    v2 = sim.step(1.0).qvel[0]
    assert v2 == pytest.approx(v1 / 2, rel=1e-3)  # same torque, double inertia -> half the velocity


def test_runtime_bias_and_viscous_take_effect():
    sim = PlantSim("flexible_servo")  # compiled with bias 0 and σ2 0
    p = EpisodeParams.nominal(sim.spec)
    f = p.friction[0]
    new = f.__class__(**{**f.__dict__, "bias": 0.5 * f.fc, "sigma2": 1e-4})
    sim.reset(EpisodeParams(**{**p.__dict__, "friction": (new, p.friction[1])}), qvel=[5.0, 5.0])
    sim.step(0.0, nstep=20)  # bristles settle in ~g/(σ0·|v|) = 0.1 ms; v barely changes in 10 ms
    expected = new.steady_state(sim.data.qvel[0])
    assert sim.friction_torque()[0] == pytest.approx(expected, rel=1e-3)


def test_batch_runs_bit_identical_to_single_simulations():
    sim = PlantSim("m220")
    params = [EpisodeParams.draw(sim.spec, s) for s in range(5)]
    b = Batch(sim.model, nsim=5, nthread=2)
    apply_batch(b, sim.spec, sim.idx, params)
    b.reset()
    ctrl = b.bind("ctrl")
    u = np.linspace(-2, 3, 5)
    for k in range(20):
        ctrl[:, sim.idx.drive_ctrl] = u * np.sin(0.3 * k)
        b.step(nstep=sim.spec.substeps)
    for i, p in enumerate(params):
        single = PlantSim("m220")
        single.reset(p)
        for k in range(20):
            single.step(u[i] * np.sin(0.3 * k))
        assert np.array_equal(b.bind("qpos")[i], single.data.qpos)
        assert np.array_equal(b.bind("act")[i], single.data.act)


def test_divergence_is_flagged():
    sim = PlantSim("kang_robot")
    sim.reset()
    sim.model.actuator_dynprm[sim.idx.friction[0], 6] = 1e7  # σ1 far outside the checked region
    res = sim.step(1.0)
    for _ in range(5):
        res = sim.step(1.0)
    assert res.diverged


def test_coulomb_model_holds_below_and_slides_above_the_directional_static_level():
    """frictionloss = Fc plus the bias: Kang's positive-direction level is Fc - b = 1.297 N·m."""
    sim = PlantSim("kang_robot", friction_model="coulomb")
    level = sim.spec.joints[0].friction.levels()["coulomb_pos"]
    sim.reset()
    for _ in range(10):
        r = sim.step(0.95 * level)
    assert abs(r.qpos[0]) < 1e-3 and abs(r.qvel[0]) < 1e-3
    sim.reset()
    for _ in range(10):
        r = sim.step(1.1 * level)
    assert r.qvel[0] > 0.01


def test_analog_rate_feedback_acts_at_physics_rate():
    """Kang's analog D loop: with friction off, ω decays as exp(-K_d·t/J) between control instants."""
    sim = PlantSim("kang_robot", {"actuator": {"rate_feedback_nm_s_per_deg": 0.1}}, friction_model="none")
    kd, J = sim.spec.rate_feedback, sim.spec.joints[0].inertia
    sim.reset(qvel=[1.0])
    r = sim.step(0.0, nstep=200)  # 0.1 s, no command
    assert r.qvel[0] == pytest.approx(np.exp(-kd * 0.1 / J), rel=0.01)


def test_jitter_delays_each_command_by_tau_plus_a_seeded_draw():
    sim = PlantSim("kang_robot")
    h, n = sim.spec.timestep, sim.spec.substeps
    p = EpisodeParams(**{**EpisodeParams.nominal(sim.spec).__dict__, "delay": 2 * h, "jitter": 3 * h})

    def onsets(seed):
        sim.reset(p, seed=seed)
        out, last = [], 0.0
        for k in range(12):
            t_k = sim.data.time
            u = 0.5 * (k + 1)  # distinct and inside the ±10 N·m limit
            for s in range(n):
                if s == 0:
                    sim.step(u, nstep=1)
                else:
                    mujoco.mj_step(sim.model, sim.data)
                if sim.data.actuator_force[sim.idx.drive] != last:
                    last = sim.data.actuator_force[sim.idx.drive]
                    out.append(round((sim.data.time - h - t_k) / h))
        return out

    a = onsets(5)
    assert a == onsets(5)  # same seed, same jitter
    assert len(a) == 12 and set(a) <= {2, 3, 4, 5}  # τ + j, j in [0, 3] steps
    assert len(set(a)) > 1  # it does vary
    assert a != onsets(6)


def test_plantsim_noise_matches_the_env_for_the_same_seed():
    ov = {"sensors": {"encoder": {"noise_std_deg": 0.01}}}
    env = ServoEnv("kang_regulation_20deg", overrides={"plant_overrides": ov})
    env.reset(seed=4)
    obs, *_ = env.step(np.zeros(1, np.float32))
    sim = PlantSim("kang_robot", ov)
    sim.reset(qpos=[0.349066], seed=4)
    r = sim.step(0.0)
    assert obs[0] == np.float32(r.measurement[0] / env.scenario.output_scale)


@pytest.mark.parametrize("scenario", ["kang_regulation", "m220_reversal_tracking_hard"])
def test_plantsim_and_the_env_step_the_same_physics(scenario):
    """PlantSim is the env's single-simulation backend (plants/backend.py) with n = 1: on an episode's
    drawn parameters and initial state, the same commands give the env's joint trajectory bit for bit
    (the M220 case with the hard scenario's actuation delay and jitter, drawn from the same seed)."""
    env = ServoEnv(scenario, randomize=True)
    env.reset(seed=7)
    core = env.core
    p, q0, v0 = core.params[0], core.backend.qpos.copy(), core.backend.qvel.copy()
    sim = PlantSim(env.scenario.spec)
    sim.reset(p, qpos=q0, qvel=v0, seed=7)
    actions = np.random.default_rng(0).uniform(-0.6, 0.6, 60).astype(np.float32)
    for a in actions:
        env.step(np.array([a]))
        sim.step(float(a) * env.scenario.action_scale)
        assert np.array_equal(sim.data.qpos, core.backend.qpos)
        assert np.array_equal(sim.data.qvel, core.backend.qvel)
    if scenario.endswith("hard"):
        assert p.jitter_steps(sim.spec) > 0  # the per-period jitter draws were exercised
