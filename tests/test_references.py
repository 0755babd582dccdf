"""References drawn per episode (type random): from the seed alone, within the family's limits, the same
in the single env, the vector env and a pickled copy."""

import pickle

import numpy as np
import pytest

from frictiongym.envs.config import ConfigError
from frictiongym.envs.references import SEGMENT_KINDS, RandomReference
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.vector import ServoVectorEnv

FAMILY = RandomReference(SEGMENT_KINDS, (0.5, 2.0), 1.0, (0.1, 2.0), 8.0, (0.1, 1.0), 0.01)


def test_a_drawn_reference_stays_within_its_limits_and_holds_carry_the_load():
    t = np.arange(20001) * 1e-3
    for seed in range(20):
        r, load = FAMILY.draw(np.random.default_rng(seed), t)
        assert np.all(np.abs(r) <= 1.0 + 1e-12)
        v = np.diff(r) / 1e-3
        moving = np.abs(v) > 1e-9
        # apart from set-point steps (jumps) no segment moves faster than the fastest speed
        assert np.mean(np.abs(v[moving]) <= 2.0 + 1e-6) > 0.99
        held = np.diff(r) == 0
        assert np.all(np.abs(load) <= 0.01) and np.all(load[1:][~held] == 0.0)  # loads only at rest
    a = FAMILY.draw(np.random.default_rng(3), t)[0]
    assert np.array_equal(a, FAMILY.draw(np.random.default_rng(3), t)[0])
    assert not np.array_equal(a, FAMILY.draw(np.random.default_rng(4), t)[0])


def test_each_episode_draws_its_reference_from_its_seed_alike_everywhere():
    kw = {"randomize": True, "episode_s": 3.0}
    single = ServoEnv("m220_random", **kw)
    refs = {}
    for seed in (11, 12, 11):
        single.reset(seed=seed)
        for _ in range(single.scenario.episode_steps):
            single.step(np.array([0.1]))
        refs.setdefault(seed, []).append(single.core.episode_log(0)["reference"].copy())
    assert np.array_equal(refs[11][0], refs[11][1]) and not np.array_equal(refs[11][0], refs[12][0])
    vec = ServoVectorEnv("m220_random", 2, nthread=2, **kw)
    vec.reset(seed=11)  # seeds 11 and 12
    for _ in range(vec.scenario.episode_steps - 1):
        vec.step(np.full((2, 1), 0.1, dtype=np.float32))
    for i, seed in enumerate((11, 12)):
        got = vec.core.episode_log(i)["reference"]
        np.testing.assert_array_equal(got, refs[seed][0][: len(got)])
    # a pickled env continues the episode's own reference
    single.reset(seed=12)
    for _ in range(50):
        single.step(np.array([0.0]))
    twin = pickle.loads(pickle.dumps(single))
    for _ in range(100):
        a, b = single.step(np.array([0.2])), twin.step(np.array([0.2]))
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]


def test_random_reference_fields_are_checked():
    with pytest.raises(ConfigError, match="segments"):
        load_scenario("m220_random", {"reference": {"segments": ["jump"]}})
    with pytest.raises(ConfigError, match="load_torque"):
        load_scenario("kang_random", {"reference": {"load_torque": 1.0}})  # no disturbance motor
    with pytest.raises(ConfigError, match="amplitude"):
        load_scenario("kang_random", {"reference": {"amplitude": 100.0}})  # beyond the envelope
    with pytest.raises(ValueError, match="per episode"):
        load_scenario("kang_random").reference(np.zeros(3))
