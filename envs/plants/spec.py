"""Plant specifications shared by every plant: the SI dataclasses a plant module builds from its preset
(configs/plants/<name>.yaml, document units), and the preset sections every plant has (sampling,
randomization). Each plant's builder, typed document data and linear models live in its own module
(kang_robot.py, flexible_servo.py, m220.py); mjcf.py turns a PlantSpec into MJCF.

A PlantSpec is plain data. Its MJCF uses, per joint, a hinge whose inertia is the dof armature,
a passive MuJoCo 4 ``dcmotor`` (input="none") carrying the LuGre friction, its σ2 (actuator
damping) and the asymmetry bias (a 0-pole cogging term), plus the drive actuator (a ``motor``
whose gear is the torque per command unit, with a history buffer for the actuation delay).
Belts (M220) are joint equality constraints; the flexible shaft is a fixed tendon spring.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from ..config import ConfigError, Node
from ..friction import LuGreParams

JOINT_KINDS = ("hinge", "slide")


@dataclass(frozen=True)
class JointSpec:
    """One rotating shaft (kind "hinge": inertia kg·m², viscous N·m·s/rad, friction in N·m and rad) or one
    carriage in translation (kind "slide": the same fields in kg, N·s/m, N and m). viscous is outside the
    friction element; friction None: none. Every other quantity of the plant follows its joint's unit."""

    name: str
    inertia: float
    viscous: float = 0.0
    friction: LuGreParams | None = None
    kind: str = "hinge"

    def __post_init__(self) -> None:
        if self.kind not in JOINT_KINDS:
            raise ConfigError(f"joint[{self.name}].kind", f"{self.kind!r} not in {list(JOINT_KINDS)}")


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
    ripple_periods_per_rev: float = 0.0
    ripple_amplitude: float = 0.0


@dataclass(frozen=True)
class Envelope:
    """What a task may ask of the plant's joints: |angle| (rad), |speed| (rad/s), |acceleration|
    (rad/s²), or for a slide joint the same in m, m/s, m/s². Scenario references and initial states
    outside it are refused (each plant says why)."""

    position_rad: float
    speed_rad_s: float
    accel_rad_s2: float


@dataclass(frozen=True)
class PlantSpec:
    """Everything needed to compile and run one plant (SI). Built by plant_spec()."""

    name: str
    joints: tuple[JointSpec, ...]
    actuator_joint: str
    actuator_gain: float  # N·m (slide joint: N) per command unit
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
    rate_loop: bool = False  # the rig has an analog rate-feedback loop (a velocity actuator, Kang §4)
    disturbance_joint: str | None = None  # joint of the rig's load-side disturbance motor (N·m, or N)
    randomization: dict[str, tuple[float, float]] = field(default_factory=dict)
    document: Any = None  # the plant module's typed document data (values the checks and designs use)
    envelope: Envelope = Envelope(1e3, 1e3, 1e5)  # each plant module gives its own

    @property
    def substeps(self) -> int:
        """Physics steps per control period."""
        return round(self.control_period / self.timestep)

    def joint_index(self, name: str) -> int:
        return self._joint_indices[name]

    @cached_property
    def _joint_indices(self) -> dict[str, int]:
        """Each joint's index by name, once (a feed-forward asks per joint per control period)."""
        return {j.name: i for i, j in enumerate(self.joints)}

    def joint_unit(self, name: str) -> str:
        """A joint's position unit: m on a slide (a carriage), rad on a hinge."""
        return "m" if self.joints[self.joint_index(name)].kind == "slide" else "rad"

    def sensor_unit(self, name: str) -> str:
        """A sensor's output unit, for labels and logs: V for a tachometer, else its joint's position
        unit (joint_unit)."""
        sensor = self.sensors[self.sensor_names.index(name)]
        return "V" if sensor.kind == "tacho" else self.joint_unit(sensor.joint)

    @cached_property
    def sensor_names(self) -> tuple[str, ...]:
        """The sensors' names in spec order (the observation's order)."""
        return tuple(s.name for s in self.sensors)

    def sensor(self, name: str) -> SensorSpec:
        """The sensor called name."""
        return self.sensors[self.sensor_names.index(name)]

    @property
    def drive_friction(self) -> LuGreParams | None:
        """Friction parameters of the actuated joint (None without friction)."""
        return self.joints[self.joint_index(self.actuator_joint)].friction

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
        """Inertia seen at `joint` (default: first) of the belt-coupled chain, kg·m² (cf. Iurian et al. 2005
        eq. 22)."""
        ratios = self.kinematic_ratios()
        joint = joint or self.joints[0].name
        if joint not in ratios:
            return self.joints[self.joint_index(joint)].inertia
        r0 = ratios[joint]
        return sum(j.inertia * (ratios[j.name] / r0) ** 2 for j in self.joints if j.name in ratios)


# --------------------------------------------------------------------------------------------------
# Preset sections shared by every plant

# Bounds of the sampling section: a physics step below 1 µs or a control period above 1 s is not a servo
# drive (1e-8 s would mean 2e6 substeps per period); the substep count bounds the work per env step.
TIMESTEP_RANGE_S = (1e-6, 0.01)
MAX_CONTROL_PERIOD_S = 1.0
MAX_SUBSTEPS = 10_000
# An episode's actuation delay plus jitter spans at most this many control periods: the plant's own (a
# configured range stays within one period) and the one more period a robustness check adds.
MAX_DELAY_PERIODS = 2
INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")


def sampling(cfg: Node) -> dict[str, Any]:
    """timestep, control period, delay, jitter and integrator of the preset's `sampling` section (s)."""
    s = cfg.section("sampling")
    dt = s.number("timestep_s", *TIMESTEP_RANGE_S)
    period = s.positive("control_period_s", MAX_CONTROL_PERIOD_S)
    n = period / dt
    if abs(n - round(n)) > 1e-9 * n or round(n) < 1:
        raise s.error("control_period_s", f"{period} must be a whole multiple of timestep {dt}")
    if round(n) > MAX_SUBSTEPS:
        raise s.error("control_period_s", f"{round(n)} physics steps per period > {MAX_SUBSTEPS}")
    delay = s.number("delay_s", 0.0, period)
    return {
        "timestep": dt,
        "control_period": period,
        "delay": delay,
        "jitter": s.number("jitter_s", 0.0, period - delay),
        "integrator": s.choice("integrator", INTEGRATORS),
    }


# Randomization keys and their ranges: scales are factors of the nominal value, asymmetry_shift a fraction
# of the symmetric Coulomb level, delay_s/jitter_s in seconds. The bounds reject ranges no real rig spans
# (an inertia x0.1 is another machine); every corner of a range is also checked against the physics and
# numerics checks when the plant is built (params.check_randomization).
RANDOMIZATION_KEYS: dict[str, tuple[float, float]] = {
    "friction_scale": (0.05, 5.0),
    "asymmetry_shift": (-0.9, 0.9),
    "stribeck_velocity_scale": (0.05, 20.0),
    "sigma0_scale": (0.05, 20.0),
    "viscous_scale": (0.0, 10.0),
    "inertia_scale": (0.25, 4.0),
    "spring_scale": (0.25, 4.0),
    "delay_s": (0.0, MAX_CONTROL_PERIOD_S),
    "jitter_s": (0.0, MAX_CONTROL_PERIOD_S),
    "noise_scale": (0.0, 100.0),
}


def randomization(cfg: Node) -> dict[str, tuple[float, float]]:
    """The preset's `randomization` ranges, each checked against RANDOMIZATION_KEYS."""
    r = cfg.section("randomization", optional=True)
    out = {}
    for key in list(r.keys()):
        if key not in RANDOMIZATION_KEYS:
            raise r.error(key, f"unknown randomization key; allowed: {sorted(RANDOMIZATION_KEYS)}")
        out[key] = r.interval(key, *RANDOMIZATION_KEYS[key])
    return out
