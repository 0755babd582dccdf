"""The physical-limit references: the friction-free twin (Ideal), the true-friction Oracle, and the
scores built on them (g, per-plant aggregates over equal sets)."""

import math

import numpy as np
import pytest

from frictiongym.agents import registry
from frictiongym.agents.evaluation import leaderboard
from frictiongym.agents.evaluation.evaluate import EnvCache, EpisodeResult, run_episode
from frictiongym.envs.config import ConfigError
from frictiongym.envs.metrics import METRIC_NAMES
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.suites import Episode

TWIN = {"nonlinear_friction": False}


def test_the_twin_draws_the_same_episode_without_the_nonlinear_friction():
    """Every draw (inertia, viscous, delay, noise, initial state, σ0, σ2, vs) is the episode's own; only
    the Coulomb, static and bias levels and the bristle damping σ1 are 0."""
    env, twin = (
        ServoEnv("m220_reversal_tracking", randomize=True),
        ServoEnv("m220_reversal_tracking", randomize=True, overrides=TWIN),
    )
    for seed in (3, 1001):
        env.reset(seed=seed)
        twin.reset(seed=seed)
        p, q = env.core.params[0], twin.core.params[0]
        assert (p.inertia, p.viscous, p.delay, p.noise_scale, p.actuator_gain) == (
            q.inertia,
            q.viscous,
            q.delay,
            q.noise_scale,
            q.actuator_gain,
        )
        for f, h in zip(p.friction, q.friction, strict=True):
            assert f.fc > 0 and f.sigma1 > 0 and (h.fc, h.fs, h.bias, h.sigma1) == (0.0, 0.0, 0.0, 0.0)
            assert (f.sigma0, f.sigma2, f.vs) == (h.sigma0, h.sigma2, h.vs)
        np.testing.assert_array_equal(env.ground_truth()["qpos"], twin.ground_truth()["qpos"])


def test_the_twin_is_the_linear_plant_and_the_drive_sticks_with_friction():
    """EMPS carriage (95.1 kg, σ2 = 203.5 N·s/m, 35.15 N/V, no delay), 0.4 V from rest: 14.06 N is below
    the static level in + direction (Fs - b = 17.2 N), so the real drive only deflects its bristles; the
    twin is m·v' = F - σ2·v, v(0.5 s) = F/σ2·(1 - exp(-σ2·0.5/m))."""
    out = {}
    for name, ov in (("friction", None), ("twin", TWIN)):
        env = ServoEnv("emps_tracking", randomize=False, overrides=ov)
        env.reset(seed=0)
        for _ in range(500):  # 1 ms periods
            env.step(np.array([0.04]))
        out[name] = env.ground_truth()
    spec = load_scenario("emps_tracking").spec
    m, c, force = spec.joints[0].inertia, spec.joints[0].friction.sigma2, 0.4 * spec.actuator_gain
    v = force / c * (1 - math.exp(-c * 0.5 / m))
    assert out["twin"]["qvel"][0] == pytest.approx(v, rel=2e-3)
    assert abs(out["friction"]["qpos"][0]) < 1e-5  # presliding: F/σ0 ≈ 0.5 µm
    # ground truth: the nonlinear part is the friction torque without the viscous term, 0 on the twin
    for gt in out.values():
        np.testing.assert_allclose(
            gt["nonlinear_friction_torque"] - c * gt["qvel"], gt["friction_torque"], rtol=1e-12, atol=1e-12
        )
    assert abs(out["twin"]["nonlinear_friction_torque"][0]) < 1e-9


def test_oracle_cancels_the_friction_torque_as_sampled():
    """On Kang's slow ramps PD loses 98 % of its IAE to stick-slip; the Oracle, cancelling the true
    friction torque one period behind (held over 20 ms), tracks within 3 % of the friction-free PD."""
    envs = EnvCache()
    ep = Episode("kang_ramp", 1000, True)
    iae = {c: run_episode(registry.make(c), ep, envs=envs).metrics["iae"] for c in ("PD", "Ideal", "Oracle")}
    assert iae["Ideal"] < iae["PD"] / 20
    assert iae["Oracle"] == pytest.approx(iae["Ideal"], rel=0.03)


def _result(c: str, sc: str, seed: int, g: float) -> EpisodeResult:
    return EpisodeResult(c, sc, seed, dict.fromkeys(METRIC_NAMES, 0.0), 0.0, False, g=g)


def test_aggregates_rank_equal_sets_only():
    """A controller defined on one of the plant's two scored scenarios is ranked in its own set, never
    against the controllers of both; references are listed, not ranked; unscored scenarios are left out."""
    scenarios = {n: load_scenario(n) for n in ("kang_regulation", "kang_ramp")}
    results = [
        _result(c, sc, s, g)
        for s in range(4)
        for c, sc, g in (
            ("A", "kang_regulation", 0.9),
            ("A", "kang_ramp", 0.8 + 0.01 * s),
            ("B", "kang_regulation", 0.5),
            ("B", "kang_ramp", 0.4),
            ("C", "kang_regulation", 2.0),  # best, but only on one scenario
            ("Ideal", "kang_regulation", 1.0),
            ("Ideal", "kang_ramp", 1.0),
        )
    ]
    agg = leaderboard.aggregate(results, scenarios)
    assert [(a["scenarios"], [r["controller"] for r in a["rows"]]) for a in agg] == [
        (["kang_ramp", "kang_regulation"], ["A", "B"]),
        (["kang_regulation"], ["C"]),
    ]
    assert [r["controller"] for r in agg[0]["references"]] == ["Ideal"]
    assert agg[0]["p_improve"][("A", "B")] == 1.0 and agg[0]["p_improve"][("B", "A")] == 0.0


def test_scenario_benchmark_fields_are_checked():
    with pytest.raises(ConfigError, match="limit_score"):
        load_scenario("kang_regulation", {"benchmark": {"limit_score": "quadratic"}})
    with pytest.raises(ValueError, match=r"benchmark\.uncompensated"):
        registry.uncompensated_loop("Oracle")
    sc = load_scenario("kang_regulation", {"benchmark": {"uncompensated": "Nope"}})
    with pytest.raises(ValueError, match=r"benchmark\.uncompensated: 'Nope'"):
        registry.make("Ideal").why_not(sc)
