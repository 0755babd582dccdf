"""Kang's single-axis robot, seed 001 (Kang 1998, Control Eng. Practice 6:359-367), §2 and §6: a 1-DOF
rotor with asymmetric stick-slip friction, a current-fed DC servo (the command is a torque, N·m) and an
analog rate-feedback loop used by RDFC (§4, Fig. 4).

Preset: configs/plants/kang_robot.yaml (document units N·m and deg, converted here with named helpers).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from .. import units
from ..config import Node
from ..friction import LuGreParams
from .spec import JointSpec, PlantSpec, SensorSpec, randomization, sampling

MAX_TORQUE_NM = 1e4  # friction levels and torque limits above this are not a servo drive
# identification holds (envs/experiments.py): §6 identified friction with 0.05 deg/s ramps and
# regulates within degrees, so 0.5-16 deg/s
IDENTIFICATION_SPEEDS_RAD_S = (0.0087, 0.28)
MAX_INERTIA_NM_S2_PER_DEG = 20.0  # ≈ 1150 kg·m², a thousand times the rotor


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
        cfg.section("rotor").positive("inertia_nm_s2_per_deg", MAX_INERTIA_NM_S2_PER_DEG)
    )
    lugre = LuGreParams.from_levels(
        fc_pos=f.positive("coulomb_pos_nm", MAX_TORQUE_NM),
        fc_neg=f.positive("coulomb_neg_nm", MAX_TORQUE_NM),
        fs_pos=f.positive("static_pos_nm", MAX_TORQUE_NM),
        fs_neg=f.positive("static_neg_nm", MAX_TORQUE_NM),
        vs=units.deg_to_rad(f.positive("stribeck_velocity_deg_s")),
        sigma0=f.positive("sigma0_nm_per_rad"),
        sigma1=f.nonneg("sigma1_nm_s_per_rad"),
        sigma2=units.per_deg_to_per_rad(f.nonneg("viscous_nm_s_per_deg")),
    )
    a = cfg.section("actuator")
    enc = cfg.section("sensors").section("encoder")
    g = cfg.section("control_gains")
    s = cfg.section("sampling")
    doc = KangDocument(
        kp_nm_per_rad=units.per_deg_to_per_rad(g.positive("kp_nm_per_deg")),
        theta_H_deg=g.number("theta_H_deg"),
        theta_L_deg=g.number("theta_L_deg"),
        natural_frequency_hz=g.positive("natural_frequency_hz"),
        coulomb_pos_range_nm=f.interval("coulomb_pos_range_nm", 0.0, MAX_TORQUE_NM),
        coulomb_neg_range_nm=f.interval("coulomb_neg_range_nm", 0.0, MAX_TORQUE_NM),
        identification_period_s=s.positive("identification_period_s", 1.0),
        kp_printed=g.number("kp_printed"),
        kd_printed=g.number("kd_printed"),
    )
    return PlantSpec(
        name="kang_robot",
        joints=(JointSpec("rotor", J, 0.0, lugre),),
        actuator_joint="rotor",
        actuator_gain=a.positive("gain_nm_per_unit"),
        command_limit=a.positive("limit_nm", MAX_TORQUE_NM),
        command_unit="N·m",
        friction_model=friction_model,
        **sampling(cfg),
        sensors=(
            SensorSpec(
                "encoder",
                "encoder",
                enc.choice("joint", ["rotor"]),
                resolution=units.deg_to_rad(enc.positive("resolution_deg", 1.0)),
                noise_std=units.deg_to_rad(enc.nonneg("noise_std_deg", 10.0)),
            ),
        ),
        rate_feedback=units.per_deg_to_per_rad(a.nonneg("rate_feedback_nm_s_per_deg", MAX_TORQUE_NM)),
        rate_loop=True,
        randomization=randomization(cfg),
        document=doc,
    )


def pd_bounds(rate_deg_s: float = 0.05) -> dict[str, float]:
    """Equilibrium-region bounds (deg) from simulated P control of slow reference ramps (the §6 method):
    the largest error held before the rotor breaks away, ramping up (θ_L) and down (θ_H). The default
    0.05 deg/s is the document's ramp: faster ramps overshoot the bound while the rotor crosses the
    Stribeck region (1.4 % at 0.5 deg/s)."""
    from . import plant_spec
    from .sim import PlantSim

    spec = plant_spec("kang_robot")
    period = spec.document.identification_period_s
    spec = replace(spec, control_period=period)
    kp = spec.document.kp_nm_per_rad
    out = {}
    for key, direction in (("theta_L_deg", 1.0), ("theta_H_deg", -1.0)):
        sim = PlantSim(spec)
        sim.reset()
        rate = direction * units.deg_to_rad(rate_deg_s)
        errors = []
        for k in range(round(12.0 / rate_deg_s / period)):
            r = rate * k * period
            e = sim.data.qpos[sim.dofs[0]] - r
            res = sim.step(-kp * e)
            errors.append(e)
            if abs(res.qvel[0]) > 20 * abs(rate):  # slipping: the bound was the error held just before
                break
        out[key] = units.rad_to_deg(max(errors, key=abs))
    return out
