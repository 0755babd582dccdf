"""Config loading and validation: every bad value is rejected with an error naming the field."""

import math
import pickle
from concurrent.futures import ProcessPoolExecutor

import pytest

from frictiongym.envs import units
from frictiongym.envs.config import ConfigError, load_extending, load_yaml, plant_names
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.plants.params import EpisodeParams


def test_presets_listed_and_load():
    assert plant_names() == ["emps", "flexible_servo", "kang_robot", "m220"]
    for name in plant_names():
        assert plant_spec(name).name == name


def test_yaml_reads_exponent_without_sign_as_float():
    # kang_robot.yaml writes σ0 as 1.0e5, which YAML 1.1 would read as a string
    assert load_yaml("kang_robot")["friction"]["sigma0_nm_per_rad"] == 1.0e5


@pytest.mark.parametrize(
    ("plant", "overrides", "field"),
    [
        ("kang_robot", {"rotor": {"inertia_nm_s2_per_deg": -0.0212}}, "rotor.inertia_nm_s2_per_deg"),
        ("kang_robot", {"friction": {"static_pos_nm": float("nan")}}, "friction.static_pos_nm"),
        ("kang_robot", {"friction": {"sigma0_nm_per_rad": 0.0}}, "friction.sigma0_nm_per_rad"),
        ("kang_robot", {"rotor": {"inertia": 1.0}}, "rotor.inertia"),  # unknown key
        ("kang_robot", {"sampling": {"control_period_s": 0.0203}}, "sampling.control_period_s"),
        ("flexible_servo", {"shafts": {"J1_kg_m2": "heavy"}}, "shafts.J1_kg_m2"),
        ("m220", {"configuration": {"n_pd": 20}}, "configuration.n_pd"),
        ("m220", {"configuration": {"brass_weights_load": 5}}, "configuration.brass_weights_load"),
        ("m220", {"viscous": {"source": "guess"}}, "viscous.source"),
        ("m220", {"randomization": {"friction_scale": [1.2, 0.8]}}, "randomization.friction_scale"),
    ],
)
def test_bad_values_name_the_field(plant, overrides, field):
    with pytest.raises(ConfigError) as e:
        plant_spec(plant, overrides)
    assert e.value.field == field


def test_static_below_coulomb_rejected():
    spec = plant_spec("kang_robot")
    p = EpisodeParams.nominal(spec)
    bad = p.friction[0].__class__(**{**p.friction[0].__dict__, "fs": 0.5 * p.friction[0].fc})
    with pytest.raises(ConfigError, match=r"params.friction\[rotor\].fs"):
        EpisodeParams(**{**p.__dict__, "friction": (bad,)}).validate(spec)


@pytest.mark.parametrize(
    ("overrides", "field"),
    [
        ({"friction": {"sigma0_nm_per_rad": 1.0e7}}, "friction[rotor].sigma0"),  # h·ω_b = 1.4
        ({"sampling": {"integrator": "implicitfast"}}, "friction[rotor].sigma1"),  # extra inertia
        ({"friction": {"static_pos_nm": 1.0, "static_neg_nm": 0.9}}, "friction[rotor].fs"),  # below Coulomb
    ],
)
def test_config_load_rejects_friction_outside_the_admissible_region(overrides, field):
    with pytest.raises(ConfigError) as e:
        plant_spec("kang_robot", overrides)
    assert e.value.field == field


def test_unknown_friction_model_rejected():
    with pytest.raises(ConfigError, match="friction_model"):
        plant_spec("kang_robot", friction_model="stribeck-only")


def test_unit_helpers_round_trip():
    assert units.rad_to_deg(units.deg_to_rad(6.97)) == pytest.approx(6.97)
    assert units.rad_per_count(16000) == pytest.approx(math.radians(0.0225))  # Iurian et al. 2005's table
    assert units.counts_to_rad(units.rad_to_counts(1.2, 16000), 16000) == pytest.approx(1.2)
    # Kang's J = 0.0212 N·m·s²/deg is 1.2147 kg·m²
    assert units.per_deg_to_per_rad(0.0212) == pytest.approx(1.21467, rel=1e-4)


def test_one_extends_resolver_merges_parents_and_refuses_cycles(tmp_path):
    """config.load_extending, which scenarios and training configs both use: the child's keys win over
    its parent's, mappings merge key by key, a chain resolves to the root, and a cycle names the file."""
    root, mid, leaf = (tmp_path / f"{n}.yaml" for n in ("root", "mid", "leaf"))
    root.write_text("a: 1\nb: {x: 1, y: 2}\n")
    mid.write_text(f"extends: {root}\nb: {{y: 3}}\n")
    leaf.write_text(f"extends: {mid}\na: 5\n")
    assert load_extending(leaf, "agents") == {"a": 5, "b": {"x": 1, "y": 3}}
    root.write_text(f"extends: {leaf}\na: 1\n")
    with pytest.raises(ConfigError, match=r"root\.yaml: extends: expected another agents file, not a cycle"):
        load_extending(leaf, "agents")
    leaf.write_text("extends: [1]\n")
    with pytest.raises(ConfigError, match=r"leaf\.yaml: extends"):
        load_extending(leaf, "agents")


def test_unknown_yaml_key_names_the_file():
    with pytest.raises(ConfigError, match=r"kang_robot\.yaml: rotor\.inertia"):
        plant_spec("kang_robot", {"rotor": {"inertia": 1.0}})
    with pytest.raises(ConfigError, match=r"configuration\.backlash_device"):
        plant_spec("m220", {"configuration": {"backlash_device": "no"}})


def test_yaml_files_are_parsed_once_per_text_and_handed_out_as_copies(tmp_path):
    """load_yaml memoises the parse by the file's text: an edited file reads anew, and a caller editing
    what it got does not change what the next caller gets."""
    f = tmp_path / "p.yaml"
    f.write_text("a: {b: 1}\n")
    first = load_yaml(f)
    first["a"]["b"] = 99
    assert load_yaml(f) == {"a": {"b": 1}}
    f.write_text("a: {b: 2}\n")
    assert load_yaml(f) == {"a": {"b": 2}}


def _raise_config_error(source: str) -> None:
    raise ConfigError("validation.episodes", "30 asked, the suite has 10", source)


def test_a_config_error_crosses_a_process_boundary_as_itself():
    """A ConfigError raised in a worker process (training runs, validation, parallel leaderboards run in
    process pools) reaches the caller with its field, message and file, not as a broken pool."""
    e = pickle.loads(pickle.dumps(ConfigError("reward.tracking", "expected a number", "a.yaml")))
    assert (e.field, e.message, e.source, str(e)) == (
        "reward.tracking",
        "expected a number",
        "a.yaml",
        "a.yaml: reward.tracking: expected a number",
    )
    with (
        ProcessPoolExecutor(1) as pool,
        pytest.raises(ConfigError, match=r"x\.yaml: validation\.episodes: 30 asked") as err,
    ):
        pool.submit(_raise_config_error, "x.yaml").result()
    assert err.value.field == "validation.episodes"
