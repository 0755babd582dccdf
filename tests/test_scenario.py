"""Scenario files (envs/scenario.py, configs/scenarios/): every key checked, errors naming the field,
`extends:` and overrides."""

from pathlib import Path

import pytest

from frictiongym.envs.config import ConfigError
from frictiongym.envs.servo_env import ServoEnv

ROOT = Path(__file__).parents[1]


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
    assert slow.reward_weights == {"tracking": 1.0, "tracking_abs": 0.0, "effort": 0.001, "smoothness": 0.01}
