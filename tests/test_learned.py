"""Learned controllers (agents/learned/policy.py): the model input, the algorithm classes, LearnedPolicy's
prediction path against model.predict, and actions on many episodes' rows at once."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("sb3_contrib")
from conftest import SCENARIO, write_config

from frictiongym.agents import registry
from frictiongym.agents.evaluation.evaluate import EnvCache
from frictiongym.agents.learned.policy import (
    LayerNetwork,
    LearnedPolicy,
    PolicyInputs,
    RowwiseActor,
    SB3Network,
    residual_action,
)
from frictiongym.agents.training import build_model, load_config, make_training_env, validation_episodes


def test_policy_inputs_sizes():
    """The model input: the scenario's observation with its history / privileged blocks, then the base
    action."""
    sc = EnvCache().scenario(validation_episodes(SCENARIO)[0])
    assert PolicyInputs().size(sc) == sc.layout.size
    assert PolicyInputs(2, False, True).size(sc) == sc.layout.size + 2 * (len(sc.spec.sensors) + 1) + 1
    assert PolicyInputs(0, False, True, differences=True).size(sc) == sc.layout.size + 1 + 2


def test_differences_are_the_tracking_error_and_the_reference_change_over_the_preview():
    """PolicyInputs.differences appends (y - r)/s of the tracked sensor and (r(t_{k+P}) - r(t_k))/s, read
    from the observation's own entries (float32 differences of the scaled readings); on a regulation
    scenario with its preview filled in (preview_fill) the reference does not change: exactly 0."""
    from frictiongym.agents.learned.policy import difference_indices, policy_observation, with_preview
    from frictiongym.envs.servo_env import ServoEnv, decode_observation

    env = ServoEnv("kang_random")
    sc = env.unwrapped.scenario
    obs, _ = env.reset(seed=500000)
    for _ in range(120):  # into the episode's first segments: a moving reference
        obs, *_ = env.step(np.array([0.3], dtype=np.float32))
    x = policy_observation(obs, np.array([0.1]), difference_indices(sc))
    assert x.shape == (sc.layout.size + 1 + 2,) and x.dtype == np.float32
    d = decode_observation(sc, obs)
    s = sc.output_scale
    y = d["sensors"][sc.spec.sensor_names[sc.tracked_sensor]]
    expected = [(y - d["reference"]) / s, (d["preview"][-1] - d["reference"]) / s]
    np.testing.assert_allclose(x[-2:], expected, atol=1e-6)
    assert x[-1] != 0.0 and x[-3] == np.float32(0.1)

    reg = EnvCache().scenario(validation_episodes("kang_regulation")[0])
    assert reg.preview_steps == 0
    env = ServoEnv("kang_regulation")
    obs, _ = env.reset(seed=500000)
    filled = with_preview(obs[None], reg.layout.slice("reference").stop, 5)
    rows = policy_observation(filled, None, difference_indices(reg, 5))
    assert rows.shape == (1, reg.layout.size + 5 + 2) and rows[0, -1] == 0.0
    tracked = reg.layout.slice("sensors").start + reg.tracked_sensor
    reference = reg.layout.slice("reference").start
    assert rows[0, -2] == filled[0, tracked] - filled[0, reference]


@pytest.mark.parametrize(
    ("algo", "privileged"),
    [
        ("SAC", False),
        ("TD3", False),
        ("TQC", False),
        ("CrossQ", False),
        ("PPO", False),
        ("SAC", True),
        ("TD3", True),
    ],
)
def test_policy_actions_equal_sb3_predict(tmp_path, algo, privileged):
    """SB3Network's own prediction path (no per-call eval-mode switch, no action distribution, its layers
    called as a plain chain) gives model.predict's actions bit for bit, in range and out of it, also after
    training switched the policy back to train mode, and with the asymmetric actor's feature selection."""
    extra = {"observation": {"privileged_critic": True}} if privileged else {}
    (cfg,) = load_config(write_config(tmp_path, algo, **extra))
    model = build_model(cfg, make_training_env(cfg, 0), 0, None)
    assert type(model.policy).__name__.startswith("Asymmetric") == privileged
    import torch

    with torch.no_grad():  # a non-trivial actor: the zeroed output layer would make every action equal
        for p in model.policy.parameters():
            p.add_(0.05 * torch.randn_like(p))
    network = SB3Network(model)
    xs = np.random.default_rng(0).normal(0.0, 3.0, (50, *model.observation_space.shape)).astype(np.float32)
    model.policy.set_training_mode(True)
    got = np.array([network._predict(x) for x in xs])
    assert not model.policy.training
    want = np.array([model.predict(x, deterministic=True)[0] for x in xs])
    assert np.array_equal(got, want) and len(np.unique(got)) > 10


@pytest.mark.parametrize(
    ("algo", "privileged", "rowwise"),
    [
        ("SAC", False, True),
        ("TD3", False, True),
        ("TQC", False, True),
        ("SAC", True, True),
        ("TD3", True, True),
        ("CrossQ", False, False),
        ("PPO", False, True),
    ],
)
def test_policy_rows_act_as_each_row_alone(tmp_path, algo, privileged, rowwise):
    """LearnedPolicy.actions on a batch of observations gives, row for row and bit for bit, the action each
    row gets alone (what lets the leaderboard run a learned model's episodes with one network call per
    step); the row-wise float64 actor (SAC-family and TD3 actors of Linear/ReLU/Tanh layers, the
    asymmetric actor's column selection included) is model.predict's network to float32 rounding, and any
    other actor (CrossQ's batch renormalisation) is called one row at a time."""
    extra = {"observation": {"privileged_critic": True}} if privileged else {}
    (cfg,) = load_config(write_config(tmp_path, algo, **extra))
    model = build_model(cfg, make_training_env(cfg, 0), 0, None)
    import torch

    with torch.no_grad():  # a non-trivial actor: the zeroed output layer would make every action equal
        for p in model.policy.parameters():
            p.add_(0.05 * torch.randn_like(p))
    model.policy.set_training_mode(False)
    assert (RowwiseActor.of(model.policy) is not None) == rowwise
    policy = LearnedPolicy(model, inputs=cfg.inputs, base=registry.BUILTIN["PID"]())
    d = model.observation_space.shape[0] - 1  # the env's observation; the base action is appended
    rng = np.random.default_rng(0)
    obs = rng.normal(0.0, 3.0, (64, d)).astype(np.float32)
    base = rng.uniform(-1.0, 1.0, (64, 1)).astype(np.float32)
    together = policy.actions(obs, base)
    alone = np.concatenate([policy.actions(obs[i : i + 1], base[i : i + 1]) for i in range(64)])
    assert together.shape == (64, 1) and np.array_equal(together, alone)
    assert np.array_equal(policy.actions(obs[:7], base[:7]), together[:7])
    x = np.concatenate([obs, base], axis=1)
    want = np.array([model.predict(row, deterministic=True)[0] for row in x])
    got = policy.network(x)
    assert isinstance(policy.network, LayerNetwork) == rowwise
    assert np.abs(got - want).max() <= (1e-5 if rowwise else 0.0) and len(np.unique(got)) > 10


def test_a_residual_share_of_one_is_the_ungated_command_to_the_last_bit():
    """residual_action's share (a gated base's grant) leaves every other residual as it was: at s = 1,
    clip(u_base + α·a) bit for bit for float32 network outputs, one row or many; at s = 0 the base's
    action; rows take their own share."""
    rng = np.random.default_rng(0)
    base, a = rng.uniform(-1, 1, (64, 1)), rng.uniform(-1, 1, (64, 1)).astype(np.float32)
    before = np.clip(base + 0.1 * a, -1.0, 1.0).astype(np.float32)  # the formula before the share
    np.testing.assert_array_equal(residual_action(base, a, 0.1), before)
    np.testing.assert_array_equal(residual_action(base, a, 0.1, np.ones((64, 1))), before)
    np.testing.assert_array_equal(residual_action(base[0], a[0], 0.1, 1.0), before[0])
    np.testing.assert_array_equal(residual_action(base, a, 0.1, 0.0), base.astype(np.float32))
    half = np.where(np.arange(64)[:, None] % 2 == 0, 1.0, 0.0)
    np.testing.assert_array_equal(residual_action(base, a, 0.1, half)[::2], before[::2])
    np.testing.assert_array_equal(residual_action(base, a, 0.1, half)[1::2], base[1::2].astype(np.float32))


def test_tree_sum_is_a_fixed_pairwise_order():
    """tree_sum adds the first half of the terms to the second until one is left: exact on integers,
    within float64 rounding of math.fsum otherwise, and a row's sum does not depend on the other rows."""
    import math

    from frictiongym.agents.learned.policy import tree_sum

    rng = np.random.default_rng(1)
    ints = rng.integers(-1000, 1000, (3, 13, 4)).astype(np.float64)
    assert np.array_equal(tree_sum(ints), ints.sum(axis=1))
    p = rng.normal(size=(5, 37, 3)) * 10.0 ** rng.integers(-8, 8, (5, 37, 3))
    exact = np.array([[math.fsum(p[i, :, j]) for j in range(3)] for i in range(5)])
    assert np.allclose(tree_sum(p), exact, rtol=1e-12, atol=1e-12 * np.abs(p).sum())
    assert np.array_equal(tree_sum(p)[2:3], tree_sum(p[2:3]))
    # the tree's order, written out for five terms: ((a + c) + (b + d)) + e
    a, b, c, d, e = 1e16, 1.0, -1e16, 1.0, 1.0
    assert tree_sum(np.array([[[a], [b], [c], [d], [e]]]))[0, 0] == ((a + c) + (b + d)) + e


def test_algorithm_class_names_the_missing_rl_extra(monkeypatch):
    from frictiongym.agents.learned import policy as learned

    assert learned.algorithm_class("TQC").__name__ == "TQC"
    with pytest.raises(ValueError, match=r"'Nope' is not a stable-baselines3 or sb3-contrib class$"):
        learned.algorithm_class("Nope")

    def no_sb3(name: str):
        raise ImportError(name)

    monkeypatch.setattr(learned.importlib, "import_module", no_sb3)
    with pytest.raises(ValueError, match=r"stable_baselines3 and sb3_contrib not installed: pip install"):
        learned.algorithm_class("SAC")
    with pytest.raises(ValueError, match=r"needs sbx: pip install -e '\.\[sbx\]'"):
        learned.algorithm_class("sbx.SAC")


def test_a_preview_model_on_a_regulation_scenario_is_given_its_constant_reference_as_the_preview(tmp_path):
    """A model trained with a 5-step reference preview (the committed M220 generalist, on m220_random)
    runs on m220_regulation, which has none: the reference is constant there, so the learned controller
    repeats the observation's reference entry where the preview stands, and every episode is bit for bit
    the one on the same scenario with the env's own 5-step preview; the residual acts (not PID's rows)."""
    import math

    from frictiongym.agents.evaluation.evaluate import run_episodes
    from frictiongym.envs.scenario import load_scenario
    from frictiongym.envs.suites import Episode

    own = tmp_path / "m220_regulation_preview.yaml"
    own.write_text("extends: m220_regulation\nreference: {type: constant, value: 0.0, preview_steps: 5}\n")
    models, name = ("agents/models/generalist",), "GenSAC-floorgated-m220_random-s0"
    sc = load_scenario("m220_regulation")
    assert sc.preview_steps == 0 and load_scenario(own).preview_steps == 5
    assert registry.why_not(name, models)(sc) is None and registry.make(name, models).why_not(sc) is None
    filled = run_episodes(
        registry.make(name, models), [Episode(sc.name, s, True) for s in (500000, 500001)], keep_log=True
    )
    shown = run_episodes(
        registry.make(name, models), [Episode(str(own), s, True) for s in (500000, 500001)], keep_log=True
    )
    pid = run_episodes(registry.make("PID"), [Episode(sc.name, s, True) for s in (500000, 500001)])
    for a, b, p in zip(filled, shown, pid, strict=True):
        for k, x in a.metrics.items():
            assert x == b.metrics[k] or (math.isnan(x) and math.isnan(b.metrics[k])), k
        assert all(np.array_equal(a.log[k], b.log[k]) for k in a.log)
        assert a.metrics["final_error"] != p.metrics["final_error"]


def test_a_differences_model_sees_in_evaluation_what_its_training_env_gave(tmp_path):
    """A residual SAC with the differences inputs, built on kang_random (its mean layer perturbed so the
    residual acts): on kang_regulation, where its preview is filled in, its episodes equal bit for bit
    those on the same scenario with the env's own 5-step preview, and differ from PID's; every network
    input it built ends with the two differences at the indices the training env uses."""
    import math

    import torch
    import yaml
    from conftest import HYPER

    from frictiongym.agents.evaluation.evaluate import run_episodes
    from frictiongym.envs.suites import Episode

    cfg_path = tmp_path / "diff.yaml"
    entry = {"residual": {"base": "PID", "alpha": 0.2}, "observation": {"differences": True}}
    cfg_path.write_text(
        yaml.safe_dump(
            {
                "name": "Diff",
                "algorithm": "SAC",
                "defaults": {"hyperparams": HYPER["SAC"]},
                "scenarios": {"kang_random": entry},
            }
        )
    )
    (cfg,) = load_config(cfg_path)
    venv = make_training_env(cfg, 0)
    model = build_model(cfg, venv, 0, None)
    with torch.no_grad():
        for p in model.actor.mu.parameters():
            p.add_(0.2 * torch.randn(p.shape, generator=torch.Generator().manual_seed(0)))
    own = tmp_path / "kang_regulation_preview.yaml"
    own.write_text("extends: kang_regulation\nreference: {type: constant, value: 0.0, preview_steps: 5}\n")

    def policy() -> LearnedPolicy:
        return LearnedPolicy(
            model, ("kang_robot",), inputs=cfg.inputs, base=registry.make("PID"), alpha=cfg.alpha
        )

    seen: list[np.ndarray] = []
    shown_policy = policy()
    network = shown_policy.network

    class Shown(type(network)):  # the same network, each model input it is given kept
        def __call__(self, x: np.ndarray) -> np.ndarray:
            seen.append(x.copy())
            return super().__call__(x)

    shown_policy.network = Shown(*(getattr(network, f.name) for f in dataclasses.fields(network)))
    seeds = (500000, 500001)
    filled = run_episodes(policy(), [Episode("kang_regulation", s, True) for s in seeds], keep_log=True)
    shown = run_episodes(shown_policy, [Episode(str(own), s, True) for s in seeds], keep_log=True)
    pid = run_episodes(registry.make("PID"), [Episode("kang_regulation", s, True) for s in seeds])
    for a, b, p in zip(filled, shown, pid, strict=True):
        for k, x in a.metrics.items():
            assert x == b.metrics[k] or (math.isnan(x) and math.isnan(b.metrics[k])), k
        assert all(np.array_equal(a.log[k], b.log[k]) for k in a.log)
        assert a.metrics["final_error"] != p.metrics["final_error"]
    tracked, reference, last = venv.differences
    x = np.concatenate(seen)
    assert x.shape[1] == venv.observation_space.shape[0] and len(x) > 100
    assert np.array_equal(x[:, -2], x[:, tracked] - x[:, reference]) and x[:, -2].any()
    assert np.array_equal(x[:, -1], x[:, last] - x[:, reference])
