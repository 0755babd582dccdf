"""The one sampler (envs/sampler.py): every random quantity of an episode is its own named stream of the
episode seed, so draws depend on (seed, name) alone and adding a stream never moves another."""

import numpy as np
import pytest

from frictiongym.envs.config import ConfigError
from frictiongym.envs.sampler import JITTER, SENSOR_NOISE, check_seed, stream


def test_a_stream_depends_on_its_seed_and_name_alone():
    alone = stream(7, "friction_scale").uniform(size=5)
    others = [stream(7, name).uniform(size=100) for name in (SENSOR_NOISE, JITTER, "a_new_effect")]
    assert np.array_equal(stream(7, "friction_scale").uniform(size=5), alone)  # drawn after the others
    assert not any(np.array_equal(alone, o[:5]) for o in others)  # other names: other draws
    assert not np.array_equal(stream(8, "friction_scale").uniform(size=5), alone)  # other seed


def test_seeds_are_non_negative_integers_of_any_size():
    assert check_seed(2**80) == 2**80 and check_seed(np.int64(3)) == 3
    stream(2**80, JITTER).uniform()  # SeedSequence takes it
    for bad in (True, 1.0, -1, "3"):
        with pytest.raises(ConfigError, match=r"options\.seed"):
            check_seed(bad, "options.seed")
