"""The simulated world: plant models, friction, sensors, sampling (frictiongym.envs)."""
