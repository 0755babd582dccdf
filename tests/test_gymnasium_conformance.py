"""Gymnasium's generic env checks (its own tests/envs/test_envs.py and test_spec.py, written here for
these ids) against every registered id: the env checker, determinism of a rollout, pickling, render
modes, sync and async vector envs against the batched one, out-of-bound actions, standard wrappers."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env, data_equivalence

import frictiongym.envs
from frictiongym.envs import ENV_IDS

IDS = list(ENV_IDS)
SHORT = {"episode_s": 0.2}  # a few periods of each plant: the checks need episodes, not long ones


@pytest.mark.parametrize("env_id", IDS)
def test_env_checker_passes_without_warnings(env_id):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(env_id, **SHORT).unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", IDS)
def test_rollout_is_determined_by_the_seed(env_id):
    """Gymnasium's test_env_determinism_rollout: two envs, the same seeds, the same actions."""
    env_1, env_2 = gym.make(env_id, randomize=True), gym.make(env_id, randomize=True)
    env_1.action_space.seed(0)
    first = [env_1.reset(seed=42), env_2.reset(seed=42)]
    assert data_equivalence(*first, exact=True)
    for _ in range(100):
        a = env_1.action_space.sample()
        out_1, out_2 = env_1.step(a), env_2.step(a)
        assert data_equivalence(out_1, out_2, exact=True)
        if out_1[2] or out_1[3]:
            assert data_equivalence(env_1.reset(), env_2.reset(), exact=True)


@pytest.mark.parametrize("env_id", IDS)
def test_pickled_env_continues_identically(env_id):
    """Gymnasium's test_pickle_env, after a reset and some steps (the copy steps on from there)."""
    env = gym.make(env_id, randomize=True)
    env.reset(seed=5)
    for _ in range(10):
        env.step(env.action_space.sample())
    twin = pickle.loads(pickle.dumps(env))
    for a in np.linspace(-1, 1, 20, dtype=np.float32):
        assert data_equivalence(env.step(a[None]), twin.step(a[None]), exact=True)


RENDER = """
import gymnasium as gym, numpy as np, frictiongym.envs
env_id = {env_id!r}
for mode in gym.make(env_id).metadata["render_modes"]:
    env = gym.make(env_id, render_mode=mode)
    env.reset(seed=0)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape == (480, 640, 3) and frame.std() > 1, mode
    env.close()
    venv = gym.make_vec(env_id, num_envs=2, render_mode=mode)
    venv.reset(seed=0)
    frames = venv.render()
    assert len(frames) == 2 and np.array_equal(frames[0], frame), "env 0 of seed 0 renders as the single env"
    venv.close()
try:
    gym.make(env_id, render_mode="ansi")
except ValueError as e:
    assert "render_mode" in str(e)
else:
    raise AssertionError("an undeclared render mode was accepted")
"""


@pytest.mark.parametrize("env_id", IDS)
def test_render_modes(env_id):
    """Every declared render mode renders, single and vector (headless EGL, chosen before MuJoCo is
    imported, hence a fresh interpreter); an undeclared one is refused."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    subprocess.run([sys.executable, "-c", RENDER.format(env_id=env_id)], check=True, env=env, timeout=120)


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("mode", ["sync", "async"])
def test_gymnasium_vector_envs_equal_the_batched_one(env_id, mode):
    kw = {**SHORT, "randomize": True}
    theirs = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, **kw)
    ours = gym.make_vec(env_id, num_envs=2, **kw)
    try:
        rng = np.random.default_rng(3)
        assert data_equivalence(theirs.reset(seed=9), ours.reset(seed=9), exact=True)
        steps = gym.make(env_id, **kw).unwrapped.scenario.episode_steps
        for _ in range(2 * steps + 2):  # across autoresets
            a = rng.uniform(-1, 1, (2, 1)).astype(np.float32)
            assert data_equivalence(theirs.step(a), ours.step(a), exact=True)
    finally:
        theirs.close()


@pytest.mark.parametrize("env_id", IDS)
def test_out_of_bound_actions_are_clipped_to_the_box(env_id):
    """Gymnasium's out-of-bounds check: an action outside the Box acts as its clipped value."""
    outside, edge = gym.make(env_id), gym.make(env_id)
    outside.reset(seed=1)
    edge.reset(seed=1)
    for big in (5.0, -7.0, 1e9):
        o_1, r_1, *_ = outside.unwrapped.step(np.array([big], np.float32))
        o_2, r_2, *_ = edge.unwrapped.step(np.array([np.sign(big)], np.float32))
        assert np.array_equal(o_1, o_2) and r_1 == r_2


WRAPPERS = [
    lambda e: gym.wrappers.ClipAction(e),
    lambda e: gym.wrappers.RescaleAction(e, np.float32(-2.0), np.float32(2.0)),
    lambda e: gym.wrappers.NormalizeObservation(e),
    lambda e: gym.wrappers.NormalizeReward(e),
    lambda e: gym.wrappers.FrameStackObservation(e, 3),
    lambda e: gym.wrappers.TimeAwareObservation(e),
    lambda e: gym.wrappers.RecordEpisodeStatistics(e),
    lambda e: gym.wrappers.FlattenObservation(e),
]


# each plant's default scenario by its own id (TimeAwareObservation needs the spec's max_episode_steps)
DEFAULT_SCENARIO_IDS = [
    frictiongym.envs.scenario_env_id(frictiongym.envs._env_class(ENV_IDS[i][0]).default_scenario) for i in IDS
]


@pytest.mark.parametrize("env_id", DEFAULT_SCENARIO_IDS)
@pytest.mark.parametrize("wrap", WRAPPERS, ids=lambda w: w.__code__.co_names[-1])
def test_standard_wrappers_run_a_whole_episode(env_id, wrap):
    env = wrap(gym.make(env_id, **SHORT))
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    steps, done = 0, False
    while not done:
        obs, reward, term, trunc, info = env.step(env.action_space.sample())
        steps, done = steps + 1, term or trunc
        assert np.isfinite(reward) and steps <= 10_000
    assert steps == env.unwrapped.scenario.episode_steps  # the env ends where its scenario does
    if isinstance(env, gym.wrappers.RecordEpisodeStatistics):
        assert info["episode"]["l"] == steps


@pytest.mark.parametrize("env_id", IDS)
def test_spec_round_trips_through_json_and_pickle(env_id):
    """Gymnasium's spec tests: to_json/pprint work and a pickled spec makes the same env."""
    env = gym.make(env_id, **SHORT)
    spec = pickle.loads(pickle.dumps(env.spec))
    assert spec.to_json() == env.spec.to_json()
    assert gym.make(spec).spec.max_episode_steps == env.spec.max_episode_steps
    assert data_equivalence(gym.make(spec).reset(seed=3), env.reset(seed=3), exact=True)
    assert frictiongym.envs.env_id(env.unwrapped.plant) == env_id
