"""The envs as Gymnasium's and SB3's own machinery uses them: make_vec's default mode against its sync
mode, episode lengths in the specs, infos that compare equal to themselves, copies that step on, the
SB3 adapter's per-index calls, the passive checker, Path scenarios, ranges checked only when used."""

from __future__ import annotations

import copy
import json
import pickle
import re
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence

import frictiongym.envs  # registers the ids
from frictiongym.envs import ENV_IDS, scenario_env_id
from frictiongym.envs.config import ConfigError, configs_dir, scenario_names
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.vector import ServoVectorEnv, make_sb3_vec_env

KANG = "frictiongym/KangRobot-v1"
ROOT = Path(__file__).resolve().parents[1]
IDS = list(ENV_IDS)


def _rollout(venv, steps: int, seed: int = 7) -> list:
    """Every output of reset and `steps` steps with actions drawn from one generator."""
    rng = np.random.default_rng(0)
    out = [venv.reset(seed=seed)]
    for _ in range(steps):
        out.append(venv.step(rng.uniform(-1, 1, (venv.num_envs, 1)).astype(np.float32)))
    return out


@pytest.mark.parametrize(
    "kwargs",
    [
        {"scenario": "kang_regulation", "episode_s": 0.1, "randomize": True},  # 5 steps: several autoresets
        {"scenario": "kang_ramp", "max_episode_steps": 4, "randomize": True},  # a limit below the scenario
        {"scenario": "m220_reversal_tracking_hard", "episode_s": 0.03, "ground_truth_in_info": True},
    ],
)
def test_vector_entry_point_equals_sync_vector_env_bit_for_bit(kwargs):
    plant = load_scenario(kwargs["scenario"]).spec.name
    env_id = frictiongym.envs.env_id(plant)
    if load_scenario(kwargs["scenario"]).episode_steps > gym.spec(env_id).max_episode_steps:
        env_id = frictiongym.envs.scenario_env_id(kwargs["scenario"])  # longer than the plant id's limit
    batched = gym.make_vec(env_id, num_envs=3, **kwargs)
    sync = gym.make_vec(env_id, num_envs=3, vectorization_mode="sync", **kwargs)
    assert isinstance(batched, ServoVectorEnv)
    a, b = _rollout(batched, 14), _rollout(sync, 14)
    for k, (x, y) in enumerate(zip(a, b, strict=True)):
        assert data_equivalence(x, y, exact=True), f"output {k} differs"
    infos = [step[-1] for step in a[1:]]
    assert any("params" in i for i in infos)  # an autoreset step carries the new episode's reset info
    if "max_episode_steps" not in kwargs:
        assert any("episode_metrics" in i for i in infos)
    else:  # a TimeLimit's truncation is not the scenario's end: no metrics, as under gym.make
        assert all("episode_metrics" not in i for i in infos)
        assert a[4][3].all()


def test_vector_entry_point_takes_make_vec_arguments_and_refuses_another_plant():
    v = gym.make_vec(KANG, num_envs=2, render_mode="rgb_array", max_episode_steps=5)
    assert v.render_mode == "rgb_array" and v.max_episode_steps == 5
    with pytest.raises(ValueError, match="is for plant 'm220', not 'kang_robot'"):
        gym.make_vec(KANG, num_envs=2, scenario="m220_regulation")
    with pytest.raises(ValueError, match="is for plant 'm220', not 'kang_robot'"):
        gym.make(KANG, scenario="m220_regulation")
    with pytest.raises(ConfigError, match="max_episode_steps"):
        ServoVectorEnv("kang_regulation", 2, max_episode_steps=0)


@pytest.mark.parametrize("env_id", IDS)
def test_a_plant_id_ends_its_episode_where_its_chosen_scenario_does(env_id):
    """A per-plant id's max_episode_steps is its default scenario's length; a scenario= whose episode is
    shorter ends where that scenario does, single and vector, with the episode's metrics; a longer one is
    refused in one line naming its own id (the TimeLimit would cut it short)."""
    entry = frictiongym.envs._env_class(ENV_IDS[env_id][0])
    default = load_scenario(entry.default_scenario).episode_steps
    assert gym.spec(env_id).max_episode_steps == default
    lengths = {n: load_scenario(n).episode_steps for n in _plant_scenarios(entry.plant)}
    shorter = [n for n, k in lengths.items() if k < default]
    other, episode_s = (shorter[0], None) if shorter else (entry.default_scenario, 0.5 * default * 0.001)
    if episode_s is not None:  # no shorter scenario: the default one, shortened
        episode_s = 0.5 * default * load_scenario(other).control_period
    env = gym.make(env_id, scenario=other, episode_s=episode_s)
    steps = env.unwrapped.scenario.episode_steps
    assert steps < default
    env.reset(seed=0)
    for k in range(1, steps + 1):
        *_, term, trunc, info = env.step(np.zeros(1, np.float32))
        assert trunc == (k == steps) and not term
    assert "episode_metrics" in info
    v = gym.make_vec(env_id, num_envs=2, scenario=other, episode_s=episode_s)
    v.reset(seed=0)
    for k in range(1, steps + 1):
        *_, term, trunc, _ = v.step(np.zeros((2, 1), np.float32))
        assert (trunc == (k == steps)).all() and not term.any()
    longer = next((n for n, k in lengths.items() if k > default), None)
    if longer is not None:
        with pytest.raises(ValueError, match=re.escape(f"use gym.make({scenario_env_id(longer)!r}")):
            gym.make(env_id, scenario=longer)
    assert gym.spec(env_id).max_episode_steps == default  # the registry is unchanged by the calls


class _Zero:
    """A policy for SB3's evaluate_policy: the zero action."""

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.zeros((len(obs), 1), np.float32), state


@pytest.mark.parametrize("env_id", sorted(i for i in gym.registry if i.startswith("frictiongym/")))
def test_every_id_works_with_time_wrappers_and_the_zoos_evaluation(env_id):
    """TimeLimit, TimeAwareObservation and rl-zoo's evaluation (its create_test_env, then SB3's
    evaluate_policy) on every registered id: each carries max_episode_steps, its scenario's length."""
    env = gym.make(env_id)
    steps = env.unwrapped.scenario.episode_steps
    assert env.spec.max_episode_steps == gym.spec(env_id).max_episode_steps == steps
    timed = gym.wrappers.TimeAwareObservation(gym.make(env_id, max_episode_steps=3))
    obs, _ = timed.reset(seed=0)
    assert obs[-1] == 0.0  # the elapsed steps
    flags = [timed.step(np.zeros(1, np.float32))[3] for _ in range(3)]
    assert flags == [False, False, True]
    rl_zoo3 = pytest.importorskip("rl_zoo3.utils")
    from stable_baselines3.common.evaluation import evaluate_policy

    short = {"episode_s": 3 * env.unwrapped.scenario.control_period}  # 3 periods
    venv = rl_zoo3.create_test_env(env_id, n_envs=1, should_render=False, hyperparams={}, env_kwargs=short)
    rewards, lengths = evaluate_policy(_Zero(), venv, n_eval_episodes=2, return_episode_rewards=True)
    assert lengths == [3, 3] and all(np.isfinite(rewards))


@pytest.mark.parametrize("scenario", scenario_names())
def test_every_scenario_has_its_own_id_with_its_length(scenario):
    """frictiongym/<Plant>-<Scenario>-v1 makes the scenario on its plant's env, and its spec's
    max_episode_steps is the scenario's length (for gym.make's TimeLimit and gym.make_vec alike)."""
    sc = load_scenario(scenario)
    id_ = scenario_env_id(scenario)
    assert frictiongym.envs.SCENARIO_IDS[id_] == scenario
    env = gym.make(id_)
    assert env.unwrapped.scenario.name == scenario and env.unwrapped.plant == sc.spec.name
    assert gym.spec(id_).max_episode_steps == env.spec.max_episode_steps == sc.episode_steps
    assert gym.make_vec(id_, num_envs=2).max_episode_steps == sc.episode_steps


def test_the_ids_are_listed_by_the_command_and_in_the_docs():
    """`frictiongym list --markdown` prints every registered id once, and docs/envs.md holds that table."""
    from conftest import load_script

    listing = load_script("list_envs")
    table = listing.markdown()
    ids = [line.split("|")[1].strip().strip("`") for line in table.splitlines()[2:]]
    assert sorted(ids) == sorted([*ENV_IDS, *frictiongym.envs.SCENARIO_IDS])
    assert table in (ROOT / "docs" / "envs.md").read_text()


def _plant_scenarios(plant: str) -> list[str]:
    return [n for n in scenario_names() if load_scenario(n).spec.name == plant]


def test_time_wrappers_agree_with_the_env():
    env = gym.wrappers.TimeAwareObservation(gym.make("frictiongym/KangRobot-Regulation-v1"))  # needs the
    # spec's max_episode_steps: a per-scenario id
    obs, _ = env.reset(seed=1)
    assert obs[-1] == 0.0
    short = gym.make(KANG, max_episode_steps=3)
    short.reset(seed=1)
    flags = [short.step(np.zeros(1, np.float32))[3] for _ in range(3)]
    assert flags == [False, False, True] and short.spec.max_episode_steps == 3


def test_infos_compare_equal_to_themselves_at_episode_ends():
    env = gym.make(KANG, scenario="kang_regulation", episode_s=0.1)  # never settles in 5 steps
    env.reset(seed=2)
    for _ in range(5):
        *_, info = env.step(np.zeros(1, np.float32))
    assert "settling_time" not in info["episode_metrics"] and "iae" in info["episode_metrics"]
    assert data_equivalence(info, copy.deepcopy(info))
    assert all(v == v for v in info["episode_metrics"].values())  # no nan


def test_undefined_metrics_stay_nan_in_results():
    """The evaluation loop keeps every metric (n/a in the CSV), while info leaves the undefined out."""
    from frictiongym.agents.evaluation.evaluate import run_episode
    from frictiongym.agents.registry import make
    from frictiongym.envs.suites import Episode

    r = run_episode(make("Zero"), Episode("kang_regulation", 3, True), episode_s=0.1)
    assert np.isnan(r.metrics["settling_time"]) and np.isnan(r.metrics["reversal_peak_error"])


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copy_after_reset_steps_on_from_the_same_state(how):
    env = gym.make("frictiongym/M220-ReversalTrackingHard-v1", randomize=True)
    env.reset(seed=4)
    rng = np.random.default_rng(1)
    for _ in range(50):
        env.step(rng.uniform(-1, 1, 1).astype(np.float32))
    twin = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    for _ in range(100):
        a = rng.uniform(-1, 1, 1).astype(np.float32)
        assert data_equivalence(env.step(a), twin.step(a), exact=True)
    assert data_equivalence(env.reset(), twin.reset(), exact=True)  # the same generator, too
    assert data_equivalence(env.unwrapped.ground_truth(), twin.unwrapped.ground_truth(), exact=True)


def test_a_copy_before_reset_must_be_reset():
    twin = copy.deepcopy(gym.make(KANG))
    with pytest.raises(gym.error.ResetNeeded):
        twin.step(np.zeros(1, np.float32))


def test_sb3_adapter_follows_sb3_index_semantics():
    venv = make_sb3_vec_env("kang_regulation", num_envs=3, nthread=1, randomize=True)
    venv.reset()
    venv.step(np.zeros((3, 1)))
    [one] = venv.env_method("ground_truth", indices=[1])
    assert one["qpos"].shape == (1,)
    assert np.array_equal(one["qpos"], venv.venv.ground_truth()["qpos"][1])
    assert venv.env_method("params") == venv.venv.params()
    assert len({p["inertia"] for p in venv.env_method("params", indices=[0, 1, 2])}) == 3  # three draws
    venv.set_attr("foo", 1, indices=[0])
    venv.set_attr("foo", 2, indices=2)
    assert venv.get_attr("foo", indices=[0, 2]) == [1, 2]
    with pytest.raises(AttributeError):
        venv.get_attr("foo", indices=1)
    assert venv.get_attr("observation_space") == [venv.observation_space] * 3
    assert venv.env_is_wrapped(gym.Wrapper, indices=[0, 1]) == [False, False]


@pytest.mark.parametrize("env_id", IDS)
def test_passive_env_checker_is_on_and_silent(env_id):
    env = gym.make(env_id)
    wrappers = []
    while isinstance(env, gym.Wrapper):
        wrappers.append(type(env))
        env = env.env
    assert gym.wrappers.PassiveEnvChecker in wrappers
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        e = gym.make(env_id)
        e.reset(seed=0)
        e.step(e.action_space.sample())


def test_path_scenario_serialises_in_the_spec():
    path = configs_dir() / "scenarios" / "kang_regulation_hard.yaml"
    env = gym.make(KANG, scenario=path)
    spec = json.loads(env.spec.to_json())
    assert spec["kwargs"]["scenario"] == str(path) and spec["max_episode_steps"] == 500
    again = gym.make(KANG, scenario=env.spec.kwargs["scenario"]).unwrapped.scenario
    assert again.name == "kang_regulation_hard" and again.episode_steps == 500
    assert gym.make_vec(KANG, num_envs=2, scenario=path).spec.to_json()


def test_randomisation_ranges_are_checked_only_when_used():
    # σ0 = 1.8e5 N·m/rad passes the integrator check h·sqrt(σ0/J) <= 0.2 (0.19), its x1.7 draw does not
    near = {"plant_overrides": {"friction": {"sigma0_nm_per_rad": 1.8e5}}}
    with pytest.raises(ConfigError, match=r"randomization.sigma0_scale: the draw at 1.7"):
        load_scenario("kang_regulation", near, randomize=True)
    env = gym.make(KANG, overrides=near, randomize=False)  # the range plays no part: accepted
    env.reset(seed=0)
    with pytest.raises(ConfigError, match="sigma0"):  # a pinned value is still checked where it is used
        env.reset(seed=0, options={"params": {"sigma0_scale": 1.7}})
