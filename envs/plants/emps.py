"""The EMPS prismatic drive (Janot, Gautier, Brunot 2019, "Data Set and Reference Models of EMPS"; text in
configs/published/emps/EMPS_Description.txt): a DC motor and ball screw moving a load in translation,
piloted at 1 kHz by the lab's PD (eq. 6) with a ±10 V saturation (no actuation delay beyond the hold:
the measurement contradicts the archive's one sample, configs/plants/emps.yaml `sampling.delay_s`). The
only plant of the suite built from measurements: every number of the preset is the IDIM-LS estimate of
the real drive's logs, or a fact of the description or of the data (configs/plants/emps.yaml).

One slide joint (the carriage, m) carries the mass, the viscous friction and LuGre friction whose
asymmetry is the description's offset (eq. 1: the offset is a constant force, the bias of the
friction element, b = -offset).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..config import Node
from ..friction import LuGreParams
from .spec import Envelope, JointSpec, PlantSpec, SensorSpec, randomization, sampling

# Ranges of the preset's values, wide around the description's: outside them it is another machine.
MASS_RANGE_KG = (1.0, 1e4)  # the EMPS moves 95 kg
FORCE_RANGE_N = (1e-3, 1e4)  # friction levels (the EMPS: 20 N)
MAX_OFFSET_N = 1e3
MAX_VISCOUS_N_S_PER_M = 1e5  # the EMPS: 204 N·s/m
STRIBECK_RANGE_M_S = (1e-5, 1.0)
SIGMA0_RANGE_N_PER_M = (1e3, 1e10)  # presliding Fc/σ0 from 20 mm to 2 nm at 20 N
MAX_SIGMA1_N_S_PER_M = 1e7
GAIN_RANGE_N_PER_V = (1e-2, 1e5)  # gτ = 35.15 N/V (eq. 7)
LIMIT_RANGE_V = (0.1, 1e3)
RESOLUTION_RANGE_M = (1e-10, 1e-3)
LAB_KP_RANGE_PER_S = (1e-2, 1e5)
LAB_KV_RANGE_V_PER_M_S = (1e-3, 1e7)
# The screw's stroke is not in the description; the logs move over 0-0.247 m at up to 0.14 m/s and
# 2.8 m/s² (filtered, the validation set). The envelope: a 0.5 m stroke either side, 1 m/s, 50 m/s²
# (18x what the drive's 351 N peak gives the 95 kg load).
ENVELOPE = Envelope(0.5, 1.0, 50.0)


@dataclass(frozen=True)
class EMPSDocument:
    """The lab's controller (eq. 6): ν = kp·kv·(q_r - q) - kv·q̇m, q̇m from the 2-tap FIR
    fir = (0.5, 0.5) of the position (§2.2); kp (1/s), kv (V per m/s). (The description's offset, eq. 1,
    is the friction element's bias, JointSpec.friction.bias = -offset.)"""

    lab_kp_per_s: float
    lab_kv_v_per_m_s: float
    lab_fir: tuple[float, float]


def build(cfg: Node, friction_model: str) -> PlantSpec:
    """The SI PlantSpec of the preset."""
    f = cfg.section("friction")
    mass = cfg.section("carriage").number("mass_kg", *MASS_RANGE_KG)
    offset = f.number("offset_n", -MAX_OFFSET_N, MAX_OFFSET_N)
    fc = f.number("coulomb_n", *FORCE_RANGE_N)
    lugre = LuGreParams(
        fc=fc,
        fs=f.number("static_n", *FORCE_RANGE_N),
        vs=f.number("stribeck_velocity_m_s", *STRIBECK_RANGE_M_S),
        sigma0=f.number("sigma0_n_per_m", *SIGMA0_RANGE_N_PER_M),
        sigma1=f.nonneg("sigma1_n_s_per_m", MAX_SIGMA1_N_S_PER_M),
        sigma2=f.nonneg("viscous_n_s_per_m", MAX_VISCOUS_N_S_PER_M),
        bias=-offset,
    )
    a = cfg.section("actuator")
    enc = cfg.section("sensors").section("encoder")
    lab = cfg.section("lab_controller")
    fir = lab["velocity_fir"]
    if not (isinstance(fir, list) and len(fir) == 2 and abs(sum(map(float, fir)) - 1.0) < 1e-12):
        raise lab.error("velocity_fir", f"expected two taps summing to 1 (§2.2: [0.5, 0.5]), got {fir!r}")
    doc = EMPSDocument(
        lab_kp_per_s=lab.number("kp_per_s", *LAB_KP_RANGE_PER_S),
        lab_kv_v_per_m_s=lab.number("kv_v_per_m_s", *LAB_KV_RANGE_V_PER_M_S),
        lab_fir=(float(fir[0]), float(fir[1])),
    )
    return PlantSpec(
        name="emps",
        joints=(JointSpec("carriage", mass, 0.0, lugre, kind="slide"),),
        actuator_joint="carriage",
        actuator_gain=a.number("gain_n_per_v", *GAIN_RANGE_N_PER_V),
        command_limit=a.number("limit_v", *LIMIT_RANGE_V),
        command_unit="V",
        friction_model=friction_model,
        **sampling(cfg),
        sensors=(
            SensorSpec(
                "encoder",
                "encoder",
                enc.choice("joint", ["carriage"]),
                resolution=enc.number("resolution_m", *RESOLUTION_RANGE_M),
                noise_std=enc.nonneg("noise_std_m", 1e-3),
            ),
        ),
        disturbance_joint="carriage",
        randomization=randomization(cfg),
        envelope=ENVELOPE,
        document=doc,
    )
