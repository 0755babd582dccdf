"""Friction that drifts within an episode: levels scaled by λ(t) drawn per episode, applied alike in the
single env, the vector env (the batched backend) and a pickled copy, with the ground truth of the levels."""

import numpy as np
import pytest
from conftest import lockstep

from frictiongym.envs.config import ConfigError
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.servo_env import ServoEnv

KW = {"randomize": True, "episode_s": 2.0}
DRIFT = {"friction_drift": {"drift": [-0.5, 0.5], "step": [-0.5, -0.4], "step_at_s": [0.5, 1.5]}}


def test_the_levels_follow_the_drawn_drift_and_the_friction_follows_them():
    env = ServoEnv("m220_reversal_tracking", overrides=DRIFT, **KW)
    env.reset(seed=7)
    base = env.core.params[0].friction[0]
    lam = env.core.drift[0]
    t = env.core.t[:-1]
    # λ = (1 + a t/T)(1 + s [t >= t_s]): one jump of 40-50 % down, linear elsewhere
    jumps = np.flatnonzero(np.abs(np.diff(lam)) > 0.1)
    assert len(jumps) == 1 and 0.5 <= t[jumps[0] + 1] <= 1.5
    ratio = lam[jumps[0] + 1] / lam[jumps[0]]
    assert 0.5 - 1e-3 <= ratio <= 0.6 + 1e-3
    for _ in range(150):
        env.step(np.array([0.3]))
        gt = env.ground_truth()
        k = env.core.k[0]
        assert gt["friction_scale"] == lam[k]
        np.testing.assert_allclose(gt["coulomb_level"], [base.fc * lam[k]], rtol=1e-15)
    # what the MuJoCo model holds is the level of the period just simulated
    assert env.core.model.actuator_biasprm[env.core.fric_act[0], 3] == base.fc * lam[149]


def test_drift_is_bit_identical_in_the_single_env_the_vector_env_and_a_copy():
    keys = ("qpos", "friction_torque", "coulomb_level", "friction_scale")
    lockstep("m220_reversal_tracking", {"overrides": DRIFT, **KW}, keys, copy_at=100)  # on the same drift


def test_drift_needs_lugre_and_bounded_fractions():
    with pytest.raises(ConfigError, match="friction_drift"):
        load_scenario("m220_reversal_tracking", {**DRIFT, "friction_model": "coulomb"})
    with pytest.raises(ConfigError, match=r"friction_drift\.step"):
        load_scenario("m220_drift", {"friction_drift": {"step": [-1.0, 0.0]}})
