"""Friction validation: each plant's native friction elements in MuJoCo against an independent stiff-ODE
solution (scipy solve_ivp, Radau) of the same rigid-body + friction equations. For a structure of N
LuGre elements (friction.elements: LuGre §1.4.6, Dahl §1.4.1, Maxwell-slip §1.4.7 of seed 000):

    J·θ'' = T(t, θ) - Σ_k (σ0k·z_k + σ1k·ż_k) - σ2·θ' + b,   ż_k = θ' - σ0k·|θ'|·z_k/g_k(θ')

Experiments run on a one-joint rig with the plant's friction parameters, timestep and integrator and
the inertia the friction sees (the reflected inertia for the M220), so the numerics are the plant's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import mujoco
import numpy as np
from scipy.integrate import solve_ivp

from .friction import Element, LuGreParams, elements
from .plants import PlantSpec
from .plants.mjcf import to_mjcf

Torque = Callable[[float, float], float]  # T(t, θ) in N·m


def _g(e: Element, v: float | np.ndarray) -> float | np.ndarray:
    """An element's Stribeck curve g_k(v) (N·m), seed 000 eq. (2)."""
    return e.fc + (e.fs - e.fc) * np.exp(-((v / e.vs) ** 2))


def lugre_ode(
    p: LuGreParams,
    J: float,
    torque: Torque,
    t_end: float,
    max_step: float = 1e-3,
    t_eval: np.ndarray | None = None,
    model: str = "lugre",
):
    """Radau solution of the one-joint rigid body + the structure's elements from rest;
    y = (θ, ω, z_1..z_N)."""
    els = elements(model, p)

    def f(t: float, y: np.ndarray) -> list[float]:
        th, v, z = y[0], y[1], y[2:]
        zd = [v - e.sigma0 * abs(v) * zk / _g(e, v) for e, zk in zip(els, z, strict=True)]
        friction = sum(e.sigma0 * zk + e.sigma1 * d for e, zk, d in zip(els, z, zd, strict=True))
        return [v, (torque(t, th) - friction - p.sigma2 * v + p.bias) / J, *zd]

    return solve_ivp(
        f,
        (0.0, t_end),
        [0.0] * (2 + len(els)),
        method="Radau",
        rtol=1e-9,
        atol=1e-13,
        max_step=max_step,
        t_eval=t_eval,
    )


def ode_friction(p: LuGreParams, y: np.ndarray, model: str = "lugre") -> np.ndarray:
    """Friction torque on the joint (N·m) along an ODE solution y = (θ, ω, z_1..z_N)."""
    v, out = y[1], -p.sigma2 * y[1] + p.bias
    for e, z in zip(elements(model, p), y[2:], strict=True):
        out = out - (e.sigma0 * z + e.sigma1 * (v - e.sigma0 * np.abs(v) * z / _g(e, v)))
    return out


def steady_state(p: LuGreParams, v: float, model: str = "lugre") -> float:
    """Steady sliding friction torque on the joint at velocity v != 0 (N·m): -(Σ g_k(v)·sgn v + σ2·v) + b."""
    g = sum(float(_g(e, v)) for e in elements(model, p))
    return -(np.copysign(g, v) + p.sigma2 * v) + p.bias


class Rig:
    """One joint of inertia J with the plant's friction elements (its friction structure), driven by a
    torque motor (gain 1)."""

    def __init__(self, spec: PlantSpec, joint: str, velocity_servo_gain: float = 0.0):
        j = spec.joints[spec.joint_index(joint)]
        self.J = spec.reflected_inertia(joint)
        self.p = j.friction
        rig = replace(
            spec,
            name="rig",
            joints=(replace(j, inertia=self.J, viscous=0.0),),
            actuator_joint=j.name,
            actuator_gain=1.0,
            command_limit=1e9,
            belts=(),
            springs=(),
            sensors=(),
            rate_feedback=0.0,
            rate_loop=False,
            disturbance_joint=None,
            delay=0.0,
        )
        xml = to_mjcf(rig)
        if velocity_servo_gain > 0:
            xml = xml.replace(
                "</actuator>",
                f'<velocity name="servo" joint="{j.name}" kv="{velocity_servo_gain!r}"/></actuator>',
            )
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        self.h = spec.timestep
        self.structure = spec.friction_model
        names = [
            mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_ACTUATOR, a)
            for a in range(self.model.nactuator)
        ]
        self.elements = [a for a, n in enumerate(names) if n.startswith("friction_")]

    def friction(self) -> float:
        """Friction torque on the joint now (N·m), incl. σ2 damping (on the first element, or on the joint
        for the Coulomb structure) and the frictionloss constraint's force (the rig's only constraint)."""
        d, m = self.data, self.model
        f = d.actuator_force[self.elements[0]]
        for a in self.elements[1:]:
            f += d.actuator_force[a]
        damping = m.actuator_damping[self.elements[0]] + m.dof_damping[0]  # σ2 (Coulomb: on the joint)
        return float(f - damping * d.qvel[0] + d.qfrc_constraint[0])

    def run(self, torque: Torque, t_end: float) -> dict[str, np.ndarray]:
        """Apply T(t, θ) (updated every physics step) from rest; log t, θ, ω, friction."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        n = round(t_end / self.h)
        log = np.empty((n, 4))
        for k in range(n):
            d.ctrl[0] = torque(d.time, d.qpos[0])
            mujoco.mj_step(m, d)
            log[k] = (d.time, d.qpos[0], d.qvel[0], self.friction())
        return {"t": log[:, 0], "theta": log[:, 1], "omega": log[:, 2], "friction": log[:, 3]}


def breakaway(spec: PlantSpec, joint: str, direction: int, duration: float = 2.0) -> dict[str, float]:
    """Breakaway torque under a slow torque ramp 0 -> 1.5·F_s (direction ±1): the peak friction
    magnitude while the joint is still presliding (|ω| <= v_s), so the viscous part after the slip
    is not counted."""
    p = spec.joints[spec.joint_index(joint)].friction
    rate = direction * 1.5 * (p.fs + abs(p.bias)) / duration
    rig = Rig(spec, joint)
    sim = rig.run(lambda t, th: rate * t, duration)
    ode = lugre_ode(p, rig.J, lambda t, th: rate * t, duration, model=rig.structure)
    stick_sim = np.abs(sim["omega"]) <= p.vs
    stick_ode = np.abs(ode.y[1]) <= p.vs
    return {
        "simulated": float(np.max(np.abs(sim["friction"][stick_sim]))),
        "reference": float(np.max(np.abs(ode_friction(p, ode.y, rig.structure)[stick_ode]))),
    }


def sliding(spec: PlantSpec, joint: str, velocity: float, settle: float = 0.5) -> dict[str, float]:
    """Steady sliding friction at ≈ velocity (rad/s), held by a stiff velocity servo; the reference is
    the structure's steady state Σ g_k(v)·sgn(v) + σ2·v - b at the velocity the simulation settles to."""
    J = spec.reflected_inertia(joint)
    p = spec.joints[spec.joint_index(joint)].friction
    # the servo must out-push the static level at the target speed, within Euler's stable range
    gain = min(
        0.8 * J / spec.timestep, max(0.05 * J / spec.timestep, 2.0 * (p.fs + abs(p.bias)) / abs(velocity))
    )
    rig = Rig(spec, joint, velocity_servo_gain=gain)
    # every element must have travelled ten of its presliding lengths F_s,k/σ0,k
    settle = max(settle, 10.0 * max(e.fs / e.sigma0 for e in elements(rig.structure, p)) / abs(velocity))
    rig.data.ctrl[1] = velocity
    mujoco.mj_step(rig.model, rig.data, round(settle / spec.timestep))
    v = float(rig.data.qvel[0])
    return {"velocity": v, "simulated": rig.friction(), "reference": steady_state(rig.p, v, rig.structure)}


def presliding(spec: PlantSpec, joint: str, fraction: float = 0.5, duration: float = 1.0) -> dict[str, float]:
    """Displacement (rad) under a torque ramped smoothly to fraction·F_s in duration/2, then held."""
    p = spec.joints[spec.joint_index(joint)].friction
    T = fraction * (p.fs - p.bias)

    def torque(t: float, th: float) -> float:
        return T * min(1.0, 2.0 * t / duration) ** 2 * (3.0 - 2.0 * min(1.0, 2.0 * t / duration))

    rig = Rig(spec, joint)
    sim = rig.run(torque, duration)
    ode = lugre_ode(p, rig.J, torque, duration, t_eval=[duration], model=rig.structure)
    return {"simulated": float(sim["theta"][-1]), "reference": float(ode.y[0, -1])}


def stickslip_period(
    spec: PlantSpec, joint: str, stiffness: float, pull_velocity: float, duration: float
) -> dict[str, float]:
    """Period (s) of the stick-slip cycle of the joint pulled through a spring k at constant speed."""
    p = spec.joints[spec.joint_index(joint)].friction

    def torque(t: float, th: float) -> float:
        return stiffness * (pull_velocity * t - th)

    rig = Rig(spec, joint)
    sim = rig.run(torque, duration)
    t_eval = sim["t"]
    ode = lugre_ode(
        p, rig.J, torque, duration, max_step=spec.timestep * 4, t_eval=t_eval, model=rig.structure
    )
    return {
        "simulated": _period(sim["t"], sim["omega"], pull_velocity),
        "reference": _period(ode.t, ode.y[1], pull_velocity),
    }


def _period(t: np.ndarray, omega: np.ndarray, pull_velocity: float) -> float:
    """Mean interval between slip onsets (ω rising through 5·pull speed), skipping the first cycle."""
    fast = omega > 5.0 * pull_velocity
    onsets = t[1:][fast[1:] & ~fast[:-1]]
    if len(onsets) < 3:
        return float("nan")
    return float(np.mean(np.diff(onsets[1:])))
