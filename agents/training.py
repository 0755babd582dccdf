"""Training learned compensators with stable-baselines3 / sb3-contrib (scripts/train.py is the front end).

A training config (configs/agents/<name>.yaml, rl-zoo style) gives `defaults` and per-scenario entries
that override them; every key is checked (unknown keys, types, ranges: errors naming the file and field).
One run = (config, scenario, seed) and writes a model folder the leaderboard loads (--models):

    model.zip, vecnormalize.pkl   the model selected on the validation suite and its frozen statistics
    manifest.yaml                 algorithm, scenario, base controller, α, hyper-parameters, seed, steps,
                                  wall time, the exact command, package version, validation score
    validation.csv, training_curve.png, tb/ (TensorBoard), checkpoint/ (for --resume)

Rules it enforces: training episodes use seeds from TRAINING_SEEDS (disjoint from every suite); the model
is selected on the `validation` suite only, by the scenario's main metric, among evaluations whose
effort_rms is at most `max_effort_ratio` times the best classical baseline's on the same episodes (a
compensator that chatters is not a result); one torch thread per process.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import inspect
import io
import json
import math
import multiprocessing as mp
import os
import pickle
import random
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml
from gymnasium import spaces

from frictiongym.envs.config import (
    ConfigError,
    Node,
    configs_dir,
    deep_merge,
    load_extending,
    load_yaml,
    preset_names,
    preset_path,
)
from frictiongym.envs.plants.spec import RANDOMIZATION_KEYS
from frictiongym.envs.records import atomic_text, atomic_write, command_line, csv_text
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import load_suite, suite_held_out

from .base import ZERO, Controller, EpisodeContext
from .engine import init_worker, provenance, stop_workers
from .evaluate import EnvCache, controller_overrides, run_episode
from .learned import (
    LearnedNeeds,
    PolicyInputs,
    SB3Policy,
    algorithm_class,
    is_jax,
    policy_observation,
    residual_action,
)
from .registry import BUILTIN, make
from .settings import knowledge_defaults
from .training_env import SEEDS_PER_RUN, TRAINING_SEEDS, TrainingVecEnv

VALIDATION_SUITE = "validation"
ASYMMETRIC = ("SAC", "TD3", "TQC", "CrossQ")  # the privileged critic (agents/asymmetric.py)
JAX = ("sbx.SAC", "sbx.TQC", "sbx.CrossQ")  # sbx's JAX learners (the optional sbx extra)
OFF_POLICY = (*ASYMMETRIC, *JAX)  # replay-buffer learners: update_to_data applies
ALGORITHMS = (*OFF_POLICY, "PPO", "RecurrentPPO")
REWARD_TERMS = ("tracking", "effort", "smoothness")
ACTIVATIONS = ("relu", "tanh", "elu", "leaky_relu")
MODEL, NORMALIZER, MANIFEST = "model.zip", "vecnormalize.pkl", "manifest.yaml"


# ------------------------------------------------------------------------------------------- config
@dataclass(frozen=True)
class RunConfig:
    """One scenario's resolved training settings (defaults + the scenario's entry)."""

    name: str  # leaderboard name prefix; the model is called f"{name}-{scenario}-s{seed}"
    algorithm: str
    scenario: str
    total_timesteps: int
    n_envs: int
    update_to_data: float | None  # gradient steps per env step (off-policy); None: hyperparams' own
    randomize: bool
    randomization: dict[str, tuple[float, float]]  # replaces the plant's ranges key by key
    reward: dict[str, float]  # scenario reward weights replaced (tracking, effort, smoothness)
    inputs: PolicyInputs
    base: str | None  # registered controller name (residual mode) or None
    alpha: float  # residual authority, fraction of the full command range
    initial_std: float  # initial action std of the (residual) policy, in action units
    normalize_observation: bool
    normalize_reward: bool
    eval_every_steps: int
    eval_episodes: int  # the first n of the scenario's validation-suite episodes
    max_effort_ratio: float  # selection: effort_rms <= ratio · best classical baseline's (validation)
    max_wall_time_s: float  # the run stops (and says so in its manifest) after this wall time
    hyperparams: dict[str, Any] = field(default_factory=dict)  # the algorithm's keyword arguments
    source: str = ""  # the config file

    def as_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["randomization"] = {k: list(v) for k, v in self.randomization.items()}
        return d


def config_names() -> list[str]:
    return preset_names("agents")


def raw_config(path: str | Path) -> tuple[dict[str, Any], str]:
    """A training config file's mapping with its `extends:` chain merged in (the child's keys win), and
    the file's path."""
    return load_extending(path, "agents"), str(preset_path(path, "agents"))


def scenario_settings(raw: dict[str, Any], scenario: str) -> dict[str, Any]:
    """A scenario's settings in a (merged) config file: configs/agents/_defaults.yaml, then the file's
    `defaults`, then its scenario entry."""

    defaults = deep_merge(load_yaml(configs_dir() / "agents" / "_defaults.yaml"), raw.get("defaults") or {})
    return copy.deepcopy(deep_merge(defaults, raw["scenarios"][scenario]))  # the caller may edit it


def load_config(path: str | Path, scenario: str | None = None) -> list[RunConfig]:
    """The runs a training config asks for: every scenario in it, or just `scenario` (scenario_settings)."""
    raw, file = raw_config(path)
    top = Node(raw, file)
    algo = top.choice("algorithm", ALGORITHMS)
    name = top["name"]
    if not isinstance(name, str) or not name.replace("-", "").replace("_", "").isalnum():
        raise top.error("name", f"expected a name of letters, digits, '-' and '_', got {name!r}")
    top.get("defaults")  # read through scenario_settings; marks the key as known for top.done()
    scenarios = top.section("scenarios")
    keys = [k for k in list(scenarios.keys()) if scenarios[k] is not None]  # null: an entry left out
    if not keys:
        raise top.error("scenarios", "expected at least one scenario")
    if scenario is not None and scenario not in keys:
        raise top.error("scenarios", f"no entry for scenario {scenario!r}; the file has {keys}")
    out = []
    for sc in keys:  # every entry is checked, the asked-for ones returned
        node = Node(scenario_settings(raw, sc), file, f"scenarios.{sc}.")
        cfg = parse_run_config(node, name, algo, sc, file)
        if scenario in (None, sc):
            out.append(cfg)
    scenarios.done()
    top.done()
    return out


def run_config_with(
    path: str | Path, scenario: str, overrides: dict[str, Any], algorithm: str | None = None
) -> RunConfig:
    """A scenario's run config with `overrides` (a mapping of its settings, merged key by key; a
    hyper-parameter set to null takes the algorithm's default) and optionally another algorithm: a
    variant of a config, e.g. one setup of scripts/bench_training.py."""
    raw, file = raw_config(path)
    if scenario not in (raw.get("scenarios") or {}):
        raise ConfigError("scenarios", f"no entry for scenario {scenario!r}", file)
    entry = deep_merge(scenario_settings(raw, scenario), overrides)
    if algorithm is not None and algorithm not in ALGORITHMS:
        raise ConfigError("algorithm", f"expected one of {list(ALGORITHMS)}, got {algorithm!r}", file)
    node = Node(entry, file, f"scenarios.{scenario}.")
    return parse_run_config(node, raw["name"], algorithm or raw["algorithm"], scenario, file)


def parse_run_config(c: Node, name: str, algo: str, scenario: str, source: str) -> RunConfig:
    """The RunConfig of one scenario entry (`c`: its merged settings), every key checked; errors name the
    field and the file."""
    try:
        algorithm_class(algo)  # an optional extra (sbx) may be missing
    except ValueError as e:
        raise ConfigError("algorithm", str(e), source) from None
    if load_scenario(scenario).held_out:  # (an unknown scenario is an error naming the available ones)
        raise ConfigError(
            f"scenarios.{scenario}",
            "is a held-out (generalisation) scenario: it is never trained or selected on",
            source,
        )
    r = c.section("randomization")
    ranges = {}
    for key in list(r.keys()):
        if key not in RANDOMIZATION_KEYS:
            raise r.error(key, f"unknown randomization key; allowed: {sorted(RANDOMIZATION_KEYS)}")
        ranges[key] = r.interval(key, *RANDOMIZATION_KEYS[key])
    w = c.section("reward")
    reward = {k: w.nonneg(k) for k in REWARD_TERMS if k in w}
    o = c.section("observation")
    res = c.section("residual")
    base = res["base"]
    if base is not None and (base not in BUILTIN or base == ZERO):
        raise res.error("base", f"unknown base controller {base!r}; allowed: {sorted(set(BUILTIN) - {ZERO})}")
    inputs = PolicyInputs(o.integer("history", 0, 64), o.boolean("privileged_critic"), base is not None)
    hp = c.section("hyperparams")
    hyper = {k: hp[k] for k in list(hp.keys()) if hp[k] is not None}  # null: the algorithm's default
    _check_hyperparams(algo, hyper, hp)
    warmup = hyper.get("learning_starts", 100) > 0 and not (
        hyper.get("use_sde") and hyper.get("use_sde_at_warmup")
    )
    if base is not None and algo in OFF_POLICY and warmup:
        raise hp.error(
            "learning_starts",
            "a residual starts at zero output: set learning_starts: 0 (no uniform random actions at "
            "full authority), or use_sde with use_sde_at_warmup",
        )
    if inputs.privileged and algo not in ASYMMETRIC:
        raise o.error(
            "privileged_critic",
            f"asymmetric actor-critic is implemented for {', '.join(ASYMMETRIC)}, not {algo}",
        )
    n_envs = c.integer("n_envs", 1, 64)
    utd = None if c.get("update_to_data") is None else c.positive("update_to_data", 64.0)
    if utd is not None:
        if algo not in OFF_POLICY:
            raise c.error("update_to_data", f"applies to {', '.join(OFF_POLICY)}, not {algo}: set it to null")
        for key in ("train_freq", "gradient_steps"):
            if key in hyper:
                raise hp.error(key, "update_to_data sets it (with n_envs): give one of the two, not both")
        try:
            sb3_schedule(utd, n_envs)
        except ValueError as e:
            raise c.error("update_to_data", str(e)) from None
    n = c.section("normalize")
    v = c.section("validation")
    cfg = RunConfig(
        name=name,
        algorithm=algo,
        scenario=scenario,
        total_timesteps=c.integer("total_timesteps", 1, 10**8),
        n_envs=n_envs,
        update_to_data=utd,
        randomize=c.boolean("randomize"),
        randomization=ranges,
        reward=reward,
        inputs=inputs,
        base=base,
        alpha=res.positive("alpha", 1.0) if base is not None else 1.0,
        initial_std=c.positive("initial_std", 1.0),
        normalize_observation=n.boolean("observation"),
        normalize_reward=n.boolean("reward"),
        eval_every_steps=v.integer("every_steps", 1),
        eval_episodes=v.integer("episodes", 1, 10_000),
        max_effort_ratio=v.positive("max_effort_ratio"),
        max_wall_time_s=c.positive("max_wall_time_s"),
        hyperparams=hyper,
        source=source,
    )
    if base is None:
        res.get("alpha")  # read (unused without a base)
    for node in (r, w, o, res, hp, n, v, c):
        node.done()
    return cfg


def sb3_schedule(update_to_data: float, n_envs: int) -> tuple[int, int]:
    """SB3's (train_freq in vector steps, gradient_steps) for `update_to_data` gradient steps per env step
    with n_envs envs (one vector step = n_envs env steps): g = ratio·n_envs gradient steps after every
    vector step if g >= 1, else one after every 1/g vector steps; either must be a whole number."""
    g = update_to_data * n_envs
    whole = round(g) if g >= 1 else round(1 / g)
    if abs((g if g >= 1 else 1 / g) - whole) > 1e-9 * whole:
        raise ValueError(
            f"{update_to_data} x n_envs {n_envs} = {g:.6g} gradient steps per vector step: it, or its "
            "inverse, must be a whole number"
        )
    return (1, whole) if g >= 1 else (whole, 1)


def _check_hyperparams(algo: str, hyper: dict[str, Any], node: Node) -> None:
    """Every hyper-parameter is a keyword of the algorithm's constructor (or one of ours, below)."""
    ours = {"action_noise_std"}
    params = set(inspect.signature(algorithm_class(algo).__init__).parameters) - {"self", "policy", "env"}
    params -= {"seed", "device", "tensorboard_log", "verbose", "_init_setup_model"}
    for key in hyper:
        if key not in params | ours:
            raise node.error(key, f"not a hyper-parameter of {algo}; allowed: {sorted(params | ours)}")
    pk = hyper.get("policy_kwargs", {})
    if not isinstance(pk, dict):
        raise node.error("policy_kwargs", f"expected a mapping, got {pk!r}")
    act = pk.get("activation_fn")
    if act is not None and act not in ACTIVATIONS:
        raise node.error("policy_kwargs.activation_fn", f"expected one of {list(ACTIVATIONS)}, got {act!r}")


def scenario_overrides(cfg: RunConfig) -> dict[str, Any]:
    """The scenario overrides of the run's training env (before the base controller's hardware)."""
    out: dict[str, Any] = {}
    if cfg.randomization:
        out["plant_overrides"] = {"randomization": {k: list(v) for k, v in cfg.randomization.items()}}
    if cfg.reward:
        out["reward"] = dict(cfg.reward)
    return out


# ------------------------------------------------------------------------------------------- env
class ResidualEnv(gym.Wrapper):
    """A scenario's env as a learned compensator sees it: in residual mode the base controller runs in the
    loop (u = clip(u_base + α·a)) and the observation is extended with its action (policy_observation);
    without a base, the env as it is: the single-env form of a training env (agents/training_env.py),
    for rl-zoo (agents/zoo.py)."""

    def __init__(self, env: gym.Env, base: Controller | None, alpha: float):
        super().__init__(env)
        self.base, self.alpha = base, alpha
        n = env.observation_space.shape[0] + int(base is not None)
        self.observation_space = spaces.Box(-np.inf, np.inf, (n,), np.float32)
        self.knowledge = knowledge_defaults()

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        return self._observe(obs, reset=True), info

    def _observe(self, obs: np.ndarray, reset: bool = False) -> np.ndarray:
        if self.base is None:
            self.u_base = None
            return obs
        if reset:
            sc = self.env.unwrapped.scenario
            self.base.reset(EpisodeContext(sc, sc.spec, self.knowledge))
        self.u_base = self.base.act(obs)
        return policy_observation(obs, self.u_base)

    def step(self, action: np.ndarray):
        u = residual_action(self.u_base, action, self.alpha) if self.base is not None else action
        obs, reward, term, trunc, info = self.env.step(np.asarray(u, dtype=np.float32).reshape(1))
        return self._observe(obs), reward, term, trunc, info


def training_env_kwargs(cfg: RunConfig) -> dict[str, Any]:
    """The env keywords of a run's training envs: the config's randomisation and reward, the base
    controller's hardware and the model's observation blocks (as the trained controller's evaluation
    env gets them). Checks that the base applies to the scenario."""

    base = make(cfg.base) if cfg.base is not None else None
    sc = load_scenario(cfg.scenario, scenario_overrides(cfg) or None, randomize=cfg.randomize)
    if base is not None and (reason := base.why_not(sc)) is not None:
        raise ConfigError(
            "residual.base", f"{cfg.base} does not apply to {cfg.scenario}: {reason}", cfg.source
        )
    probe = SB3PolicyShape(cfg.inputs, base)
    return {"randomize": cfg.randomize, "overrides": controller_overrides(probe, sc, scenario_overrides(cfg))}


def make_training_env(cfg: RunConfig, seed: int, nthread: int = 1) -> TrainingVecEnv:
    """The n_envs training envs of run seed `seed` on the batched core, each env's own base controller in
    the loop (agents/training_env.py)."""

    bases = (lambda: make(cfg.base)) if cfg.base is not None else None
    kw = training_env_kwargs(cfg)
    return TrainingVecEnv(cfg.scenario, cfg.n_envs, seed, bases=bases, alpha=cfg.alpha, nthread=nthread, **kw)


class SB3PolicyShape(LearnedNeeds, Controller):
    """A learned controller's needs (LearnedNeeds) without a model: builds the training env exactly as the
    evaluation builds the trained controller's."""

    name = "shape"

    def __init__(self, inputs: PolicyInputs, base: Controller | None):
        self.inputs, self.base = inputs, base

    def reset(self, ctx: EpisodeContext) -> None:
        raise NotImplementedError("a shape does not act")

    def act(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError("a shape does not act")


# ------------------------------------------------------------------------------------------- model
def build_model(cfg: RunConfig, venv: Any, seed: int, tb: str | None) -> Any:
    """The algorithm with the config's hyper-parameters; in residual mode its policy starts at exactly
    zero output with a small action std (zero_output)."""
    import torch

    hyper = dict(cfg.hyperparams)
    if cfg.update_to_data is not None:
        hyper["train_freq"], hyper["gradient_steps"] = sb3_schedule(cfg.update_to_data, cfg.n_envs)
    pk = dict(hyper.pop("policy_kwargs", {}) or {})
    if "activation_fn" in pk:
        pk["activation_fn"] = {
            "relu": torch.nn.ReLU,
            "tanh": torch.nn.Tanh,
            "elu": torch.nn.ELU,
            "leaky_relu": torch.nn.LeakyReLU,
        }[pk["activation_fn"]]
    noise_std = hyper.pop("action_noise_std", None)
    if noise_std is not None:
        from stable_baselines3.common.noise import NormalActionNoise

        hyper["action_noise"] = NormalActionNoise(np.zeros(1), np.full(1, float(noise_std)))
    policy: Any = "MlpLstmPolicy" if cfg.algorithm == "RecurrentPPO" else "MlpPolicy"
    if cfg.algorithm in ("PPO", "RecurrentPPO") or hyper.get("use_sde"):
        pk.setdefault("log_std_init", math.log(cfg.initial_std))
    if cfg.inputs.privileged:
        from .asymmetric import asymmetric_policy  # builds torch modules at import: only when asked for

        sc = load_scenario(cfg.scenario)
        policy = asymmetric_policy(cfg.algorithm)
        pk["actor_indices"] = cfg.inputs.actor_indices(sc)
    model = algorithm_class(cfg.algorithm)(
        policy, venv, seed=seed, device="cpu", verbose=0, tensorboard_log=tb, policy_kwargs=pk, **hyper
    )
    if cfg.base is not None:
        zero_output(model, cfg.initial_std)
    return model


def zero_output(model: Any, std: float) -> None:
    """Make the policy's mean action exactly 0 (last layer zeroed) and its std `std` (action units)."""
    if is_jax(model):
        return _zero_output_flax(model, std)
    import torch

    with torch.no_grad():
        policy = model.policy
        if hasattr(policy, "action_net"):  # PPO, RecurrentPPO
            last = policy.action_net
            policy.log_std.fill_(math.log(std))
        elif hasattr(model, "actor_target"):  # TD3: mu = Sequential(..., Linear, Tanh)
            last = [m for m in model.actor.mu if isinstance(m, torch.nn.Linear)][-1]
        else:  # SAC, TQC: squashed Gaussian with a state-dependent log std
            last = model.actor.mu
            if isinstance(model.actor.log_std, torch.nn.Linear):
                model.actor.log_std.weight.zero_()
                model.actor.log_std.bias.fill_(math.log(std))
        last.weight.zero_()
        last.bias.zero_()
        if hasattr(model, "actor_target"):
            model.actor_target.load_state_dict(model.actor.state_dict())


def _zero_output_flax(model: Any, std: float) -> None:
    """zero_output for sbx's squashed-Gaussian actors: their last two Dense layers are the mean and the
    log std (SAC and TQC nest the layers under "params", CrossQ does not)."""
    import jax.numpy as jnp

    state = model.policy.actor_state
    nested = "params" in state.params
    tree = state.params["params"] if nested else state.params
    dense = sorted((k for k in tree if k.startswith("Dense_")), key=lambda k: int(k.split("_")[1]))
    mean, log_std = dense[-2], dense[-1]
    tree = {
        **tree,
        mean: {k: jnp.zeros_like(v) for k, v in tree[mean].items()},
        log_std: {
            "kernel": jnp.zeros_like(tree[log_std]["kernel"]),
            "bias": jnp.full_like(tree[log_std]["bias"], math.log(std)),
        },
    }
    model.policy.actor_state = state.replace(params={**state.params, "params": tree} if nested else tree)


# ------------------------------------------------------------------------------------------- validation
@dataclass
class Baseline:
    """The best classical controller of a scenario on the validation episodes (by its main metric)."""

    name: str
    main: float
    effort_rms: float
    limit_cycle_amp: float


def validation_episodes(scenario: str, suite: str = VALIDATION_SUITE) -> list:
    """The selection episodes of a scenario: never from a held-out suite."""
    if suite_held_out(suite):
        raise ConfigError("suite", f"{suite} is held out: models are never selected on it")
    return [e for e in load_suite(suite) if e.scenario == scenario]


def evaluate_controller(controller: Controller, episodes: list, envs: EnvCache) -> dict[str, float]:
    """Means of every metric over the episodes, through the one evaluation loop."""
    rows = [run_episode(controller, e, envs=envs).metrics for e in episodes]
    return {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}


def classical_on(episodes: list, envs: EnvCache) -> dict[str, dict[str, float]]:
    """Metric means of every applicable built-in controller (Zero included) on the episodes."""

    out = {}
    for name, factory in BUILTIN.items():
        c = factory()
        if c.applies_to(envs.scenario(episodes[0])):
            out[name] = evaluate_controller(c, episodes, envs)
    return out


def best_classical(scenario: str, results: dict[str, dict[str, float]]) -> Baseline:
    """The best classical baseline by the scenario's main metric (Zero is not a baseline)."""
    main = load_scenario(scenario).main_metric
    name = min((n for n in results if n != ZERO), key=lambda n: results[n][main])
    m = results[name]
    return Baseline(name, m[main], m["effort_rms"], m["limit_cycle_amp"])


def gradient_steps(model: Any) -> int:
    """The gradient steps a model has taken (PPO's _n_updates counts epochs of minibatches)."""
    n = int(getattr(model, "_n_updates", 0))
    if hasattr(model, "n_epochs"):
        return n * math.ceil(model.n_steps * model.n_envs / model.batch_size)
    return n


@dataclass(frozen=True)
class Snapshot:
    """A model as saved (model.zip bytes) with its VecNormalize's pickle (None without one): what is
    evaluated, kept as the best model, and checkpointed."""

    model: bytes
    normalizer: bytes | None

    @classmethod
    def of(cls, model: Any) -> Snapshot:
        from stable_baselines3.common.vec_env import VecNormalize

        buf = io.BytesIO()
        model.save(buf)
        venv = model.get_env()  # a VecNormalize pickles without the env it wraps
        return cls(buf.getvalue(), pickle.dumps(venv) if isinstance(venv, VecNormalize) else None)

    @classmethod
    def read(cls, folder: Path) -> Snapshot:
        norm = folder / NORMALIZER
        return cls((folder / MODEL).read_bytes(), norm.read_bytes() if norm.exists() else None)

    def write(self, folder: Path) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write(folder / MODEL, lambda p: p.write_bytes(self.model))
        if self.normalizer is not None:
            atomic_write(folder / NORMALIZER, lambda p: p.write_bytes(self.normalizer))


@dataclass
class _Pending:
    """An evaluation started and not yet recorded: its row's step and clocks, the snapshot, the result."""

    meta: dict[str, Any]
    snapshot: Snapshot
    result: Future


_EVAL_ENVS = EnvCache()  # the validation envs of this process (a worker's, or the training process')


def evaluate_snapshot(cfg: RunConfig, name: str, snap: Snapshot, episodes: list) -> dict[str, float]:
    """Metric means of a saved model on the episodes through the leaderboard's loop (evaluate_controller),
    deterministic, its observation statistics frozen (SB3Policy): in the validation worker or in the
    training process, the same numbers (picklable for the worker). The global random generators are left
    as they were (SB3's load reseeds them), so validation in the training process does not change the
    training."""

    with _generators_kept():
        model = algorithm_class(cfg.algorithm).load(io.BytesIO(snap.model), device="cpu")
        norm = pickle.loads(snap.normalizer) if snap.normalizer is not None else None
        base = make(cfg.base) if cfg.base is not None else None
        policy = SB3Policy(model, (), name, inputs=cfg.inputs, base=base, alpha=cfg.alpha, normalizer=norm)
        return evaluate_controller(policy, episodes, _EVAL_ENVS)


@contextlib.contextmanager
def _generators_kept() -> Any:
    """Python's, numpy's and torch's global random generators restored on exit."""

    import torch

    saved = random.getstate(), np.random.get_state(), torch.get_rng_state()
    try:
        yield
    finally:
        random.setstate(saved[0])
        np.random.set_state(saved[1])
        torch.set_rng_state(saved[2])


def _callback_class():
    from stable_baselines3.common.callbacks import BaseCallback

    class Validation(BaseCallback):
        """Every `every` steps: evaluate the deterministic policy on the validation episodes through the
        leaderboard's loop (in the validation worker, while training goes on), log it, keep the best
        admissible model, write a checkpoint; stop at the wall time limit."""

        def __init__(self, run: TrainingRun):
            super().__init__()
            self.run = run

        def _on_training_start(self) -> None:
            self.run.logger = self.logger

        def _on_step(self) -> bool:
            r = self.run
            if self.num_timesteps >= r.next_eval:
                r.next_eval += r.cfg.eval_every_steps
                r.collect(block=True)  # the previous evaluation: at most one runs beside training
                r.checkpoint(self.model, r.validate(self.model))
            over = r.stop_after_train_s is not None and r.train_s() > r.stop_after_train_s
            if r.elapsed() > r.cfg.max_wall_time_s or over:
                r.stopped_early = True
                return False
            return True

    return Validation


class TrainingRun:
    """One (config, scenario, seed) run into `out`, resumable from out/checkpoint."""

    def __init__(
        self,
        cfg: RunConfig,
        seed: int,
        out: Path,
        command: str,
        progress: bool = True,
        parallel_validation: bool = False,
    ):
        self.cfg, self.seed, self.out, self.command, self.progress = cfg, seed, Path(out), command, progress
        # validation in a worker process on the other core (scripts/train.py's runs), with the same results
        # as in turn (the same saved snapshot is evaluated). The worker is spawned: a calling script needs
        # multiprocessing's `if __name__ == "__main__":` guard; a daemonic pool worker may not have children.
        self.parallel_validation = parallel_validation and not mp.current_process().daemon
        self.pool: ProcessPoolExecutor | None = None
        self.pending: list[_Pending] = []
        self.name = f"{cfg.name}-{cfg.scenario}-s{seed}"  # unique across a config's scenarios
        self.episodes = validation_episodes(cfg.scenario)[: cfg.eval_episodes]
        if not self.episodes:
            raise ConfigError("scenario", f"{cfg.scenario} is not in the {VALIDATION_SUITE} suite")
        self.main = load_scenario(cfg.scenario).main_metric
        self.envs = EnvCache()
        self.history: list[dict[str, float]] = []
        self.best: dict[str, float] | None = None
        self.next_eval = cfg.eval_every_steps
        self.wall_before, self.stopped_early = 0.0, False
        self.eval_s = 0.0  # wall time the training waited for validation (train_s = elapsed - eval_s)
        self.stop_after_train_s: float | None = None  # also stop after this much training time (bench)
        self.reporter: Callable[[dict[str, float]], None] | None = None  # e.g. Ray Tune's report
        self.logger: Any = None  # the model's logger (validation metrics to TensorBoard)

    def elapsed(self) -> float:
        return self.wall_before + time.monotonic() - self.t0

    # ----------------------------------------------------------------------------- evaluation
    def train_s(self) -> float:
        """Wall time spent training (learning and env stepping), waits for validation excluded."""
        return self.elapsed() - self.eval_s

    def validate(self, model: Any) -> Snapshot:
        """Start the evaluation of the model as it is now (a saved snapshot, in the validation worker, or
        here); collect() records it. Returns the snapshot (the checkpoint's model)."""
        t0 = time.monotonic()
        snap = Snapshot.of(model)
        job = (self.cfg, self.name, snap, self.episodes)
        if self.parallel_validation:
            if self.pool is None:
                self.pool = ProcessPoolExecutor(
                    1, mp.get_context("spawn"), initializer=init_worker, initargs=(os.getpid(),)
                )
            result = self.pool.submit(evaluate_snapshot, *job)
        else:
            result = Future()
            result.set_result(evaluate_snapshot(*job))
        meta = {"step": model.num_timesteps, "gradient_steps": gradient_steps(model)}
        self.eval_s += time.monotonic() - t0
        meta |= {"wall_s": round(self.elapsed(), 1), "train_s": round(self.train_s(), 1)}
        self.pending.append(_Pending(meta, snap, result))
        self.collect(block=False)
        return snap

    def collect(self, block: bool) -> None:
        """Record the finished evaluations in order (all of them, waiting, if block)."""
        while self.pending and (block or self.pending[0].result.done()):
            p = self.pending.pop(0)
            t0 = time.monotonic()
            try:
                m = p.result.result()
            except BrokenProcessPool:  # the worker died (e.g. killed): validate here from now on
                print(f"{self.name}: the validation worker stopped; validating in turn", file=sys.stderr)
                self.parallel_validation, self.pool = False, None
                m = evaluate_snapshot(self.cfg, self.name, p.snapshot, self.episodes)
            self.eval_s += time.monotonic() - t0
            self._record(p.meta, p.snapshot, m)

    def _record(self, meta: dict[str, Any], snap: Snapshot, m: dict[str, float]) -> None:
        zero = self.zero[self.main]
        row = {
            **meta,
            "main": m[self.main],
            "score": 1.0 - m[self.main] / zero if zero > 0 else math.nan,
            "effort_rms": m["effort_rms"],
            "limit_cycle_amp": m["limit_cycle_amp"],
            "iae": m["iae"],
        }
        row["admissible"] = float(row["effort_rms"] <= self.cfg.max_effort_ratio * self.effort_ref)
        self.history.append(row)
        if self.logger is not None:
            for k in ("main", "score", "effort_rms"):
                self.logger.record(f"validation/{k}", row[k])
        if row["admissible"] and (self.best is None or row["main"] < self.best["main"]):
            self.best = row
            snap.write(self.out)
        atomic_text(self.out / "validation.csv", csv_text(self.history))
        if self.reporter is not None:
            self.reporter(row)

    # ----------------------------------------------------------------------------- checkpoints
    def checkpoint(self, model: Any, snap: Snapshot) -> None:
        """The model now (snap: its snapshot), normalizer, replay buffer and this run's state into
        out/checkpoint, each atomically; an evaluation still running is re-run on --resume."""
        ck = self.out / "checkpoint"
        snap.write(ck)
        if hasattr(model, "replay_buffer") and model.replay_buffer is not None:
            atomic_write(ck / "replay_buffer.pkl", lambda p: model.save_replay_buffer(p))
        self.write_state(model)

    def write_state(self, model: Any) -> None:
        state = {
            "num_timesteps": model.num_timesteps,
            "wall_s": self.elapsed(),
            "history": self.history,
            "eval_s": self.eval_s,
            "best": self.best,
            "next_eval": self.next_eval,
            "episodes": model.get_env().get_attr("episodes"),
            "pending": [p.meta for p in self.pending],  # at most the checkpoint's own model
        }
        atomic_text(self.out / "checkpoint" / "state.json", json.dumps(state))

    # ----------------------------------------------------------------------------- the run
    def train(self, resume: bool = False) -> dict[str, Any]:
        """Train, select, write the model folder; returns the manifest."""
        import torch
        from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

        torch.set_num_threads(1)
        cfg, out = self.cfg, self.out
        ck = out / "checkpoint"
        if (out / MANIFEST).exists() and not resume:
            raise FileExistsError(f"{out} holds a finished run; use another --out, or --resume to extend it")
        if not resume and (ck / "state.json").exists():
            raise FileExistsError(f"{out} holds an unfinished run: continue it with --resume")
        out.mkdir(parents=True, exist_ok=True)
        classical = classical_on(self.episodes, self.envs)
        self.baseline, self.zero = best_classical(cfg.scenario, classical), classical[ZERO]
        # admissible effort: relative to the best baseline, and to the base controller in residual mode
        self.effort_ref = min(
            self.baseline.effort_rms, classical[cfg.base]["effort_rms"] if cfg.base else math.inf
        )
        (out / "monitor").mkdir(exist_ok=True)
        venv: Any = VecMonitor(make_training_env(cfg, self.seed), str(out / "monitor"))
        gamma = cfg.hyperparams.get("gamma", 0.99)
        state = None
        if resume and (ck / "state.json").exists():
            state = json.loads((ck / "state.json").read_text())
            if (ck / NORMALIZER).exists():
                venv = VecNormalize.load(str(ck / NORMALIZER), venv)
                venv.training = True
            model = algorithm_class(cfg.algorithm).load(str(ck / MODEL), env=venv, device="cpu")
            model.tensorboard_log = str(out / "tb")
            if (ck / "replay_buffer.pkl").exists():
                model.load_replay_buffer(str(ck / "replay_buffer.pkl"))
            for i, n in enumerate(state["episodes"]):
                venv.env_method("set_episodes", n, indices=[i])
            self.history, self.best, self.next_eval = state["history"], state["best"], state["next_eval"]
            self.wall_before, self.eval_s = state["wall_s"], state.get("eval_s", 0.0)
            for meta in state.get("pending", []):  # the checkpoint's model, not evaluated before the stop
                snap = Snapshot.read(ck)
                self._record(meta, snap, evaluate_snapshot(cfg, self.name, snap, self.episodes))
        else:
            if cfg.normalize_observation or cfg.normalize_reward:
                venv = VecNormalize(
                    venv, norm_obs=cfg.normalize_observation, norm_reward=cfg.normalize_reward, gamma=gamma
                )
            model = build_model(cfg, venv, self.seed, str(out / "tb"))
        done = model.num_timesteps
        self.t0 = time.monotonic()
        remaining = cfg.total_timesteps - done
        try:
            if remaining > 0:
                model.learn(
                    remaining,
                    callback=_callback_class()(self),
                    reset_num_timesteps=state is None,
                    progress_bar=self.progress,
                    tb_log_name="run",
                )
                self.collect(block=True)  # so that a pending evaluation is always the checkpoint's model
                evaluated = self.history and self.history[-1]["step"] == model.num_timesteps
                self.checkpoint(model, Snapshot.of(model) if evaluated else self.validate(model))
                self.collect(block=True)  # the final model's evaluation
                self.write_state(model)
        finally:
            if self.pool is not None:
                self.pool.shutdown(cancel_futures=True)
                self.pool = None
        if self.best is None:
            raise RuntimeError(
                f"{self.name}: no validation evaluation had effort_rms <= {cfg.max_effort_ratio} x "
                f"{self.effort_ref:.4g} (the baseline's): nothing to select"
            )
        manifest = self.manifest(model.num_timesteps)
        atomic_text(out / MANIFEST, yaml.safe_dump(manifest, sort_keys=False))
        plot_curve(self.history, self.baseline, self.main, out / "training_curve.png", self.name)
        return manifest

    def manifest(self, steps: int) -> dict[str, Any]:
        import stable_baselines3

        cfg = self.cfg
        prov = provenance()
        return {
            "name": self.name,
            "algorithm": cfg.algorithm,
            "model": MODEL,
            "normalizer": NORMALIZER if (self.out / NORMALIZER).exists() else None,
            "scenario": cfg.scenario,
            "plants": [load_scenario(cfg.scenario).spec.name],
            "base_controller": cfg.base,
            "alpha": cfg.alpha,
            "inputs": dataclasses.asdict(cfg.inputs),
            "seed": self.seed,
            "steps": int(steps),
            "selected_step": int(self.best["step"]),
            "wall_time_s": round(self.elapsed(), 1),
            "stopped_at_wall_time_limit": self.stopped_early,
            "command": self.command,
            "package_version": prov["package_version"],
            "git_commit": prov["git_commit"],
            "stable_baselines3": stable_baselines3.__version__,
            "torch_threads": 1,
            "training_seeds": (
                f"{TRAINING_SEEDS + self.seed * SEEDS_PER_RUN} + k·{cfg.n_envs} + i (env i, episode k)"
            ),
            "validation": {
                "suite": VALIDATION_SUITE,
                "episodes": len(self.episodes),
                "seeds": [e.seed for e in self.episodes],
                "main_metric": self.main,
                "value": self.best["main"],
                "score": self.best["score"],
                "effort_rms": self.best["effort_rms"],
                "limit_cycle_amp": self.best["limit_cycle_amp"],
                "best_classical": dataclasses.asdict(self.baseline),
                "admissible_effort_rms": self.cfg.max_effort_ratio * self.effort_ref,
            },
            "config": {**cfg.as_dict(), "inputs": dataclasses.asdict(cfg.inputs)},
        }


def plot_curve(
    history: list[dict[str, float]], baseline: Baseline, main: str, path: Path, title: str
) -> None:
    """Validation main metric and effort against training steps, with the best classical baseline."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = [h["step"] for h in history]
    fig, ax = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    ax[0].plot(steps, [h["main"] for h in history], "o-", label="policy (validation mean)")
    ax[0].axhline(baseline.main, color="k", ls="--", label=f"{baseline.name} (best classical)")
    ax[0].set(ylabel=main, yscale="log")
    ax[0].legend()
    ax[1].plot(steps, [h["effort_rms"] for h in history], "o-")
    ax[1].axhline(baseline.effort_rms, color="k", ls="--")
    ax[1].set(ylabel="effort_rms", xlabel="training steps")
    ax[0].set_title(title)
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, dpi=90, format="png"))
    plt.close(fig)


# ------------------------------------------------------------------------------------------- runs
def run_dir(out: Path, cfg: RunConfig, seed: int) -> Path:
    return Path(out) / cfg.name / cfg.scenario / f"seed{seed}"


EXPORTED = (MODEL, NORMALIZER, MANIFEST, "validation.csv", "training_curve.png")


def export_model(run: Path, dest: Path) -> Path:
    """Copy a finished run's model folder (model, statistics, manifest, validation record, curve; not the
    checkpoint or logs) to dest/<name>/, e.g. into agents/models/headline/ to commit it."""

    m = Node(load_yaml(Path(run) / MANIFEST), str(Path(run) / MANIFEST))
    folder = Path(dest) / m["name"]
    folder.mkdir(parents=True, exist_ok=True)
    for f in EXPORTED:
        if (Path(run) / f).exists():
            shutil.copy2(Path(run) / f, folder / f)
    return folder


def train_one(args: tuple[RunConfig, int, str, str, bool, bool]) -> dict[str, Any]:
    """One run (picklable for a process pool): (config, seed, out dir, command, resume, progress), its
    validation beside it."""
    cfg, seed, out, command, resume, progress = args
    with contextlib.redirect_stdout(sys.stderr) if not progress else contextlib.nullcontext():
        return TrainingRun(cfg, seed, Path(out), command, progress, parallel_validation=True).train(resume)


def train_many(
    cfgs: Sequence[RunConfig], seeds: Sequence[int], out: Path, resume: bool, workers: int
) -> list[dict[str, Any]]:
    """Every (config, seed) run; with workers > 1 on a spawn pool, one torch thread each."""
    command = command_line()
    jobs = [(c, s, str(run_dir(out, c, s)), command, resume, workers == 1) for c in cfgs for s in seeds]
    if workers == 1:
        return [train_one(j) for j in jobs]
    # Ctrl-C is the parent's (workers ignore it; the pool's processes are terminated); a killed parent's
    # workers exit by themselves. The pool's processes are not daemonic, so that each run can start its
    # validation worker on the other core (TrainingRun.parallel_validation).
    pool = ProcessPoolExecutor(
        workers,
        mp.get_context("spawn"),
        initializer=init_worker,
        initargs=(os.getpid(),),
        max_tasks_per_child=1,
    )
    try:
        return list(pool.map(train_one, jobs))
    except BaseException:
        stop_workers()
        raise
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
