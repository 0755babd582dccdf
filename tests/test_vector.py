"""The batched vector env and its stable-baselines3 adapter (envs/vector.py): bit for bit the single envs
across autoresets, seeding, errors, divergence."""

import pickle

import gymnasium as gym
import numpy as np
import pytest

from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.vector import ServoVectorEnv, make_sb3_vec_env

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
        ServoEnv(scenario, randomize=True, episode_s=0.4, overrides=overrides, ground_truth_in_info=True)
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
    venv = gym.make_vec("frictiongym/KangRobot-v1", num_envs=2, vectorization_mode="vector_entry_point")
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


def test_vector_env_step_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match="reset"):
        ServoVectorEnv("kang_regulation", 2).step(np.zeros(2))


def test_sb3_adapter_step_before_reset_is_an_error():
    venv = make_sb3_vec_env("kang_regulation", 2)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((2, 1)))
