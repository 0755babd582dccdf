"""Vector environments over mujoco.batch.Batch: a gymnasium.vector.VectorEnv (next-step autoreset) and a
stable-baselines3 VecEnv adapter (same-step autoreset with terminal_observation). Both run ServoCore,
so N envs reset with seeds s_i give the same episodes, bit for bit, as N single envs reset with s_i."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .config import integer
from .core import ServoCore, check_action, check_options
from .sampler import check_seed
from .scenario import load_scenario
from .step import OBS_CLIP


def _seeds(seed: int | Sequence[int] | None, n: int, rng: np.random.Generator) -> list[int]:
    """Env i's seed: seed + i, or the i-th of a list, or drawn; each checked as the single env checks it."""
    if seed is None:
        return [int(x) for x in rng.integers(2**63, size=n)]
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer | list | tuple | np.ndarray):
        raise ValueError(f"seed: expected a non-negative integer or a list of {n}, got {seed!r}")
    if isinstance(seed, int | np.integer):
        return [check_seed(seed) + i for i in range(n)]
    if len(seed) != n:
        raise ValueError(f"seed: expected {n} seeds, got {len(seed)}")
    return [check_seed(s, f"seed[{i}]") for i, s in enumerate(seed)]


def _seed_array(seeds: list[int]) -> np.ndarray:
    """The seeds for info: uint64 when they fit, else Python ints (numpy's seeds have no upper bound)."""
    return np.array(seeds, dtype=np.uint64 if max(seeds) < 2**64 else object)


class ServoVectorEnv(VectorEnv):
    """num_envs episodes of one scenario stepped together on a thread pool (nthread 0: all CPUs).

    reset(seed=s) seeds env i with s + i (or pass a list). An env whose episode ended is reset on the
    next step() call (AutoresetMode.NEXT_STEP), with the next seed drawn from its own generator, seeded
    by its reset seed exactly as a single env's np_random: env i then runs the same episode sequence as a
    single env reset with seed s + i and then reset without a seed after each episode.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012 (Gymnasium's convention)

    def __init__(
        self,
        scenario: str | Path,
        num_envs: int,
        nthread: int = 0,
        *,
        randomize: bool | None = None,
        control_period_s: float | None = None,
        episode_s: float | None = None,
        overrides: dict | None = None,
    ):
        integer(num_envs, "num_envs", 1)
        integer(nthread, "nthread", 0)  # 0: all CPUs
        self.scenario = load_scenario(
            scenario, overrides, randomize=randomize, control_period_s=control_period_s, episode_s=episode_s
        )
        self.num_envs = int(num_envs)
        self.core = ServoCore(self.scenario, n=num_envs, nthread=nthread, batch=True)
        self.single_observation_space = spaces.Box(-OBS_CLIP, OBS_CLIP, (self.core.obs_dim,), np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._rngs = [np.random.default_rng(i) for i in range(num_envs)]
        self._done = np.zeros(num_envs, dtype=bool)
        self._all = np.arange(num_envs)
        self._started = False

    def ground_truth(self) -> dict[str, np.ndarray]:
        """True states of every env now, one row each: what a single env's ground_truth() returns (qpos
        rad, qvel rad/s, bristle rad, friction_torque N·m). A method, not info, so that step() stays cheap."""
        return self.core.ground_truth(slice(None))

    def params(self) -> list[dict[str, Any]]:
        """Each env's current episode parameters: what a single env's reset info["params"] holds."""
        return [self.core.params_dict(i) for i in range(self.num_envs)]

    def __reduce__(self):
        raise TypeError(
            "ServoVectorEnv cannot be pickled: it holds a mujoco.batch.Batch and its threads. Build it where "
            "it is used, from its arguments (ServoVectorEnv(scenario, num_envs, ...))."
        )

    def reset(self, *, seed: int | Sequence[int] | None = None, options: dict | None = None):
        """Reset every env (see the class docstring for seeds); options={"params": {...}} pins parameters
        for these episodes. A failed reset (bad seed or options) leaves the env as it was."""
        pinned = check_options(options)
        given = None if seed is None else _seeds(seed, self.num_envs, self.np_random)  # checked first
        super().reset(seed=int(seed) if isinstance(seed, int | np.integer) else None)
        seeds = given if given is not None else _seeds(None, self.num_envs, self.np_random)
        obs = self.core.reset(self._all, seeds, pinned)
        self._rngs = [np.random.default_rng(s) for s in seeds]
        self._done[:] = False
        self._started = True
        return obs, {"episode_seed": _seed_array(seeds), "pinned": pinned}

    def _next_seeds(self, ids: np.ndarray) -> list[int]:
        return [int(self._rngs[i].integers(2**63)) for i in ids]

    def step(self, actions: np.ndarray):
        if not self._started:
            raise RuntimeError("step() before reset(): call reset() first")
        actions = check_action(actions, self.num_envs)
        n = self.num_envs
        active, was_done = np.flatnonzero(~self._done), np.flatnonzero(self._done)
        obs = np.zeros((n, self.core.obs_dim), dtype=np.float32)
        reward, term, trunc = np.zeros(n), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        info: dict[str, Any] = {}
        if len(active):
            o, r, te, tr, inf = self.core.step(actions[active], active)
            obs[active], reward[active], term[active], trunc[active] = o, r, te, tr
            for key, value in inf.items():  # Gymnasium's vector info convention: value array + mask
                full = np.zeros(n, dtype=np.asarray(value).dtype)
                full[active] = value
                info[key], info[f"_{key}"] = full, ~self._done
        if len(was_done):  # autoreset: the action is ignored, the observation is the new episode's first
            obs[was_done] = self.core.reset(was_done, self._next_seeds(was_done))
        self._done = term | trunc
        ended = np.flatnonzero(self._done)
        if len(ended):
            info["episode_metrics"] = np.array(
                [self.core.metrics(i) if self._done[i] else None for i in range(self.num_envs)], dtype=object
            )
            info["_episode_metrics"] = self._done.copy()
        return obs, reward.astype(np.float64), term, trunc, info


def make_sb3_vec_env(scenario: str | Path, num_envs: int, nthread: int = 0, seed: int = 0, **kwargs: Any):
    """A stable-baselines3 VecEnv over the batched core (same-step autoreset; terminal_observation and
    TimeLimit.truncated in infos as SB3 expects)."""
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv

    class SB3ServoVecEnv(VecEnv):
        def __init__(self) -> None:
            self.venv = ServoVectorEnv(scenario, num_envs, nthread, **kwargs)
            super().__init__(num_envs, self.venv.single_observation_space, self.venv.single_action_space)
            self._seed = seed
            self._actions = np.zeros(num_envs)

        def reset(self) -> np.ndarray:
            obs, _ = self.venv.reset(seed=self._seed)
            return obs

        def step_async(self, actions: np.ndarray) -> None:
            self._actions = check_action(actions, num_envs)

        def step_wait(self):
            if not self.venv._started:
                raise RuntimeError("step() before reset(): call reset() first")
            core = self.venv.core
            obs, reward, term, trunc, _ = core.step(self._actions)
            done = term | trunc
            infos: list[dict] = [{} for _ in range(num_envs)]
            ids = np.flatnonzero(done)
            for i in ids:
                infos[i] = {
                    "terminal_observation": obs[i].copy(),
                    "TimeLimit.truncated": bool(trunc[i] and not term[i]),
                    "episode_metrics": core.metrics(i),
                }
            if len(ids):
                obs[ids] = core.reset(ids, self.venv._next_seeds(ids))
            return obs, reward.astype(np.float32), done, infos

        def close(self) -> None:
            return None

        def get_attr(self, attr_name: str, indices=None) -> list:
            return [getattr(self.venv, attr_name)] * len(self._indices(indices))

        def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
            setattr(self.venv, attr_name, value)

        def env_method(self, method_name: str, *args, indices=None, **kw) -> list:
            return [getattr(self.venv, method_name)(*args, **kw)] * len(self._indices(indices))

        def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
            return [False] * len(self._indices(indices))

        def _indices(self, indices) -> list[int]:
            if indices is None:
                return list(range(num_envs))
            return [indices] if isinstance(indices, int) else list(indices)

        def seed(self, seed: int | None = None) -> list[int | None]:
            self._seed = 0 if seed is None else seed
            return [self._seed + i for i in range(num_envs)]

    return SB3ServoVecEnv()


def _vector_entry(default_scenario: str):
    """A gym.make_vec entry point (vectorization_mode="vector_entry_point") over mujoco.batch."""

    def make(num_envs: int = 1, scenario: str | Path | None = None, **kwargs: Any) -> ServoVectorEnv:
        return ServoVectorEnv(scenario or default_scenario, num_envs, **kwargs)

    return make


m220_vector = _vector_entry("m220_regulation")
flexible_servo_vector = _vector_entry("flexible_speed_step")
kang_robot_vector = _vector_entry("kang_regulation")
