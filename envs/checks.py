"""Plant-level checks against the documents: M220 reflected inertia (seed 000 eq. 22), flexible-servo
frequency responses (seed 002 eq. 3.2/3.3), Kang's PD equilibrium bounds (seed 001 eq. 6)."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
from mujoco import rollout

from . import units
from .plants import PlantSpec, plant_spec
from .sim import PlantSim


def m220_reflected_inertia_sim(overrides: dict, torque_nm: float = 0.01, duration: float = 0.3) -> float:
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


def flexible_transfer(spec: PlantSpec, s: complex | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """G1(s), G2(s) of seed 002 eq. (3.2)/(3.3), built from the spec's parameters (not typed in)."""
    J1, J2 = (j.inertia for j in spec.joints)
    d1, d2 = (j.viscous for j in spec.joints)
    k, d = spec.springs[0].stiffness, spec.springs[0].damping
    kk = spec.actuator_gain
    kw1, kw2 = spec.info["k_w1"], spec.info["k_w2"]
    A = (
        J1 * J2 * s**3
        + (J2 * (d1 + d) + J1 * (d2 + d)) * s**2
        + (k * (J1 + J2) + d1 * d2 + d * d1 + d * d2) * s
        + (d1 + d2) * k
    )
    return kk * kw1 * (J2 * s**2 + (d2 + d) * s + k) / A, kk * kw2 * (d * s + k) / A


def linearize(sim: PlantSim, eps: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time (A, B) of the MuJoCo model at rest: central differences of qacc from mj_forward
    over (qpos, qvel) and the drive command. State x = (qpos, qvel)."""
    m, d = sim.model, sim.data
    nv = m.nv

    def acc(q: np.ndarray, v: np.ndarray, u: float) -> np.ndarray:
        d.qpos[:], d.qvel[:], d.ctrl[:] = q, v, 0.0
        d.ctrl[sim.idx.drive_ctrl] = u
        mujoco.mj_forward(m, d)
        return d.qacc.copy()

    q0, v0 = np.zeros(nv), np.zeros(nv)
    A = np.zeros((2 * nv, 2 * nv))
    A[:nv, nv:] = np.eye(nv)
    for i in range(2 * nv):
        dx = np.zeros(2 * nv)
        dx[i] = eps
        A[nv:, i] = (acc(q0 + dx[:nv], v0 + dx[nv:], 0.0) - acc(q0 - dx[:nv], v0 - dx[nv:], 0.0)) / (2 * eps)
    B = np.zeros(2 * nv)
    B[nv:] = (acc(q0, v0, eps) - acc(q0, v0, -eps)) / (2 * eps)
    return A, B


def flexible_frf_linearized(freqs_hz: np.ndarray) -> np.ndarray:
    """(len(freqs), 2) complex u->y1, u->y2 responses of the linearised friction-free MuJoCo model."""
    sim = PlantSim("flexible_servo", friction_model="none")
    A, B = linearize(sim)
    C = np.zeros((2, A.shape[0]))
    C[0, sim.model.nv + sim.dofs[0]] = sim.spec.info["k_w1"]
    C[1, sim.model.nv + sim.dofs[1]] = sim.spec.info["k_w2"]
    return np.array([C @ np.linalg.solve(2j * np.pi * f * np.eye(len(A)) - A, B) for f in freqs_hz])


def flexible_frf_sine(
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
        for dof, gain in ((sim.dofs[0], sim.spec.info["k_w1"]), (sim.dofs[1], sim.spec.info["k_w2"])):
            y = gain * state[0, -n_fit:, qvel0 + dof]
            a, b, _ = np.linalg.lstsq(basis, y, rcond=None)[0]
            resp.append((a + 1j * b) / amplitude_v)  # y = Im{G e^{jwt}}·A = A(|G|cos φ sin + |G| sin φ cos)
        out.append(resp)
    return np.array(out)


def kang_pd_bounds(rate_deg_s: float = 0.05) -> dict[str, float]:
    """Equilibrium-region bounds (deg) from simulated P control of slow reference ramps (the §6 method):
    the largest error held before the rotor breaks away, ramping up (θ_L) and down (θ_H). The default
    0.05 deg/s is the document's ramp: faster ramps overshoot the bound while the rotor crosses the
    Stribeck region (1.4 % at 0.5 deg/s)."""
    spec = plant_spec("kang_robot")
    period = spec.info["identification_period_s"]
    spec = replace(spec, control_period=period)
    kp = spec.info["kp_nm_per_rad"]
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
