"""The simulated world (frictiongym.envs): plants, friction, sensors, sampling, scenarios, metrics, envs.

Importing this package registers the Gymnasium ids frictiongym/M220-v0, frictiongym/FlexibleServo-v0 and
frictiongym/KangRobot-v0 (each takes scenario= and keyword overrides); gym.make_vec(id, num_envs,
vectorization_mode="vector_entry_point") gives the batched ServoVectorEnv.
"""

import logging
from functools import cache

import gymnasium as gym
import mujoco

# MuJoCo writes its warnings to MUJOCO_LOG.TXT in the working directory; route them to Python logging
# instead (a divergence is reported per episode through info["diverged"]).
mujoco.set_mju_user_warning(lambda msg: logging.getLogger("frictiongym.mujoco").warning(msg))

ENV_IDS = {  # id -> (single env, vector env over mujoco.batch for gym.make_vec)
    "frictiongym/M220-v0": ("servo_env:M220Env", "vector:m220_vector"),
    "frictiongym/FlexibleServo-v0": ("servo_env:FlexibleServoEnv", "vector:flexible_servo_vector"),
    "frictiongym/KangRobot-v0": ("servo_env:KangRobotEnv", "vector:kang_robot_vector"),
}


@cache
def env_id(plant: str) -> str:
    """The registered Gymnasium id (name and version) of a plant's env (its class's `plant`)."""
    from gymnasium.envs.registration import load_env_creator

    return next(
        i for i, (entry, _) in ENV_IDS.items() if load_env_creator(f"frictiongym.envs.{entry}").plant == plant
    )


for _id, (_entry, _vector) in ENV_IDS.items():
    if _id not in gym.registry:
        gym.register(
            id=_id,
            entry_point=f"frictiongym.envs.{_entry}",
            vector_entry_point=f"frictiongym.envs.{_vector}",
            disable_env_checker=True,
        )
