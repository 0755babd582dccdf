"""The training envs of one run, stepped together on the batched core (one mujoco.batch.Batch).

TrainingVecEnv is a stable-baselines3 VecEnv of n_envs episodes of the run's scenario, each as a learned
compensator sees it (agents/training/env.py's ResidualEnv): in residual mode every env's own base controller
runs in the loop (u = clip(u_base + α·a), learned.residual_action) and the observation ends with its action
(learned.policy_observation). It behaves as SB3's DummyVecEnv over n such single envs (same-step
autoreset, terminal_observation, TimeLimit.truncated, float32 rewards), bit for bit (tests/test_training.py
trains both ways and compares the networks), without one Python env step per env: the physics, sensors
and rewards of all envs are one call of ServoCore.step.

Episode seeds follow a fixed schedule, never a suite's: env i's k-th episode has seed
TRAINING_SEEDS + s·SEEDS_PER_RUN + k·n_envs + i for run seed s (seeds passed to reset are ignored, so
SB3's seeding cannot move training onto a suite's seeds). `episodes` counts each env's started episodes,
for --resume.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from frictiongym.agents.learned.policy import (
    difference_indices,
    model_input_size,
    policy_observation,
    residual_action,
)
from frictiongym.envs.suites import seed_range
from frictiongym.envs.vector import ServoVectorEnv

from ..base import Controller, EpisodeContext
from ..settings import knowledge_defaults

TRAINING_SEEDS, _LAST = seed_range("training")  # configs/suites.yaml's range: no suite or study uses it
SEEDS_PER_RUN = 1_000_000  # run seed s owns TRAINING_SEEDS + s·SEEDS_PER_RUN ... + SEEDS_PER_RUN - 1
RUN_SEEDS = (_LAST + 1 - TRAINING_SEEDS) // SEEDS_PER_RUN  # run seeds 0 ... RUN_SEEDS - 1 fit the range


def episode_seed(run_seed: int, env: int, episode: int, n_envs: int) -> int:
    """The seed of env `env`'s episode `episode` (from 0) in a run with n_envs envs."""
    return TRAINING_SEEDS + run_seed * SEEDS_PER_RUN + episode * n_envs + env


def residual_smoothness(
    action: np.ndarray, previous: np.ndarray, weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """The residual's own smoothness penalty, w·(a - a_prev)² on the policy's actions clipped to [-1, 1]
    (float64, elementwise), and the clipped actions, the next call's `previous`: it prices the residual's
    sample-to-sample change, its dither, which the scenario's smoothness term (on the whole command)
    cannot tell from its base's own switching (a relay). `previous` is 0 at an episode's start, where a
    residual starts."""
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    d = a - previous
    return weight * (d * d), a


def _vec_env_base() -> type:
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv

    return VecEnv


class _Slot:
    """Env i as SB3's get_attr / env_method see it: its episode count (for --resume)."""

    render_mode = None  # VecEnv asks its envs

    def __init__(self, owner: TrainingVecEnv, index: int):
        self.owner, self.index = owner, index

    @property
    def episodes(self) -> int:
        return int(self.owner.episodes[self.index])

    def set_episodes(self, n: int) -> None:
        """Continue env i's seed schedule after n episodes (--resume)."""
        self.owner.episodes[self.index] = n


class TrainingVecEnv(_vec_env_base()):
    """n_envs training episodes of one run on the batched core (module docstring)."""

    def __init__(
        self,
        scenario: str,
        n_envs: int,
        run_seed: int,
        *,
        bases: Callable[[], Controller] | None,
        alpha: float,
        randomize: bool,
        overrides: dict | None,
        nthread: int = 1,
        differences: bool = False,
        smoothness: float = 0.0,
    ):
        if not 0 <= run_seed < RUN_SEEDS:
            raise ValueError(f"run seed {run_seed} outside 0-{RUN_SEEDS - 1} (the training seed range)")
        self.venv = ServoVectorEnv(scenario, n_envs, nthread, randomize=randomize, overrides=overrides)
        self.core, self.scenario = self.venv.core, self.venv.scenario
        self.bases = [bases() for _ in range(n_envs)] if bases is not None else None
        self.alpha, self.run_seed = alpha, run_seed
        self.knowledge = knowledge_defaults()
        self.episodes = np.zeros(n_envs, dtype=np.int64)  # episodes started, per env
        self.seeds = np.zeros(n_envs, dtype=np.int64)  # each env's current episode seed
        self.slots = [_Slot(self, i) for i in range(n_envs)]
        self.u_base: list[np.ndarray] = [np.zeros(1)] * n_envs  # each env's base action now, as it gave it
        self.differences = difference_indices(self.scenario) if differences else None
        size = model_input_size(self.core.obs_dim, self.bases is not None, differences)
        space = spaces.Box(-np.inf, np.inf, (size,), np.float32)
        super().__init__(n_envs, space, self.venv.single_action_space)
        self._actions = np.zeros((n_envs, 1), dtype=np.float32)
        self.smoothness = smoothness  # residual_smoothness's weight (residual mode)
        self.a_prev = np.zeros((n_envs, 1))  # each env's previous policy action (residual_smoothness)

    # ------------------------------------------------------------------ episodes
    def _start(self, ids: np.ndarray) -> np.ndarray:
        """New episodes in envs ids, on their schedule's next seeds; their policy observations."""
        seeds = [episode_seed(self.run_seed, int(i), int(self.episodes[i]), self.num_envs) for i in ids]
        self.episodes[ids] += 1
        self.seeds[ids] = seeds
        self.a_prev[ids] = 0.0
        obs = self.core.reset(ids, seeds)
        if self.bases is not None:
            ctx = EpisodeContext(self.scenario, self.scenario.spec, self.knowledge)
            for i in ids:
                self.bases[i].reset(ctx)
        return self._observe(ids, obs)

    def _observe(self, ids: Sequence[int] | np.ndarray, obs: np.ndarray) -> np.ndarray:
        """The policy observations of envs ids: the env's, then (residual) the base's action on it."""
        if self.bases is None:
            return policy_observation(obs, None, self.differences)
        out = np.empty((len(ids), self.observation_space.shape[0]), dtype=np.float32)
        for row, i in enumerate(ids):
            self.u_base[i] = self.bases[i].act(obs[row])
            out[row] = policy_observation(obs[row], self.u_base[i], self.differences)
        return out

    # ------------------------------------------------------------------ VecEnv
    def reset(self) -> np.ndarray:
        return self._start(np.arange(self.num_envs))

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions).reshape(self.num_envs, 1)  # float32, or float64 with noise

    def step_wait(self):
        a, n = self._actions, self.num_envs
        if self.bases is None:  # the env's action is a float32, as a single env receives it
            u = a.astype(np.float32).reshape(n)
        else:
            shares = np.array([np.broadcast_to(b.residual_share(), (1,)) for b in self.bases])
            u = residual_action(np.concatenate(self.u_base).reshape(n, 1), a, self.alpha, shares).reshape(n)
        obs, reward, term, trunc, _ = self.core.step(u)
        if self.smoothness:
            penalty, self.a_prev = residual_smoothness(a, self.a_prev, self.smoothness)
            reward = reward - penalty.reshape(n)
        obs = self._observe(range(self.num_envs), obs)
        done = term | trunc
        infos: list[dict[str, Any]] = [
            {"TimeLimit.truncated": bool(t and not d)} for t, d in zip(trunc, term, strict=True)
        ]
        ids = np.flatnonzero(done)
        for i in ids:
            infos[i]["terminal_observation"] = obs[i].copy()
        if len(ids):
            obs[ids] = self._start(ids)
        return obs, reward.astype(np.float32), done, infos

    def close(self) -> None:
        self.venv.close()

    def _slots(self, indices: Any) -> list[_Slot]:
        return [self.slots[i] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices: Any = None) -> list:
        return [getattr(s, attr_name) for s in self._slots(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        raise AttributeError(f"TrainingVecEnv's envs have no settable attribute {attr_name!r}")

    def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list:
        return [getattr(s, method_name)(*args, **kwargs) for s in self._slots(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False] * len(self._slots(indices))
