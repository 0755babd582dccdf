"""Suites and seed ranges (envs/suites.py, configs/suites.yaml): defined, disjoint, held out, and the same
episode in a fresh process."""

import itertools
import subprocess
import sys

import pytest

from frictiongym.envs.config import ConfigError
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.suites import load_suite, seed_ranges, suite_names


def test_suites_are_defined_and_test_seeds_are_held_out():
    assert {"paper", "default", "test"} <= set(suite_names())
    default, test, paper = load_suite("default"), load_suite("test"), load_suite("paper")
    assert {e.seed for e in default}.isdisjoint({e.seed for e in test})
    assert all(e.randomize for e in default) and not any(e.randomize for e in paper)
    for name in ("kang_regulation", "m220_reversal_tracking", "flexible_speed_step", "flexible_zero_speed"):
        assert name in {e.scenario for e in default}
    # the same suite episode gives the same drawn parameters in a fresh process
    e = default[0]
    code = (
        "import gymnasium as gym, frictiongym.envs;"
        f"e=gym.make('frictiongym/KangRobot-v1', scenario='{e.scenario}', randomize=True);"
        f"print(e.reset(seed={e.seed})[1]['params'])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    here = ServoEnv(e.scenario, randomize=True).reset(seed=e.seed)[1]["params"]
    assert out == str(here)


def test_every_seed_range_is_disjoint():
    """configs/suites.yaml's table: the suites, the sim-to-real study and training never share a seed,
    so no number a study reports comes from an episode another one selected or trained on. Each user
    reads its range from the table."""
    from frictiongym.agents import sim2real, training
    from frictiongym.agents.training import vec_env as training_env

    table = seed_ranges()
    assert set(table) == {*suite_names(), "sim2real", "training"}
    spans = sorted(table.values())
    assert all(a[1] < b[0] for a, b in itertools.pairwise(spans))
    assert (sim2real.SEEDS, sim2real.SEED_RANGE[1] - 1) == table["sim2real"] and sim2real.SET_SPAN == 10_000
    assert table["training"][0] == training.TRAINING_SEEDS
    last = training_env.episode_seed(training_env.RUN_SEEDS - 1, 0, training_env.SEEDS_PER_RUN - 1, 1)
    assert last == table["training"][1]  # the last run seed's last episode is the range's last seed
    ranges = {name: {e.seed for e in load_suite(name)} for name in suite_names()}
    for name, seeds in ranges.items():
        assert table[name][0] <= min(seeds) and max(seeds) <= table[name][1], name
    lo, hi = sim2real.SEED_RANGE
    for name, seeds in ranges.items():
        assert not any(lo <= s < hi for s in seeds), name
        assert max(seeds) < training.TRAINING_SEEDS, name
        for other, theirs in ranges.items():
            assert other == name or seeds.isdisjoint(theirs), (name, other)
    episodes, _ = sim2real.plan("kang_regulation", 2, 2, 2)
    assert all(lo <= e.seed < hi for e in episodes)
    # the largest seeds the study's limits allow: shifts, the last joint set, the model-error plants
    span = sim2real.SET_SPAN
    assert sim2real.SEEDS + span <= sim2real.MODEL_ERROR_SEEDS  # after the shifts' and structures' seeds
    assert sim2real.SEEDS + 2 * span + span - 1 < hi < training.TRAINING_SEEDS
    with pytest.raises(ValueError, match="seed sets"):
        sim2real.plan("kang_regulation", span + 1, 2, 0)


def test_a_seed_outside_its_range_or_overlapping_ranges_are_errors(monkeypatch):
    from frictiongym.envs import suites

    raw = suites.load_yaml(suites.configs_dir() / suites.FILE)
    moved = {**raw, "test": {**raw["test"], "seeds": [1500]}}  # the default suite's range
    monkeypatch.setattr(suites, "load_yaml", lambda *_a, **_k: moved)
    with pytest.raises(ConfigError, match=r"test\.seeds: 1500-1500 leave the suite's range \[900000"):
        load_suite("test")
    overlap = {**raw, "seed_ranges": {**raw["seed_ranges"], "test": [1999, 1000000]}}
    monkeypatch.setattr(suites, "load_yaml", lambda *_a, **_k: overlap)
    with pytest.raises(ConfigError, match=r"seed_ranges.* overlaps"):
        seed_ranges()


def test_an_episode_comes_back_from_run_json_equal_to_itself():
    """run.json holds the episodes as asdict wrote them (JSON: the pinned parameters as lists); read back,
    they equal the suite's, so a report from a finished run names its suite (not "inline")."""
    import json
    from dataclasses import asdict

    from frictiongym.envs.suites import Episode

    suite = [*load_suite("default")[:3], Episode("m220_regulation", 7, True, (("delay", 0.001),))]
    back = [Episode.from_dict(e) for e in json.loads(json.dumps([asdict(e) for e in suite]))]
    assert back == suite
    assert back[:3] != [Episode(**e) for e in json.loads(json.dumps([asdict(e) for e in suite[:3]]))]
