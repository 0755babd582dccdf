"""The servo engineer's toolbox (model feed-forward, disturbance observer, iterative learning, adaptive
Coulomb level), its tuning and the tracking-limit reference: known answers on plants simulated exactly
here (zero-order hold) and on the suite's own episodes."""

import dataclasses
import math

import numpy as np
import pytest

from frictiongym.agents import registry
from frictiongym.agents.base import EpisodeContext
from frictiongym.agents.classical import (
    AdaptiveCoulomb,
    DisturbanceObserver,
    FeedForwardSettings,
    IterativeLearning,
    PIDModelFF,
)
from frictiongym.agents.classical.design import rigid_position_plant
from frictiongym.agents.classical.iterative import period_steps
from frictiongym.agents.classical.model_feedforward import ModelFeedForward
from frictiongym.agents.evaluation import leaderboard
from frictiongym.agents.evaluation.evaluate import EpisodeResult, run_episode
from frictiongym.agents.tuning.search import tune
from frictiongym.agents.tuning.tuned import Tuned
from frictiongym.envs.config import ConfigError
from frictiongym.envs.metrics import METRIC_NAMES
from frictiongym.envs.plants.identified import drive_friction
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode


class RigidPlant:
    """J·v' + c·v = b·u + d under a zero-order hold over h, integrated exactly (position and velocity)."""

    def __init__(self, J: float, c: float, b: float, h: float):
        self.J, self.c, self.b, self.h = J, c, b, h
        self.x = self.v = 0.0

    def step(self, u: float, d: float = 0.0) -> None:
        J, c, h = self.J, self.c, self.h
        f = self.b * u + d  # force over the period
        if c == 0:
            self.x += self.v * h + f * h * h / (2 * J)
            self.v += f * h / J
            return
        a, vinf = math.exp(-c * h / J), f / c
        self.x += vinf * h + (self.v - vinf) * J / c * (1 - a)
        self.v = vinf + (self.v - vinf) * a


def context(name: str, h: float | None = None) -> EpisodeContext:
    sc = load_scenario(name, control_period_s=h)
    return EpisodeContext(sc, sc.spec)


def feedforward_tracking_error(h: float) -> float:
    """Max |r - x| of the M220's rigid model driven by the feed-forward alone along r(t) = 0.05·t³ rad
    over 2 s (friction terms off: a friction-free plant)."""
    ctx = context("m220_point_to_point", h)
    entry = dataclasses.replace(FeedForwardSettings.defaults().of("m220"), friction_scale=0.0)
    ff = ModelFeedForward(ctx, entry)
    J, c, b = rigid_position_plant(ctx.plant)
    plant = RigidPlant(J, c, b, h)
    n = round(2.0 / h)
    r = 0.05 * (np.arange(n + 8) * h) ** 3
    err = 0.0
    for k in range(n):
        err = max(err, abs(r[k] - plant.x))
        plant.step(ff.command(np.array([r[k]]), r[None, k + 1 : k + 6])[0])
    return err


def test_model_feedforward_tracks_a_polynomial_to_the_discretisation_error():
    # the central differences of a cubic are exact at t_k; what remains is the zero-order hold's error
    # (the acceleration held over a period), first order in h: halving h halves it
    # the held acceleration loses 0.15·h² rad/s of speed per period on r = 0.05·t³ (r'' = 0.3·t), which
    # adds up to 0.075·h·T² rad of position after T = 2 s
    e1, e2 = feedforward_tracking_error(0.005), feedforward_tracking_error(0.0025)
    assert e1 == pytest.approx(0.075 * 0.005 * 2.0**2, rel=0.05)
    assert e1 / e2 == pytest.approx(2.0, rel=0.05)


def test_feedforward_two_mass_inverse_moves_the_load_with_the_motor():
    # a constant reference speed: the simulated load reaches it and the spring carries the load's damping
    ctx = context("flexible_speed_reversal")
    ff = ModelFeedForward(ctx, FeedForwardSettings.defaults().of("flexible_servo"))
    gain = ctx.plant.sensors[0].gain
    w = 5.0  # rad/s
    for _ in range(20000):  # 800 s: the soft shaft (k = 0.0024 N·m/rad) settles slowly
        u = ff.command(np.array([w * gain]), np.zeros((1, 0)))[0]
    w2, _ = ff.x[0]
    assert w2 == pytest.approx(w, rel=1e-6)
    d1, d2 = (j.viscous for j in ctx.plant.joints)
    friction = sum(j.friction.fc for j in ctx.plant.joints)  # Coulomb on both shafts (smooth sign ~ 1)
    assert u * ctx.plant.actuator_gain == pytest.approx((d1 + d2) * w + friction, rel=1e-3)


def test_disturbance_observer_estimates_a_constant_load_with_its_q_filter():
    ctx = context("kang_regulation")
    dob = DisturbanceObserver()
    dob.reset(ctx)
    dob.preview = np.zeros(0)
    J, _, b = rigid_position_plant(ctx.plant)
    plant = RigidPlant(J, 0.0, b, ctx.scenario.control_period)
    dob.J, dob.c = J, 0.0  # the nominal model is the plant: d_raw is the load exactly
    tau = dob.observer.of("kang_robot").q_time_constant_s
    a = math.exp(-ctx.scenario.control_period / tau)
    d0 = 2.0  # N·m
    est = []
    for _ in range(400):
        u = dob.command(plant.x, 0.0)
        plant.step(u, d0)
        est.append(dob.d_hat[0])
    k = np.arange(len(est))
    expected = d0 * (1 - a ** np.maximum(k - 1, 0))  # the first estimate needs two differences
    assert np.allclose(est[2:], expected[2:], rtol=1e-9, atol=1e-9)
    assert abs(plant.x) < 1e-6  # cancelled: the PD holds the set-point with no steady error


def test_iterative_learning_error_falls_from_period_to_period():
    ep = Episode("m220_reversal_tracking", 500000, True)
    sc = load_scenario(ep.scenario)
    n = period_steps(sc)
    assert n == round(1 / (sc.reference.frequency_hz * sc.control_period))

    def per_period(controller):  # mean |error| over each 5 s period of a 40 s episode (8 periods)
        log = run_episode(controller, ep, keep_log=True, episode_s=40.0).log
        e = np.abs(log["reference"] - log["output"])
        return np.array([e[i * n : (i + 1) * n].mean() for i in range(len(e) // n)])

    learned, loop = per_period(IterativeLearning()), per_period(PIDModelFF())
    assert len(learned) == 8
    assert np.all(np.diff(learned) < 0)  # falls from every period to the next
    assert learned[-1] < 0.7 * learned[0]  # and stays bounded below where it began
    assert learned[0] == pytest.approx(loop[0], rel=1e-4)  # nothing learned before the first period ends
    assert np.all(learned[2:] < 0.9 * loop[2:])  # the loop alone repeats its error


def test_iterative_learning_refuses_a_reference_that_does_not_repeat():
    assert "does not repeat" in IterativeLearning().why_not(load_scenario("m220_random"))
    assert IterativeLearning().why_not(load_scenario("m220_reversal_tracking_slow")) is None


def test_adaptive_coulomb_level_converges_at_its_rate():
    ctx = context("kang_ramp")
    c = AdaptiveCoulomb()
    c.reset(ctx)
    h = ctx.scenario.control_period
    J, visc, b = rigid_position_plant(ctx.plant)
    true = 1.5 * c.level0  # command units: the drive's Coulomb level is half as large again
    plant = RigidPlant(J, visc, b, h)
    speed = 0.2  # rad/s
    rate = c.adaptive.of("kang_robot").adaptation_rate_per_s
    steps = round(6 / rate / h)
    r = speed * np.arange(steps + 8) * h
    for k in range(steps):
        c.preview = r[k + 1 : k + 6]
        u = c.command(plant.x, r[k])
        plant.step(u - true * math.copysign(1.0, plant.v) if plant.v else u)
    assert c.level[0] == pytest.approx(
        true, rel=0.03
    )  # e^-6 of the initial error, and the encoder's rounding


def test_adaptive_coulomb_is_for_drifting_friction():
    assert "drifts" in AdaptiveCoulomb().why_not(load_scenario("m220_reversal_tracking"))
    assert AdaptiveCoulomb().why_not(load_scenario("m220_drift")) is None


def test_tuned_twin_uses_its_values_and_only_on_its_plants():
    values = {"m220": {"values": {"learning_gain": 0.25, "lead_steps": 3, "filter_s": 0.1}}}
    twin = Tuned("ILC", IterativeLearning, values)
    assert twin.name == "ILC[tuned]"
    assert "not tuned for plant flexible_servo" in twin.why_not(load_scenario("flexible_speed_reversal"))
    assert twin.why_not(load_scenario("m220_reversal_tracking")) is None
    assert twin.inner.learning.of("m220").lead_steps == 3
    design = {"learning_gain": 0.5, "lead_steps": 2, "filter_s": 0.05}  # a tuning that kept the design
    entry = {"values": design, "manifest": {"design_values": design}}
    kept = Tuned("ILC", IterativeLearning, {"m220": entry})
    assert "kept the design's settings" in kept.why_not(load_scenario("m220_reversal_tracking"))
    bad = {"m220": {"values": {"learning_gain": 7.0}}}
    with pytest.raises(ConfigError, match="learning_gain"):
        Tuned("ILC", IterativeLearning, bad)


@pytest.mark.slow  # a tuning run
def test_tuning_improves_on_the_design_on_validation():
    entry = tune(
        "PID+MFF", "kang_robot", budget_s=600, trials=6, seed=0, episodes=2, workers=1, progress=False
    )
    m = entry["manifest"]
    obj = m["objective"]
    assert obj["tuned"] < obj["design"]
    assert m["trials"] == 6 and set(m["validation"]) == {"kang_ramp", "kang_random", "kang_drift"}
    assert all(s in range(500000, 600000) for seeds in m["validation"].values() for s in seeds)
    assert m["env_steps"] == 6 * sum(2 * load_scenario(sc).episode_steps for sc in m["validation"])
    assert entry["values"] != m["design_values"]


def test_tracking_limit_is_below_the_ideal_loop_on_a_ramp():
    # the friction-free twin under model feed-forward tracks a ramp closer than the 1-DOF loop on it
    ep = Episode("kang_ramp", 500000, True)
    ideal = run_episode(registry.make("Ideal"), ep).metrics["iae"]
    limit = run_episode(registry.make("TrackingLimit"), ep).metrics["iae"]
    assert limit < 0.1 * ideal
    assert "Ideal" in registry.make("TrackingLimit").why_not(load_scenario("kang_regulation"))


def result(name: str, seed: int, main: float, roughness: float, effort: float = 1.0) -> EpisodeResult:
    metrics = dict.fromkeys(METRIC_NAMES, 0.0)
    metrics.update(iae=main, command_roughness=roughness, effort_rms=effort)
    return EpisodeResult(name, "kang_ramp", seed, metrics, 0.0, False)


def test_a_row_that_chatters_is_never_the_baseline_and_effort_alone_is_not_chatter():
    """The rule reads the command's change per period against the reference point (PD, the loop, and
    TrackingLimit here: 0.05 V): DOB at 0.5 V > 3 x 0.05 + 0.1 V chatters and cannot be the baseline;
    PID+FF, at twice the loop's effort but a smooth command, is a result."""
    sc = {"kang_ramp": load_scenario("kang_ramp")}
    rows = [result("PD", s, 1.0, 0.02) for s in range(5)]
    rows += [result("TrackingLimit", s, 0.01, 0.05) for s in range(5)]
    rows += [result("DOB", s, 0.1, 0.5) for s in range(5)]  # far better, with a chattering command
    rows += [result("PID+FF", s, 0.5, 0.2, effort=2.0) for s in range(5)]
    table = leaderboard.summarize(rows, sc)["kang_ramp"]
    by = {r["controller"]: r for r in table}
    assert by["DOB"]["chatters"].startswith("chatters (0.5 vs 0.05")
    assert by["PID+FF"]["chatters"] == ""
    assert by["PID+FF"]["baseline"] == "PID+FF" and by["DOB"]["baseline"] == "PID+FF"


def test_drive_friction_of_the_feedforward_is_the_presets():
    # the feed-forward's friction at a steady speed is the identified steady state (command units)
    ctx = context("m220_point_to_point")
    ff = ModelFeedForward(ctx, FeedForwardSettings.defaults().of("m220"))
    h, v = ctx.scenario.control_period, 2.0  # rad/s, far above the smoothing width
    r = v * h * np.arange(10)
    for k in range(3):
        ff.command(r[k : k + 1], r[None, k + 1 : k + 6])
    df = drive_friction(ctx.plant)
    assert ff.c / ctx.plant.actuator_gain == pytest.approx(df.viscous)  # the linear part, fed apart
    assert ff.friction[0] == pytest.approx(df.coulomb_pos, rel=1e-6)  # Stribeck gone at 34 v_s
