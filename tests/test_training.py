"""Training pipeline (agents/training/, scripts/train.py): configs, every algorithm, save/load, resume,
the residual's zero start, asymmetric actor-critic, registry entries."""

from __future__ import annotations

import csv
import dataclasses
import importlib.util
import itertools
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")
pytest.importorskip("sb3_contrib")
from conftest import HYPER, SCENARIO, load_script, write_config

from frictiongym.agents import registry
from frictiongym.agents.base import EpisodeContext
from frictiongym.agents.classical import SpeedScheduled, SpeedScheduledSettings
from frictiongym.agents.classical.scheduled import GATES
from frictiongym.agents.evaluation.engine import plan
from frictiongym.agents.evaluation.evaluate import EnvCache, run_episode
from frictiongym.agents.learned.folder import POLICY, SEAL, UntrustedModel
from frictiongym.agents.learned.manifest import MANIFEST
from frictiongym.agents.learned.policy import LearnedPolicy, residual_action
from frictiongym.agents.settings import knowledge_defaults
from frictiongym.agents.training import (
    RECORDS,
    NothingSelected,
    ResidualEnv,
    TrainingRun,
    build_model,
    export_model,
    load_config,
    make_training_env,
    run_config_with,
    sb3_schedule,
    train_many,
    training_env_kwargs,
    validation_episodes,
)
from frictiongym.agents.training.vec_env import SEEDS_PER_RUN, TRAINING_SEEDS, episode_seed
from frictiongym.envs.config import ConfigError
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import load_suite

ROOT = Path(__file__).parents[1]


def latest(folder: Path) -> Path:
    """The complete checkpoint set a run's checkpoint/LATEST names."""
    return folder / "checkpoint" / (folder / "checkpoint" / "LATEST").read_text().strip()


def train(
    tmp_path: Path, algo: str, out: str = "run", resume: bool = False, parallel: bool = False, **kw
) -> tuple[dict, Path]:
    (cfg,) = load_config(write_config(tmp_path, algo, **kw))
    folder = tmp_path / out
    run = TrainingRun(cfg, 0, folder, "pytest", progress=False, parallel_validation=parallel)
    return run.train(resume), folder


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["SAC", "TD3", "TQC", "CrossQ", "PPO", "RecurrentPPO"])
@pytest.mark.parametrize("n_envs", [1, 2])
def test_every_algorithm_trains_and_its_saved_model_acts_identically(tmp_path, algo, n_envs):
    """A few hundred steps per algorithm, on one env and on two batched ones; the model folder loads
    through the registry and reproduces the validation evaluation that selected it, to the last bit
    (same actions on the same episodes)."""
    manifest, folder = train(tmp_path, algo, n_envs=n_envs)
    assert manifest["algorithm"] == algo and manifest["steps"] >= 256 and manifest["base_controller"] == "PID"
    assert manifest["config"]["n_envs"] == n_envs
    safe = algo not in ("CrossQ", "RecurrentPPO")  # batch renormalisation, an LSTM: no layer chain
    for f in (POLICY if safe else "model.zip", "manifest.yaml", "validation.csv", "training_curve.png"):
        assert (folder / f).is_file(), f
    if not safe:  # such a folder holds SB3's zip: refused, naming the conversion, never unpickled
        with pytest.raises(UntrustedModel, match="convert-model"):
            registry.make(manifest["name"], (str(folder),))
        return
    c = registry.make(manifest["name"], (str(folder),))
    envs = EnvCache()
    episodes = validation_episodes(SCENARIO)[:2]
    main = [run_episode(c, e, envs=envs).metrics[manifest["validation"]["main_metric"]] for e in episodes]
    assert np.mean(main) == manifest["validation"]["value"]


@pytest.mark.slow
def test_selection_on_more_scenarios_keeps_the_model_that_beats_the_most(tmp_path):
    """With validation.scenarios, every evaluation is scored on each scenario's validation episodes
    against that scenario's best classical baseline by the leaderboard's rule (paired interval, effort,
    limit cycle); the kept model is the row with the most scenarios beaten, then the lowest geometric
    mean of metric / baseline, and the manifest says so. The kept model, loaded through the registry,
    gives the recorded main metric on the scenario's episodes."""
    manifest, folder = train(tmp_path, "SAC", validation={"scenarios": ["flexible_speed_reversal"]})
    rows = list(csv.DictReader((folder / "validation.csv").open()))
    assert len(rows) >= 2 and all(0 <= float(r["won"]) <= 2 and float(r["ratio"]) > 0 for r in rows)
    key = [(float(r["won"]), -float(r["ratio"])) for r in rows]
    best = rows[key.index(max(key))]  # the first of equals: a later row must be strictly better
    sel = manifest["validation"]["selection"]
    assert manifest["selected_step"] == int(best["step"])
    assert sel["scenarios"] == [SCENARIO, "flexible_speed_reversal"]
    assert (sel["won"], sel["ratio"]) == (int(float(best["won"])), float(best["ratio"]))
    assert set(sel["best_classical"]) == set(sel["scenarios"])
    c = registry.make(manifest["name"], (str(folder),))
    main = [
        run_episode(c, e).metrics[manifest["validation"]["main_metric"]]
        for e in validation_episodes(SCENARIO)[:2]
    ]
    assert np.mean(main) == manifest["validation"]["value"]


@pytest.mark.slow
def test_a_run_that_selects_nothing_is_reported_and_the_other_runs_go_on(tmp_path):
    """A run none of whose validation evaluations meets the effort rule (here: at most 1e-9 x the
    baseline's effort) selects no model; train_many returns its NothingSelected, naming the rule and the
    rows, in its place among the other runs' manifests instead of stopping them."""
    ok = write_config(tmp_path, "SAC")
    strict = yaml.safe_load(ok.read_text())
    strict["name"] = "Strict"
    strict["defaults"]["validation"]["max_effort_ratio"] = 1e-9
    (tmp_path / "strict.yaml").write_text(yaml.safe_dump(strict))
    cfgs = [*load_config(tmp_path / "strict.yaml"), *load_config(ok)]
    first, second = train_many(cfgs, [0], tmp_path / "runs", False, 1)
    assert isinstance(first, NothingSelected)
    assert "Strict-flexible_speed_step-s0: no validation evaluation had effort_rms <= 1e-09 x" in str(first)
    assert "nothing to select" in str(first) and "validation.csv" in str(first)
    assert second["name"] == "SmokeSAC-flexible_speed_step-s0" and second["selected_step"] > 0


@pytest.mark.slow
def test_resume_continues_the_same_run(tmp_path, monkeypatch):
    """--resume keeps the history, the step count, the training-seed schedule and the provenance of the
    code the run started with, and trains to the new total; without --resume a finished folder is
    refused."""
    from frictiongym.agents.training import run as run_module

    monkeypatch.setattr(run_module, "provenance", lambda: {"package_version": "0", "git_commit": "start"})
    first, folder = train(tmp_path, "SAC", steps=256, parallel=True)
    assert first["git_commit"] == "start"
    monkeypatch.setattr(run_module, "provenance", lambda: {"package_version": "0", "git_commit": "later"})
    episodes_before = json.loads((latest(folder) / "state.json").read_text())["episodes"]
    assert episodes_before == [2]  # 256 steps of 250-step episodes: the second episode is running
    with pytest.raises(FileExistsError, match="finished run"):
        train(tmp_path, "SAC", steps=512)
    second, _ = train(tmp_path, "SAC", steps=512, resume=True, parallel=True)
    assert second["steps"] == 512 and second["wall_time_s"] >= first["wall_time_s"]
    assert second["git_commit"] == "start"  # the manifest names the commit the run started at
    steps = [int(r.split(",")[0]) for r in (folder / "validation.csv").read_text().splitlines()[1:]]
    assert steps[:2] == [128, 256] and steps[-1] == 512
    state = json.loads((latest(folder) / "state.json").read_text())
    # the resumed run starts a fresh episode (SB3 resets the env after loading) with the schedule's next
    # seed: episodes 3 (steps 257-506) and 4; a restarted schedule would have counted 2
    assert state["episodes"] == [4]


@pytest.mark.slow
def test_an_evaluation_running_at_the_stop_is_rerun_on_resume(tmp_path):
    """A checkpoint written while its own model's evaluation was still running (the state lists it as
    pending) resumes by evaluating the checkpoint's model: the same row as the one it would have had."""
    _, folder = train(tmp_path, "SAC", steps=300, parallel=True)  # evaluated at 128, 256 and its end
    path = latest(folder) / "state.json"
    state = json.loads(path.read_text())
    last = state["history"].pop()  # as if the run had stopped before this evaluation came back
    state["pending"] = [{k: last[k] for k in ("step", "gradient_steps", "wall_s", "train_s")}]
    path.write_text(json.dumps(state))
    (folder / "manifest.yaml").unlink()
    train(tmp_path, "SAC", steps=384, resume=True)
    rows = list(csv.DictReader((folder / "validation.csv").open()))
    assert [int(r["step"]) for r in rows] == [128, 256, 300, 384]
    assert float(rows[2]["main"]) == last["main"] and float(rows[2]["effort_rms"]) == last["effort_rms"]


@pytest.mark.slow
def test_validation_beside_training_gives_the_same_run_as_validation_in_turn(tmp_path):
    """Validation in the worker process (on the other core) and in the training process record the same
    rows and select the same model; training itself is not touched by either."""

    (cfg,) = load_config(write_config(tmp_path, "SAC", steps=384))
    runs = {}
    for parallel in (True, False):
        folder = tmp_path / f"parallel{parallel}"
        run = TrainingRun(cfg, 0, folder, "pytest", progress=False, parallel_validation=parallel)
        manifest = run.train()
        runs[parallel] = (run.history, manifest, (folder / POLICY).read_bytes())
    keys = ("step", "gradient_steps", "main", "effort_rms", "admissible")
    (h1, m1, p1), (h2, m2, p2) = runs[True], runs[False]
    assert [[r[k] for k in keys] for r in h1] == [[r[k] for k in keys] for r in h2]
    assert [r["step"] for r in h1] == [128, 256, 384]
    assert m1["selected_step"] == m2["selected_step"] and p1 == p2


def test_a_residual_with_zero_output_is_bit_identical_to_its_base(tmp_path):
    """The residual starts at exactly zero output (zeroed last layer): its episodes equal the base
    controller's, bit for bit, for every algorithm family."""
    base = registry.make("PID")
    episode = validation_episodes(SCENARIO)[0]
    ref = run_episode(base, episode, keep_log=True)
    for algo in ("SAC", "TD3", "CrossQ", "PPO"):
        (cfg,) = load_config(write_config(tmp_path, algo))
        model = build_model(cfg, make_training_env(cfg, 0), 0, None)
        c = LearnedPolicy(model, inputs=cfg.inputs, base=registry.make("PID"), alpha=cfg.alpha)
        got = run_episode(c, episode, keep_log=True)
        assert got.metrics == ref.metrics, algo
        for k in ref.log:
            np.testing.assert_array_equal(got.log[k], ref.log[k])


def test_a_lin_learning_rate_decays_linearly_to_zero_over_the_run(tmp_path):
    """learning_rate "lin_<rate>" (rl-zoo3's spelling): the optimiser's rate is <rate> at the start, half
    of it halfway through total_timesteps and 0 at the end (SB3 passes the progress remaining, 1 -> 0);
    the manifest keeps the string as written."""
    hyper = {**HYPER["SAC"], "learning_rate": "lin_2e-3"}
    path = write_config(tmp_path, "SAC", hyperparams=hyper)
    (cfg,) = load_config(path)
    assert cfg.hyperparams["learning_rate"] == "lin_2e-3"
    model = build_model(cfg, make_training_env(cfg, 0), 0, None)
    assert [model.lr_schedule(p) for p in (1.0, 0.5, 0.0)] == pytest.approx([2e-3, 1e-3, 0.0])
    from stable_baselines3.common.callbacks import BaseCallback

    class Rates(BaseCallback):
        def _on_step(self) -> bool:
            seen.append(self.model.actor.optimizer.param_groups[0]["lr"])
            return True

    seen: list[float] = []
    model.learn(cfg.total_timesteps, callback=Rates())  # SB3 sets the rate before each update
    assert seen[1] == pytest.approx(2e-3, rel=0.01) and seen[-1] < 0.01 * 2e-3
    assert all(b <= a for a, b in itertools.pairwise(seen))


@pytest.mark.parametrize(
    "bad", ["lin_", "lin_x", "lin_-1e-3", "lin_inf", "lin_nan", "cos_3e-4", -1e-3, True, math.nan, math.inf]
)
def test_a_bad_learning_rate_is_refused_by_name(tmp_path, bad):
    path = write_config(tmp_path, "SAC", hyperparams={**HYPER["SAC"], "learning_rate": bad})
    with pytest.raises(ConfigError, match="learning_rate"):
        load_config(path)


def test_training_env_uses_its_own_seeds_and_the_base_in_the_loop(tmp_path):
    """Training episodes run on TRAINING_SEEDS + s·SEEDS_PER_RUN + k·n_envs + i, never a suite's seeds;
    the observation ends with the env's base action."""
    (cfg,) = load_config(write_config(tmp_path, "SAC", n_envs=3))
    venv = make_training_env(cfg, 3)
    suites = {e.seed for s in ("paper", "default", "validation", "test") for e in load_suite(s)}
    obs = venv.reset()
    for k in range(3):
        assert list(venv.seeds) == [TRAINING_SEEDS + 3 * SEEDS_PER_RUN + k * 3 + i for i in range(3)]
        assert not set(venv.seeds) & suites
        if k < 2:
            obs = venv.reset()
    assert venv.get_attr("episodes") == [3, 3, 3]
    sc = venv.scenario
    for i in range(3):
        pid = registry.make("PID")
        pid.reset(EpisodeContext(sc, sc.spec, knowledge_defaults()))
        assert obs[i, -1] == pid.act(obs[i, :-1])[0]
    assert venv.observation_space.shape[0] == venv.core.obs_dim + 1


class _Scheduled:
    """Test helper: a single training env (ResidualEnv over ServoEnv) on env i's seed schedule."""

    def __init__(self, env, i: int, n: int):
        self.env, self.i, self.n, self.k = env, i, n, 0

    def __getattr__(self, name):
        return getattr(self.env, name)

    def reset(self, *, seed=None, options=None):
        self.k += 1
        return self.env.reset(seed=episode_seed(0, self.i, self.k - 1, self.n))


def _single_env_form(cfg):
    """SB3's DummyVecEnv over n single envs as the batched training env's docstring says it behaves."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv

    from frictiongym.envs.servo_env import ServoEnv

    kw = training_env_kwargs(cfg)

    def one(i):
        base = registry.make(cfg.base)
        env = ResidualEnv(
            ServoEnv(cfg.scenario, **kw),
            base,
            cfg.alpha,
            cfg.inputs.differences,
            smoothness=cfg.residual_smoothness,
        )
        return type("Scheduled", (_Scheduled, gym.Wrapper), {})(env, i, cfg.n_envs)

    return DummyVecEnv([lambda i=i: one(i) for i in range(cfg.n_envs)])


@pytest.mark.parametrize(("differences", "smoothness"), [(False, 0.0), (True, 0.0), (False, 50.0)])
def test_batched_training_env_equals_sb3_dummy_vec_env_of_single_envs(tmp_path, differences, smoothness):
    """The batched training env gives DummyVecEnv's observations, rewards (float32), dones and terminal
    observations over single residual envs, bit for bit, across episode ends, for float32 actions and
    the float64 ones exploration noise makes; and SAC trained on either learns the same network. With
    the differences inputs too (two more columns, the same in both forms), and with the residual's own
    smoothness penalty."""
    import torch

    residual = {"base": "PID", "alpha": 0.1, "smoothness": smoothness}
    obs = {"differences": differences}
    (cfg,) = load_config(write_config(tmp_path, "SAC", n_envs=3, observation=obs, residual=residual))
    assert (cfg.inputs.differences, cfg.residual_smoothness) == (differences, smoothness)
    ref, new = _single_env_form(cfg), make_training_env(cfg, 0)
    assert new.observation_space.shape[0] == new.core.obs_dim + 1 + 2 * differences
    assert np.array_equal(ref.reset(), new.reset())
    rng = np.random.default_rng(0)
    ends = 0
    for t in range(300):  # the 250-step episodes end at t = 249
        a = rng.uniform(-1.2, 1.2, (3, 1)).astype(np.float32 if t % 2 else np.float64)
        (o1, r1, d1, i1), (o2, r2, d2, i2) = ref.step(a), new.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
        assert r1.dtype == r2.dtype == np.float32
        for x, y in zip(i1, i2, strict=True):
            assert x["TimeLimit.truncated"] == y["TimeLimit.truncated"]
            assert ("terminal_observation" in x) == ("terminal_observation" in y)
            if "terminal_observation" in x:
                ends += 1
                assert np.array_equal(x["terminal_observation"], y["terminal_observation"])
    assert ends == 3
    models = []
    for venv in (_single_env_form(cfg), make_training_env(cfg, 0)):
        model = build_model(cfg, venv, 0, None)
        model.learn(300)
        models.append(torch.nn.utils.parameters_to_vector(model.policy.parameters()))
    assert torch.equal(*models)


def test_the_residual_smoothness_prices_the_residuals_change_and_nothing_else(tmp_path):
    """residual.smoothness w subtracts w·(a - a_prev)² from the reward, a the policy's action clipped to
    [-1, 1] and a_prev 0 at each episode's start (where a residual starts), and changes nothing else: the
    same actions give the same observations and dones as without it. A held residual costs nothing after
    its first step; an alternating one 4·w·a² per step."""
    w = 50.0
    envs = []
    for smoothness in (0.0, w):
        residual = {"base": "PID", "alpha": 0.1, "smoothness": smoothness}
        (cfg,) = load_config(write_config(tmp_path, "SAC", n_envs=2, residual=residual))
        envs.append(make_training_env(cfg, 0))
    plain, priced = envs
    assert np.array_equal(plain.reset(), priced.reset())
    a_prev, ends = np.zeros((2, 1)), 0
    for t in range(260):  # the 250-step episodes end at t = 249
        held = 0.5 if t < 100 else 0.5 * (-1) ** t
        a = np.array([[held], [1.7 if t % 3 else -0.2]], dtype=np.float32)  # 1.7: clipped to 1
        (o1, r1, d1, _), (o2, r2, d2, _) = plain.step(a), priced.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(d1, d2)
        clipped = np.clip(a.astype(np.float64), -1.0, 1.0)
        expected = w * ((clipped - a_prev) ** 2).ravel()
        np.testing.assert_allclose(r1 - r2, expected, rtol=1e-5, atol=1e-4)
        if 1 <= t < 100:
            assert r1[0] == r2[0]  # held: free
        if t >= 101 and t != 250:
            assert r1[0] - r2[0] == pytest.approx(4 * w * 0.25, rel=1e-5)
        a_prev = np.where(d1[:, None], 0.0, clipped)  # a new episode starts from a_prev = 0
        ends += int(d1.sum())
    assert ends == 2


@pytest.mark.parametrize(
    ("ratio", "n_envs", "schedule"),
    [(1.0, 1, (1, 1)), (0.125, 64, (1, 8)), (0.25, 2, (2, 1)), (2.0, 16, (1, 32))],
)
def test_update_to_data_sets_sb3s_schedule(ratio, n_envs, schedule):
    """update_to_data gradient steps per env step: (train_freq in vector steps, gradient_steps)."""
    assert sb3_schedule(ratio, n_envs) == schedule
    train_freq, gradient_steps = schedule
    assert gradient_steps / (train_freq * n_envs) == ratio


def test_asymmetric_actor_ignores_the_privileged_block(tmp_path):
    """With privileged_critic the critic reads ground truth, the actor does not: changing the privileged
    entries leaves the action unchanged, changing a sensor entry does not (on batched training envs, whose
    observations carry the privileged block)."""
    (cfg,) = load_config(write_config(tmp_path, "SAC", n_envs=2, observation={"privileged_critic": True}))
    venv = make_training_env(cfg, 0)
    model = build_model(cfg, venv, 0, None)
    model.learn(64)  # the critic trains on the batched envs' privileged observations
    import torch

    with torch.no_grad():  # give the actor a non-zero output first
        for p in model.actor.parameters():
            p.add_(0.1)
    sc = EnvCache().scenario(validation_episodes(SCENARIO)[0])
    priv = cfg.inputs.actor_indices(sc)
    hidden = [i for i in range(cfg.inputs.size(sc)) if i not in priv]
    assert hidden, "the privileged block is empty"
    x = np.linspace(-0.5, 0.5, cfg.inputs.size(sc)).astype(np.float32)
    y = x.copy()
    y[hidden] += 3.0
    a = model.predict(x, deterministic=True)[0]
    assert np.array_equal(a, model.predict(y, deterministic=True)[0])
    z = x.copy()
    z[priv[0]] += 3.0
    assert not np.array_equal(a, model.predict(z, deterministic=True)[0])


@pytest.mark.slow  # trains
@pytest.mark.parametrize("algo", ["SAC", "PPO"])
def test_an_exported_model_is_the_safe_folder_and_acts_as_the_run_s(tmp_path, algo):
    """export_model copies the run's model folder (manifest, policy.safetensors, records; no checkpoint,
    no logs, no pickle) and the exported folder gives the run's episode to the last bit through the
    registry."""
    manifest, run = train(tmp_path, algo)
    folder = export_model(run, tmp_path / "committed")
    assert sorted(p.name for p in folder.iterdir()) == sorted([MANIFEST, POLICY, SEAL, *RECORDS])
    assert (folder / SEAL).read_text() == (run / SEAL).read_text()  # the run's folder is sealed as it
    episode = validation_episodes(SCENARIO)[0]
    make = registry.make
    run_row, exported_row = (run_episode(make(manifest["name"], (str(f),)), episode) for f in (run, folder))
    np.testing.assert_equal(exported_row.metrics, run_row.metrics)  # NaN metrics (e.g. no settling) equal


def test_registry_skips_scenarios_with_another_observation(tmp_path):
    """A model trained on the flexible servo is planned on its scenarios and skipped on others, with the
    reason named (the plant, checked before the observation shape)."""
    manifest, run = train(tmp_path, "PPO")
    export_model(run, tmp_path / "committed")
    eps = [e for e in load_suite("validation") if e.scenario in (SCENARIO, "kang_regulation")][::5]
    jobs, skipped = plan([manifest["name"]], eps, (str(tmp_path / "committed"),))
    assert {j.scenario for j in jobs} == {SCENARIO}
    assert [s[1] for s in skipped] == ["kang_regulation"]
    assert skipped[0][2] == "trained for plants ['flexible_servo'], the scenario's plant is kang_robot"


@pytest.mark.parametrize(
    ("entry", "field"),
    [
        ({"hyperparams": {"learning_rat": 1e-3}}, "learning_rat"),
        ({"residual": {"base": "PIDD"}}, "residual.base"),
        ({"randomization": {"friction_scale": [0.5, 50]}}, "randomization.friction_scale"),
        ({"totl_timesteps": 5}, "totl_timesteps"),
        ({"hyperparams": {"learning_starts": 100}}, "learning_starts"),
        ({"n_envs": 16, "update_to_data": 0.3}, "update_to_data"),
        (
            {"update_to_data": 0.5, "hyperparams": {"learning_starts": 0, "gradient_steps": 2}},
            "gradient_steps",
        ),
        ({"validation": {"scenarios": ["flexible_chirp"]}}, r"validation\.scenarios.*held-out"),
        ({"validation": {"scenarios": ["kang_ramp"]}}, r"validation\.scenarios.*kang_robot"),
        ({"validation": {"scenarios": ["flexible_nope"]}}, r"validation\.scenarios"),
        ({"validation": {"scenarios": "flexible_drift"}}, r"validation\.scenarios.*list"),
        ({"residual": {"base": "PID", "smoothness": -1.0}}, r"residual\.smoothness"),
        ({"residual": {"base": None, "smoothness": 5.0}}, r"residual\.smoothness.*residual mode"),
    ],
)
def test_config_errors_name_the_field(tmp_path, entry, field):
    """Typos, unknown controllers, out-of-range randomisation, a random warm-up at full authority over a
    residual and selection scenarios that are held out, of another plant or unknown are errors naming the
    file and the field."""
    path = write_config(tmp_path, "SAC", **entry)
    with pytest.raises(ConfigError, match=field) as e:
        load_config(path)
    assert str(path) in str(e.value)


def test_the_absolute_tracking_term_reaches_the_training_env(tmp_path):
    """reward.tracking_abs in a training config is the training env's weight of |e/s| (the other weights
    stay the scenario's): from the same seed and state, with the same (zero) residual, every step's
    reward is lower by that term alone, w_a·|e/s| > 0 while the output is off its reference."""
    (off,) = load_config(write_config(tmp_path, "SAC"))
    (on,) = load_config(write_config(tmp_path, "SAC", reward={"tracking_abs": 5.0}))
    envs = [make_training_env(c, 0) for c in (off, on)]
    w = envs[1].core.sc.reward_weights
    assert w["tracking_abs"] == 5.0 and w["tracking"] == load_scenario(SCENARIO).reward_weights["tracking"]
    obs = [v.reset() for v in envs]
    assert np.array_equal(*obs)
    for _ in range(20):
        (o0, r0, *_), (o1, r1, *_) = (v.step(np.zeros((1, 1), dtype=np.float32)) for v in envs)
        assert np.array_equal(o0, o1) and r1[0] < r0[0]


def test_a_training_reference_override_reaches_the_training_envs_only(tmp_path):
    """reference: {...} replaces keys of the training scenario's random reference for the training envs
    (here holds only: the reference never moves from its start), while validation keeps the scenario's
    own episodes; a bad key, or a scenario without a random reference, is an error naming the field."""
    path = write_config(tmp_path, "SAC", reference={"segments": ["hold"], "segment_s": [5.0, 10.0]})
    path.write_text(path.read_text().replace(SCENARIO, "flexible_random"))
    (cfg,) = load_config(path)
    assert cfg.reference == {"segments": ["hold"], "segment_s": [5.0, 10.0]}
    venv = make_training_env(cfg, 0)
    assert venv.core.sc.reference.family.kinds == ("hold",)
    venv.reset()
    refs = [venv.core.ref[0, 0]]
    for _ in range(50):
        venv.step(np.zeros((1, 1), dtype=np.float32))
        refs.append(venv.core.ref[0, venv.core.k[0]])
    assert len(set(refs)) == 1  # a hold from the initial value
    run = TrainingRun(cfg, 0, tmp_path / "run", "pytest", progress=False)
    assert run.episodes == validation_episodes("flexible_random")[: cfg.eval_episodes]
    assert run.envs.scenario(run.episodes[0]).reference.family.kinds != ("hold",)
    bad = write_config(tmp_path, "SAC", reference={"segments": ["nope"]})
    bad.write_text(bad.read_text().replace(SCENARIO, "flexible_random"))
    with pytest.raises(ConfigError, match=r"flexible_random\.reference\.segments") as e:
        load_config(bad)
    assert str(bad) in str(e.value)
    with pytest.raises(ConfigError, match=r"reference.*only a random reference"):
        load_config(write_config(tmp_path, "SAC", reference={"segment_s": [1.0, 2.0]}))


def test_more_validation_episodes_than_the_suite_holds_is_an_error(tmp_path):
    """A run asking for more selection episodes than the validation suite has of a scenario stops before
    training with the field named, rather than selecting on fewer episodes than the config says."""
    n = len(validation_episodes(SCENARIO))
    (cfg,) = load_config(write_config(tmp_path, "SAC", validation={"episodes": n + 1}))
    with pytest.raises(ConfigError, match=rf"validation\.episodes.*{n + 1} asked.*has {n} of {SCENARIO}"):
        TrainingRun(cfg, 0, tmp_path / "run", "pytest", progress=False)
    (cfg,) = load_config(write_config(tmp_path, "SAC", validation={"episodes": n}))
    assert len(TrainingRun(cfg, 0, tmp_path / "run", "pytest", progress=False).episodes) == n


@pytest.mark.slow  # trains
def test_held_out_scenarios_and_suites_are_never_trained_or_selected_on(tmp_path):
    """A generalisation scenario is refused by the config loader (and so by scripts/train.py and the
    sweeps), and model selection refuses a held-out suite; a held-out scenario may not sit in another
    suite."""
    path = write_config(tmp_path, "SAC")
    path.write_text(path.read_text().replace(SCENARIO, "kang_chirp"))
    with pytest.raises(ConfigError, match=r"scenarios\.kang_chirp.*held-out") as e:
        load_config(path)
    assert str(path) in str(e.value)
    with pytest.raises(ConfigError, match="generalisation is held out"):
        validation_episodes("kang_chirp", "generalisation")
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts/train.py"), "--config", str(path), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode != 0 and "held-out" in proc.stderr and not (tmp_path / "SmokeSAC").exists()


def test_committed_configs_load():
    """Every training config in configs/agents/ is valid."""
    from frictiongym.agents.training import config_names

    names = config_names()
    assert "residual_sac" in names
    for name in names:
        assert load_config(name)


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["sbx.SAC", "sbx.CrossQ"])
def test_sbx_learners_start_at_their_base_and_reload_identically(tmp_path, algo):
    """The optional JAX learners (sbx extra): the residual starts at exactly its base controller (the
    flax mean layer zeroed), and the trained folder loads through the registry and reproduces the
    validation evaluation that selected it."""
    pytest.importorskip("sbx")
    (cfg,) = load_config(write_config(tmp_path, algo))
    episode = validation_episodes(SCENARIO)[0]
    model = build_model(cfg, make_training_env(cfg, 0), 0, None)
    got = run_episode(
        LearnedPolicy(model, inputs=cfg.inputs, base=registry.make("PID"), alpha=cfg.alpha), episode
    )
    assert got.metrics == run_episode(registry.make("PID"), episode).metrics
    manifest, folder = train(tmp_path, algo)
    c = registry.make(manifest["name"], (str(folder),))
    main = [
        run_episode(c, e).metrics[manifest["validation"]["main_metric"]]
        for e in validation_episodes(SCENARIO)[:2]
    ]
    assert np.mean(main) == manifest["validation"]["value"] and manifest["algorithm"] == algo


def test_every_bench_training_setup_is_a_valid_run_config():
    """configs/bench/training.yaml: each setup, applied to the config and scenario of the committed
    measurements (docs/training.md), parses into a run config with its algorithm; a mistyped key fails
    here, not after the setups before it have trained. sbx's setups need the optional extra."""
    _, setups = load_script("bench_training").load_setups(ROOT / "configs/bench/training.yaml")
    has_sbx = importlib.util.find_spec("sbx") is not None
    checked = 0
    for name, (algorithm, overrides) in setups.items():
        if (algorithm or "").startswith("sbx.") and not has_sbx:
            continue
        cfg = run_config_with("residual_sac", "m220_reversal_tracking", overrides, algorithm)
        assert cfg.algorithm == (algorithm or "SAC"), name
        assert cfg.n_envs == overrides.get("n_envs", 1), name
        checked += 1
    assert checked >= 5  # the SB3 setups run without the extra


@pytest.mark.slow
def test_bench_training_prints_speed_time_to_beat_and_ratios(tmp_path):
    """scripts/bench_training.py on two tiny setups: one CSV row per run with its speed, the baseline it
    is timed against, and the ratio table led by the reference setup at 1.00x."""
    config = write_config(tmp_path, "SAC")
    setups = tmp_path / "setups.yaml"
    setups.write_text(
        yaml.safe_dump(
            {
                "budget_train_s": 3,
                "setups": {"one": {}, "four": {"n_envs": 4, "update_to_data": 0.25, "hyperparams": {}}},
            },
            sort_keys=False,  # the first setup is the reference
        )
    )
    proc = subprocess.run(
        [
            sys.executable,
            str(ROOT / "scripts/bench_training.py"),
            str(config),
            "--scenario",
            SCENARIO,
            "--setups",
            str(setups),
            "--out",
            str(tmp_path / "out"),
            "--workers",
            "2",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = list(csv.DictReader((tmp_path / "out" / config.stem / SCENARIO / "bench_training.csv").open()))
    assert sorted(r["setup"] for r in rows) == ["four", "one"]
    for r in rows:
        assert float(r["env_steps_per_s"]) > 0 and float(r["gradient_steps_per_s"]) > 0
        assert r["baseline"] in registry.BUILTIN and float(r["baseline_main"]) > 0
        assert float(r["train_s"]) >= 3  # the budget ends the run
    four = next(r for r in rows if r["setup"] == "four")
    assert int(four["n_envs"]) == 4
    assert "one                      env steps/s   1.00x" in proc.stdout


@pytest.mark.parametrize(
    "config, base, scenario",
    [
        ("generalist_sac_m220", "SpeedScheduled", "m220_reversal_tracking_slow"),
        ("generalist_sac_m220", "SpeedScheduled", "m220_regulation"),
        ("generalist_sac_kang", "TaskScheduled", "kang_ramp"),
        ("generalist_sac_kang", "TaskScheduled", "kang_regulation"),
        ("generalist_sac_flexible", "SF+relay/residual-base", "flexible_zero_speed_hard"),
        ("generalist_sac_flexible", "SF+relay/residual-base", "flexible_speed_step"),
    ],
)
def test_a_residual_over_a_scheduled_base_starts_as_that_base_bit_for_bit(config, base, scenario):
    """The committed generalists' configs over a base from registry.BASES (not a baseline): its
    zero-output residual's episode equals the base's own, on a tracking scenario and at a set-point, where
    the model's preview is filled in (the flexible servo has none; its base's observer reads the held
    command back)."""
    (cfg,) = load_config(config)
    assert cfg.base == base and cfg.base not in registry.BUILTIN
    episode = validation_episodes(scenario)[0]
    ref = run_episode(registry.make(base), episode, keep_log=True)
    model = build_model(cfg, make_training_env(cfg, 0), 0, None)
    c = LearnedPolicy(
        model,
        inputs=cfg.inputs,
        base=registry.base_controller(cfg.base),
        alpha=cfg.alpha,
        plants=(load_scenario(cfg.scenario).spec.name,),
    )
    got = run_episode(c, episode, keep_log=True)
    np.testing.assert_equal(got.metrics, ref.metrics)
    for k in ref.log:
        np.testing.assert_array_equal(got.log[k], ref.log[k])


def gated(gate: str) -> SpeedScheduled:
    """The M220 schedule of controllers.yaml with another residual gate (the floor only with `floor`)."""
    default = SpeedScheduledSettings.defaults().schedules["m220"]
    floor = default.residual_floor if gate == "floor" else 0.0
    s = dataclasses.replace(default, residual_gate=gate, residual_floor=floor)
    return SpeedScheduled(registry.builtin, SpeedScheduledSettings({"m220": s}))


def test_a_residual_gate_changes_no_command_of_the_schedule():
    """Every gate (none, motion, rest, floor) commands as the others, bit for bit, on a set-point and on
    the 0.05 Hz reversals: the gate is a residual's share, not a loop."""
    for scenario in ("m220_regulation", "m220_reversal_tracking_slow"):
        episode = validation_episodes(scenario)[0]
        logs = [run_episode(gated(g), episode, keep_log=True).log["command"] for g in GATES]
        for log in logs[1:]:
            np.testing.assert_array_equal(log, logs[0])


def test_each_residual_gate_grants_its_share():
    """The share of its authority a residual gets, sample by sample, over a 0.05 Hz reversal of 0.5 rad
    for 9 s, held 1 s, then a 0.2 Hz one (peak speed 0.63 rad/s, above speed_high 0.4): `none` 1
    throughout; `motion` the schedule's w (0 at rest, below 0.2 on the slow reversal, 1 at the fast
    one's peak speed); `rest` 1 on every sample whose reference equals the last one's and w otherwise;
    `floor` as `rest`, and at least the floor (0.5 on the M220) in motion."""
    sc = load_scenario("m220_reversal_tracking_slow")
    cs = {g: gated(g) for g in GATES}
    for c in cs.values():
        c.reset(EpisodeContext(sc, sc.spec, knowledge_defaults()))
    h = cs["none"].h
    refs = [0.5 * np.sin(2 * np.pi * 0.05 * min(k, 1800) * h) for k in range(2000)]
    refs += [0.5 * np.sin(2 * np.pi * 0.2 * k * h) for k in range(1000)]
    shares: dict[str, list[float]] = {g: [] for g in GATES}
    ws, rest = [], []
    for r in refs:
        for g, c in cs.items():
            c.command(r, r)
            shares[g].append(float(np.broadcast_to(c.residual_share(), (1,))[0]))
        ws.append(float(cs["none"].w[0]))
        rest.append(bool(cs["rest"].at_rest[0]))
    floor = cs["floor"].s.residual_floor
    assert floor == 0.5 and shares["none"] == [1.0] * len(refs)
    assert shares["motion"] == ws and 0.0 < max(ws[:1801]) < 0.2 and max(ws[2000:]) == 1.0
    assert shares["rest"] == [1.0 if at else w for at, w in zip(rest, ws, strict=True)]
    assert rest[1801:2000] == [True] * 199 and not any(rest[1:1801])
    assert shares["floor"] == [1.0 if at else max(w, floor) for at, w in zip(rest, ws, strict=True)]


def test_a_gated_residual_is_the_base_where_its_share_is_zero():
    """A network whose output is not zero (its mean's bias set to 0.5): at a set-point under the motion
    gate (w = 0 throughout) the residual's episode is the base's own, bit for bit; under `none` it is not.
    On the 0.2 Hz reversals w reaches 1 and the gated residual moves the episode."""
    (cfg,) = load_config("generalist_sac_m220")
    model = build_model(cfg, make_training_env(cfg, 0), 0, None)
    model.policy.actor.mu.bias.data.fill_(0.5)

    def over(gate: str) -> LearnedPolicy:
        return LearnedPolicy(model, inputs=cfg.inputs, base=gated(gate), alpha=cfg.alpha, plants=("m220",))

    rest = validation_episodes("m220_regulation")[0]
    base = run_episode(gated("motion"), rest, keep_log=True).log["command"]
    np.testing.assert_array_equal(run_episode(over("motion"), rest, keep_log=True).log["command"], base)
    assert not np.array_equal(run_episode(over("none"), rest, keep_log=True).log["command"], base)
    moving = validation_episodes("m220_reversal_tracking")[0]
    moved = run_episode(over("motion"), moving).metrics["reversal_peak_error"]
    assert moved != run_episode(gated("motion"), moving).metrics["reversal_peak_error"]


def test_the_training_envs_apply_the_gated_bases_share_as_evaluation_does():
    """The training env's command (what the core steps) is residual_action with each env's own base
    action and share, as LearnedPolicy's: the committed M220 config's floor gate grants less than 1 on
    some steps (m220_random moves) and 1 on others (it starts at rest and holds)."""
    (cfg,) = load_config("generalist_sac_m220")
    env = make_training_env(cfg, 0)
    env.reset()
    sent, step = [], env.core.step
    env.core.step = lambda u: (sent.append(np.array(u)), step(u))[1]
    shares = []
    for _ in range(300):
        base, share = env.u_base.copy(), [b.residual_share() for b in env.bases]
        env.step(np.ones((env.num_envs, 1), dtype=np.float32))
        one = np.ones(1, dtype=np.float32)
        want = [residual_action(b, one, cfg.alpha, w) for b, w in zip(base, share, strict=True)]
        np.testing.assert_array_equal(sent[-1], np.concatenate(want))
        shares += share
    assert min(shares) < 1.0 and max(shares) == 1.0


@pytest.mark.slow
def test_a_run_over_a_base_that_is_not_a_baseline_records_it_and_loads_through_the_registry(tmp_path):
    """TrainingRun measures the admissible effort against the base too when the base is no baseline
    (it runs on the validation episodes beside the classical rows); the manifest names the base, and the
    exported model loads through the registry with it and acts as its validation row says."""
    cfg = {
        "name": "SmokeSched",
        "algorithm": "SAC",
        "defaults": {
            "total_timesteps": 256,
            "validation": {"every_steps": 128, "episodes": 1, "max_effort_ratio": 100.0},
            "hyperparams": HYPER["SAC"],
        },
        "scenarios": {"m220_reversal_tracking": {"residual": {"base": "SpeedScheduled", "alpha": 0.1}}},
    }
    path = tmp_path / "sched.yaml"
    path.write_text(yaml.safe_dump(cfg))
    (rc,) = load_config(path)
    run = TrainingRun(rc, 0, tmp_path / "run", "pytest", progress=False)
    manifest = run.train(False)
    assert manifest["base_controller"] == "SpeedScheduled"
    base_effort = run_episode(registry.make("SpeedScheduled"), validation_episodes(rc.scenario)[0])
    assert run.effort_ref == min(run.baseline.effort_rms, base_effort.metrics["effort_rms"])
    folder = export_model(tmp_path / "run", tmp_path / "committed")
    name = manifest["name"]
    loaded = registry.make(name, (str(tmp_path / "committed"),))
    assert loaded.base is not None and loaded.base.name == "SpeedScheduled"
    got = run_episode(loaded, validation_episodes(rc.scenario)[0])
    assert got.metrics[load_scenario(rc.scenario).main_metric] == pytest.approx(
        manifest["validation"]["value"], rel=1e-12
    ), folder


class Killed(BaseException):
    """A stop at a write, as kill -9 would leave it (nothing of the run's catches it)."""


@pytest.mark.slow
def test_a_run_stopped_at_any_write_of_a_checkpoint_resumes_from_one_complete_set(tmp_path, monkeypatch):
    """Stopped at each file write between the first checkpoint's LATEST and the second's (the model, the
    normalizer, the replay buffer, the selected model, the state, LATEST, validation.csv), --resume
    continues from the set LATEST names: no step evaluated twice or missing, the rows before that set
    as the uninterrupted run's, and the model folder's file the one its manifest's SHA-256 names."""
    import frictiongym.envs.records as records
    from frictiongym.agents.learned.folder import read_policy, read_sealed
    from frictiongym.agents.learned.manifest import Manifest

    real = records.os.replace
    targets: list[str] = []

    def recording(a, b):
        targets.append(Path(b).name)
        return real(a, b)

    monkeypatch.setattr(records.os, "replace", recording)
    _, folder = train(tmp_path, "SAC", steps=256, out="clean")
    rows = list(csv.DictReader((folder / "validation.csv").open()))
    first, second = [i for i, t in enumerate(targets) if t == "LATEST"][:2]
    for k in range(first + 1, second + 1):
        calls = iter(range(10**6))

        def stopping(a, b, k=k, calls=calls):
            if next(calls) == k:
                raise Killed(Path(b).name)
            return real(a, b)

        monkeypatch.setattr(records.os, "replace", stopping)
        out = f"killed{k}"
        with pytest.raises(Killed):
            train(tmp_path, "SAC", steps=256, out=out)
        monkeypatch.setattr(records.os, "replace", real)
        _, run = train(tmp_path, "SAC", steps=256, out=out, resume=True)
        got = list(csv.DictReader((run / "validation.csv").open()))
        assert [int(r["step"]) for r in got] == [128, 256], (k, targets[k])
        clocks = ("wall_s", "train_s")
        assert {**got[0], **dict.fromkeys(clocks)} == {**rows[0], **dict.fromkeys(clocks)}, (k, targets[k])
        m = Manifest.read(run)
        read_policy(read_sealed(run), m, str(run / MANIFEST))  # the seal and the SHA-256 match
        best = min(got, key=lambda r: float(r["main"]) if float(r["admissible"]) else math.inf)
        assert m.selected_step == int(best["step"]), (k, targets[k])
        assert not list(run.glob(".*.tmp*")) and len(list((run / "checkpoint").iterdir())) == 2


@pytest.mark.parametrize(
    ("key", "value"),
    [("gamma", math.nan), ("gamma", 1.5), ("tau", 1e9), ("batch_size", 0), ("buffer_size", 2.5)],
)
def test_a_hyper_parameter_out_of_its_range_is_refused_when_the_config_is_read(tmp_path, key, value):
    """A discount of NaN or above 1, a soft-update rate of 1e9, an empty batch: values that diverge or
    fail inside torch are refused at config time, naming the field and the range."""
    path = write_config(tmp_path, "SAC")
    raw = yaml.safe_load(path.read_text())
    raw["defaults"]["hyperparams"][key] = value
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(ConfigError, match=r"expected a (whole )?number in \[") as e:
        load_config(path)
    assert e.value.field.endswith(f"hyperparams.{key}")


@pytest.mark.slow  # trains
def test_train_takes_a_step_count_for_a_try(tmp_path, capsys):
    """`frictiongym train --steps N` replaces the config's total_timesteps for every run (a short try
    without writing a config); the manifest records N and the command."""
    code = load_script("train").main(
        ["--config", str(write_config(tmp_path, "SAC")), "--steps", "130", "--out", str(tmp_path / "runs")]
    )
    assert code == 0
    [manifest] = list((tmp_path / "runs").rglob("manifest.yaml"))
    m = yaml.safe_load(manifest.read_text())
    assert m["config"]["total_timesteps"] == 130 and m["steps"] >= 130
