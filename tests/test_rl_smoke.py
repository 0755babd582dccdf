"""SB3 runs on every env without extra wrappers, and a short SAC run learns Kang's regulation task."""

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import PPO, SAC

import frictiongym.envs
from frictiongym.envs.vector import make_sb3_vec_env

torch.set_num_threads(1)


@pytest.mark.parametrize("env_id", list(frictiongym.envs.ENV_IDS))
@pytest.mark.parametrize("algo", [PPO, SAC])
def test_sb3_runs_on_every_env(env_id, algo):
    env = gym.make(env_id, episode_s=0.4)
    kw = {"n_steps": 64, "batch_size": 32} if algo is PPO else {"learning_starts": 32, "batch_size": 32}
    model = algo("MlpPolicy", env, seed=0, **kw).learn(128)
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action)


def test_ppo_on_the_batched_vec_env():
    venv = make_sb3_vec_env("kang_regulation", 4, nthread=2, episode_s=0.4)
    PPO("MlpPolicy", venv, n_steps=32, batch_size=64, seed=0).learn(256)


def _episode_return(policy, seed: int) -> float:
    env = gym.make("frictiongym/KangRobot-v1")
    obs, _ = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        obs, r, term, trunc, _ = env.step(policy(obs))
        total += r
        done = term or trunc
    return total


@pytest.mark.slow
def test_short_sac_run_beats_random_and_zero_policies():
    """4000 steps (~45 s CPU). Random torques score about -1900 per episode, zero torque -500 (the rotor
    stays at 20 deg); a learned regulator must at least halve the zero policy's cost."""
    env = gym.make("frictiongym/KangRobot-v1")
    model = SAC("MlpPolicy", env, seed=0, learning_starts=1000).learn(4000)
    rng = np.random.default_rng(0)
    seeds = [11, 12]
    learned = np.mean([_episode_return(lambda o: model.predict(o, deterministic=True)[0], s) for s in seeds])
    random = np.mean([_episode_return(lambda o: rng.uniform(-1, 1, 1).astype(np.float32), s) for s in seeds])
    zero = np.mean([_episode_return(lambda o: np.zeros(1, np.float32), s) for s in seeds])
    assert learned > 0.5 * zero > random


def test_a_learned_policy_runs_through_the_same_evaluation_loop():
    from frictiongym.agents.evaluation.evaluate import evaluate
    from frictiongym.agents.learned.policy import LearnedPolicy
    from frictiongym.envs.suites import Episode

    env = gym.make("frictiongym/KangRobot-v1", episode_s=0.4)
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=32, seed=0).learn(64)
    res = evaluate(
        [LearnedPolicy(model, ("kang_robot",), "ppo-tiny")],
        [Episode("kang_regulation", 0, False), Episode("m220_regulation", 0, False)],
        progress=False,
    )
    assert [(r.controller, r.scenario) for r in res] == [("ppo-tiny", "kang_regulation")]
    assert np.isfinite(res[0].metrics["iae"])
