"""The ECP Model 220 industrial emulator, Iurian et al. 2005 part 2 (Iurian et al., UPC IOC-DT-P-2005-20):
drive disk, belt, speed-reduction (SR) pulley shaft, belt, load disk; encoders on drive and load.

The physical layout is three hinge joints coupled by belt-ratio equality constraints, so the reflected
inertia of eq. (22) is a result, checked here by simulation. The identified model of §2.2-2.3 is given in
the document's software units (encoder counts, volts at the amplifier input) and converted to SI:
1 count = 2π/16000 rad; 1 V gives k_M N·m on the drive, k_M = gain · (rad per count) · J_d.

Preset: configs/plants/m220.yaml.
"""

from __future__ import annotations

from dataclasses import dataclass

from .. import units
from ..config import Node
from ..friction import LuGreParams
from .spec import BeltSpec, Envelope, JointSpec, PlantSpec, SensorSpec, randomization, sampling

PULLEY_TEETH = (18, 24, 36, 72)  # SR pulley table, §2.1.3
MAX_VOLTS = 100.0  # friction levels in volts at the amplifier input (the D/A range is ±10 V)
# identification holds (agents/lab/experiments.py): §2.3 held 150-40000 counts/s, i.e. 0.06-15.7 rad/s
IDENTIFICATION_SPEEDS_RAD_S = (0.06, 15.7)
# the disks turn freely (16 turns), 100 rad/s = 250k counts/s, ~20x what ±10 V gives the drive
# (≈ 420 rad/s² on J_d)
ENVELOPE = Envelope(100.0, 100.0, 1e4)
MAX_INERTIA_KG_M2 = 10.0
# Ranges of the preset's values (§2.1-2.3), each wide around the document's: a value outside is another
# machine, or makes the model meaningless or the simulation ill-conditioned.
DISK_INERTIA_RANGE_KG_M2 = (1e-6, MAX_INERTIA_KG_M2)  # bare disks 4e-4 and 6.5e-3: a disk weighs something
PULLEY_INERTIA_RANGE_KG_M2 = (
    1e-9,
    MAX_INERTIA_KG_M2,
)  # the SR shaft's only inertia; the table's least is 3e-6
TEETH_RANGE = (1.0, 1000.0)  # belt pulleys n = 12, N = 72 (§2.1.3)
MAX_VISCOUS_NM_S_PER_RAD = 1.0  # manual c1 = 0.004, c2 = 0.05 (x250, x20)
COUNTS_RANGE = (4.0, 1e9)  # counts per revolution: a quadrature encoder has at least 4; 16000 here
GAIN_RANGE_COUNTS_PER_V_S2 = (1.0, 1e9)  # k = 82421 (document), 106198 (fitted)
STRIBECK_RANGE_COUNTS_S = (1.0, 1e6)  # the preset's 150 counts/s; 1e6 counts/s = 390 rev/s, past the motor
SIGMA0_RANGE_V_PER_COUNT = (1e-4, MAX_VOLTS)  # presliding F_c/σ0 from ~1000 counts (very soft) down
MAX_SIGMA1_V_S_PER_COUNT = 1.0  # 200x the preset's 4.6e-3
LIMIT_RANGE_V = (1e-3, MAX_VOLTS)
BELT_TIMECONST_RANGE_S = (1e-5, 1.0)  # MuJoCo's solref time constant of the belt constraint
# printed numbers of §2.2 (checks and the identification report use them)
STEP_INPUT_RANGE_V = (1e-3, 10.0)
STEP_TIME_RANGE_S = (0.0, 100.0)
STEP_COUNTS_RANGE = (0.0, 1e9)
POLE_RANGE_PER_S = (1e-3, 100.0)  # a = 0.512 1/s


@dataclass(frozen=True)
class M220Document:
    """Seed 000 §2.2 values and derived constants (SI unless the name says counts or V).

    J_d_eq22: reflected drive inertia of eq. (22) (kg·m²); k_M_nm_per_v: torque per amplifier volt;
    n_g: overall gear ratio 6·n_pd/n_pl; step_*: the 0.25 V open-loop step and its two measured points;
    document_a_per_s, document_k_counts_per_v_s2: the two-point fit as printed; gain_counts_per_v_s2:
    the plant gain the preset uses (fitted, m220.yaml).
    """

    J_d_eq22: float
    k_M_nm_per_v: float
    rad_per_count: float
    counts_per_rev: float
    n_g: float
    step_input_v: float
    step_points_t_s: tuple[float, float]
    step_points_counts: tuple[float, float]
    document_a_per_s: float
    document_k_counts_per_v_s2: float
    gain_counts_per_v_s2: float


def inertias(cfg: Node) -> dict[str, float]:
    """Joint inertias (kg·m²) of drive, SR shaft and load for the configured pulleys/weights (§2.1.2)."""
    c, inr = cfg.section("configuration"), cfg.section("inertia")
    n_pd, n_pl = c.choice("n_pd", PULLEY_TEETH), c.choice("n_pl", PULLEY_TEETH)

    def weights(count_key: str, four: str, mass: str, radius: str) -> float:
        # the table value is for 4 weights incl. their own inertia: J_own = J_four/4 - m r²
        n = c.integer(count_key, 0, 4)
        m, r = inr.nonneg(mass, 100.0), inr.nonneg(radius, 10.0)
        j_own = inr.positive(four, MAX_INERTIA_KG_M2) / 4.0 - m * r * r
        if j_own < 0:
            raise inr.error(four, "smaller than 4·m·r² of the weights")
        return n * (m * r * r + j_own)

    jp = inr.section("J_pulley_kg_m2")
    for teeth in PULLEY_TEETH:
        jp.number(teeth, *PULLEY_INERTIA_RANGE_KG_M2)
    J_p = jp.number(n_pd, *PULLEY_INERTIA_RANGE_KG_M2) + jp.number(n_pl, *PULLEY_INERTIA_RANGE_KG_M2)
    backlash = inr.nonneg("J_backlash_kg_m2", MAX_INERTIA_KG_M2)
    if c.boolean("backlash_device"):
        J_p += backlash
    return {
        "drive": inr.number("J_dd_kg_m2", *DISK_INERTIA_RANGE_KG_M2)
        + weights("brass_weights_drive", "J_wd_four_kg_m2", "weight_drive_mass_kg", "weight_drive_radius_m"),
        "sr": J_p,
        "load": inr.number("J_dl_kg_m2", *DISK_INERTIA_RANGE_KG_M2)
        + weights("brass_weights_load", "J_wl_four_kg_m2", "weight_load_mass_kg", "weight_load_radius_m"),
    }


def eq22(cfg: Node) -> float:
    """Reflected drive inertia by the document's closed form, eq. (22) of Iurian et al. 2005 (kg·m²)."""
    J = inertias(cfg)
    c, b = cfg.section("configuration"), cfg.section("belt")
    n_g1 = c["n_pd"] / b.number("n_drive_pulley_teeth", *TEETH_RANGE)
    n_g = (b.number("n_load_pulley_teeth", *TEETH_RANGE) / c["n_pl"]) * n_g1
    return J["drive"] + J["sr"] / n_g1**2 + J["load"] / n_g**2


def build(cfg: Node, friction_model: str) -> PlantSpec:
    """The SI PlantSpec of the preset."""
    c, b, idf, f = (cfg.section(k) for k in ("configuration", "belt", "identified", "friction"))
    J = inertias(cfg)
    ratio1 = b.number("n_drive_pulley_teeth", *TEETH_RANGE) / c["n_pd"]  # 1/n_g'
    ratio2 = c["n_pl"] / b.number("n_load_pulley_teeth", *TEETH_RANGE)  # 1/n_g''
    belts = (BeltSpec("sr", "drive", ratio1), BeltSpec("load", "sr", ratio2))
    J_d = eq22(cfg)
    counts_per_rev = idf.number("counts_per_rev", *COUNTS_RANGE)
    rpc = units.rad_per_count(counts_per_rev)
    gain = idf.number("gain_counts_per_v_s2", *GAIN_RANGE_COUNTS_PER_V_S2)
    k_M = gain * rpc * J_d  # N·m per V
    fv = 0.5 * (f.nonneg("viscous_pos_v_s_per_count", 1.0) + f.nonneg("viscous_neg_v_s_per_count", 1.0))
    v = cfg.section("viscous")
    source = v.choice("source", ("identified", "manual"))
    sigma2 = fv * k_M / rpc if source == "identified" else 0.0
    fc_pos, fc_neg = (
        f.positive("coulomb_pos_v", MAX_VOLTS) * k_M,
        f.positive("coulomb_neg_v", MAX_VOLTS) * k_M,
    )
    excess = f.nonneg("stribeck_excess_v", MAX_VOLTS) * k_M
    lugre = LuGreParams.from_levels(
        fc_pos,
        fc_neg,
        fc_pos + excess,
        fc_neg + excess,
        vs=f.number("stribeck_velocity_counts_s", *STRIBECK_RANGE_COUNTS_S) * rpc,
        sigma0=f.number("sigma0_v_per_count", *SIGMA0_RANGE_V_PER_COUNT) * k_M / rpc,
        sigma1=f.nonneg("sigma1_v_s_per_count", MAX_SIGMA1_V_S_PER_COUNT) * k_M / rpc,
        sigma2=sigma2,
    )
    c1, c2 = (
        v.nonneg(k, MAX_VISCOUS_NM_S_PER_RAD) for k in ("c1_manual_nm_s_per_rad", "c2_manual_nm_s_per_rad")
    )
    manual = source == "manual"
    joints = (
        JointSpec("drive", J["drive"], c1 if manual else 0.0, lugre),
        JointSpec("sr", J["sr"]),
        JointSpec("load", J["load"], c2 if manual else 0.0),
    )
    sens = cfg.section("sensors")
    sensors = []
    for name in list(sens.keys()):
        s = sens.section(name)
        res = units.rad_per_count(s.number("counts_per_rev", *COUNTS_RANGE))
        sensors.append(
            SensorSpec(
                name,
                "encoder",
                s.choice("joint", ("drive", "sr", "load")),
                resolution=res,
                noise_std=s.nonneg("noise_std_counts", 1e3) * res,
            )
        )
    doc = M220Document(
        J_d_eq22=J_d,
        k_M_nm_per_v=k_M,
        rad_per_count=rpc,
        counts_per_rev=counts_per_rev,
        n_g=c["n_pd"] * b["n_load_pulley_teeth"] / (b["n_drive_pulley_teeth"] * c["n_pl"]),
        step_input_v=idf.number("step_input_v", *STEP_INPUT_RANGE_V),
        step_points_t_s=idf.interval("step_points_t_s", *STEP_TIME_RANGE_S),
        step_points_counts=idf.interval("step_points_counts", *STEP_COUNTS_RANGE),
        document_a_per_s=idf.number("document_a_per_s", *POLE_RANGE_PER_S),
        document_k_counts_per_v_s2=idf.number("document_k_counts_per_v_s2", *GAIN_RANGE_COUNTS_PER_V_S2),
        gain_counts_per_v_s2=gain,
    )
    return PlantSpec(
        name="m220",
        joints=joints,
        actuator_joint="drive",
        actuator_gain=k_M,
        command_limit=cfg.section("actuator").number("limit_v", *LIMIT_RANGE_V),
        command_unit="V",
        friction_model=friction_model,
        **sampling(cfg),
        belts=belts,
        sensors=tuple(sensors),
        belt_timeconst=cfg.section("sampling").number("belt_timeconst_s", *BELT_TIMECONST_RANGE_S),
        disturbance_joint="load",  # the load disk carries a disturbance motor (J_dl, §2.1.2)
        randomization=randomization(cfg),
        envelope=ENVELOPE,
        document=doc,
    )
