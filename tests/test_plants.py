"""Plant models against the documents (Iurian et al. 2005 eq. 22 and §2.2, Wallenborg 1987 eq. 3.2/3.3, Kang
1998 eq. 6)."""

import math

import numpy as np
import pytest

from frictiongym.agents.lab.fits import two_point_step_id
from frictiongym.agents.reproduce import iurian2005, kang1998, wallenborg1987
from frictiongym.agents.reproduce.iurian2005 import CONFIGS as M220_CONFIGS
from frictiongym.envs.config import ConfigError
from frictiongym.envs.plants import flexible_servo, plant_spec
from frictiongym.envs.plants.identified import drive_friction


@pytest.mark.parametrize("name", list(M220_CONFIGS))
def test_m220_reflected_inertia_equals_eq22(name):
    ov = M220_CONFIGS[name]
    assert iurian2005.reflected_inertia_sim(ov) == pytest.approx(iurian2005.eq22_of(ov), rel=0.005)


def test_eq22_by_hand_for_default_configuration():
    # n_pd = 24, n_pl = 36: n_g' = 2, n_g = 4; J_p = 8e-6 + 3.9e-5 (SR pulley table)
    assert iurian2005.eq22_of() == pytest.approx(0.00040 + (8e-6 + 3.9e-5) / 4 + 0.0065 / 16)


def test_m220_step_passes_measured_points_and_two_point_method_recovers_a_k():
    doc = plant_spec("m220").document
    t, y = doc.step_points_t_s, doc.step_points_counts
    sim = iurian2005.step_counts(doc.gain_counts_per_v_s2, t, doc.step_input_v)
    assert sim == pytest.approx(y, rel=0.02)
    ident = two_point_step_id(t, tuple(sim), doc.step_input_v)
    assert ident["a"] == pytest.approx(doc.document_a_per_s, rel=0.05)
    assert ident["k"] == pytest.approx(doc.document_k_counts_per_v_s2, rel=0.05)
    # the document's own numbers from its own points (Iurian et al. 2005 §2.2)
    two = two_point_step_id(t, tuple(y), doc.step_input_v)
    assert two["a"] == pytest.approx(0.512081, rel=1e-5) and two["k"] == pytest.approx(82421.02, rel=1e-5)


FREQS = np.array([0.1, 0.5, 1.0, 1.78, 2.0, 5.0, 10.0])


def _compare(resp, G):
    assert np.all(np.abs(np.abs(resp) / np.abs(G) - 1) <= 0.01)
    assert np.all(np.abs(np.degrees(np.angle(resp / G))) <= 1.0)


def test_flexible_linearisation_matches_G1_G2():
    G = np.array(flexible_servo.transfer(plant_spec("flexible_servo"), 2j * np.pi * FREQS)).T
    _compare(wallenborg1987.frf_linearized(FREQS), G)


@pytest.mark.slow  # reproduces a document's frequency responses
def test_flexible_sine_responses_match_G1_G2():
    f = FREQS[[0, 3, 6]]
    G = np.array(flexible_servo.transfer(plant_spec("flexible_servo"), 2j * np.pi * f)).T
    _compare(wallenborg1987.frf_sine(f), G)


def test_flexible_transfer_from_parameters_matches_printed_3_5_3_6():
    """The printed G1, G2 are rounded (ERRATA 002); built from §3.1 parameters they agree within 2 %."""
    s = 2j * np.pi * np.array([0.1, 1.0, 5.0])
    G1, G2 = flexible_servo.transfer(plant_spec("flexible_servo"), s)
    den = (s + 0.1) * (s**2 + 0.4 * s + 125)
    assert np.abs(G1) == pytest.approx(np.abs(113.6 * (s**2 + 0.07 * s + 16) / den), rel=0.02)
    assert np.abs(G2) == pytest.approx(np.abs(1818 / den), rel=0.02)


@pytest.mark.slow  # reproduces a document's bounds
def test_kang_resolved_gain_reproduces_printed_bounds():
    spec = plant_spec("kang_robot")
    kp_deg = spec.document.kp_nm_per_rad * math.pi / 180
    lv = spec.joints[0].friction.levels()
    assert lv["static_neg"] / kp_deg == pytest.approx(6.97, abs=0.01)  # θ_H = -T_s^-/K_p, eq. 6
    assert -lv["static_pos"] / kp_deg == pytest.approx(-8.64, abs=0.01)  # θ_L = -T_s^+/K_p
    b = kang1998.pd_bounds()
    assert b["theta_H_deg"] == pytest.approx(6.97, abs=0.05)
    assert b["theta_L_deg"] == pytest.approx(-8.64, abs=0.05)


@pytest.mark.parametrize(
    ("values", "field"),
    [
        ({"coulomb_pos": 0.1, "coulomb_neg": 0.1}, "viscous_per_rad_s"),  # a required value missing
        ({"coulomb_pos": 0.1, "coulomb_neg": -0.1, "viscous_per_rad_s": 0.01}, "coulomb_neg"),
        ({"coulomb_pos": "x", "coulomb_neg": 0.1, "viscous_per_rad_s": 0.01}, "coulomb_pos"),  # not a number
        (
            {"coulomb_pos": 0.1, "coulomb_neg": 0.1, "viscous_per_rad_s": 0.01, "static_pos": 0.05},
            "static_pos",
        ),
        ({"coulomb_pos": 0.1, "coulomb_neg": 0.1, "viscous_per_rad_s": 0.01, "stiction": 0.2}, "stiction"),
    ],
)
def test_identified_friction_errors_name_the_value(values, field):
    with pytest.raises(ConfigError) as e:
        plant_spec("m220", {"friction_identified": values})
    assert e.value.field.endswith(field)
    assert "m220.yaml" in str(e.value)


def test_identified_friction_replaces_the_presets_drive_referred_levels():
    """Identified Coulomb levels and viscous slope are what the plant's drive then shows (static levels
    default to the Coulomb ones: no Stribeck drop)."""
    values = {"coulomb_pos": 0.2, "coulomb_neg": 0.15, "viscous_per_rad_s": 0.003}
    got = drive_friction(plant_spec("m220", {"friction_identified": values}))
    assert got.coulomb_pos == pytest.approx(0.2, rel=0.02)
    assert got.coulomb_neg == pytest.approx(0.15, rel=0.02)
    assert got.static_pos == pytest.approx(0.2, rel=1e-9)
    assert got.viscous == pytest.approx(0.003, rel=1e-9)
