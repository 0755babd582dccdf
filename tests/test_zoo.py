"""rl-baselines3-zoo: the hyper-parameter file trains through the zoo's own command, its agents load as
suite controllers, the residual wrapper starts as its base, and record_video works through the front end."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import frictiongym.envs
from frictiongym.agents.registry import make
from frictiongym.agents.training.zoo import Residual, zoo_env_kwargs, zoo_policy, zoo_run
from frictiongym.envs.config import ConfigError, configs_dir

# rl_zoo3 is run in subprocesses only: importing it patches Gymnasium's TimeLimit for the whole process
# (rl_zoo3.gym_patches adds info["TimeLimit.truncated"]), which would change every other test's envs
pytestmark = pytest.mark.skipif(importlib.util.find_spec("rl_zoo3") is None, reason="the zoo extra")
ZOO_FILE = configs_dir() / "zoo" / "sac.yml"
ROOT = Path(__file__).resolve().parents[1]


def test_zoo_file_has_an_entry_per_plant_on_a_per_scenario_id():
    """One entry per plant, each on a per-scenario id, so the evaluation env rl-zoo builds from the id
    alone (without env_kwargs) runs that scenario with a base that applies to it."""
    conf = yaml.safe_load(ZOO_FILE.read_text())
    plants = {gym.make(i).unwrapped.plant for i in conf}
    assert plants == {"m220", "flexible_servo", "kang_robot", "emps"} and len(conf) == 4
    for env_id, hyper in conf.items():
        assert env_id in frictiongym.envs.SCENARIO_IDS and "scenario" not in hyper["env_kwargs"]
        env = gym.make(env_id, **hyper["env_kwargs"])
        [wrapper] = hyper["env_wrapper"]
        settings = wrapper["frictiongym.agents.training.zoo.Residual"]
        Residual(env, **settings)  # the base applies, needs no hardware
        Residual(gym.make(env_id), **settings)  # the zoo's eval env


def test_residual_wrapper_with_a_zero_residual_is_its_base_bit_for_bit():
    wrapped = Residual(gym.make("frictiongym/KangRobot-v1", randomize=True), "Southward", 0.05)
    plain, base = gym.make("frictiongym/KangRobot-v1", randomize=True), make("Southward")
    from frictiongym.agents.base import EpisodeContext
    from frictiongym.agents.settings import knowledge_defaults

    x, _ = wrapped.reset(seed=11)
    obs, _ = plain.reset(seed=11)
    sc = plain.unwrapped.scenario
    base.reset(EpisodeContext(sc, sc.spec, knowledge_defaults()))
    for _ in range(200):
        u = base.act(obs)
        assert x[-1] == u[0]  # the policy observes the base action last
        x, r_1, *_ = wrapped.step(np.zeros(1, np.float32))
        obs, r_2, *_ = plain.step(u)
        assert np.array_equal(x[:-1], obs) and r_1 == r_2


def test_residual_wrapper_refuses_a_base_that_brings_hardware():
    with pytest.raises(ConfigError, match="RDFC brings hardware"):
        Residual(gym.make("frictiongym/KangRobot-v1"), "RDFC", 0.05)
    with pytest.raises(ConfigError, match="does not apply"):
        Residual(gym.make("frictiongym/M220-v1"), "RDFC", 0.05)


def _run(*args: str, env: dict) -> str:
    return subprocess.run(
        [sys.executable, *args], check=True, env=env, timeout=600, capture_output=True, text=True
    ).stdout


@pytest.mark.slow
def test_zoo_train_then_load_as_a_controller_then_record_video(tmp_path):
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "OMP_NUM_THREADS": "1"}
    common = ["--algo", "sac", "--env", "frictiongym/M220-ReversalTracking-v1", "-f", str(tmp_path / "logs")]
    zoo = str(ROOT / "scripts" / "zoo.py")
    train = [
        "--gym-packages",
        "frictiongym.envs",
        "--conf-file",
        str(ZOO_FILE),
        "-n",
        "300",
        "--eval-freq",
        "200",  # evaluation on: the zoo's evaluation env is built from the id alone
        "--eval-episodes",
        "1",
    ]
    _run("-m", "rl_zoo3.train", *common, *train, "--seed", "1", env=env)
    run = zoo_run(tmp_path / "logs", "sac", "frictiongym/M220-ReversalTracking-v1")
    assert "scenario" not in zoo_env_kwargs(run)  # the id carries it
    policy = zoo_policy(run, "sac", trust_pickle=True)
    assert policy.base.name == "CoulombViscousFF" and policy.alpha == 0.1
    from frictiongym.envs.scenario import load_scenario

    assert policy.why_not(load_scenario("m220_reversal_tracking")) is None
    assert policy.why_not(load_scenario("m220_regulation")) is not None  # another observation
    _run(zoo, "record_video", *common, "-n", "20", "-o", str(tmp_path / "videos"), env=env)
    [video] = list((tmp_path / "videos").glob("*.mp4"))
    assert video.stat().st_size > 1000
    out = _run(zoo, "validate", *common, "--episodes", "1", "--trust-pickle", env=env)
    assert "best classical" in out and "zoo agent" in out
