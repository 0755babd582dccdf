"""The single Gymnasium env (envs/servo_env.py): the API and both env checkers, determinism, errors that
name the bad field or value, divergence, observation helpers, rendering."""

import os
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import frictiongym.envs  # noqa: F401  (registers the ids)
from frictiongym.envs import scenario_env_id
from frictiongym.envs.config import ConfigError, scenario_names
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.step import REWARD_TERMS


def make(scenario, **kw):
    """The scenario's env by its own id (its TimeLimit is the scenario's length)."""
    return gym.make(scenario_env_id(scenario), **kw)


@pytest.mark.parametrize("scenario", scenario_names())
def test_check_env_passes_for_every_scenario(scenario):
    env = make(scenario, randomize=True, episode_s=1.0)
    check_env(env.unwrapped, skip_render_check=True)
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # SB3's checker reports problems as warnings: none allowed
        sb3_checker.check_env(env.unwrapped, warn=True)


def test_ground_truth_is_a_method_and_in_info_on_request():
    """The same values either way, without changing the episode; left out of info by default."""
    keys = {"qpos", "qvel", "bristle", "friction_torque"}
    plain = ServoEnv("m220_reversal_tracking", randomize=True)
    full = ServoEnv("m220_reversal_tracking", randomize=True, ground_truth_in_info=True)
    (_, ip), (_, i_full) = plain.reset(seed=4), full.reset(seed=4)
    assert not keys & set(ip) and keys <= set(i_full)
    rng = np.random.default_rng(0)
    for _ in range(30):
        a = rng.uniform(-1, 1, 1).astype(np.float32)
        (op, rp, *_, ip), (of, rf, *_, i_full) = plain.step(a), full.step(a)
        assert np.array_equal(op, of) and rp == rf and not keys & set(ip)
        truth = plain.ground_truth()
        assert all(np.array_equal(truth[k], i_full[k]) for k in keys)
    assert np.any(truth["friction_torque"] != 0.0) and np.any(truth["bristle"] != 0.0)
    with pytest.raises(ConfigError, match="ground_truth_in_info"):
        ServoEnv("kang_regulation", ground_truth_in_info="yes")


def test_wrong_plant_for_id_is_rejected():
    with pytest.raises(ValueError, match="is for plant"):
        gym.make("frictiongym/KangRobot-v1", scenario="m220_regulation")


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"control_period_s": 0.0123}, "sampling.control_period_s"),  # not a multiple of dt
        ({"episode_s": 0.011}, "episode_s"),
        (
            {"overrides": {"task": {"action_scale_nm": 50.0}}},
            "task.action_scale_nm",
        ),  # above the 10 N·m limit
        ({"overrides": {"reference": {"type": "square"}}}, "reference.type"),
        ({"overrides": {"task": {"tracked_sensor": "tacho9"}}}, "task.tracked_sensor"),
        ({"overrides": {"rewards": {}}}, "rewards"),
    ],
)
def test_invalid_scenario_values_name_the_field(kwargs, field):
    with pytest.raises(ConfigError) as e:
        gym.make("frictiongym/KangRobot-v1", **kwargs)
    assert e.value.field == field


def test_nan_action_is_a_clear_error():
    env = gym.make("frictiongym/KangRobot-v1")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan], dtype=np.float32))


def test_same_seed_same_episode_different_seed_different_episode():
    def run(seed):
        env = gym.make("frictiongym/KangRobot-v1", randomize=True, episode_s=1.0)
        obs, info = env.reset(seed=seed)
        out = [obs]
        rng = np.random.default_rng(0)
        for _ in range(50):
            obs, _r, *_ = env.step(rng.uniform(-1, 1, 1).astype(np.float32))
            out.append(obs)
        return np.array(out), info["params"]

    (a, pa), (b, pb), (c, pc) = run(3), run(3), run(4)
    assert np.array_equal(a, b) and pa == pb
    assert not np.array_equal(a, c) and pa != pc


def test_episode_structure_ground_truth_and_metrics():
    # flexible_speed_step: 10 s at 40 ms
    env = gym.make("frictiongym/FlexibleServo-v1", ground_truth_in_info=True)
    _, info = env.reset(seed=0)
    assert {"params", "qpos", "qvel", "bristle", "friction_torque"} <= set(info)
    assert info["qvel"][0] == pytest.approx(1.0)  # ω1(0) = 1 rad/s, Wallenborg §4.3
    n, done = 0, False
    while not done:
        _obs, r, term, trunc, info = env.step(np.zeros(1, dtype=np.float32))
        n += 1
        done = term or trunc
        total = sum(info[k] for k in REWARD_TERMS)
        assert r == pytest.approx(total)
    assert n == 250 and trunc and not term
    m = info["episode_metrics"]
    # zero command: the shafts coast to a stop under friction, so the output ends at 0 V while the
    # reference is 0 again after t = 5 s, and the 1 V step was never followed (IAE ≥ 3 V·s)
    assert m["final_error"] == pytest.approx(0.0, abs=1e-3) and m["iae"] > 3.0


def test_observation_layout_and_scaling_helpers():
    env = gym.make("frictiongym/M220-ReversalTracking-v1")
    obs, _ = env.reset(seed=0)
    u = env.unwrapped
    assert obs.shape == (2 + 1 + 5 + 1,)
    obs, *_ = env.step(u.command_to_action(1.0))
    d = u.decode_observation(obs)
    assert d["previous_command"] == pytest.approx(1.0)
    assert d["reference"] == pytest.approx(0.5 * np.sin(2 * np.pi * 0.2 * 0.005), rel=1e-5)
    res = 2 * np.pi / 16000
    assert d["sensors"]["encoder_drive"] / res == pytest.approx(
        round(d["sensors"]["encoder_drive"] / res), abs=1e-3
    )
    assert u.action_to_command(np.array([2.0])) == pytest.approx(2.0)  # clipped to 1 -> 2 V


def test_privileged_observation_only_on_request():
    plain = make("kang_regulation_20deg")
    priv = make("kang_regulation_20deg", overrides={"observation": {"privileged": True}})
    assert priv.observation_space.shape[0] == plain.observation_space.shape[0] + 3
    obs, _ = priv.reset(seed=0)
    assert obs[-3] == pytest.approx(1.0)  # true output / output_scale = 20 deg / 20 deg


def test_divergence_ends_the_episode_with_a_flag_and_finite_observation():
    env = gym.make("frictiongym/KangRobot-v1")
    env.reset(seed=0)
    core = env.unwrapped.core
    core.model.actuator_dynprm[core.idx.friction[0], 6] = (
        1e9  # bristle damping far outside the checked region
    )
    obs, r, term, _trunc, info = env.step(np.array([0.5], dtype=np.float32))
    assert term and info["diverged"] and np.all(np.isfinite(obs)) and np.isfinite(r)


def test_rgb_render_headless_and_episode_plot(tmp_path):
    code = (
        "import gymnasium as gym, frictiongym.envs, numpy as np;"
        "e=gym.make('frictiongym/M220-v1', render_mode='rgb_array'); e.reset(seed=0);"
        "f=e.render(); assert f.shape == (480, 640, 3) and f.std() > 1, f.std();"
        f"e.unwrapped.plot_episode(r'{tmp_path / 'ep.png'}')"
    )
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=120)
    assert (tmp_path / "ep.png").stat().st_size > 10_000


def test_huge_state_ends_the_episode_as_diverged():
    with pytest.raises(ConfigError, match=r"initial_state.qpos\[0\]\[0\]: 20000000000.0 is outside"):
        ServoEnv("kang_regulation", overrides={"initial_state": {"qpos": [[2e10, 2e10]]}})  # the envelope
    env = ServoEnv("kang_regulation")
    env.reset(seed=0)
    env.core.backend.qpos[:] = 2e10  # a state no scenario may start from, e.g. after a numerical blow-up
    _, reward, term, _, info = env.step(np.zeros(1, np.float32))
    assert term and info["diverged"] and np.isfinite(reward)
    assert reward < -(env.scenario.reward_weights["tracking"] * 1e6)  # below any step that did not diverge


@pytest.mark.parametrize("bad", ["x", b"1", 1j, True, np.array([]), np.zeros(2), np.zeros((3, 2))])
def test_actions_other_than_one_finite_real_are_clear_errors(bad):
    env = ServoEnv("kang_regulation")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(bad)


def test_step_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match="reset"):
        ServoEnv("kang_regulation").step(np.zeros(1))
