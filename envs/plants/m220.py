"""The ECP Model 220 industrial emulator, seed 000 part 2 (Iurian et al., UPC IOC-DT-P-2005-20): drive
disk, belt, speed-reduction (SR) pulley shaft, belt, load disk; encoders on drive and load.

The physical layout is three hinge joints coupled by belt-ratio equality constraints, so the reflected
inertia of eq. (22) is a result, checked here by simulation. The identified model of §2.2-2.3 is given in
the document's software units (encoder counts, volts at the amplifier input) and converted to SI:
1 count = 2π/16000 rad; 1 V gives k_M N·m on the drive, k_M = gain · (rad per count) · J_d.

Preset: configs/plants/m220.yaml.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from .. import units
from ..config import Node
from ..friction import LuGreParams
from .sim import PlantSim
from .spec import BeltSpec, JointSpec, PlantSpec, SensorSpec, randomization, sampling

PULLEY_TEETH = (18, 24, 36, 72)  # SR pulley table, §2.1.3
MAX_VOLTS = 100.0  # friction levels in volts at the amplifier input (the D/A range is ±10 V)
# identification holds (envs/experiments.py): §2.3 held 150-40000 counts/s, i.e. 0.06-15.7 rad/s
IDENTIFICATION_SPEEDS_RAD_S = (0.06, 15.7)
MAX_INERTIA_KG_M2 = 10.0


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
        m, r = inr.positive(mass, 100.0), inr.positive(radius, 10.0)
        j_own = inr.positive(four, MAX_INERTIA_KG_M2) / 4.0 - m * r * r
        if j_own < 0:
            raise inr.error(four, "smaller than 4·m·r² of the weights")
        return n * (m * r * r + j_own)

    jp = inr.section("J_pulley_kg_m2")
    for teeth in PULLEY_TEETH:
        jp.positive(teeth, MAX_INERTIA_KG_M2)
    J_p = jp.positive(n_pd) + jp.positive(n_pl)
    backlash = inr.positive("J_backlash_kg_m2", MAX_INERTIA_KG_M2)
    if c.boolean("backlash_device"):
        J_p += backlash
    return {
        "drive": inr.positive("J_dd_kg_m2", MAX_INERTIA_KG_M2)
        + weights("brass_weights_drive", "J_wd_four_kg_m2", "weight_drive_mass_kg", "weight_drive_radius_m"),
        "sr": J_p,
        "load": inr.positive("J_dl_kg_m2", MAX_INERTIA_KG_M2)
        + weights("brass_weights_load", "J_wl_four_kg_m2", "weight_load_mass_kg", "weight_load_radius_m"),
    }


def eq22(cfg: Node) -> float:
    """Reflected drive inertia by the document's closed form, eq. (22) of seed 000 (kg·m²)."""
    J = inertias(cfg)
    c, b = cfg.section("configuration"), cfg.section("belt")
    n_g1 = c["n_pd"] / b.positive("n_drive_pulley_teeth", 1000)
    n_g = (b.positive("n_load_pulley_teeth", 1000) / c["n_pl"]) * n_g1
    return J["drive"] + J["sr"] / n_g1**2 + J["load"] / n_g**2


def eq22_of(overrides: dict | None = None) -> float:
    """eq22 for the preset with YAML-level overrides (e.g. another pulley configuration)."""
    from . import plant_config

    return eq22(Node(plant_config("m220", overrides), "m220.yaml"))


def build(cfg: Node, friction_model: str) -> PlantSpec:
    """The SI PlantSpec of the preset."""
    c, b, idf, f = (cfg.section(k) for k in ("configuration", "belt", "identified", "friction"))
    J = inertias(cfg)
    ratio1 = b.positive("n_drive_pulley_teeth", 1000) / c["n_pd"]  # 1/n_g'
    ratio2 = c["n_pl"] / b.positive("n_load_pulley_teeth", 1000)  # 1/n_g''
    belts = (BeltSpec("sr", "drive", ratio1), BeltSpec("load", "sr", ratio2))
    J_d = eq22(cfg)
    counts_per_rev = idf.positive("counts_per_rev", 1e9)
    rpc = units.rad_per_count(counts_per_rev)
    gain = idf.positive("gain_counts_per_v_s2", 1e9)
    k_M = gain * rpc * J_d  # N·m per V
    fv = 0.5 * (f.positive("viscous_pos_v_s_per_count", 1.0) + f.positive("viscous_neg_v_s_per_count", 1.0))
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
        vs=f.positive("stribeck_velocity_counts_s") * rpc,
        sigma0=f.positive("sigma0_v_per_count", MAX_VOLTS) * k_M / rpc,
        sigma1=f.nonneg("sigma1_v_s_per_count") * k_M / rpc,
        sigma2=sigma2,
    )
    c1, c2 = v.nonneg("c1_manual_nm_s_per_rad"), v.nonneg("c2_manual_nm_s_per_rad")
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
        res = units.rad_per_count(s.positive("counts_per_rev", 1e9))
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
        step_input_v=idf.positive("step_input_v", 10.0),
        step_points_t_s=idf.interval("step_points_t_s", 0.0),
        step_points_counts=idf.interval("step_points_counts"),
        document_a_per_s=idf.positive("document_a_per_s"),
        document_k_counts_per_v_s2=idf.positive("document_k_counts_per_v_s2"),
        gain_counts_per_v_s2=gain,
    )
    return PlantSpec(
        name="m220",
        joints=joints,
        actuator_joint="drive",
        actuator_gain=k_M,
        command_limit=cfg.section("actuator").positive("limit_v", MAX_VOLTS),
        command_unit="V",
        friction_model=friction_model,
        **sampling(cfg),
        belts=belts,
        sensors=tuple(sensors),
        belt_timeconst=cfg.section("sampling").positive("belt_timeconst_s", 1.0),
        disturbance_joint="load",  # the load disk carries a disturbance motor (J_dl, §2.1.2)
        randomization=randomization(cfg),
        document=doc,
    )


# ------------------------------------------------------------------------------------------------------
# Checks and identification of this plant (seed 000 §2.1.2, §2.2)


def reflected_inertia_sim(overrides: dict, torque_nm: float = 0.01, duration: float = 0.3) -> float:
    """Drive inertia (kg·m²) measured from the simulated motion of the belt-coupled model without
    friction: θ(t) = T·t²/(2·J) fitted over the second half of a constant-torque run from rest."""
    sim = PlantSim("m220", overrides, friction_model="none")
    sim.reset()
    u = torque_nm / sim.spec.actuator_gain
    n = round(duration / sim.spec.timestep)
    t, th = np.empty(n), np.empty(n)
    for k in range(n):
        sim.step(u, nstep=1)
        t[k], th[k] = sim.data.time, sim.data.qpos[sim.dofs[0]]
    half = slice(n // 2, n)
    curvature = np.polyfit(t[half], th[half], 2)[0]  # = T/(2J)
    return torque_nm / (2.0 * curvature)


def step_counts(gain: float, times: tuple[float, ...], v: float, overrides: dict | None = None) -> np.ndarray:
    """Drive-encoder counts of the simulated M220 open-loop step of v volts at the given times."""
    # a nominal experiment: no randomization, so other gains do not trip the range checks (σ0 ∝ gain)
    ov = {
        "identified": {"gain_counts_per_v_s2": float(gain)},
        "randomization": {k: [1.0, 1.0] for k in ("sigma0_scale", "inertia_scale")},
    }
    for key, value in (overrides or {}).items():
        ov.setdefault(key, {}).update(value)
    sim = PlantSim("m220", ov)
    sim.reset()
    dt, out, t_now = sim.spec.timestep, [], 0.0
    rpc = sim.spec.document.rad_per_count
    for t in times:
        n = round((t - t_now) / dt)
        sim.step(v, nstep=n)
        t_now += n * dt
        out.append(np.floor(sim.data.qpos[sim.dofs[0]] / rpc))
    return np.array(out)


def fit_gain(times: tuple[float, float], counts: tuple[float, float], v: float) -> float:
    """Plant gain (counts/(V·s²)) whose simulated step of v volts best matches the measured points
    (times s, counts; §2.2's are in m220.yaml's identified section), relative least squares."""
    target = np.asarray(counts, dtype=float)

    def cost(g: float) -> float:
        return float(np.sum((step_counts(g, times, v) / target - 1.0) ** 2))

    res = minimize_scalar(cost, bounds=(5e4, 2e5), method="bounded", options={"xatol": 1.0})
    return float(res.x)
