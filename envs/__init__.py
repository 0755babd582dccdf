"""The simulated world (frictiongym.envs): plants, friction, sensors, sampling, scenarios, metrics, envs.

Importing this package registers the Gymnasium ids frictiongym/M220-v0, frictiongym/FlexibleServo-v0 and
frictiongym/KangRobot-v0 (each takes scenario= and keyword overrides).
"""

import gymnasium as gym

ENV_IDS = {
    "frictiongym/M220-v0": "frictiongym.envs.servo_env:M220Env",
    "frictiongym/FlexibleServo-v0": "frictiongym.envs.servo_env:FlexibleServoEnv",
    "frictiongym/KangRobot-v0": "frictiongym.envs.servo_env:KangRobotEnv",
}

for _id, _entry in ENV_IDS.items():
    if _id not in gym.registry:
        gym.register(id=_id, entry_point=_entry, disable_env_checker=True)
