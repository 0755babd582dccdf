"""Foundation v2 hardening: each behaviour found by trying the envs as a new user would (issue 7)."""

import dataclasses
import pickle
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import frictiongym.envs  # noqa: F401
from frictiongym.envs.config import ConfigError
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.plants.params import EpisodeParams, rejected_draws
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.vector import ServoVectorEnv

ROOT = Path(__file__).parents[1]


@pytest.mark.parametrize("plant", ["kang_robot", "m220", "flexible_servo"])
def test_every_draw_passes_the_checks(plant):
    """The corner check at load makes every seed's parameters valid (Kang's seed 66 failed before)."""
    assert rejected_draws(plant_spec(plant), [66, *range(2000)]) == []


def test_rejected_draws_counts_what_reset_refuses():
    """The counter behind scripts/check_draws.py finds the draws a range too wide gives (the load check
    bypassed with dataclasses.replace; Kang's σ0 stability bound h·sqrt(σ0/J) <= 0.2) and none on the
    preset."""
    spec = plant_spec("kang_robot")
    wide = dataclasses.replace(spec, randomization={**spec.randomization, "sigma0_scale": (0.5, 5.0)})
    bad = rejected_draws(wide, range(200))
    assert 50 < len(bad) < 200 and all("sigma0" in why for _, why in bad)
    with pytest.raises(ConfigError):
        EpisodeParams.draw(wide, bad[0][0]).validate(wide)
    assert rejected_draws(spec, range(200)) == []


@pytest.mark.slow
def test_check_draws_script_reports_zero_rejections():
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts/check_draws.py"), "--seeds", "300", "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = [ln.split() for ln in proc.stdout.splitlines()[1:]]
    assert {r[1] for r in rows} >= {"kang_robot", "m220", "flexible_servo", "kang_regulation"}
    assert all(r[2:4] == ["300", "0"] for r in rows)


@pytest.mark.parametrize(
    ("key", "rng"), [("sigma0_scale", [0.5, 5.0]), ("inertia_scale", [0.1, 1.0]), ("friction_scale", [0, 0])]
)
def test_bad_randomization_ranges_rejected_at_load_naming_the_field(key, rng):
    with pytest.raises(ConfigError) as e:
        plant_spec("kang_robot", {"randomization": {key: rng}})
    assert e.value.field.startswith(f"randomization.{key}")  # the range or its bad end


def test_huge_state_ends_the_episode_as_diverged():
    with pytest.raises(ConfigError, match=r"initial_state.qpos\[0\]\[0\]: 20000000000.0 is outside"):
        ServoEnv("kang_regulation", overrides={"initial_state": {"qpos": [[2e10, 2e10]]}})  # the envelope
    env = ServoEnv("kang_regulation")
    env.reset(seed=0)
    env.core.backend.qpos[:] = 2e10  # a state no scenario may start from, e.g. after a numerical blow-up
    _, reward, term, _, info = env.step(np.zeros(1, np.float32))
    assert term and info["diverged"] and np.isfinite(reward)
    assert reward < -(env.scenario.reward_weights["tracking"] * 1e6)  # below any step that did not diverge


def test_coulomb_model_keeps_the_viscous_term():
    """3 N·m on Kang's rotor with Coulomb + viscous (σ2 = 0.86 N·m·s/rad): steady speed
    (3 - T_C+)/σ2 ≈ 2.0 rad/s, reached within 10 s (it was 14 rad/s without the viscous term)."""
    sim = PlantSim("kang_robot", friction_model="coulomb")
    sim.reset()
    for _ in range(500):
        r = sim.step(3.0)
    p = sim.spec.drive_friction
    assert r.qvel[0] == pytest.approx((3.0 - p.levels()["coulomb_pos"]) / p.sigma2, rel=0.02)


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


def test_make_vec_uses_the_batched_env_and_matches_single_envs():
    venv = gym.make_vec("frictiongym/KangRobot-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert isinstance(venv, ServoVectorEnv)
    obs, _ = venv.reset(seed=3)
    single = ServoEnv("kang_regulation")
    assert np.array_equal(obs[1], single.reset(seed=4)[0])


def test_pinned_parameters_are_applied_and_echoed():
    env = ServoEnv("kang_regulation", randomize=True)
    _, free = env.reset(seed=9)
    _, info = env.reset(seed=9, options={"params": {"friction_scale": 1.3}})
    assert info["pinned"] == {"friction_scale": 1.3}
    nominal = plant_spec("kang_robot").drive_friction
    assert info["params"]["friction"][0]["fs"] == pytest.approx(1.3 * nominal.fs)
    assert info["params"]["inertia"] == free["params"]["inertia"]  # the other draws are unchanged
    with pytest.raises(ConfigError, match="unknown parameter"):
        env.reset(seed=9, options={"params": {"frction_scale": 1.3}})


def test_plantsim_noise_matches_the_env_for_the_same_seed():
    ov = {"sensors": {"encoder": {"noise_std_deg": 0.01}}}
    env = ServoEnv("kang_regulation_20deg", overrides={"plant_overrides": ov})
    env.reset(seed=4)
    obs, *_ = env.step(np.zeros(1, np.float32))
    sim = PlantSim("kang_robot", ov)
    sim.reset(qpos=[0.349066], seed=4)
    r = sim.step(0.0)
    assert obs[0] == np.float32(r.measurement[0] / env.scenario.output_scale)


def test_model_inertia_is_exactly_the_presets():
    """Visual geoms add no mass: J·α = τ at rest without friction gives J1 = 22e-6 kg·m² (§3.1)."""
    sim = PlantSim("flexible_servo", friction_model="none")
    sim.reset()
    sim.step(1.0, nstep=1)
    assert sim.spec.actuator_gain / sim.data.qacc[sim.dofs[0]] == pytest.approx(22e-6, rel=1e-9)


def test_unknown_yaml_key_names_the_file():
    with pytest.raises(ConfigError, match=r"kang_robot\.yaml: rotor\.inertia"):
        plant_spec("kang_robot", {"rotor": {"inertia": 1.0}})
    with pytest.raises(ConfigError, match=r"configuration\.backlash_device"):
        plant_spec("m220", {"configuration": {"backlash_device": "no"}})


def _stepped_once(seed: int) -> np.ndarray:
    venv = ServoVectorEnv("kang_regulation", 2)
    venv.reset(seed=seed)
    return venv.step(np.zeros(2))[0]


def test_controllers_yaml_unknown_keys_name_the_file(monkeypatch):
    from frictiongym.agents import classical, settings

    assert classical.PIDSettings.SECTION in settings.FamilySettings.sections
    raw = settings.load_yaml(settings.configs_dir() / settings.FILE)
    for bad, match in (
        ({**raw, "southwrd": {}}, r"controllers\.yaml: southwrd: unknown section"),
        ({**raw, "pid": {**raw["pid"], "zta": 1.0}}, r"controllers\.yaml: pid\.zta: unknown key"),
    ):
        monkeypatch.setattr(settings, "load_yaml", lambda *_a, bad=bad, **_k: bad)
        settings._raw.cache_clear()
        with pytest.raises(ConfigError, match=match):
            settings.read("pid", lambda s: (s.get("integrator_pole_ratio"), s.get("loops")))
    settings._raw.cache_clear()


@pytest.mark.parametrize(
    ("overrides", "field"),
    [
        ({"observation": {"privileged": "false"}}, "observation.privileged"),  # was truthy
        ({"observation": {"history": 2.7}}, "observation.history"),  # was truncated to 2
        ({"episode_s": 1e7}, "episode_s"),  # was a 3.7 GiB allocation
        ({"reward": {"tracking": 1e308}}, "reward.tracking"),  # gave -inf rewards
        ({"plant": 1.0}, "plant"),
        ({"plant_overrides": {"friction": {"static_pos_nm": 1e30}}}, "friction.static_pos_nm"),
        ({"plant_overrides": {"sampling": {"timestep_s": 1e-8}}}, "sampling.timestep_s"),  # 2e6 substeps
        ({"plant_overrides": {"sensors": {"encoder": {"joint": "shaft9"}}}}, "sensors.encoder.joint"),
        ({"plant_overrides": 1.0}, "plant_overrides"),
    ],
)
def test_bad_scenario_values_are_rejected_at_load_naming_the_field(overrides, field):
    with pytest.raises(ConfigError) as e:
        ServoEnv("kang_regulation", overrides=overrides)
    assert e.value.field == field


def test_scenario_files_are_checked_for_unknown_and_missing_keys(tmp_path):
    typo = tmp_path / "typo.yaml"
    typo.write_text("extends: kang_regulation\nepisodes_s: 5.0\n")
    with pytest.raises(ConfigError, match=r"typo\.yaml: episodes_s: unknown key"):
        ServoEnv(typo)
    missing = tmp_path / "missing.yaml"
    missing.write_text("plant: kang_robot\nepisode_s: 5.0\n")
    with pytest.raises(ConfigError, match=r"missing\.yaml: task: missing required key"):
        ServoEnv(missing)


def test_bad_scenario_names_and_overrides_are_clear_errors():
    with pytest.raises(ConfigError, match="kang_regulation"):  # lists the scenarios, not the plants
        ServoEnv("kang_regulaton")
    with pytest.raises(ConfigError, match="preset name"):
        ServoEnv("")
    with pytest.raises(ConfigError, match="overrides"):
        ServoEnv("kang_regulation", overrides=[1, 2])


def test_reference_type_and_jitter_range_can_be_overridden():
    env = ServoEnv(
        "kang_regulation",
        randomize=True,
        overrides={
            "reference": {"type": "sine", "amplitude": 0.1, "frequency_hz": 0.5},
            "plant_overrides": {"randomization": {"jitter_s": [0.002, 0.004]}},
        },
    )
    _, info = env.reset(seed=1)
    assert env.scenario.reference.type == "sine" and env.scenario.reference.amplitude == 0.1
    assert 0.002 <= info["params"]["jitter"] <= 0.004


def test_scenarios_extend_the_defaults_and_each_other():
    from frictiongym.envs.scenario import load_scenario

    fast, slow = load_scenario("flexible_zero_speed_fast"), load_scenario("flexible_zero_speed")
    assert (fast.control_period, slow.control_period) == (0.001, 0.04)  # 0.04: the plant preset's period
    assert fast.reference == slow.reference and fast.reference.type == "constant"
    assert slow.reward_weights == {"tracking": 1.0, "effort": 0.001, "smoothness": 0.01}  # _defaults.yaml


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
