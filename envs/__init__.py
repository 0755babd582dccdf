"""The simulated world (frictiongym.envs): plants, friction, sensors, sampling, scenarios, metrics, envs.

Importing this package registers the Gymnasium ids frictiongym/M220-v0, frictiongym/FlexibleServo-v0,
frictiongym/KangRobot-v0 and frictiongym/EMPS-v0 (each takes scenario= and keyword overrides).
gym.make_vec(id, num_envs) gives the batched ServoVectorEnv (its default vector_entry_point mode); "sync"
and "async" give Gymnasium's vector envs over gym.make, with the same episodes.

Each spec's max_episode_steps is the episode length of the scenario the call chooses (the default
scenario's when read from the registry), so TimeLimit, TimeAwareObservation and anything reading
env.spec agree with the env; gym.make(..., max_episode_steps=N) with N below it truncates earlier.
"""

from __future__ import annotations

import logging
import sys
from functools import cache
from typing import Any

import gymnasium as gym
import mujoco
from gymnasium.envs import registration
from gymnasium.envs.registration import EnvSpec

# MuJoCo writes its warnings to MUJOCO_LOG.TXT in the working directory; route them to Python logging
# instead (a divergence is reported per episode through info["diverged"]).
mujoco.set_mju_user_warning(lambda msg: logging.getLogger("frictiongym.mujoco").warning(msg))

ENV_IDS = {  # id -> (single env, vector env over mujoco.batch for gym.make_vec)
    "frictiongym/M220-v0": ("servo_env:M220Env", "vector:m220_vector"),
    "frictiongym/FlexibleServo-v0": ("servo_env:FlexibleServoEnv", "vector:flexible_servo_vector"),
    "frictiongym/KangRobot-v0": ("servo_env:KangRobotEnv", "vector:kang_robot_vector"),
    "frictiongym/EMPS-v0": ("servo_env:EMPSEnv", "vector:emps_vector"),
}
_MAKERS = (registration.make.__code__, registration.make_vec.__code__)


@cache
def _env_class(entry: str) -> Any:
    return registration.load_env_creator(f"frictiongym.envs.{entry}")


@cache
def env_id(plant: str) -> str:
    """The registered Gymnasium id (name and version) of a plant's env (its class's `plant`)."""
    return next(i for i, (entry, _) in ENV_IDS.items() if _env_class(entry).plant == plant)


def episode_steps(entry: str, kwargs: dict[str, Any]) -> int:
    """Control periods in an episode of the env `entry` made with these keyword arguments."""
    from .scenario import load_scenario  # start-up cost: importing the package only registers ids

    return load_scenario(
        kwargs.get("scenario") or _env_class(entry).default_scenario,
        kwargs.get("overrides"),
        control_period_s=kwargs.get("control_period_s"),
        episode_s=kwargs.get("episode_s"),
    ).episode_steps


class ScenarioSpec(EnvSpec):
    """An EnvSpec whose max_episode_steps is the episode length of the scenario being made.

    Gymnasium reads a spec's max_episode_steps inside gym.make (for its TimeLimit) and gym.make_vec (for
    the vector entry point's max_episode_steps) from the registered spec, which cannot know the call's
    `scenario=`. Read from one of those two calls, this spec answers for the env they are making (the
    env just built, or the call's keyword arguments); read anywhere else, for the registered arguments
    (the default scenario). A value assigned explicitly is kept as it is.
    """

    @property
    def max_episode_steps(self) -> int | None:
        if self._fixed_steps is not None:
            return self._fixed_steps
        caller = sys._getframe(1)
        if caller.f_code in _MAKERS:
            env = caller.f_locals.get("env")
            if env is not None and hasattr(env.unwrapped, "scenario"):  # gym.make: the env it just built
                return env.unwrapped.scenario.episode_steps
            return episode_steps(self._entry, caller.f_locals.get("env_spec_kwargs", {}))
        return episode_steps(self._entry, self.kwargs)

    @max_episode_steps.setter
    def max_episode_steps(self, value: int | None) -> None:
        self._fixed_steps = value

    @property
    def _entry(self) -> str:
        return ENV_IDS[self.id][0]


for _id, (_entry, _vector) in ENV_IDS.items():
    if _id not in gym.registry:
        gym.registry[_id] = ScenarioSpec(
            id=_id,
            entry_point=f"frictiongym.envs.{_entry}",
            vector_entry_point=f"frictiongym.envs.{_vector}",
        )
