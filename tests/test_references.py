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


def test_a_suite_is_held_out_whole_or_not_at_all(tmp_path, monkeypatch):
    from frictiongym.envs import suites

    (tmp_path / "suites.yaml").write_text(
        "mixed: {randomize: true, seeds: [1], scenarios: [kang_regulation, kang_chirp]}\n"
        "held: {randomize: true, held_out: true, seeds: [1], scenarios: [kang_chirp, kang_ramp]}\n"
    )
    monkeypatch.setattr(suites, "configs_dir", lambda: tmp_path)
    with pytest.raises(ConfigError, match=r"scenarios\[1\].*kang_chirp is held out"):
        suites.load_suite("mixed")
    with pytest.raises(ConfigError, match=r"scenarios\[1\].*kang_ramp is not held out"):
        suites.load_suite("held")
    monkeypatch.undo()
    gen = suites.load_suite("generalisation")
    assert suites.suite_held_out("generalisation") and not suites.suite_held_out("validation")
    assert {e.seed for e in gen}.isdisjoint({e.seed for e in suites.load_suite("validation")})
    assert all(load_scenario(s).held_out for s in {e.scenario for e in gen})


def test_chirp_sweeps_its_frequency_and_scurve_moves_within_its_limits():
    from frictiongym.envs.scenario import Reference

    t = np.arange(0, 10, 1e-3)
    chirp = Reference("chirp", amplitude=1.0, frequency_hz=0.5, end_frequency_hz=2.5, sweep_s=10.0)
    up = np.flatnonzero(np.diff(np.signbit(chirp(t)).astype(int)) == -1)  # upward zero crossings
    periods = np.diff(t[up])
    # instantaneous frequency f0 + (f1 - f0) t / T: about 0.6 Hz near the start, 2.4 Hz near the end
    assert 1 / periods[0] == pytest.approx(0.5 + 0.2 * t[up][:2].mean(), rel=0.05)
    assert 1 / periods[-1] == pytest.approx(0.5 + 0.2 * t[up][-2:].mean(), rel=0.05)
    # frequency_hz_at (the windows' bands) is the frequency r(t) has: every measured period's, held after T
    mid = (t[up][1:] + t[up][:-1]) / 2
    np.testing.assert_allclose(chirp.frequency_hz_at(mid), 1 / periods, rtol=0.01)
    assert chirp.frequency_hz_at(25.0) == 2.5
    assert Reference("sine", frequency_hz=0.3).frequency_hz_at(7.0) == 0.3
    assert np.isnan(Reference("constant", value=1.0).frequency_hz_at(1.0))
    s = Reference("scurve", schedule=((0.5, 1.0), (3.0, -0.5)), max_velocity=2.0, max_acceleration=8.0)
    x = s(t)
    v = np.gradient(x, t)
    a = np.gradient(v, t)
    # cycloid: T = max(2d/v, sqrt(2πd/a)); continuous acceleration peaking at 2πd/T² (no jumps)
    assert x[2900] == pytest.approx(1.0) and x[-1] == pytest.approx(-0.5)
    assert np.abs(v).max() <= 2.0 + 1e-3 and np.abs(a).max() <= 8.0 + 1e-2
    assert np.abs(np.diff(a)).max() < 0.1  # per 1 ms sample: no acceleration steps (trapezoid's are 8)
