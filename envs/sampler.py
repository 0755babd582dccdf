"""The one sampler: every random quantity of an episode comes from its own named child of the episode
seed, so adding a randomised effect never changes the existing draws, and the single env, the vector env
and PlantSim draw the same values for the same seed.

    stream(seed, "friction_scale")  ->  np.random.Generator of SeedSequence(seed, spawn_key=(crc32(name),))
"""

from __future__ import annotations

import zlib

import numpy as np

from .config import integer

# Names of the non-parameter streams (parameters use their randomization key as the name).
INITIAL_STATE, SENSOR_NOISE, JITTER = "initial_state", "sensor_noise", "jitter"
REFERENCE, DRIFT = "reference", "friction_drift"  # per-episode references, friction drift


def check_seed(seed: object, field: str = "seed") -> int:
    """A seed is a non-negative integer of any size (numpy's SeedSequence has no upper bound); bools and
    floats are errors that name the field."""
    return integer(seed, field, 0)


def stream(seed: int, name: str) -> np.random.Generator:
    """The generator of stream `name` of episode `seed` (independent of every other name)."""
    key = zlib.crc32(name.encode())
    return np.random.default_rng(np.random.SeedSequence(check_seed(seed), spawn_key=(key,)))
