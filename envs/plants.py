"""Plant specifications: each preset's YAML (document units) -> one SI PlantSpec -> MJCF.

A PlantSpec is plain data. Its MJCF uses, per joint, a hinge whose inertia is the dof armature,
a passive MuJoCo 4 ``dcmotor`` (input="none") carrying the LuGre friction, its σ2 (actuator
damping) and the asymmetry bias (a 0-pole cogging term), plus the drive actuator (a ``motor``
whose gear is the torque per command unit, with a history buffer for the actuation delay).
Belts (M220) are joint equality constraints; the flexible shaft is a fixed tendon spring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from . import units
from .config import ConfigError, interval, load_yaml, merge, nonneg, number, positive
from .friction import FRICTION_MODELS, LuGreParams, check_numerics


@dataclass(frozen=True)
class JointSpec:
    """One rotating shaft. inertia (kg·m²), viscous (N·m·s/rad, outside friction), friction (None: none)."""

    name: str
    inertia: float
    viscous: float = 0.0
    friction: LuGreParams | None = None


@dataclass(frozen=True)
class BeltSpec:
    """Rigid belt coupling q_driven = ratio · q_driver (rad)."""

    driven: str
    driver: str
    ratio: float


@dataclass(frozen=True)
class SpringSpec:
    """Torsional spring between joints a and b: torque k·(θ_b - θ_a) on a (N·m/rad, N·m·s/rad)."""

    a: str
    b: str
    stiffness: float
    damping: float


@dataclass(frozen=True)
class SensorSpec:
    """A sampled sensor: 'encoder' (resolution rad) or 'tacho' (gain V per rad/s, ripple).

    noise_std is in the sensor's output unit (rad for encoders, V for tachometers).
    """

    name: str
    kind: str
    joint: str
    resolution: float = 0.0
    gain: float = 1.0
    noise_std: float = 0.0
    ripple_periods_per_rad: float = 0.0
    ripple_amplitude: float = 0.0


@dataclass(frozen=True)
class PlantSpec:
    """Everything needed to compile and run one plant (SI). Built by plant_spec()."""

    name: str
    joints: tuple[JointSpec, ...]
    actuator_joint: str
    actuator_gain: float  # N·m per command unit
    command_limit: float  # |command| limit (command units)
    command_unit: str  # "V" or "N·m"
    timestep: float  # s
    integrator: str
    control_period: float  # s
    delay: float  # s, actuation delay
    jitter: float  # s, extra per-period actuation delay, uniform in [0, jitter] on the dt grid
    friction_model: str
    belts: tuple[BeltSpec, ...] = ()
    springs: tuple[SpringSpec, ...] = ()
    sensors: tuple[SensorSpec, ...] = ()
    rate_feedback: float = 0.0  # N·m·s/rad, analog velocity feedback at physics rate (Kang §4)
    belt_timeconst: float = 0.0  # s, equality solref time constant
    randomization: dict[str, tuple[float, float]] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)  # document values used by checks/reports

    @property
    def substeps(self) -> int:
        """Physics steps per control period."""
        return round(self.control_period / self.timestep)

    def joint_index(self, name: str) -> int:
        return [j.name for j in self.joints].index(name)

    def kinematic_ratios(self) -> dict[str, float]:
        """dq_joint/dq_driver for joints rigidly coupled by belts to the first joint (others absent)."""
        ratios = {self.joints[0].name: 1.0}
        for b in self.belts:
            ratios[b.driven] = b.ratio * ratios[b.driver]
        return ratios

    def full_state(self, x: np.ndarray | list | None) -> np.ndarray:
        """Per-joint values from x: all joints, or the first joint only for a belt drive (the others follow
        the belt ratios). None gives zeros."""
        n = len(self.joints)
        if x is None:
            return np.zeros(n)
        x = np.atleast_1d(np.asarray(x, dtype=float))
        if x.shape == (n,):
            return x
        if x.shape == (1,) and self.belts:
            ratios = self.kinematic_ratios()
            return np.array([x[0] * ratios[j.name] for j in self.joints])
        raise ConfigError("initial state", f"expected {n} values (or 1 for a belt drive), got {x.shape}")

    def reflected_inertia(self, joint: str | None = None) -> float:
        """Inertia seen at `joint` (default: first) of the belt-coupled chain, kg·m² (cf. seed 000 eq. 22)."""
        ratios = self.kinematic_ratios()
        joint = joint or self.joints[0].name
        if joint not in ratios:
            return self.joints[self.joint_index(joint)].inertia
        r0 = ratios[joint]
        return sum(j.inertia * (ratios[j.name] / r0) ** 2 for j in self.joints if j.name in ratios)


# --------------------------------------------------------------------------------------------------
# Presets


def _sampling(cfg: dict, section: str = "sampling") -> dict[str, Any]:
    s = cfg[section]
    dt = positive(s["timestep_s"], f"{section}.timestep_s")
    period = positive(s["control_period_s"], f"{section}.control_period_s")
    n = period / dt
    if abs(n - round(n)) > 1e-9 * n or round(n) < 1:
        raise ConfigError(
            f"{section}.control_period_s", f"{period} must be a whole multiple of timestep {dt}"
        )
    delay = number(s.get("delay_s", 0.0), f"{section}.delay_s", 0.0, period)
    jitter = number(s.get("jitter_s", 0.0), f"{section}.jitter_s", 0.0, period - delay)
    return {
        "timestep": dt,
        "control_period": period,
        "delay": delay,
        "jitter": jitter,
        "integrator": s["integrator"],
    }


def _randomization(cfg: dict) -> dict[str, tuple[float, float]]:
    out = {}
    for key, value in cfg.get("randomization", {}).items():
        low = -1.0 if key == "asymmetry_shift" else 0.0
        out[key] = interval(value, f"randomization.{key}", low=low)
    return out


def _kang(cfg: dict, friction_model: str) -> PlantSpec:
    f = cfg["friction"]
    J = units.per_deg_to_per_rad(
        positive(cfg["rotor"]["inertia_nm_s2_per_deg"], "rotor.inertia_nm_s2_per_deg")
    )
    lugre = LuGreParams.from_levels(
        fc_pos=positive(f["coulomb_pos_nm"], "friction.coulomb_pos_nm"),
        fc_neg=positive(f["coulomb_neg_nm"], "friction.coulomb_neg_nm"),
        fs_pos=positive(f["static_pos_nm"], "friction.static_pos_nm"),
        fs_neg=positive(f["static_neg_nm"], "friction.static_neg_nm"),
        vs=units.deg_to_rad(positive(f["stribeck_velocity_deg_s"], "friction.stribeck_velocity_deg_s")),
        sigma0=positive(f["sigma0_nm_per_rad"], "friction.sigma0_nm_per_rad"),
        sigma1=nonneg(f["sigma1_nm_s_per_rad"], "friction.sigma1_nm_s_per_rad"),
        sigma2=units.per_deg_to_per_rad(nonneg(f["viscous_nm_s_per_deg"], "friction.viscous_nm_s_per_deg")),
    )
    a = cfg["actuator"]
    enc = cfg["sensors"]["encoder"]
    g = cfg["control_gains"]
    return PlantSpec(
        name="kang_robot",
        joints=(JointSpec("rotor", J, 0.0, lugre),),
        actuator_joint="rotor",
        actuator_gain=positive(a["gain_nm_per_unit"], "actuator.gain_nm_per_unit"),
        command_limit=positive(a["limit_nm"], "actuator.limit_nm"),
        command_unit="N·m",
        friction_model=friction_model,
        **_sampling(cfg),
        sensors=(
            SensorSpec(
                "encoder",
                "encoder",
                "rotor",
                resolution=units.deg_to_rad(
                    positive(enc["resolution_deg"], "sensors.encoder.resolution_deg")
                ),
                noise_std=units.deg_to_rad(nonneg(enc["noise_std_deg"], "sensors.encoder.noise_std_deg")),
            ),
        ),
        rate_feedback=units.per_deg_to_per_rad(
            nonneg(a["rate_feedback_nm_s_per_deg"], "actuator.rate_feedback_nm_s_per_deg")
        ),
        randomization=_randomization(cfg),
        info={
            "kp_nm_per_rad": units.per_deg_to_per_rad(
                positive(g["kp_nm_per_deg"], "control_gains.kp_nm_per_deg")
            ),
            "theta_H_deg": g["theta_H_deg"],
            "theta_L_deg": g["theta_L_deg"],
            "natural_frequency_hz": g["natural_frequency_hz"],
            "coulomb_pos_range_nm": f["coulomb_pos_range_nm"],
            "coulomb_neg_range_nm": f["coulomb_neg_range_nm"],
            "identification_period_s": cfg["sampling"]["identification_period_s"],
        },
    )


def _flexible(cfg: dict, friction_model: str) -> PlantSpec:
    s, f, a = cfg["shafts"], cfg["friction"], cfg["actuator"]
    J1 = positive(s["J1_kg_m2"], "shafts.J1_kg_m2")
    J2 = positive(s["J2_kg_m2"], "shafts.J2_kg_m2")

    def lugre(sigma1_key: str) -> LuGreParams:
        fc = positive(f["coulomb_nm"], "friction.coulomb_nm")
        fs = positive(f["static_nm"], "friction.static_nm")
        return LuGreParams.from_levels(
            fc,
            fc,
            fs,
            fs,
            positive(f["stribeck_velocity_rad_s"], "friction.stribeck_velocity_rad_s"),
            positive(f["sigma0_nm_per_rad"], "friction.sigma0_nm_per_rad"),
            nonneg(f[sigma1_key], f"friction.{sigma1_key}"),
            0.0,
        )

    # d1, d2 (§3.1) are joint damping; the friction elements carry no extra σ2 (Wallenborg eq. 3.9)
    joints = (
        JointSpec(
            "shaft1",
            J1,
            nonneg(s["d1_nm_s_per_rad"], "shafts.d1_nm_s_per_rad"),
            lugre("sigma1_shaft1_nm_s_per_rad"),
        ),
        JointSpec(
            "shaft2",
            J2,
            nonneg(s["d2_nm_s_per_rad"], "shafts.d2_nm_s_per_rad"),
            lugre("sigma1_shaft2_nm_s_per_rad"),
        ),
    )
    sensors = []
    for name in ("tacho1", "tacho2"):
        t = cfg["sensors"][name]
        sensors.append(
            SensorSpec(
                name,
                "tacho",
                t["joint"],
                gain=positive(t["gain_v_per_rad_s"], f"sensors.{name}.gain_v_per_rad_s"),
                noise_std=nonneg(t["noise_std_v"], f"sensors.{name}.noise_std_v"),
                ripple_periods_per_rad=nonneg(
                    t["ripple_periods_per_rad"], f"sensors.{name}.ripple_periods_per_rad"
                ),
                ripple_amplitude=nonneg(t["ripple_amplitude_v"], f"sensors.{name}.ripple_amplitude_v"),
            )
        )
    km = positive(a["km_nm_per_a"], "actuator.km_nm_per_a")
    ki = positive(a["ki_a_per_v"], "actuator.ki_a_per_v")
    return PlantSpec(
        name="flexible_servo",
        joints=joints,
        actuator_joint="shaft1",
        actuator_gain=km * ki,
        command_limit=positive(a["limit_v"], "actuator.limit_v"),
        command_unit="V",
        friction_model=friction_model,
        **_sampling(cfg),
        springs=(
            SpringSpec(
                "shaft1",
                "shaft2",
                positive(s["spring_nm_per_rad"], "shafts.spring_nm_per_rad"),
                nonneg(s["spring_damping_nm_s_per_rad"], "shafts.spring_damping_nm_s_per_rad"),
            ),
        ),
        sensors=tuple(sensors),
        randomization=_randomization(cfg),
        info={
            "fast_control_period_s": cfg["sampling"]["fast_control_period_s"],
            "k_w1": sensors[0].gain,
            "k_w2": sensors[1].gain,
        },
    )


M220_PULLEYS = (18, 24, 36, 72)


def m220_inertias(cfg: dict) -> dict[str, float]:
    """Joint inertias (kg·m²) of drive, SR shaft and load for the configured pulleys/weights (§2.1.2)."""
    c, inr = cfg["configuration"], cfg["inertia"]
    for key in ("n_pd", "n_pl"):
        if c[key] not in M220_PULLEYS:
            raise ConfigError(f"configuration.{key}", f"{c[key]!r} not in the SR pulley table {M220_PULLEYS}")
    for key in ("brass_weights_drive", "brass_weights_load"):
        if not isinstance(c[key], int) or not 0 <= c[key] <= 4:
            raise ConfigError(f"configuration.{key}", f"{c[key]!r} must be an integer in [0, 4]")

    def weights(n: int, four: str, mass: str, radius: str) -> float:
        # the table value is for 4 weights incl. their own inertia: J_own = J_four/4 - m r²
        m, r = positive(inr[mass], f"inertia.{mass}"), positive(inr[radius], f"inertia.{radius}")
        j_own = positive(inr[four], f"inertia.{four}") / 4.0 - m * r * r
        if j_own < 0:
            raise ConfigError(f"inertia.{four}", "smaller than 4·m·r² of the weights")
        return n * (m * r * r + j_own)

    jp = inr["J_pulley_kg_m2"]
    J_p = positive(jp[c["n_pd"]], "inertia.J_pulley_kg_m2") + positive(
        jp[c["n_pl"]], "inertia.J_pulley_kg_m2"
    )
    if c["backlash_device"]:
        J_p += positive(inr["J_backlash_kg_m2"], "inertia.J_backlash_kg_m2")
    return {
        "drive": positive(inr["J_dd_kg_m2"], "inertia.J_dd_kg_m2")
        + weights(
            c["brass_weights_drive"], "J_wd_four_kg_m2", "weight_drive_mass_kg", "weight_drive_radius_m"
        ),
        "sr": J_p,
        "load": positive(inr["J_dl_kg_m2"], "inertia.J_dl_kg_m2")
        + weights(c["brass_weights_load"], "J_wl_four_kg_m2", "weight_load_mass_kg", "weight_load_radius_m"),
    }


def m220_eq22(cfg: dict) -> float:
    """Reflected drive inertia by the document's closed form, eq. (22) of seed 000 (kg·m²)."""
    J = m220_inertias(cfg)
    c, b = cfg["configuration"], cfg["belt"]
    n_g1 = c["n_pd"] / b["n_drive_pulley_teeth"]
    n_g = (b["n_load_pulley_teeth"] / c["n_pl"]) * n_g1
    return J["drive"] + J["sr"] / n_g1**2 + J["load"] / n_g**2


def _m220(cfg: dict, friction_model: str) -> PlantSpec:
    c, b, idf, f = cfg["configuration"], cfg["belt"], cfg["identified"], cfg["friction"]
    inertias = m220_inertias(cfg)
    ratio1 = positive(b["n_drive_pulley_teeth"], "belt.n_drive_pulley_teeth") / c["n_pd"]  # 1/n_g'
    ratio2 = c["n_pl"] / positive(b["n_load_pulley_teeth"], "belt.n_load_pulley_teeth")  # 1/n_g''
    belts = (BeltSpec("sr", "drive", ratio1), BeltSpec("load", "sr", ratio2))
    J_d = m220_eq22(cfg)
    counts_per_rev = positive(idf["counts_per_rev"], "identified.counts_per_rev")
    rpc = units.rad_per_count(counts_per_rev)
    k_M = positive(idf["gain_counts_per_v_s2"], "identified.gain_counts_per_v_s2") * rpc * J_d  # N·m per V

    def v_to_nm(x: float, field: str) -> float:
        return positive(x, field) * k_M

    fv = 0.5 * (
        positive(f["viscous_pos_v_s_per_count"], "friction.viscous_pos_v_s_per_count")
        + positive(f["viscous_neg_v_s_per_count"], "friction.viscous_neg_v_s_per_count")
    )
    source = cfg["viscous"]["source"]
    if source not in ("identified", "manual"):
        raise ConfigError("viscous.source", f"{source!r} not in ['identified', 'manual']")
    sigma2 = fv * k_M / rpc if source == "identified" else 0.0
    fc_pos, fc_neg = (
        v_to_nm(f["coulomb_pos_v"], "friction.coulomb_pos_v"),
        v_to_nm(f["coulomb_neg_v"], "friction.coulomb_neg_v"),
    )
    excess = nonneg(f["stribeck_excess_v"], "friction.stribeck_excess_v") * k_M
    lugre = LuGreParams.from_levels(
        fc_pos,
        fc_neg,
        fc_pos + excess,
        fc_neg + excess,
        vs=positive(f["stribeck_velocity_counts_s"], "friction.stribeck_velocity_counts_s") * rpc,
        sigma0=v_to_nm(f["sigma0_v_per_count"], "friction.sigma0_v_per_count") / rpc,
        sigma1=nonneg(f["sigma1_v_s_per_count"], "friction.sigma1_v_s_per_count") * k_M / rpc,
        sigma2=sigma2,
    )
    manual = source == "manual"
    joints = (
        JointSpec(
            "drive",
            inertias["drive"],
            nonneg(cfg["viscous"]["c1_manual_nm_s_per_rad"], "viscous.c1_manual_nm_s_per_rad")
            if manual
            else 0.0,
            lugre,
        ),
        JointSpec("sr", inertias["sr"]),
        JointSpec(
            "load",
            inertias["load"],
            nonneg(cfg["viscous"]["c2_manual_nm_s_per_rad"], "viscous.c2_manual_nm_s_per_rad")
            if manual
            else 0.0,
        ),
    )
    sensors = tuple(
        SensorSpec(
            name,
            "encoder",
            s["joint"],
            resolution=units.rad_per_count(positive(s["counts_per_rev"], f"sensors.{name}.counts_per_rev")),
            noise_std=nonneg(s["noise_std_counts"], f"sensors.{name}.noise_std_counts")
            * units.rad_per_count(s["counts_per_rev"]),
        )
        for name, s in cfg["sensors"].items()
    )
    return PlantSpec(
        name="m220",
        joints=joints,
        actuator_joint="drive",
        actuator_gain=k_M,
        command_limit=positive(cfg["actuator"]["limit_v"], "actuator.limit_v"),
        command_unit="V",
        friction_model=friction_model,
        **_sampling(cfg),
        belts=belts,
        sensors=sensors,
        belt_timeconst=positive(cfg["sampling"]["belt_timeconst_s"], "sampling.belt_timeconst_s"),
        randomization=_randomization(cfg),
        info={
            "J_d_eq22": J_d,
            "k_M_nm_per_v": k_M,
            "rad_per_count": rpc,
            "counts_per_rev": counts_per_rev,
            "identified": idf,
            "n_g": c["n_pd"] * b["n_load_pulley_teeth"] / (b["n_drive_pulley_teeth"] * c["n_pl"]),
        },
    )


_BUILDERS = {"kang_robot": _kang, "flexible_servo": _flexible, "m220": _m220}


def plant_config(name: str, overrides: dict | None = None) -> dict[str, Any]:
    """The preset's YAML merged with overrides (keys must exist)."""
    return merge(load_yaml(name), overrides)


def plant_spec(name: str, overrides: dict | None = None, friction_model: str = "lugre") -> PlantSpec:
    """Build the SI PlantSpec of preset `name` with YAML-level overrides; validates every value."""
    if friction_model not in FRICTION_MODELS:
        raise ConfigError("friction_model", f"{friction_model!r} not in {list(FRICTION_MODELS)}")
    cfg = plant_config(name, overrides)
    builder = _BUILDERS.get(cfg.get("plant"))
    if builder is None:
        raise ConfigError("plant", f"{cfg.get('plant')!r} not in {sorted(_BUILDERS)}")
    spec = builder(cfg, friction_model)
    delay_hi = spec.randomization.get("delay_s", (0.0, spec.delay))[1]
    jitter_hi = spec.randomization.get("jitter_s", (0.0, spec.jitter))[1]
    if delay_hi + jitter_hi > spec.control_period + 1e-12:
        raise ConfigError(
            "randomization.delay_s",
            f"delay up to {delay_hi} s plus jitter up to {jitter_hi} s exceeds "
            f"the control period {spec.control_period} s",
        )
    for j in spec.joints:
        if j.friction is not None:
            j.friction.validate(f"friction[{j.name}]")
            if friction_model == "lugre":
                check_numerics(
                    j.friction,
                    spec.reflected_inertia(j.name),
                    spec.timestep,
                    spec.integrator,
                    f"friction[{j.name}]",
                )
    if friction_model != "lugre":
        spec = replace(spec, joints=tuple(_strip(j, friction_model) for j in spec.joints))
    return spec


def _strip(j: JointSpec, model: str) -> JointSpec:
    """Reduce a joint's LuGre friction to the requested simpler model (kept as LuGreParams fields)."""
    if j.friction is None:
        return j
    if model == "none":
        return replace(j, friction=None)
    if model == "viscous":
        return replace(j, viscous=j.viscous + j.friction.sigma2, friction=None)
    return j  # coulomb: the MJCF uses frictionloss = fc and the bias; σ's are unused


# --------------------------------------------------------------------------------------------------
# MJCF


def friction_joints(spec: PlantSpec) -> list[str]:
    """Joints that carry a friction actuator, in actuator order."""
    return [j.name for j in spec.joints if j.friction is not None]


def to_mjcf(spec: PlantSpec) -> str:
    """MJCF text of the plant. Actuator order: drive motor, friction elements, rate feedback."""
    nsample = spec.substeps + 2  # history for delays up to one control period
    bodies, actuators, extra = [], [], []
    for i, j in enumerate(spec.joints):
        x = 0.25 * i
        fl = j.friction.fc if (j.friction is not None and spec.friction_model == "coulomb") else 0.0
        bodies.append(
            f'<body name="{j.name}" pos="{x} 0 0"><joint name="{j.name}" type="hinge" axis="0 0 1" '
            f'armature="{j.inertia!r}" damping="{j.viscous!r}" frictionloss="{fl!r}"/>'
            f'<geom type="cylinder" size="0.08 0.01" mass="1e-6" rgba="0.6 0.6 0.7 1"/>'
            f'<geom type="box" pos="0.05 0 0.012" size="0.03 0.005 0.002" mass="1e-6" '
            f'rgba="0.9 0.3 0.2 1"/></body>'
        )
    actuators.append(
        f'<motor name="drive" joint="{spec.actuator_joint}" gear="{spec.actuator_gain!r}" ctrllimited="true" '
        f'ctrlrange="{-spec.command_limit!r} {spec.command_limit!r}" nsample="{nsample}" interp="zoh" '
        f'delay="{spec.delay!r}"/>'
    )
    for j in spec.joints:
        p = j.friction
        if p is None:
            continue
        lugre = (
            f'lugre="{p.sigma0!r} {p.sigma1!r} {p.fc!r} {p.fs!r} {p.vs!r}" damping="{p.sigma2!r}" '
            if spec.friction_model == "lugre"
            else ""
        )
        actuators.append(
            f'<dcmotor name="friction_{j.name}" joint="{j.name}" input="none" resistance="1" '
            f'motorconst="0 0" {lugre}cogging="{p.bias!r} 0 {math.pi / 2!r}"/>'
        )
    if spec.rate_feedback > 0 or spec.name == "kang_robot":
        actuators.append(
            f'<velocity name="rate_feedback" joint="{spec.actuator_joint}" '
            f'kv="{max(spec.rate_feedback, 1e-12)!r}"/>'
        )
    for b in spec.belts:
        extra.append(
            f'<equality><joint joint1="{b.driven}" joint2="{b.driver}" polycoef="0 {b.ratio!r} 0 0 0" '
            f'solref="{spec.belt_timeconst!r} 1"/></equality>'
        )
    for s in spec.springs:
        extra.append(
            f'<tendon><fixed name="spring_{s.a}_{s.b}" stiffness="{s.stiffness!r}" damping="{s.damping!r}">'
            f'<joint joint="{s.b}" coef="1"/><joint joint="{s.a}" coef="-1"/></fixed></tendon>'
        )
    return (
        f'<mujoco model="{spec.name}"><option timestep="{spec.timestep!r}" integrator="{spec.integrator}" '
        f'gravity="0 0 0"/><visual><global offwidth="640" offheight="480"/></visual>'
        f'<worldbody><light pos="0 0 2"/><camera name="top" pos="0.25 -0.6 0.6" xyaxes="1 0 0 0 0.7 0.7"/>'
        f"{''.join(bodies)}</worldbody><actuator>{''.join(actuators)}</actuator>{''.join(extra)}</mujoco>"
    )
