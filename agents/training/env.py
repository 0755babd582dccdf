"""The training env of a run: the residual wrapper over a single env (the form SB3's DummyVecEnv would
step) and the batched training vector env a run actually steps (vec_env.py)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from frictiongym.agents.evaluation.evaluate import controller_overrides
from frictiongym.agents.learned.policy import (
    LearnedNeeds,
    PolicyInputs,
    difference_indices,
    model_input_size,
    policy_observation,
    residual_action,
)
from frictiongym.envs.config import (
    ConfigError,
)
from frictiongym.envs.scenario import load_scenario

from ..base import Controller, EpisodeContext
from ..registry import base_controller
from ..settings import knowledge_defaults
from .config import RunConfig, scenario_overrides
from .vec_env import TrainingVecEnv, residual_smoothness


# ------------------------------------------------------------------------------------------- env
class ResidualEnv(gym.Wrapper):
    """A scenario's env as a learned compensator sees it: in residual mode the base controller runs in the
    loop (u = clip(u_base + α·a)) and the observation is extended with its action (policy_observation);
    without a base, the env as it is: the single-env form of a training env (agents/training/vec_env.py),
    for rl-zoo (agents/training/zoo.py). `smoothness` > 0 (residual mode) subtracts residual_smoothness from
    the reward."""

    def __init__(
        self,
        env: gym.Env,
        base: Controller | None,
        alpha: float,
        differences: bool = False,
        smoothness: float = 0.0,
    ):
        super().__init__(env)
        if smoothness and base is None:
            raise ValueError("the residual smoothness applies in residual mode (with a base controller)")
        self.base, self.alpha, self.smoothness = base, alpha, smoothness
        self.a_prev = np.zeros(1)
        self.differences = difference_indices(env.unwrapped.scenario) if differences else None
        n = model_input_size(env.observation_space.shape[0], base is not None, differences)
        self.observation_space = spaces.Box(-np.inf, np.inf, (n,), np.float32)
        self.knowledge = knowledge_defaults()

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.a_prev = np.zeros(1)
        return self._observe(obs, reset=True), info

    def _observe(self, obs: np.ndarray, reset: bool = False) -> np.ndarray:
        if self.base is None:
            self.u_base = None
            return policy_observation(obs, None, self.differences)
        if reset:
            sc = self.env.unwrapped.scenario
            self.base.reset(EpisodeContext(sc, sc.spec, self.knowledge))
        self.u_base = self.base.act(obs)
        return policy_observation(obs, self.u_base, self.differences)

    def step(self, action: np.ndarray):
        if self.base is None:
            u = action
        else:
            u = residual_action(self.u_base, action, self.alpha, self.base.residual_share())
        obs, reward, term, trunc, info = self.env.step(np.asarray(u, dtype=np.float32).reshape(1))
        if self.smoothness:
            penalty, self.a_prev = residual_smoothness(np.reshape(action, 1), self.a_prev, self.smoothness)
            reward = float(reward - penalty[0])
        return self._observe(obs), reward, term, trunc, info


def training_env_kwargs(cfg: RunConfig) -> dict[str, Any]:
    """The env keywords of a run's training envs: the config's randomisation and reward, the base
    controller's hardware and the model's observation blocks (as the trained controller's evaluation
    env gets them). Checks that the base applies to the scenario."""

    base = base_controller(cfg.base) if cfg.base is not None else None
    sc = load_scenario(cfg.scenario, scenario_overrides(cfg) or None, randomize=cfg.randomize)
    if base is not None and (reason := base.why_not(sc)) is not None:
        raise ConfigError(
            "residual.base", f"{cfg.base} does not apply to {cfg.scenario}: {reason}", cfg.source
        )
    probe = PolicyShape(cfg.inputs, base)
    return {"randomize": cfg.randomize, "overrides": controller_overrides(probe, sc, scenario_overrides(cfg))}


def make_training_env(cfg: RunConfig, seed: int, nthread: int = 1) -> TrainingVecEnv:
    """The n_envs training envs of run seed `seed` on the batched core, each env's own base controller in
    the loop (agents/training/vec_env.py)."""

    bases = (lambda: base_controller(cfg.base)) if cfg.base is not None else None
    kw = training_env_kwargs(cfg)
    return TrainingVecEnv(
        cfg.scenario,
        cfg.n_envs,
        seed,
        bases=bases,
        alpha=cfg.alpha,
        nthread=nthread,
        differences=cfg.inputs.differences,
        smoothness=cfg.residual_smoothness,
        **kw,
    )


class PolicyShape(LearnedNeeds, Controller):
    """A learned controller's needs (LearnedNeeds) without a model: builds the training env exactly as the
    evaluation builds the trained controller's."""

    name = "shape"

    def __init__(self, inputs: PolicyInputs, base: Controller | None):
        self.inputs, self.base = inputs, base

    def reset(self, ctx: EpisodeContext) -> None:
        raise NotImplementedError("a shape does not act")

    def act(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError("a shape does not act")
