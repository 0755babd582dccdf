"""LuGre friction: asymmetric construction, numerics admissibility, and MuJoCo vs Radau."""

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest

from frictiongym.agents.lab import radau
from frictiongym.envs.config import ConfigError
from frictiongym.envs.friction import LuGreParams, check_numerics
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.plants.params import EpisodeParams

warnings.filterwarnings("ignore", category=RuntimeWarning)


def test_from_levels_exact_when_drops_equal():
    p = LuGreParams.from_levels(1.0, 1.4, 1.5, 1.9, 0.1, 1e4, 10.0, 0.0)
    assert p.levels() == pytest.approx(
        {"coulomb_pos": 1.0, "coulomb_neg": 1.4, "static_pos": 1.5, "static_neg": 1.9}
    )


def test_kang_construction_keeps_static_levels_and_coulomb_in_document_range():
    spec = plant_spec("kang_robot")
    lv = spec.joints[0].friction.levels()
    assert lv["static_pos"] == pytest.approx(1.785) and lv["static_neg"] == pytest.approx(1.441)
    lo, hi = spec.document.coulomb_pos_range_nm
    assert lo <= lv["coulomb_pos"] <= hi
    lo, hi = spec.document.coulomb_neg_range_nm
    assert lo <= lv["coulomb_neg"] <= hi


def test_m220_coulomb_levels_follow_section_2_3():
    spec = plant_spec("m220")
    k = spec.document.k_M_nm_per_v
    lv = spec.joints[0].friction.levels()
    assert lv["coulomb_pos"] / k == pytest.approx(0.114716)
    assert lv["coulomb_neg"] / k == pytest.approx(0.152784)


@pytest.mark.parametrize("integrator", ["Euler", "RK4", "implicitfast"])
def test_numerics_check_rejects_stiff_bristles(integrator):
    p = LuGreParams(fc=1.0, fs=1.5, vs=0.1, sigma0=1e5, sigma1=700.0, sigma2=0.0)
    with pytest.raises(ConfigError, match="sigma"):
        check_numerics(p, inertia=1.0, timestep=1e-3, integrator=integrator, field="f")
    check_numerics(p, inertia=1.0, timestep=1e-4, integrator="Euler", field="f")  # inside the region


def test_random_draws_are_checked_and_reproducible():
    spec = plant_spec("kang_robot")
    a, b = EpisodeParams.draw(spec, 7), EpisodeParams.draw(spec, 7)
    assert a == b and a != EpisodeParams.draw(spec, 8)
    for seed in range(50):
        EpisodeParams.draw(spec, seed).validate(spec)
    # a pinned σ0 outside the admissible region is rejected when the episode's parameters are checked
    with pytest.raises(ConfigError, match=r"friction\[rotor\].sigma0"):
        EpisodeParams.draw(spec, 0, {"sigma0_scale": 55.0}).validate(spec)


@pytest.mark.parametrize(
    ("plant", "joint"), [("kang_robot", "rotor"), ("flexible_servo", "shaft2"), ("m220", "drive")]
)
@pytest.mark.slow
def test_breakaway_and_presliding_match_radau(plant, joint):
    spec = plant_spec(plant)
    for d in (1, -1):
        r = radau.breakaway(spec, joint, d)
        assert r["simulated"] == pytest.approx(r["reference"], rel=0.02)
    p = spec.joints[spec.joint_index(joint)].friction
    # the break-away in each direction is that direction's static level, at any slow ramp rate
    for d, key in ((1, "static_pos"), (-1, "static_neg")):
        for duration in (0.5, 8.0):
            r = radau.breakaway(spec, joint, d, duration)
            assert r["reference"] == pytest.approx(p.levels()[key], rel=0.01)
    r = radau.presliding(spec, joint)
    assert r["simulated"] == pytest.approx(r["reference"], rel=0.02)
    assert 0 < r["simulated"] < 2 * p.fs / p.sigma0  # presliding is of order F/σ0


def test_sliding_follows_stribeck_curve_both_directions():
    spec = plant_spec("kang_robot")
    p = spec.joints[0].friction
    forces = []
    for mult in (0.5, 1.0, 2.0, 5.0, 20.0):
        for sg in (1, -1):
            r = radau.sliding(spec, "rotor", sg * mult * p.vs)
            assert np.sign(r["velocity"]) == sg
            assert r["simulated"] == pytest.approx(r["reference"], rel=0.02)
            forces.append(abs(r["simulated"]))
    # Stribeck dip: friction at ~vs is below the level near standstill (0.5 vs)
    assert forces[2] < forces[0]


@pytest.mark.slow
def test_stickslip_period_matches_radau():
    spec = plant_spec("kang_robot")
    r = radau.stickslip_period(spec, "rotor", spec.document.kp_nm_per_rad, math.radians(1.0), 25.0)
    assert r["simulated"] == pytest.approx(r["reference"], rel=0.02)


def test_implicitfast_shows_the_documented_extra_inertia():
    """Why the presets use Euler: implicitfast slows a sliding rotor by ≈ h·σ1/J (docs/physics.md)."""
    spec = plant_spec("kang_robot")
    fast = replace(spec, integrator="implicitfast")
    T = 3.0
    out = {}
    for s in (spec, fast):
        rig = radau.Rig(s, "rotor")
        out[s.integrator] = rig.run(lambda t, th: T, 1.0)["omega"][-1]
    p = spec.joints[0].friction
    ode = radau.lugre_ode(p, rig.J, lambda t, th: T, 1.0, t_eval=[1.0]).y[1, -1]
    assert out["Euler"] == pytest.approx(ode, rel=0.002)
    assert out["implicitfast"] < 0.95 * ode
