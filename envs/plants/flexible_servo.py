"""Wallenborg's two-inertia flexible servo, seed 002 (Licentiate thesis, Lund 1987), §3: a DC drive
motor (J1) and an inertial load (J2) on a weak torsional shaft, tachometers on both shafts, Coulomb
friction on both. Also its linear models: the state space of eq. (3.1) and G1, G2 of eq. (3.2)/(3.3),
and their checks against the MuJoCo model (linearisation, simulated sine responses).

Preset: configs/plants/flexible_servo.yaml (SI, as printed in §3.1).
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import rollout

from ..config import Node
from ..friction import LuGreParams
from .sim import PlantSim, linearize
from .spec import JointSpec, PlantSpec, SensorSpec, SpringSpec, randomization, sampling

MAX_TORQUE_NM = 10.0  # friction levels: the motor gives 0.025 N·m per volt at ±10 V
MAX_INERTIA_KG_M2 = 1.0  # the shafts are 22e-6 and 150e-6 kg·m²
MAX_STIFFNESS_NM_PER_RAD = 1e3
# identification holds (envs/experiments.py): the references are 1 V = 10 rad/s (§4), 0.5-16 rad/s here
IDENTIFICATION_SPEEDS_RAD_S = (0.5, 16.0)


def build(cfg: Node, friction_model: str) -> PlantSpec:
    """The SI PlantSpec of the preset."""
    s, f, a = cfg.section("shafts"), cfg.section("friction"), cfg.section("actuator")
    J1 = s.positive("J1_kg_m2", MAX_INERTIA_KG_M2)
    J2 = s.positive("J2_kg_m2", MAX_INERTIA_KG_M2)
    fc = f.positive("coulomb_nm", MAX_TORQUE_NM)
    fs = f.positive("static_nm", MAX_TORQUE_NM)
    vs = f.positive("stribeck_velocity_rad_s")
    sigma0 = f.positive("sigma0_nm_per_rad")

    def lugre(sigma1_key: str) -> LuGreParams:
        return LuGreParams.from_levels(fc, fc, fs, fs, vs, sigma0, f.nonneg(sigma1_key), 0.0)

    # d1, d2 (§3.1) are joint damping; the friction elements carry no extra σ2 (Wallenborg eq. 3.9)
    joints = (
        JointSpec("shaft1", J1, s.nonneg("d1_nm_s_per_rad"), lugre("sigma1_shaft1_nm_s_per_rad")),
        JointSpec("shaft2", J2, s.nonneg("d2_nm_s_per_rad"), lugre("sigma1_shaft2_nm_s_per_rad")),
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
                gain=t.positive("gain_v_per_rad_s"),
                noise_std=t.nonneg("noise_std_v", 10.0),
                ripple_periods_per_rad=t.nonneg("ripple_periods_per_rad"),
                ripple_amplitude=t.nonneg("ripple_amplitude_v", 10.0),
            )
        )
    return PlantSpec(
        name="flexible_servo",
        joints=joints,
        actuator_joint="shaft1",
        actuator_gain=a.positive("km_nm_per_a") * a.positive("ki_a_per_v"),
        command_limit=a.positive("limit_v", 1e3),
        command_unit="V",
        friction_model=friction_model,
        **sampling(cfg),
        springs=(
            SpringSpec(
                "shaft1",
                "shaft2",
                s.positive("spring_nm_per_rad", MAX_STIFFNESS_NM_PER_RAD),
                s.nonneg("spring_damping_nm_s_per_rad"),
            ),
        ),
        sensors=tuple(sensors),
        disturbance_joint="shaft2",  # motor 2 sits on the load (J2 "incl. motor 2", §3.1)
        randomization=randomization(cfg),
    )


def tacho_gains(spec: PlantSpec) -> tuple[float, float]:
    """(k_ω1, k_ω2), V per rad/s, §3.1."""
    return spec.sensor("tacho1").gain, spec.sensor("tacho2").gain


def transfer(spec: PlantSpec, s: complex | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """G1(s), G2(s) of seed 002 eq. (3.2)/(3.3), built from the spec's parameters (not typed in)."""
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
    """(A, B, C) of seed 002 eq. (3.1) from the plant parameters; x = (ω1, ω2, θ2 - θ1), u in V, y in V;
    sensor "y1" (colocated tacho) or "y2" (load tacho)."""
    J1, J2 = (j.inertia for j in spec.joints)
    d1, d2 = (j.viscous for j in spec.joints)
    k, d = spec.springs[0].stiffness, spec.springs[0].damping
    A = np.array([[-(d1 + d) / J1, d / J1, k / J1], [d / J2, -(d2 + d) / J2, -k / J2], [-1.0, 1.0, 0.0]])
    B = np.array([[spec.actuator_gain / J1], [0.0], [0.0]])
    kw1, kw2 = tacho_gains(spec)
    C = np.array([[kw1, 0.0, 0.0]]) if sensor == "y1" else np.array([[0.0, kw2, 0.0]])
    return A, B, C


def frf_linearized(freqs_hz: np.ndarray) -> np.ndarray:
    """(len(freqs), 2) complex u->y1, u->y2 responses of the linearised friction-free MuJoCo model."""
    sim = PlantSim("flexible_servo", friction_model="none")
    A, B = linearize(sim)
    C = np.zeros((2, A.shape[0]))
    C[0, sim.model.nv + sim.dofs[0]] = tacho_gains(sim.spec)[0]
    C[1, sim.model.nv + sim.dofs[1]] = tacho_gains(sim.spec)[1]
    return np.array([C @ np.linalg.solve(2j * np.pi * f * np.eye(len(A)) - A, B) for f in freqs_hz])


def frf_sine(
    freqs_hz: np.ndarray, amplitude_v: float = 0.1, settle_s: float = 80.0, periods: int = 4
) -> np.ndarray:
    """Same responses from simulated sine inputs (mujoco.rollout, command updated every physics step
    with the mid-step value, so the per-step hold adds no phase lag), fitted over whole periods."""
    sim = PlantSim("flexible_servo", friction_model="none")
    m, h = sim.model, sim.spec.timestep
    out = []
    state0 = np.zeros((1, mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    mujoco.mj_resetData(m, sim.data)
    mujoco.mj_getState(m, sim.data, state0[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    for f in freqs_hz:
        w = 2 * np.pi * f
        n_fit = round(periods / f / h)
        n = round(settle_s / h) + n_fit
        t_mid = (np.arange(n) + 0.5) * h
        ctrl = np.zeros((1, n, m.nu))
        ctrl[0, :, sim.idx.drive_ctrl] = amplitude_v * np.sin(w * t_mid)
        state, _ = rollout.rollout(m, sim.data, state0, ctrl)
        qvel0 = 1 + m.nq  # FULLPHYSICS: time, qpos, qvel, ...
        t_end = (np.arange(n) + 1) * h
        basis = np.stack([np.sin(w * t_end[-n_fit:]), np.cos(w * t_end[-n_fit:]), np.ones(n_fit)], axis=1)
        resp = []
        for dof, gain in ((sim.dofs[0], tacho_gains(sim.spec)[0]), (sim.dofs[1], tacho_gains(sim.spec)[1])):
            y = gain * state[0, -n_fit:, qvel0 + dof]
            a, b, _ = np.linalg.lstsq(basis, y, rcond=None)[0]
            resp.append((a + 1j * b) / amplitude_v)  # y = Im{G e^{jwt}}·A = A(|G|cos φ sin + |G| sin φ cos)
        out.append(resp)
    return np.array(out)
