"""Kang's single-axis robot, Kang 1998 (Kang 1998, Control Eng. Practice 6:359-367), §2 and §6: a 1-DOF
rotor with asymmetric stick-slip friction, a current-fed DC servo (the command is a torque, N·m) and an
analog rate-feedback loop used by RDFC (§4, Fig. 4).

Preset: configs/plants/kang_robot.yaml (document units N·m and deg, converted here with named helpers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .. import units
from ..config import Node
from ..friction import LuGreParams
from .spec import Envelope, JointSpec, PlantSpec, SensorSpec, randomization, sampling

# Ranges of the preset's values (§6), each wide around the document's: a value outside is another
# machine, or makes the model meaningless or the simulation ill-conditioned.
MAX_TORQUE_NM = 1e4  # friction levels and torque limits above this are not a servo drive
# friction levels from 1/10000 of §6's (below, the bristle equation's σ0/g(v) grows without bound: use
# friction_model viscous or none for a frictionless rotor)
FRICTION_RANGE_NM = (1e-4, MAX_TORQUE_NM)
STRIBECK_RANGE_DEG_S = (1e-3, 1e3)  # 1/1000 .. 1000x the chosen 1 deg/s (20x the §6 ramp)
SIGMA0_RANGE_NM_PER_RAD = (1e2, 1e9)  # presliding F_s/σ0 from 1 deg (a very soft contact) to 1e-7 deg
MAX_SIGMA1_NM_S_PER_RAD = 1e6  # 1400x the critically damped 697
MAX_VISCOUS_NM_S_PER_DEG = 10.0  # 650x the §6 0.015; at 10, 1 deg/s costs the actuator's 10 N·m
GAIN_RANGE = (1e-3, 1e3)  # the command is a torque (gain 1 N·m per unit); another gain maps another unit
LIMIT_RANGE_NM = (1e-3, MAX_TORQUE_NM)
RESOLUTION_RANGE_DEG = (1e-9, 1.0)  # the §6 encoder's 2.44e-6 deg is 27 bits a turn; 1 deg is 9 bits
IDENTIFICATION_PERIOD_RANGE_S = (1e-5, 1.0)  # §6 identified friction at 5 ms
# printed numbers of §6 (checks and designs use them): within a half turn, a plausible ω_n and K_p
ANGLE_RANGE_DEG = (-180.0, 180.0)
FREQUENCY_RANGE_HZ = (1e-3, 100.0)
KP_RANGE_NM_PER_DEG = (1e-3, 100.0)
PRINTED_GAIN_RANGE = (0.0, 1.0)  # K_p = 0.0066, K_d = 0.0033 as printed, without units (ERRATA 001)
# identification holds (agents/lab/experiments.py): §6 identified friction with 0.05 deg/s ramps and
# regulates within degrees, so 0.5-16 deg/s
IDENTIFICATION_SPEEDS_RAD_S = (0.0087, 0.28)
# the §6 rotor regulates within degrees: a turn either side, 570 deg/s, 12x what the 10 N·m limit
# gives the 1.21 kg·m² rotor (8.2 rad/s²)
ENVELOPE = Envelope(2 * math.pi, 10.0, 100.0)
INERTIA_RANGE_NM_S2_PER_DEG = (2e-5, 20.0)  # a thousandth .. a thousand times the rotor's 0.0212 (§6)


@dataclass(frozen=True)
class KangDocument:
    """Seed 001 values the checks and designs use (SI unless the name says deg).

    kp_nm_per_rad: K_p resolved from the printed bounds (kang_robot.yaml, ERRATA 001); theta_*_deg: the
    printed equilibrium bounds (§6); natural_frequency_hz: printed ω_n; coulomb_*_range_nm: the printed
    Coulomb ranges; identification_period_s: sampling of the friction identification (§6).
    """

    kp_nm_per_rad: float
    theta_H_deg: float
    theta_L_deg: float
    natural_frequency_hz: float
    coulomb_pos_range_nm: tuple[float, float]
    coulomb_neg_range_nm: tuple[float, float]
    identification_period_s: float
    kp_printed: float
    kd_printed: float


def build(cfg: Node, friction_model: str) -> PlantSpec:
    """The SI PlantSpec of the preset."""
    f = cfg.section("friction")
    J = units.per_deg_to_per_rad(
        cfg.section("rotor").number("inertia_nm_s2_per_deg", *INERTIA_RANGE_NM_S2_PER_DEG)
    )
    lugre = LuGreParams.from_levels(
        fc_pos=f.number("coulomb_pos_nm", *FRICTION_RANGE_NM),
        fc_neg=f.number("coulomb_neg_nm", *FRICTION_RANGE_NM),
        fs_pos=f.number("static_pos_nm", *FRICTION_RANGE_NM),
        fs_neg=f.number("static_neg_nm", *FRICTION_RANGE_NM),
        vs=units.deg_to_rad(f.number("stribeck_velocity_deg_s", *STRIBECK_RANGE_DEG_S)),
        sigma0=f.number("sigma0_nm_per_rad", *SIGMA0_RANGE_NM_PER_RAD),
        sigma1=f.nonneg("sigma1_nm_s_per_rad", MAX_SIGMA1_NM_S_PER_RAD),
        sigma2=units.per_deg_to_per_rad(f.nonneg("viscous_nm_s_per_deg", MAX_VISCOUS_NM_S_PER_DEG)),
    )
    a = cfg.section("actuator")
    enc = cfg.section("sensors").section("encoder")
    g = cfg.section("control_gains")
    s = cfg.section("sampling")
    doc = KangDocument(
        kp_nm_per_rad=units.per_deg_to_per_rad(g.number("kp_nm_per_deg", *KP_RANGE_NM_PER_DEG)),
        theta_H_deg=g.number("theta_H_deg", *ANGLE_RANGE_DEG),
        theta_L_deg=g.number("theta_L_deg", *ANGLE_RANGE_DEG),
        natural_frequency_hz=g.number("natural_frequency_hz", *FREQUENCY_RANGE_HZ),
        coulomb_pos_range_nm=f.interval("coulomb_pos_range_nm", 0.0, MAX_TORQUE_NM),
        coulomb_neg_range_nm=f.interval("coulomb_neg_range_nm", 0.0, MAX_TORQUE_NM),
        identification_period_s=s.number("identification_period_s", *IDENTIFICATION_PERIOD_RANGE_S),
        kp_printed=g.number("kp_printed", *PRINTED_GAIN_RANGE),
        kd_printed=g.number("kd_printed", *PRINTED_GAIN_RANGE),
    )
    return PlantSpec(
        name="kang_robot",
        joints=(JointSpec("rotor", J, 0.0, lugre),),
        actuator_joint="rotor",
        actuator_gain=a.number("gain_nm_per_unit", *GAIN_RANGE),
        command_limit=a.number("limit_nm", *LIMIT_RANGE_NM),
        command_unit="N·m",
        friction_model=friction_model,
        **sampling(cfg),
        sensors=(
            SensorSpec(
                "encoder",
                "encoder",
                enc.choice("joint", ["rotor"]),
                resolution=units.deg_to_rad(enc.number("resolution_deg", *RESOLUTION_RANGE_DEG)),
                noise_std=units.deg_to_rad(enc.nonneg("noise_std_deg", 10.0)),
            ),
        ),
        rate_feedback=units.per_deg_to_per_rad(a.nonneg("rate_feedback_nm_s_per_deg", MAX_TORQUE_NM)),
        rate_loop=True,
        randomization=randomization(cfg),
        envelope=ENVELOPE,
        document=doc,
    )
