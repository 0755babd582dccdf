"""Vector environments over mujoco.batch.Batch: a gymnasium.vector.VectorEnv (next-step autoreset) and a
stable-baselines3 VecEnv adapter (same-step autoreset with terminal_observation). Both run ServoCore,
so N envs reset with seeds s_i give the same episodes, bit for bit, as N single envs reset with s_i."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .config import boolean, integer
from .core import ServoCore, check_action, check_options, new_renderer, render_frame
from .metrics import defined_metrics
from .sampler import check_seed
from .scenario import load_scenario
from .servo_env import EMPSEnv, FlexibleServoEnv, JsonSafeSpec, KangRobotEnv, M220Env, ServoEnv, check_plant
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


class ServoVectorEnv(JsonSafeSpec, VectorEnv):
    """num_envs episodes of one scenario stepped together on a thread pool (nthread 0: all CPUs).

    reset(seed=s) seeds env i with s + i (or pass a list). An env whose episode ended is reset on the
    next step() call (AutoresetMode.NEXT_STEP), with the next seed drawn from its own generator, seeded
    by its reset seed exactly as a single env's np_random: env i then runs the same episode sequence as a
    single env reset with seed s + i and then reset without a seed after each episode.

    It takes what gym.make_vec passes to a vector entry point: the single env's keywords (randomize,
    control_period_s, episode_s, overrides, render_mode, ground_truth_in_info) and max_episode_steps,
    which truncates as Gymnasium's TimeLimit does. Observations, rewards, flags and infos equal those of
    a SyncVectorEnv over gym.make with the same arguments, bit for bit: infos follow its convention (a
    value array and a `_key` mask per key, nested for dicts), an autoreset step carries the new
    episode's reset info, and the last step of an episode its episode_metrics.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": ["rgb_array"]}  # noqa: RUF012

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
        render_mode: str | None = None,
        max_episode_steps: int | None = None,
        ground_truth_in_info: bool = False,
        plant: str | None = None,
    ):
        integer(num_envs, "num_envs", 1)
        integer(nthread, "nthread", 0)  # 0: all CPUs
        self.max_episode_steps = (
            None if max_episode_steps is None else integer(max_episode_steps, "max_episode_steps", 1)
        )
        self.ground_truth_in_info = boolean(ground_truth_in_info, "ground_truth_in_info")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} not in {self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.scenario = load_scenario(
            scenario, overrides, randomize=randomize, control_period_s=control_period_s, episode_s=episode_s
        )
        check_plant(self.scenario, plant)
        self.num_envs = int(num_envs)
        self.core = ServoCore(self.scenario, n=num_envs, nthread=nthread, batch=True)
        self.single_observation_space = spaces.Box(-OBS_CLIP, OBS_CLIP, (self.core.obs_dim,), np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._rngs = [np.random.default_rng(i) for i in range(num_envs)]
        self._done = np.zeros(num_envs, dtype=bool)
        self._elapsed = np.zeros(num_envs, dtype=int)  # steps since each env's reset (max_episode_steps)
        self._all = np.arange(num_envs)
        self._started = False  # VectorEnv.close() sets self.closed
        self._renderer: tuple[mujoco.Renderer, mujoco.MjData] | None = None

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

    def _reset_info(self, i: int, seed: int, pinned: dict) -> dict[str, Any]:
        """What a single env's reset returns as info for env i's new episode."""
        info = {"params": self.core.params_dict(i), "pinned": pinned, "episode_seed": seed}
        if self.ground_truth_in_info:
            info.update(self.core.ground_truth(i))
        return info

    def _reset_envs(self, ids: np.ndarray, seeds: list[int], pinned: dict, info: dict) -> np.ndarray:
        """Start new episodes in envs ids; their reset infos are added to info (Gymnasium's convention)."""
        obs = self.core.reset(ids, seeds, pinned)
        if "episode_seed" not in info:  # Python ints above int64 (numpy seeds are unbounded) as objects
            info["episode_seed"] = np.zeros(self.num_envs, dtype=int if max(seeds) < 2**63 else object)
        for i, s in zip(ids, seeds, strict=True):
            self._add_info(info, self._reset_info(int(i), s, pinned), int(i))
        self._elapsed[ids] = 0
        return obs

    def reset(self, *, seed: int | Sequence[int] | None = None, options: dict | None = None):
        """Reset every env (see the class docstring for seeds); options={"params": {...}} pins parameters
        for these episodes. A failed reset (bad seed or options) leaves the env as it was."""
        if self.closed:
            raise RuntimeError("reset() after close(): make a new env")
        pinned = check_options(options)
        given = None if seed is None else _seeds(seed, self.num_envs, self.np_random)  # checked first
        super().reset(seed=int(seed) if isinstance(seed, int | np.integer) else None)
        seeds = given if given is not None else _seeds(None, self.num_envs, self.np_random)
        info: dict[str, Any] = {}
        obs = self._reset_envs(self._all, seeds, pinned, info)
        self._rngs = [np.random.default_rng(s) for s in seeds]  # as a single env's np_random
        self._done[:] = False
        self._started = True
        return obs, info

    def _next_seeds(self, ids: np.ndarray) -> list[int]:
        return [int(self._rngs[i].integers(2**63)) for i in ids]

    def step(self, actions: np.ndarray):
        if not self._started:
            if self.closed:
                raise RuntimeError("step() after close(): make a new env")
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
            if self.ground_truth_in_info:
                inf.update({k: v[active] for k, v in self.ground_truth().items()})
            mask = ~self._done
            for key, value in inf.items():  # Gymnasium's vector info convention: value array + mask
                value = np.asarray(value)
                full = np.zeros((n, *value.shape[1:]), dtype=value.dtype)
                full[active] = value
                info[key], info[f"_{key}"] = full, mask
            self._elapsed[active] += 1
            if self.max_episode_steps is not None:  # as TimeLimit: truncated at the limit
                trunc[active] |= self._elapsed[active] >= self.max_episode_steps
        if len(was_done):  # autoreset: the action is ignored, the observation is the new episode's first
            obs[was_done] = self._reset_envs(was_done, self._next_seeds(was_done), {}, info)
        for i in np.flatnonzero(self.core.ended & (term | trunc)):  # the env's own end, not a TimeLimit's
            self._add_info(info, {"episode_metrics": defined_metrics(self.core.metrics(i))}, int(i))
        self._done = term | trunc
        return obs, reward.astype(np.float64), term, trunc, info

    def render(self) -> tuple[np.ndarray, ...] | None:
        """One RGB frame per env, as SyncVectorEnv's render gives (headless: MUJOCO_GL=egl or osmesa)."""
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            self._renderer = (new_renderer(self.core.model), mujoco.MjData(self.core.model))
        renderer, data = self._renderer
        qpos, qvel, *_ = self.core.backend.state()
        frames = []
        for i in range(self.num_envs):
            data.qpos[:], data.qvel[:] = qpos[i], qvel[i]
            mujoco.mj_forward(self.core.model, data)
            frames.append(render_frame(renderer, data))
        return tuple(frames)

    def close_extras(self, **kwargs: Any) -> None:
        """Release the renderer; the env cannot step or reset after close() (VectorEnv.close)."""
        if self._renderer is not None:
            self._renderer[0].close()
            self._renderer = None
        self._started = False


class SubEnv:
    """Env i of a ServoVectorEnv as a sub-env of SB3's VecEnv methods see it: its own ground truth and
    episode parameters, the single env's spaces, the vector env's other attributes (scenario, core, ...),
    and attributes set on it alone (VecEnv.set_attr with indices)."""

    def __init__(self, venv: ServoVectorEnv, index: int):
        self.venv, self.index = venv, index
        self.observation_space, self.action_space = venv.single_observation_space, venv.single_action_space

    def ground_truth(self) -> dict[str, np.ndarray]:
        """What ServoEnv.ground_truth() returns, for this env."""
        return self.venv.core.ground_truth(self.index)

    def params(self) -> dict[str, Any]:
        """This env's episode parameters (a single env's reset info["params"])."""
        return self.venv.core.params_dict(self.index)

    def __getattr__(self, name: str) -> Any:  # only for names not set on this sub-env
        return getattr(self.venv, name)


def make_sb3_vec_env(scenario: str | Path, num_envs: int, nthread: int = 0, seed: int = 0, **kwargs: Any):
    """A stable-baselines3 VecEnv over the batched core (same-step autoreset; terminal_observation and
    TimeLimit.truncated in infos as SB3 expects). get_attr, set_attr and env_method act per sub-env
    (SubEnv), with SB3's indices (None: all, an int, or a list)."""
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv

    class SB3ServoVecEnv(VecEnv):
        def __init__(self) -> None:
            self.venv = ServoVectorEnv(scenario, num_envs, nthread, **kwargs)
            self.envs = [SubEnv(self.venv, i) for i in range(num_envs)]  # before VecEnv asks them
            super().__init__(num_envs, self.venv.single_observation_space, self.venv.single_action_space)
            self._seed = seed
            self._actions = np.zeros(num_envs)

        def reset(self) -> np.ndarray:
            obs, _ = self.venv.reset(seed=self._seed)  # after close(): the vector env's error
            return obs

        def step_async(self, actions: np.ndarray) -> None:
            self._actions = check_action(actions, num_envs)

        def step_wait(self):
            if not self.venv._started:
                if self.venv.closed:
                    raise RuntimeError("step() after close(): make a new env")
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
                    "episode_metrics": defined_metrics(core.metrics(i)),
                }
            if len(ids):
                obs[ids] = core.reset(ids, self.venv._next_seeds(ids))
            return obs, reward.astype(np.float32), done, infos

        def close(self) -> None:
            self.venv.close()

        def get_attr(self, attr_name: str, indices=None) -> list:
            return [getattr(self.envs[i], attr_name) for i in self._get_indices(indices)]

        def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
            for i in self._get_indices(indices):
                setattr(self.envs[i], attr_name, value)

        def env_method(self, method_name: str, *args, indices=None, **kw) -> list:
            return [getattr(self.envs[i], method_name)(*args, **kw) for i in self._get_indices(indices)]

        def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
            return [False] * len(list(self._get_indices(indices)))

        def seed(self, seed: int | None = None) -> list[int | None]:
            self._seed = 0 if seed is None else seed
            return [self._seed + i for i in range(num_envs)]

    return SB3ServoVecEnv()


def _vector_entry(env_class: type[ServoEnv]):
    """The gym.make_vec entry point (vectorization_mode="vector_entry_point", its default here) of a
    plant's env: its default scenario, and a scenario of another plant refused as gym.make refuses it."""

    def make(num_envs: int = 1, scenario: str | Path | None = None, **kwargs: Any) -> ServoVectorEnv:
        return ServoVectorEnv(
            scenario or env_class.default_scenario, num_envs, plant=env_class.plant, **kwargs
        )

    return make


m220_vector = _vector_entry(M220Env)
flexible_servo_vector = _vector_entry(FlexibleServoEnv)
kang_robot_vector = _vector_entry(KangRobotEnv)
emps_vector = _vector_entry(EMPSEnv)
