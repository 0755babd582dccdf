"""Friction validation: each plant's native friction elements in MuJoCo against an independent stiff-ODE
solution (scipy solve_ivp, Radau) of the same rigid-body + friction equations. For a structure of N
LuGre elements (friction.elements: LuGre §1.4.6, Dahl §1.4.1, Maxwell-slip §1.4.7 of Iurian et al. 2005):

    J·θ'' = T(t, θ) - Σ_k (σ0k·z_k + σ1k·ż_k) - σ2·θ' + b,   ż_k = θ' - σ0k·|θ'|·z_k/g_k(θ')

Experiments run on a one-joint rig with the plant's friction parameters, timestep and integrator and
the inertia the friction sees (the reflected inertia for the M220), so the numerics are the plant's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import ClassVar

import mujoco
import numpy as np
from scipy.integrate import solve_ivp

from frictiongym.envs.friction import LuGreParams, elements
from frictiongym.envs.plants import PlantSpec
from frictiongym.envs.plants.mjcf import to_mjcf
from frictiongym.envs.plants.params import ModelIndex

Torque = Callable[[float, float], float]  # T(t, θ) in N·m


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
        zd = [v - e.sigma0 * abs(v) * zk / e.g(v) for e, zk in zip(els, z, strict=True)]
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
        out = out - (e.sigma0 * z + e.sigma1 * (v - e.sigma0 * np.abs(v) * z / e.g(v)))
    return out


def steady_state(p: LuGreParams, v: float, model: str = "lugre") -> float:
    """Steady sliding friction torque on the joint at velocity v != 0 (N·m): -(Σ g_k(v)·sgn v + σ2·v) + b."""
    g = sum(float(e.g(v)) for e in elements(model, p))
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
        self.idx = ModelIndex.of(self.model, rig)

    def friction(self) -> float:
        """Friction torque on the joint now (N·m), incl. σ2 damping (on the first element, or on the joint
        for the Coulomb structure) and the frictionloss constraint's force (the rig's only constraint)."""
        d, m = self.data, self.model
        f = self.idx.joint_forces(d.actuator_force)[0]
        damping = m.actuator_damping[self.idx.friction[0]] + m.dof_damping[0]  # σ2 (Coulomb: on the joint)
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


# ------------------------------------------------------------------------------ reference-only structures
# Seed 000's Bliman-Sorine (§1.4.5) and reset-integrator (§1.4.3) models are not native MuJoCo elements
# (docs/physics.md, "Friction structures": a passive element cannot subtract a slow branch, and no native
# element switches its equations inside a physics step). Their reference implementations below run the
# phenomena experiments of the report on a one-joint rig by a fine fixed step (explicit in the friction
# state, semi-implicit in the joint), outside the simulator: they are never an env's plant.


@dataclass(frozen=True)
class BlimanSorine:
    """d²F/ds² + 2ξω·dF/ds + ω²F = ω²·F_C·sgn(v), ds = |v|·dt (§1.4.5). From the preset: ω = σ0/F_C (Dahl's
    spatial rate), ξ such that the overshoot of a start from rest is F_s/F_C - 1 (the stiction peak; ξ = 1
    where F_s = F_C). State (F, H = dF/dx): dF/dt = H·v, dH/dt = v·ω²(F_C·sgn v - F) - 2ξω|v|·H, so the
    stiffness dF/dx is continuous through a velocity reversal (dF/ds = sgn(v)·H between reversals)."""

    fc: float
    omega: float
    xi: float
    initial: ClassVar[tuple[float, ...]] = (0.0, 0.0)  # (F, dF/dx) at rest

    @classmethod
    def of(cls, p: LuGreParams) -> BlimanSorine:
        overshoot = p.fs / p.fc - 1.0
        if overshoot <= 0.0:
            return cls(p.fc, p.sigma0 / p.fc, 1.0)
        ln = math.log(overshoot)
        return cls(p.fc, p.sigma0 / p.fc, -ln / math.sqrt(math.pi**2 + ln**2))

    def rate(self, v: float, x: tuple[float, float]) -> tuple[float, float]:
        f, k = x  # F and dF/dx
        w = self.omega
        return k * v, v * w * w * (self.fc * math.copysign(1.0, v) * (v != 0) - f) - 2 * self.xi * w * abs(
            v
        ) * k

    def stiffness(self, v: float) -> float:
        """The state's fastest rate (1/s) at velocity v, for the step size."""
        return self.omega * abs(v)

    def force(self, v: float, x: tuple[float, float], dx: tuple[float, float]) -> float:
        return x[0]


@dataclass(frozen=True)
class ResetIntegrator:
    """ż = v unless sliding (z at ±z1 and v pushing it further), F = σ0(1 + a)z + σ1ż while |z| < z1,
    σ0·z1·sgn(z) at the limit (§1.4.3). From the preset: z1 = F_C/σ0, a = F_s/F_C - 1 (the stiction
    peak σ0(1 + a)z1 = F_s), σ1 the preset's."""

    sigma0: float
    sigma1: float
    z1: float
    a: float
    initial: ClassVar[tuple[float, ...]] = (0.0,)  # z at rest

    @classmethod
    def of(cls, p: LuGreParams) -> ResetIntegrator:
        return cls(p.sigma0, p.sigma1, p.fc / p.sigma0, p.fs / p.fc - 1.0)

    def rate(self, v: float, x: tuple[float]) -> tuple[float]:
        (z,) = x
        sliding = (v > 0 and z >= self.z1) or (v < 0 and z <= -self.z1)
        return (0.0 if sliding else v,)

    def stiffness(self, v: float) -> float:
        return 0.0

    def force(self, v: float, x: tuple[float], dx: tuple[float]) -> float:
        (z,) = x
        if abs(z) >= self.z1:
            return self.sigma0 * self.z1 * math.copysign(1.0, z)
        return self.sigma0 * (1.0 + self.a) * z + self.sigma1 * dx[0]


REFERENCE_STRUCTURES = {"bliman_sorine": BlimanSorine, "reset_integrator": ResetIntegrator}
REFERENCE_STEP_S = 2e-5  # fixed step of the reference runs (Kang's rotor: h·sqrt(σ0/J) = 0.006)


def reference_run(
    structure: str, p: LuGreParams, J: float, torque: Torque, t_end: float, h: float = REFERENCE_STEP_S
) -> dict[str, np.ndarray]:
    """A reference-only structure on a one-joint rig of inertia J under T(t, θ) from rest (σ2 and the bias
    as the native structures have them); logs t, θ, ω, friction torque on the joint, as Rig.run."""
    model = REFERENCE_STRUCTURES[structure].of(p)
    n = round(t_end / h)
    x = model.initial
    th = v = 0.0
    log = np.empty((n, 4))
    for k in range(n):
        t = k * h
        dx = model.rate(v, x)
        f = -(model.force(v, x, dx) + p.sigma2 * v) + p.bias
        v += h * (torque(t, th) + f) / J
        th += h * v
        x = _advance(model, v, x, h)
        log[k] = (t + h, th, v, f)
    return {"t": log[:, 0], "theta": log[:, 1], "omega": log[:, 2], "friction": log[:, 3]}


def reference_friction_along(
    structure: str,
    p: LuGreParams,
    velocity: Callable[[float], float],
    t_end: float,
    h: float = REFERENCE_STEP_S,
) -> dict[str, np.ndarray]:
    """The friction torque of a reference-only structure along an imposed velocity v(t) (as a stiff
    velocity servo imposes it on the rig): t, v, friction."""
    model = REFERENCE_STRUCTURES[structure].of(p)
    n = round(t_end / h)
    x = model.initial
    log = np.empty((n, 3))
    for k in range(n):
        t = k * h
        v = velocity(t)
        dx = model.rate(v, x)
        log[k] = (t, v, -(model.force(v, x, dx) + p.sigma2 * v) + p.bias)
        x = _advance(model, v, x, h)
    return {"t": log[:, 0], "v": log[:, 1], "friction": log[:, 2]}


def _advance(model: BlimanSorine | ResetIntegrator, v: float, x: tuple, h: float) -> tuple:
    """The friction state over h at velocity v, by explicit steps of at most 0.05 / the state's rate."""
    m = max(1, math.ceil(model.stiffness(v) * h / 0.05))
    for _ in range(m):
        x = tuple(xi + h / m * di for xi, di in zip(x, model.rate(v, x), strict=True))
    return x
