"""The friction-free optimum (agents/evaluation/optimum.py): the twin it is computed on is linear and
time-invariant, the realisation reproduces the twin's pulse response, the program's commands reach what
the program says, and no controller of the registry goes below it on the twin."""

from __future__ import annotations

import numpy as np
import pytest

from frictiongym.agents import registry
from frictiongym.agents.evaluation import optimum as opt
from frictiongym.agents.evaluation.evaluate import EnvCache, run_episode
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode

TWIN = {"nonlinear_friction": False}


def outputs(episode: Episode, actions: np.ndarray, envs: EnvCache) -> np.ndarray:
    """The twin's tracked output after each control period under these actions."""
    return run_episode(opt.Commands(actions), episode, True, envs=envs).log["output"][1:]


LINEAR = ["kang_random", "kang_ramp", "emps_random", "flexible_random", "m220_random"]


@pytest.mark.parametrize("scenario", LINEAR)
def test_the_twin_is_linear_and_time_invariant_in_the_commands(scenario):
    """y(u1 + u2) = y(u1) + y(u2) - y(0), and the response to u delayed by 7 periods is the response to u
    delayed by 7 periods (the draws of the episode, its initial state and load torque are in y(0)), to
    rounding: kang_ramp runs 50 s with a delay, where a delay of whole steps used to read one step later
    after 16 s; the M220's belts hold a constant impedance."""
    envs, episode = EnvCache(), Episode(scenario, 5000, True)
    n = load_scenario(scenario).episode_steps
    rng = np.random.default_rng(0)
    u1, u2 = rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n)
    y0, y1, y2, y12 = (outputs(episode, u, envs) for u in (np.zeros(n), u1, u2, u1 + u2))
    size = np.max(np.abs(y12 - y0))
    assert np.max(np.abs(y12 - y1 - y2 + y0)) <= 1e-10 * size
    late = outputs(episode, np.concatenate([np.zeros(7), u1[:-7]]), envs) - y0
    assert np.max(np.abs(late[7:] - (y1 - y0)[:-7])) <= 1e-10 * size


@pytest.mark.parametrize(
    ("scenario", "order"), [("kang_random", 2), ("emps_random", 2), ("flexible_random", 3)]
)
def test_the_realisation_reproduces_the_pulse_response_over_the_episode(scenario, order):
    """Kang's rotor and the EMPS are a mass with viscous damping (an integrator and one real pole, no delay
    on these draws), the flexible servo's speed a two-mass system seen at the load (three states): the
    Ho-Kalman realisation finds that order and reproduces every sample of the pulse response."""
    envs, episode = EnvCache(), Episode(scenario, 5000, True)
    n = load_scenario(scenario).episode_steps
    g = outputs(episode, np.eye(1, n)[0], envs) - outputs(episode, np.zeros(n), envs)
    A, B, C = opt.realisation(g)
    assert len(B) == order
    x, h = B.copy(), np.empty(n)
    for k in range(n):
        h[k], x = C @ x, A @ x
    assert np.max(np.abs(h - g)) <= 1e-9 * np.max(np.abs(g))


def test_the_program_is_the_metric_it_minimises():
    """On an integrator, g = (1, 1, ...): a target reachable within |u| <= 1 is met exactly by the
    deadbeat commands (no program solved), and a target that moves faster than the limit allows is
    followed at the limit, the program's minimum equal to what those commands leave through g."""
    n = 50
    g = np.ones(n)  # y(k) = Σ_{i<k} u(i)
    w = np.ones(n)
    reachable = 0.5 * np.arange(1, n + 1)  # speed 0.5 per period, |u| = 0.5
    u, best, value = opt.solve(reachable, g, w, peak=False)
    assert best == 0.0 and value == pytest.approx(0.0, abs=1e-9) and np.allclose(u, 0.5)
    fast = 2.0 * np.arange(1, n + 1)  # speed 2 per period: u = 1 leaves k behind after period k
    u, best, value = opt.solve(fast, g, w, peak=False)
    assert np.allclose(u, 1.0) and best == pytest.approx(np.sum(np.arange(1, n + 1)))
    assert value == pytest.approx(best)
    _, peak, _ = opt.solve(fast, g, w, peak=True)
    assert peak == pytest.approx(n)


def test_at_a_set_point_the_optimum_is_zero_and_jitter_is_refused():
    """Kang's rotor stopped at its set-point: a friction-free drive that knows it holds it exactly
    (final_error 0 to rounding; the sensor's resolution is the limit there). A scenario that draws jitter
    is refused in one line, naming it: its twin varies from period to period."""
    o = opt.optimum(Episode("kang_regulation", 5000, True))
    assert o.metric == "final_error" and o.exact and o.value < 1e-9
    with pytest.raises(ValueError, match=r"^optimum: kang_regulation_hard seed 5000: its jitter"):
        opt.optimum(Episode("kang_regulation_hard", 5000, True))


def test_a_solved_program_is_read_back_bit_for_bit_and_a_damaged_entry_is_solved_again(tmp_path, monkeypatch):
    """The cache (FRICTIONGYM_CACHE) keeps each episode's program: a second computation of the episode
    solves nothing (linprog is not called) and gives the same commands and value, bit for bit; an entry
    that is not an archive of the right arrays is solved again and replaced; "off" keeps nothing."""
    monkeypatch.setenv(opt.CACHE_VARIABLE, str(tmp_path))
    episode = Episode("kang_random", 5000, True)  # a reference faster than the drive: a program runs
    first = opt.optimum(episode)
    (entry,) = (tmp_path / "optimum").iterdir()

    def refuse(*args, **kwargs):
        raise AssertionError("a cached program was solved again")

    with monkeypatch.context() as m:
        m.setattr(opt, "linprog", refuse)
        again = opt.optimum(episode)
    assert np.array_equal(again.actions, first.actions) and again.value == first.value
    assert again.objective == first.objective
    entry.write_bytes(b"not an archive")
    damaged = opt.optimum(episode)
    assert np.array_equal(damaged.actions, first.actions) and damaged.value == first.value
    assert np.load(entry, allow_pickle=False)["u"].shape == first.actions.shape  # replaced
    monkeypatch.setenv(opt.CACHE_VARIABLE, opt.CACHE_OFF)
    assert opt.cache_dir() is None


def below(scenario: str, seed: int) -> list[tuple[str, float, float]]:
    """(controller, its main metric on the twin, the optimum) for every registry controller that applies
    to the episode and goes below the optimum on its friction-free twin."""
    envs, episode = EnvCache(), Episode(scenario, seed, True)
    o = opt.optimum(episode, envs)
    assert o.exact
    limit = o.value
    sc = envs.scenario(episode)
    out = []
    for name in registry.available():
        c = registry.make(name)
        if c.why_not(sc) is not None:
            continue
        m = run_episode(c, episode, envs=envs, overrides=TWIN).metrics[o.metric]
        if m < limit - opt.AGREE * max(limit, 1e-12):
            out.append((name, m, limit))
    return out


def test_no_registry_controller_goes_below_the_optimum_on_kang_s_twin():
    assert below("kang_random", 5000) == []


@pytest.mark.slow  # every registry controller on one episode of each plant's twin
@pytest.mark.parametrize(
    "scenario", ["kang_ramp", "m220_random", "m220_point_to_point", "emps_random", "flexible_speed_step"]
)
def test_no_registry_controller_goes_below_the_optimum_on_any_plant_s_twin(scenario):
    assert below(scenario, 5001) == []
