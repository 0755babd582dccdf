"""The simulated world (frictiongym.envs): plants, friction, sensors, sampling, scenarios, metrics, envs.

Importing this package registers two kinds of Gymnasium id (`frictiongym list` prints them):

- one per plant, frictiongym/M220-v1, frictiongym/FlexibleServo-v1, frictiongym/KangRobot-v1 and
  frictiongym/EMPS-v1, taking scenario= (default: the plant's default scenario) and keyword overrides.
  Their max_episode_steps is the default scenario's length; a scenario= or episode_s= whose episode is
  longer is refused in one line naming the per-scenario id to use (its TimeLimit would cut the episode).
- one per scenario, e.g. frictiongym/M220-ReversalTracking-v1 for m220_reversal_tracking (the plant's
  name, then the scenario's name without its plant prefix), whose max_episode_steps is that scenario's
  episode length, so TimeLimit, TimeAwareObservation and anything reading env.spec agree with the env.

gym.make_vec(id, num_envs) gives the batched ServoVectorEnv (its default vector_entry_point mode); "sync"
and "async" give Gymnasium's vector envs over gym.make, with the same episodes. gym.make(...,
max_episode_steps=N) with N below the scenario's length truncates earlier.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import gymnasium as gym
from gymnasium.envs import registration
from gymnasium.envs.registration import EnvSpec

VERSION = "v1"  # every id's version: a change that can alter learning results bumps it (VERSION_HISTORY)
PLANT_NAMES = {  # a scenario file's prefix -> its plant's id name (tests check every scenario's plant)
    "m220": "M220",
    "flexible": "FlexibleServo",
    "kang": "KangRobot",
    "emps": "EMPS",
}
ENTRIES = {  # id name -> (single env, vector env over mujoco.batch for gym.make_vec)
    "M220": ("servo_env:M220Env", "vector:m220_vector"),
    "FlexibleServo": ("servo_env:FlexibleServoEnv", "vector:flexible_servo_vector"),
    "KangRobot": ("servo_env:KangRobotEnv", "vector:kang_robot_vector"),
    "EMPS": ("servo_env:EMPSEnv", "vector:emps_vector"),
}
ENV_IDS = {f"frictiongym/{name}-{VERSION}": entries for name, entries in ENTRIES.items()}
VERSION_HISTORY = {  # what each version changed (docs/envs.md, "Versions")
    "v0": "first release: the four plants and their scenarios as configs/ holds them",
    "v1": "a delay of whole physics steps reads the same history sample at every step (it read one step "
    "later after about 32,000 steps, 16 s on a 0.5 ms step, from the rounding of MuJoCo's time: episodes "
    "longer than that changed); the M220's belts hold a constant constraint impedance (a linear "
    "spring-damper; the default impedance grew with the stretch); the friction-free twin "
    "(nonlinear_friction false) drops the bristle damping σ1 too",
}
PREFIXES = {prefix: f"frictiongym/{name}-{VERSION}" for prefix, name in PLANT_NAMES.items()}


@cache
def _env_class(entry: str) -> Any:
    return registration.load_env_creator(f"frictiongym.envs.{entry}")


def plant_env(id_: str, **kwargs: Any) -> gym.Env:
    """A per-plant id's env (its registered entry point, through one function per id below): the plant's
    env class with the make's keywords, refused in one line if its episode is longer than the id's
    TimeLimit (the default scenario's length), which would cut it short."""
    env = _env_class(ENV_IDS[id_][0])(**kwargs)
    limit, steps = gym.spec(id_).max_episode_steps, env.scenario.episode_steps
    if limit is not None and steps > limit:
        env.close()
        name = env.scenario.name
        use = (
            f"gym.make({scenario_env_id(name)!r}, ...)"
            if name in SCENARIO_IDS.values()
            else f"gymnasium.wrappers.TimeLimit({type(env).__name__}(scenario=...), {steps})"
        )
        raise ValueError(
            f"{id_}: this episode is {steps} steps, longer than the id's TimeLimit of {limit} (its default "
            f"scenario's length), which would cut it short; use {use}"
        )
    return env


def _plant_entry(id_: str) -> str:
    """The name of the module-level function that makes a per-plant id's env (an entry point must be a
    string for specs to round-trip through JSON and pickle)."""
    return "make_" + id_.split("/")[1].split("-")[0].lower()


for _id in ENV_IDS:
    globals()[_plant_entry(_id)] = lambda _i=_id, **kwargs: plant_env(_i, **kwargs)


@cache
def env_id(plant: str) -> str:
    """The registered Gymnasium id (name and version) of a plant's env (its class's `plant`)."""
    return next(i for i, (entry, _) in ENV_IDS.items() if _env_class(entry).plant == plant)


def scenario_env_id(scenario: str) -> str:
    """The registered id of a scenario of configs/scenarios/ (a name such as m220_reversal_tracking):
    its plant's id with the scenario's name, without its plant prefix, in CamelCase before the version
    (frictiongym/M220-ReversalTracking-v1)."""
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


class PlantIdSpec(ScenarioSpec):
    """The spec of a per-plant id: its scenario is the plant's default one, read from the env class the
    first time it is asked for (importing the package imports no MuJoCo: a command's --help)."""

    plant_entry: str = ""

    @property
    def scenario(self) -> str:  # type: ignore[override]
        return _env_class(self.plant_entry).default_scenario


def _register() -> dict[str, str]:
    """Register every id (the per-plant ones, then one per scenario); returns {scenario id: scenario}."""
    from .config import scenario_names  # configs/scenarios/*.yaml, listed, not loaded

    for id_, (entry, vector) in ENV_IDS.items():
        if id_ not in gym.registry:
            plant = PlantIdSpec(
                id=id_,
                entry_point=f"frictiongym.envs:{_plant_entry(id_)}",
                vector_entry_point=f"frictiongym.envs.{vector}",
            )
            plant.plant_entry = entry
            gym.registry[id_] = plant
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
