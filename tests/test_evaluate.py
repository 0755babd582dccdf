"""The one evaluation loop (agents/evaluation/evaluate.py): episodes stepped together give each episode's own
result."""

from __future__ import annotations

import math

import numpy as np
import pytest

from frictiongym.agents import registry
from frictiongym.agents.base import EpisodeContext, PhysicalController
from frictiongym.agents.evaluation.engine import Job, run_chunk
from frictiongym.agents.evaluation.evaluate import (
    EnvCache,
    EpisodeResult,
    evaluate,
    run_episode,
    run_episodes,
)
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode

HEADLINE = ("agents/models/specialist",)


def assert_same(a: EpisodeResult, b: EpisodeResult) -> None:
    """Two results of one episode equal field for field, logs bit for bit (nan equal to nan)."""
    assert (a.controller, a.scenario, a.seed, a.params, a.randomize) == (
        b.controller,
        b.scenario,
        b.seed,
        b.params,
        b.randomize,
    )
    assert a.metrics.keys() == b.metrics.keys()
    for k, x in a.metrics.items():
        y = b.metrics[k]
        assert x == y or (math.isnan(x) and math.isnan(y)), (k, x, y)
    assert a.episode_return == b.episode_return and type(b.episode_return) is float
    assert a.diverged == b.diverged and a.controller_params == b.controller_params
    assert (a.log is None) == (b.log is None)
    for k in a.log or {}:
        assert np.array_equal(a.log[k], b.log[k]), k


@pytest.mark.parametrize(
    ("name", "scenario", "episode_s"),
    [
        ("PID", "m220_reversal_tracking_hard", 4.0),  # sampling delay and its jitter
        ("Oracle", "m220_reversal_tracking", 4.0),  # reads the ground truth every period
        ("RDFC", "kang_regulation", None),  # a switching compensator with its own state
        ("LuGreObserver", "kang_drift", 6.0),  # friction drifting within the episode
        ("SF+relay", "flexible_zero_speed", None),  # an observer and the analog rate loop's hardware
        ("Cascade+MFF", "emps_tracking", 2.0),  # the feed-forward's reference window, a filtered cascade
        ("ILC", "m220_reversal_tracking", 6.0),  # learns at the end of its first 5 s period
        ("MFF+DOB", "flexible_speed_reversal", 4.0),  # the two-mass feed-forward and the observer
        ("AdaptiveFF", "kang_drift", 6.0),  # adapts in motion only, re-anchored at each
        ("ResSAC-m220_reversal_tracking-s0", "m220_reversal_tracking", 4.0),  # residual, normaliser
        ("ResSAC-kang_regulation-s1", "kang_regulation_coarse", None),
    ],
)
def test_episodes_stepped_together_equal_each_episode_run_alone(name, scenario, episode_s):
    """run_episodes steps episodes that share an env as one batch with one Lockstep of the controller (a
    learned one calls its network once per step for all); every result, log included, is bit for bit
    the result of the episode run alone on the single env, whatever the batch (pinned parameters per
    episode; a pinned friction structure is another env, run in its own group)."""
    kw = {"episode_s": episode_s} if episode_s else {}
    episodes = [Episode(scenario, 500000 + i, True) for i in range(3)]
    episodes.insert(1, Episode(scenario, 500007, True, (("friction_scale", 1.3),)))
    episodes.append(Episode(scenario, 500008, True, (("friction_model", "dahl"),)))
    alone = [run_episode(registry.make(name, HEADLINE), e, keep_log=True, **kw) for e in episodes]
    together = run_episodes(registry.make(name, HEADLINE), episodes, keep_log=True, **kw)
    assert len(together) == len(episodes)
    for a, b in zip(alone, together, strict=True):
        assert_same(a, b)
    assert len({r.metrics["iae"] for r in together}) == len(episodes)  # five different episodes


def test_an_array_controllers_rows_after_an_episode_ends_are_the_rows_without_it():
    """A controller that steps arrays acts on every episode it was reset for; once an episode has ended
    (its row is no longer asked for), the others' actions are those of a lockstep that never had it."""
    sc = load_scenario("emps_tracking")
    rng = np.random.default_rng(0)
    three, two = registry.make("Cascade+MFF").lockstep(3), registry.make("Cascade+MFF").lockstep(2)
    three.reset(EpisodeContext(sc, sc.spec))
    two.reset(EpisodeContext(sc, sc.spec))
    obs = np.zeros((3, sc.layout.size), dtype=np.float32)
    for k in range(50):
        obs = obs + rng.normal(0, 1e-4, obs.shape).astype(np.float32)
        rows = np.arange(3) if k < 20 else np.array([0, 2])  # episode 1 ends after 20 periods
        got = three.act(obs[rows], rows)
        np.testing.assert_array_equal(got[rows != 1], two.act(obs[[0, 2]], np.arange(2)))


class _Dither(PhysicalController):
    """A plug-in for one episode whose reset draws from its own generator: PD plus a constant bias drawn
    at each reset."""

    name = "Dither"
    sensor_kinds = ("encoder",)

    def __init__(self):
        self.rng = np.random.default_rng(7)

    def start(self, ctx):
        self.pd = registry.make("PD")
        self.pd.reset(ctx)
        self.bias = 0.1 * self.rng.normal()

    def command(self, y, r):
        return self.pd.command(y, r) + self.bias


def test_a_controller_for_one_episode_is_reset_once_per_episode_in_a_lockstep():
    """Stepped together, each episode of a per-episode controller gets a copy of the controller as it was
    given, reset once: its draws at reset are those of the episode run alone (and a built-in loop it
    uses acts on its one episode)."""
    episodes = [Episode("kang_regulation", 500000 + i, True) for i in range(3)]
    alone = [run_episode(_Dither(), e, episode_s=1.0) for e in episodes]
    together = run_episodes(_Dither(), episodes, episode_s=1.0)
    for a, b in zip(alone, together, strict=True):
        np.testing.assert_equal(a.metrics, b.metrics)  # NaN equal to NaN


def test_evaluate_orders_results_by_episode_then_controller_and_skips_the_inapplicable():
    """evaluate() runs each controller's applicable episodes together and returns them episode-major,
    controllers in the given order, each equal to its episode run alone."""
    controllers = [registry.make("RDFC"), registry.make("PD")]
    episodes = [Episode("kang_regulation", s, True) for s in (3, 4)] + [Episode("kang_ramp", 5, True)]
    got = evaluate(controllers, episodes, progress=False, episode_s=2.0)
    assert [(r.scenario, r.seed, r.controller) for r in got] == [
        ("kang_regulation", 3, "RDFC"),
        ("kang_regulation", 3, "PD"),
        ("kang_regulation", 4, "RDFC"),
        ("kang_regulation", 4, "PD"),
        ("kang_ramp", 5, "PD"),  # RDFC is defined for set-point regulation only
    ]
    envs = EnvCache()
    for r in got:
        c = next(c for c in controllers if c.name == r.controller)
        assert_same(run_episode(c, Episode(r.scenario, r.seed, True), envs=envs, episode_s=2.0), r)


def test_a_chunk_runs_one_controller():
    """The engine's task is one controller's episodes (stepped together); a mixed chunk is refused."""
    jobs = [Job("PD", "kang_regulation", 1, True), Job("PID", "kang_regulation", 1, True)]
    with pytest.raises(ValueError, match=r"a chunk runs one controller; got \['PD', 'PID'\]"):
        run_chunk(jobs, {})
