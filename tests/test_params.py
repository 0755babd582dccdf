"""Per-episode plant parameters (envs/plants/params.py): draws, their checks, pinned values."""

import dataclasses
from pathlib import Path

import pytest

from frictiongym.envs.config import ConfigError
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.plants.params import EpisodeParams, check_randomization, rejected_draws
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.servo_env import ServoEnv

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


@pytest.mark.parametrize(
    ("key", "rng"), [("sigma0_scale", [0.5, 5.0]), ("inertia_scale", [0.1, 1.0]), ("friction_scale", [0, 0])]
)
def test_bad_randomization_ranges_rejected_at_load_naming_the_field(key, rng):
    with pytest.raises(ConfigError) as e:
        plant_spec("kang_robot", {"randomization": {key: rng}})
    assert e.value.field.startswith(f"randomization.{key}")  # the range or its bad end


def test_a_remembered_admissible_spec_does_not_pass_a_wider_one():
    """check_randomization remembers the specs it passed: the preset passes twice, and a range that
    differs only in one bad end is still built and refused after them."""
    spec = plant_spec("kang_robot")
    check_randomization(spec)
    check_randomization(spec)
    wide = dataclasses.replace(spec, randomization={**spec.randomization, "sigma0_scale": (0.5, 5.0)})
    with pytest.raises(ConfigError, match="sigma0_scale"):
        check_randomization(wide)


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


def test_model_inertia_is_exactly_the_presets():
    """Visual geoms add no mass: J·α = τ at rest without friction gives J1 = 22e-6 kg·m² (§3.1)."""
    sim = PlantSim("flexible_servo", friction_model="none")
    sim.reset()
    sim.step(1.0, nstep=1)
    assert sim.spec.actuator_gain / sim.data.qacc[sim.dofs[0]] == pytest.approx(22e-6, rel=1e-9)
