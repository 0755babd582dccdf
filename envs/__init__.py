"""The simulated world (frictiongym.envs): plants, friction, sensors, sampling, scenarios, metrics, envs.

Importing this package registers two kinds of Gymnasium id (`frictiongym list` prints them):

- one per plant, frictiongym/M220-v0, frictiongym/FlexibleServo-v0, frictiongym/KangRobot-v0 and
  frictiongym/EMPS-v0, taking scenario= (default: the plant's default scenario) and keyword overrides.
  Their spec has no max_episode_steps: the env ends its own episode (truncated) at its scenario's end.
- one per scenario, e.g. frictiongym/M220-ReversalTracking-v0 for m220_reversal_tracking (the plant's
  name, then the scenario's name without its plant prefix), whose max_episode_steps is that scenario's
  episode length, so TimeLimit, TimeAwareObservation and anything reading env.spec agree with the env.

gym.make_vec(id, num_envs) gives the batched ServoVectorEnv (its default vector_entry_point mode); "sync"
and "async" give Gymnasium's vector envs over gym.make, with the same episodes. gym.make(...,
max_episode_steps=N) with N below the scenario's length truncates earlier.
"""

from __future__ import annotations

import logging
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
VERSION_HISTORY = {  # an env id's version: a change that can alter learning results bumps it (docs/envs)
    "v0": "first release: the four plants and their scenarios as configs/ holds them",
}
PREFIXES = {  # a scenario file's name starts with its plant's prefix (tests check every scenario's plant)
    "m220": "frictiongym/M220-v0",
    "flexible": "frictiongym/FlexibleServo-v0",
    "kang": "frictiongym/KangRobot-v0",
    "emps": "frictiongym/EMPS-v0",
}


@cache
def _env_class(entry: str) -> Any:
    return registration.load_env_creator(f"frictiongym.envs.{entry}")


@cache
def env_id(plant: str) -> str:
    """The registered Gymnasium id (name and version) of a plant's env (its class's `plant`)."""
    return next(i for i, (entry, _) in ENV_IDS.items() if _env_class(entry).plant == plant)


def scenario_env_id(scenario: str) -> str:
    """The registered id of a scenario of configs/scenarios/ (a name such as m220_reversal_tracking):
    its plant's id with the scenario's name, without its plant prefix, in CamelCase before the version
    (frictiongym/M220-ReversalTracking-v0)."""
    prefix, _, rest = scenario.partition("_")
    if prefix not in PREFIXES or not rest:
        raise ValueError(f"scenario {scenario!r} does not start with a plant prefix {list(PREFIXES)}")
    name, _, version = PREFIXES[prefix].rpartition("-")
    return f"{name}-{''.join(w.capitalize() for w in rest.split('_'))}-{version}"


class ScenarioSpec(EnvSpec):
    """The spec of a per-scenario id: its max_episode_steps is its scenario's episode length, read from
    the scenario's YAML the first time it is asked for (importing the package loads no scenario); a value
    assigned explicitly is kept as it is. The scenario is kept apart from kwargs, which gym.make_vec
    empties in its copy of the spec."""

    scenario: str = ""

    @property
    def max_episode_steps(self) -> int | None:
        if self._fixed_steps is None and self.scenario:
            from .scenario import load_scenario  # start-up cost: importing the package only registers ids

            self._fixed_steps = load_scenario(self.scenario).episode_steps
        return self._fixed_steps

    @max_episode_steps.setter
    def max_episode_steps(self, value: int | None) -> None:
        self._fixed_steps = value


def _register() -> dict[str, str]:
    """Register every id (the per-plant ones, then one per scenario); returns {scenario id: scenario}."""
    from .scenario import scenario_names  # configs/scenarios/*.yaml, listed, not loaded

    for id_, (entry, vector) in ENV_IDS.items():
        if id_ not in gym.registry:
            gym.registry[id_] = EnvSpec(
                id=id_,
                entry_point=f"frictiongym.envs.{entry}",
                vector_entry_point=f"frictiongym.envs.{vector}",
            )
    out = {}
    for scenario in scenario_names():
        id_ = scenario_env_id(scenario)
        entry, vector = ENV_IDS[PREFIXES[scenario.partition("_")[0]]]
        out[id_] = scenario
        if id_ not in gym.registry:
            spec = ScenarioSpec(
                id=id_,
                entry_point=f"frictiongym.envs.{entry}",
                vector_entry_point=f"frictiongym.envs.{vector}",
                kwargs={"scenario": scenario},
            )
            spec.scenario = scenario
            gym.registry[id_] = spec
    return out


SCENARIO_IDS = _register()  # per-scenario id -> scenario name
