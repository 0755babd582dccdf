"""Wallenborg's two-inertia flexible servo, Wallenborg 1987 (Licentiate thesis, Lund 1987), §3: a DC drive
motor (J1) and an inertial load (J2) on a weak torsional shaft, tachometers on both shafts, Coulomb
friction on both. Also its linear models: the state space of eq. (3.1) and G1, G2 of eq. (3.2)/(3.3),
and their checks against the MuJoCo model (linearisation, simulated sine responses).

Preset: configs/plants/flexible_servo.yaml (SI, as printed in §3.1).
"""

from __future__ import annotations

import numpy as np

from ..config import Node
from ..friction import LuGreParams
from .spec import Envelope, JointSpec, PlantSpec, SensorSpec, SpringSpec, randomization, sampling

# Ranges of the preset's values (§3.1-3.2), each wide around the document's: a value outside is another
# machine, or makes the model meaningless or the simulation ill-conditioned.
MAX_TORQUE_NM = 10.0  # friction levels: the motor gives 0.025 N·m per volt at ±10 V
INERTIA_RANGE_KG_M2 = (1e-8, 1.0)  # the shafts are 22e-6 and 150e-6 kg·m² (x1/2000 .. x6000)
STIFFNESS_RANGE_NM_PER_RAD = (1e-6, 1e3)  # k = 2.4e-3 (§3.1): the weak shaft of the thesis, x1/2400 .. x4e5
MAX_DAMPING_NM_S_PER_RAD = 1.0  # d1 = d2 = 1e-5 (§3.1); at 1, 1 rad/s costs 1 N·m, 4x the motor's peak
STRIBECK_RANGE_RAD_S = (1e-4, 100.0)  # below the tachometers' resolution .. the drive's top speed
SIGMA0_RANGE_NM_PER_RAD = (1e-3, 1e6)  # presliding F_s/σ0 from 0.5 rad (very soft) to 5e-10 rad
MAX_SIGMA1_NM_S_PER_RAD = 10.0  # 400x the critically damped 2.45e-2 of shaft 2
GAIN_RANGE_NM_PER_A = (1e-4, 10.0)  # k_m = 0.1 N·m/A (§3.1)
GAIN_RANGE_A_PER_V = (1e-4, 10.0)  # k_i = 0.25 A/V (§3.1)
TACHO_GAIN_RANGE_V_PER_RAD_S = (1e-4, 10.0)  # k_ω = 0.1 V/(rad/s) (§3.1)
MAX_RIPPLE_PERIODS_PER_REV = 1e3  # commutator ripple: tens of segments per turn, not thousands
LIMIT_RANGE_V = (1e-3, 100.0)  # ±10 V signal levels (§7.1)
# identification holds (agents/lab/experiments.py): the references are 1 V = 10 rad/s (§4), 0.5-16 rad/s here
IDENTIFICATION_SPEEDS_RAD_S = (0.5, 16.0)
# a speed servo turns freely; 200 rad/s is 20 V on the 0.1 V/(rad/s) tachometers (twice the ±10 V
# signal range, §7.1); 1e5 rad/s² is 9x what 0.25 N·m gives J1 (1.1e4)
ENVELOPE = Envelope(1e3, 200.0, 1e5)


def build(cfg: Node, friction_model: str) -> PlantSpec:
    """The SI PlantSpec of the preset."""
    s, f, a = cfg.section("shafts"), cfg.section("friction"), cfg.section("actuator")
    J1 = s.number("J1_kg_m2", *INERTIA_RANGE_KG_M2)
    J2 = s.number("J2_kg_m2", *INERTIA_RANGE_KG_M2)
    fc = f.positive("coulomb_nm", MAX_TORQUE_NM)
    fs = f.positive("static_nm", MAX_TORQUE_NM)
    vs = f.number("stribeck_velocity_rad_s", *STRIBECK_RANGE_RAD_S)
    sigma0 = f.number("sigma0_nm_per_rad", *SIGMA0_RANGE_NM_PER_RAD)

    def lugre(sigma1_key: str) -> LuGreParams:
        sigma1 = f.nonneg(sigma1_key, MAX_SIGMA1_NM_S_PER_RAD)
        return LuGreParams.from_levels(fc, fc, fs, fs, vs, sigma0, sigma1, 0.0)

    # d1, d2 (§3.1) are joint damping; the friction elements carry no extra σ2 (Wallenborg eq. 3.9)
    d1, d2 = (s.nonneg(k, MAX_DAMPING_NM_S_PER_RAD) for k in ("d1_nm_s_per_rad", "d2_nm_s_per_rad"))
    joints = (
        JointSpec("shaft1", J1, d1, lugre("sigma1_shaft1_nm_s_per_rad")),
        JointSpec("shaft2", J2, d2, lugre("sigma1_shaft2_nm_s_per_rad")),
    )
    sensors = []
    sens = cfg.section("sensors")
    for name in ("tacho1", "tacho2"):
        t = sens.section(name)
        sensors.append(
            SensorSpec(
                name,
                "tacho",
                t.choice("joint", ["shaft1", "shaft2"]),
                gain=t.number("gain_v_per_rad_s", *TACHO_GAIN_RANGE_V_PER_RAD_S),
                noise_std=t.nonneg("noise_std_v", 10.0),
                ripple_periods_per_rev=t.nonneg("ripple_periods_per_rev", MAX_RIPPLE_PERIODS_PER_REV),
                ripple_amplitude=t.nonneg("ripple_amplitude_v", 10.0),
            )
        )
    return PlantSpec(
        name="flexible_servo",
        joints=joints,
        actuator_joint="shaft1",
        actuator_gain=a.number("km_nm_per_a", *GAIN_RANGE_NM_PER_A)
        * a.number("ki_a_per_v", *GAIN_RANGE_A_PER_V),
        command_limit=a.number("limit_v", *LIMIT_RANGE_V),
        command_unit="V",
        friction_model=friction_model,
        **sampling(cfg),
        springs=(
            SpringSpec(
                "shaft1",
                "shaft2",
                s.number("spring_nm_per_rad", *STIFFNESS_RANGE_NM_PER_RAD),
                s.nonneg("spring_damping_nm_s_per_rad", MAX_DAMPING_NM_S_PER_RAD),
            ),
        ),
        sensors=tuple(sensors),
        disturbance_joint="shaft2",  # motor 2 sits on the load (J2 "incl. motor 2", §3.1)
        randomization=randomization(cfg),
        envelope=ENVELOPE,
    )


def tacho_gains(spec: PlantSpec) -> tuple[float, float]:
    """(k_ω1, k_ω2), V per rad/s, §3.1."""
    return spec.sensor("tacho1").gain, spec.sensor("tacho2").gain


def transfer(spec: PlantSpec, s: complex | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """G1(s), G2(s) of Wallenborg 1987 eq. (3.2)/(3.3), built from the spec's parameters (not typed in)."""
    J1, J2 = (j.inertia for j in spec.joints)
    d1, d2 = (j.viscous for j in spec.joints)
    k, d = spec.springs[0].stiffness, spec.springs[0].damping
    kk = spec.actuator_gain
    kw1, kw2 = tacho_gains(spec)
    A = (
        J1 * J2 * s**3
        + (J2 * (d1 + d) + J1 * (d2 + d)) * s**2
        + (k * (J1 + J2) + d1 * d2 + d * d1 + d * d2) * s
        + (d1 + d2) * k
    )
    return kk * kw1 * (J2 * s**2 + (d2 + d) * s + k) / A, kk * kw2 * (d * s + k) / A


def state_space(spec: PlantSpec, sensor: str = "y1") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, C) of Wallenborg 1987 eq. (3.1) from the plant parameters; x = (ω1, ω2, θ2 - θ1), u in V, y in
    V; sensor "y1" (colocated tacho) or "y2" (load tacho)."""
    J1, J2 = (j.inertia for j in spec.joints)
    d1, d2 = (j.viscous for j in spec.joints)
    k, d = spec.springs[0].stiffness, spec.springs[0].damping
    A = np.array([[-(d1 + d) / J1, d / J1, k / J1], [d / J2, -(d2 + d) / J2, -k / J2], [-1.0, 1.0, 0.0]])
    B = np.array([[spec.actuator_gain / J1], [0.0], [0.0]])
    kw1, kw2 = tacho_gains(spec)
    C = np.array([[kw1, 0.0, 0.0]]) if sensor == "y1" else np.array([[0.0, kw2, 0.0]])
    return A, B, C
