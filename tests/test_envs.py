"""Gymnasium environments: API, determinism, robustness, vector env equivalence, suites."""

import itertools
import os
import pickle
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import frictiongym.envs  # noqa: F401  (registers the ids)
from frictiongym.envs import env_id
from frictiongym.envs.config import ConfigError
from frictiongym.envs.scenario import load_scenario, scenario_names
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.suites import load_suite, seed_ranges, suite_names
from frictiongym.envs.vector import ServoVectorEnv, make_sb3_vec_env


def make(scenario, **kw):
    return gym.make(env_id(load_scenario(scenario).spec.name), scenario=scenario, **kw)


@pytest.mark.parametrize("scenario", scenario_names())
def test_check_env_passes_for_every_scenario(scenario):
    env = make(scenario, randomize=True, episode_s=1.0)
    check_env(env.unwrapped, skip_render_check=True)
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # SB3's checker reports problems as warnings: none allowed
        sb3_checker.check_env(env.unwrapped, warn=True)


def test_ground_truth_is_a_method_and_in_info_on_request():
    """The same values either way, without changing the episode; left out of info by default."""
    keys = {"qpos", "qvel", "bristle", "friction_torque"}
    plain = ServoEnv("m220_reversal_tracking", randomize=True)
    full = ServoEnv("m220_reversal_tracking", randomize=True, ground_truth_in_info=True)
    (_, ip), (_, i_full) = plain.reset(seed=4), full.reset(seed=4)
    assert not keys & set(ip) and keys <= set(i_full)
    rng = np.random.default_rng(0)
    for _ in range(30):
        a = rng.uniform(-1, 1, 1).astype(np.float32)
        (op, rp, *_, ip), (of, rf, *_, i_full) = plain.step(a), full.step(a)
        assert np.array_equal(op, of) and rp == rf and not keys & set(ip)
        truth = plain.ground_truth()
        assert all(np.array_equal(truth[k], i_full[k]) for k in keys)
    assert np.any(truth["friction_torque"] != 0.0) and np.any(truth["bristle"] != 0.0)
    with pytest.raises(ConfigError, match="ground_truth_in_info"):
        ServoEnv("kang_regulation", ground_truth_in_info="yes")


def test_wrong_plant_for_id_is_rejected():
    with pytest.raises(ValueError, match="is for plant"):
        gym.make("frictiongym/KangRobot-v0", scenario="m220_regulation")


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"control_period_s": 0.0123}, "sampling.control_period_s"),  # not a multiple of dt
        ({"episode_s": 0.011}, "episode_s"),
        (
            {"overrides": {"task": {"action_scale_nm": 50.0}}},
            "task.action_scale_nm",
        ),  # above the 10 N·m limit
        ({"overrides": {"reference": {"type": "square"}}}, "reference.type"),
        ({"overrides": {"task": {"tracked_sensor": "tacho9"}}}, "task.tracked_sensor"),
        ({"overrides": {"rewards": {}}}, "rewards"),
    ],
)
def test_invalid_scenario_values_name_the_field(kwargs, field):
    with pytest.raises(ConfigError) as e:
        gym.make("frictiongym/KangRobot-v0", **kwargs)
    assert e.value.field == field


def test_nan_action_is_a_clear_error():
    env = gym.make("frictiongym/KangRobot-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan], dtype=np.float32))


def test_same_seed_same_episode_different_seed_different_episode():
    def run(seed):
        env = gym.make("frictiongym/KangRobot-v0", randomize=True, episode_s=1.0)
        obs, info = env.reset(seed=seed)
        out = [obs]
        rng = np.random.default_rng(0)
        for _ in range(50):
            obs, _r, *_ = env.step(rng.uniform(-1, 1, 1).astype(np.float32))
            out.append(obs)
        return np.array(out), info["params"]

    (a, pa), (b, pb), (c, pc) = run(3), run(3), run(4)
    assert np.array_equal(a, b) and pa == pb
    assert not np.array_equal(a, c) and pa != pc


def test_episode_structure_ground_truth_and_metrics():
    # flexible_speed_step: 10 s at 40 ms
    env = gym.make("frictiongym/FlexibleServo-v0", ground_truth_in_info=True)
    _, info = env.reset(seed=0)
    assert {"params", "qpos", "qvel", "bristle", "friction_torque"} <= set(info)
    assert info["qvel"][0] == pytest.approx(1.0)  # ω1(0) = 1 rad/s, Wallenborg §4.3
    n, done = 0, False
    while not done:
        _obs, r, term, trunc, info = env.step(np.zeros(1, dtype=np.float32))
        n += 1
        done = term or trunc
        total = info["reward_tracking"] + info["reward_effort"] + info["reward_smoothness"]
        assert r == pytest.approx(total)
    assert n == 250 and trunc and not term
    m = info["episode_metrics"]
    # zero command: the shafts coast to a stop under friction, so the output ends at 0 V while the
    # reference is 0 again after t = 5 s, and the 1 V step was never followed (IAE ≥ 3 V·s)
    assert m["final_error"] == pytest.approx(0.0, abs=1e-3) and m["iae"] > 3.0


def test_observation_layout_and_scaling_helpers():
    env = gym.make("frictiongym/M220-v0", scenario="m220_reversal_tracking")
    obs, _ = env.reset(seed=0)
    u = env.unwrapped
    assert obs.shape == (2 + 1 + 5 + 1,)
    obs, *_ = env.step(u.command_to_action(1.0))
    d = u.decode_observation(obs)
    assert d["previous_command"] == pytest.approx(1.0)
    assert d["reference"] == pytest.approx(0.5 * np.sin(2 * np.pi * 0.2 * 0.005), rel=1e-5)
    res = 2 * np.pi / 16000
    assert d["sensors"]["encoder_drive"] / res == pytest.approx(
        round(d["sensors"]["encoder_drive"] / res), abs=1e-3
    )
    assert u.action_to_command(np.array([2.0])) == pytest.approx(2.0)  # clipped to 1 -> 2 V


def test_privileged_observation_only_on_request():
    plain = make("kang_regulation_20deg")
    priv = make("kang_regulation_20deg", overrides={"observation": {"privileged": True}})
    assert priv.observation_space.shape[0] == plain.observation_space.shape[0] + 3
    obs, _ = priv.reset(seed=0)
    assert obs[-3] == pytest.approx(1.0)  # true output / output_scale = 20 deg / 20 deg


def test_divergence_ends_the_episode_with_a_flag_and_finite_observation():
    env = gym.make("frictiongym/KangRobot-v0")
    env.reset(seed=0)
    core = env.unwrapped.core
    core.model.actuator_dynprm[core.idx.friction[0], 6] = (
        1e9  # bristle damping far outside the checked region
    )
    obs, r, term, _trunc, info = env.step(np.array([0.5], dtype=np.float32))
    assert term and info["diverged"] and np.all(np.isfinite(obs)) and np.isfinite(r)


NOISY = {  # sensor noise and delay jitter on, to exercise those streams too
    "kang_regulation": {
        "plant_overrides": {"sensors": {"encoder": {"noise_std_deg": 0.01}}, "sampling": {"jitter_s": 0.002}}
    },
    "m220_reversal_tracking": {
        "plant_overrides": {
            "sensors": {"encoder_drive": {"noise_std_counts": 3.0}},
            "sampling": {"jitter_s": 0.001},
        }
    },
}


@pytest.mark.parametrize(
    ("scenario", "overrides"),
    [
        ("kang_regulation", None),
        ("m220_reversal_tracking", None),
        ("flexible_zero_speed", None),
        ("kang_regulation", NOISY["kang_regulation"]),
        ("m220_reversal_tracking", NOISY["m220_reversal_tracking"]),
    ],
)
def test_vector_env_matches_single_envs_bit_for_bit_across_autoresets(scenario, overrides):
    v = ServoVectorEnv(scenario, 3, nthread=2, randomize=True, episode_s=0.4, overrides=overrides)
    singles = [
        make(scenario, randomize=True, episode_s=0.4, overrides=overrides, ground_truth_in_info=True)
        for _ in range(3)
    ]
    o, _ = v.reset(seed=50)
    so, sinfo = zip(*(s.reset(seed=50 + i) for i, s in enumerate(singles)), strict=True)
    assert all(np.array_equal(o[i], so[i]) for i in range(3))
    assert v.params() == [info["params"] for info in sinfo]
    rng, done = np.random.default_rng(1), [False] * 3
    for _ in range(2 * v.scenario.episode_steps + 3):
        a = rng.uniform(-1, 1, (3, 1)).astype(np.float32)
        o, r, *_ = v.step(a)
        truth = v.ground_truth()
        for i, s in enumerate(singles):
            if done[i]:
                (oi, info), ri, done[i] = s.reset(), 0.0, False
                assert v.params()[i] == info["params"]  # the autoreset drew the same episode
            else:
                oi, ri, te, tr, info = s.step(a[i])
                done[i] = te or tr
            assert np.array_equal(o[i], oi) and r[i] == ri
            for key in ("qpos", "qvel", "bristle", "friction_torque"):  # the single env's info, as rows
                assert np.array_equal(truth[key][i], info[key]), key


def test_sb3_adapter_autoresets_with_terminal_observation():
    venv = make_sb3_vec_env("kang_regulation_20deg", 2, nthread=2, episode_s=0.1)  # 5 steps per episode
    venv.reset()
    for _k in range(5):
        obs, _rew, done, infos = venv.step(np.zeros((2, 1)))
    assert done.all() and all("terminal_observation" in i and i["TimeLimit.truncated"] for i in infos)
    assert obs[0][0] == pytest.approx(1.0, abs=1e-4)  # new episode starts again at θ(0) = 20 deg


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
        f"e=gym.make('frictiongym/KangRobot-v0', scenario='{e.scenario}', randomize=True);"
        f"print(e.reset(seed={e.seed})[1]['params'])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    here = make(e.scenario, randomize=True).reset(seed=e.seed)[1]["params"]
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


def test_rgb_render_headless_and_episode_plot(tmp_path):
    code = (
        "import gymnasium as gym, frictiongym.envs, numpy as np;"
        "e=gym.make('frictiongym/M220-v0', render_mode='rgb_array'); e.reset(seed=0);"
        "f=e.render(); assert f.shape == (480, 640, 3) and f.std() > 1, f.std();"
        f"e.unwrapped.plot_episode(r'{tmp_path / 'ep.png'}')"
    )
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=120)
    assert (tmp_path / "ep.png").stat().st_size > 10_000


def test_huge_state_ends_the_episode_as_diverged():
    with pytest.raises(ConfigError, match=r"initial_state.qpos\[0\]\[0\]: 20000000000.0 is outside"):
        ServoEnv("kang_regulation", overrides={"initial_state": {"qpos": [[2e10, 2e10]]}})  # the envelope
    env = ServoEnv("kang_regulation")
    env.reset(seed=0)
    env.core.backend.qpos[:] = 2e10  # a state no scenario may start from, e.g. after a numerical blow-up
    _, reward, term, _, info = env.step(np.zeros(1, np.float32))
    assert term and info["diverged"] and np.isfinite(reward)
    assert reward < -(env.scenario.reward_weights["tracking"] * 1e6)  # below any step that did not diverge


@pytest.mark.parametrize("bad", ["x", b"1", 1j, True, np.array([]), np.zeros(2), np.zeros((3, 2))])
def test_actions_other_than_one_finite_real_are_clear_errors(bad):
    env = ServoEnv("kang_regulation")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(bad)


def test_step_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match="reset"):
        ServoEnv("kang_regulation").step(np.zeros(1))
    with pytest.raises(RuntimeError, match="reset"):
        ServoVectorEnv("kang_regulation", 2).step(np.zeros(2))


def test_vector_env_seeds_checks_failed_reset_and_pickling():
    venv = ServoVectorEnv("kang_regulation", 2)
    _, info = venv.reset(seed=2**64)  # works as in the single env
    assert list(info["episode_seed"]) == [2**64, 2**64 + 1]
    venv.reset(seed=5)
    for bad in (1.5, -1, True):
        with pytest.raises(ValueError, match="seed"):
            venv.reset(seed=bad)
    assert np.array_equal(venv.step(np.zeros(2))[0], _stepped_once(5))  # failed resets changed nothing
    with pytest.raises(TypeError, match="cannot be pickled"):
        pickle.dumps(venv)
    with pytest.raises(ValueError, match="num_envs"):
        ServoVectorEnv("kang_regulation", 2.5)


def _stepped_once(seed: int) -> np.ndarray:
    venv = ServoVectorEnv("kang_regulation", 2)
    venv.reset(seed=seed)
    return venv.step(np.zeros(2))[0]


def test_make_vec_uses_the_batched_env_and_matches_single_envs():
    venv = gym.make_vec("frictiongym/KangRobot-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert isinstance(venv, ServoVectorEnv)
    obs, _ = venv.reset(seed=3)
    single = ServoEnv("kang_regulation")
    assert np.array_equal(obs[1], single.reset(seed=4)[0])


def test_vector_env_reports_divergence_and_writes_no_mujoco_log(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo would write MUJOCO_LOG.TXT here
    venv = ServoVectorEnv("kang_regulation", 2)
    venv.reset(seed=0)
    venv.core.backend.qpos[:] = 2e10  # a blown-up state (no scenario may start from it)
    _, reward, term, _, info = venv.step(np.zeros(2))
    assert term.all() and info["diverged"].all() and np.isfinite(reward).all()
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


@pytest.mark.parametrize("bad", [np.zeros((2, 2)), np.zeros(3), "ab", np.array([1j, 0])])
def test_vector_env_rejects_anything_but_one_real_per_env(bad):
    venv = ServoVectorEnv("kang_regulation", 2)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        venv.step(bad)


def test_sb3_adapter_step_before_reset_is_an_error():
    from frictiongym.envs.vector import make_sb3_vec_env

    venv = make_sb3_vec_env("kang_regulation", 2)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((2, 1)))
