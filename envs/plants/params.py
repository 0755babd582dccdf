"""Per-episode plant parameters: drawn from the preset's ranges with a seed, checked, and written into
an already compiled MjModel (or per simulation into a mujoco.batch.Batch) without recompiling."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from ..config import ConfigError, nonneg, number, positive
from ..friction import LuGreParams, check_numerics
from .mjcf import friction_joints
from .spec import PlantSpec


@dataclass(frozen=True)
class EpisodeParams:
    """Runtime-changeable parameters of one episode (SI).

    friction: LuGre parameters per frictional joint (friction_joints order); inertia, viscous: per
    joint (kg·m², N·m·s/rad); spring_stiffness/damping per spring; actuator_gain (N·m per command
    unit); rate_feedback (N·m·s/rad); delay (s, snapped to the physics timestep); noise_scale
    multiplies the preset's sensor noise levels; jitter (s): each control period's command acts
    after delay + j, j drawn uniformly on the timestep grid in [0, jitter] (PlantSim.step).
    """

    friction: tuple[LuGreParams, ...]
    inertia: tuple[float, ...]
    viscous: tuple[float, ...]
    spring_stiffness: tuple[float, ...]
    spring_damping: tuple[float, ...]
    actuator_gain: float
    rate_feedback: float
    delay: float
    noise_scale: float = 1.0
    jitter: float = 0.0

    @classmethod
    def nominal(cls, spec: PlantSpec) -> EpisodeParams:
        """The preset's own values."""
        return cls(
            friction=tuple(j.friction for j in spec.joints if j.friction is not None),
            inertia=tuple(j.inertia for j in spec.joints),
            viscous=tuple(j.viscous for j in spec.joints),
            spring_stiffness=tuple(s.stiffness for s in spec.springs),
            spring_damping=tuple(s.damping for s in spec.springs),
            actuator_gain=spec.actuator_gain,
            rate_feedback=spec.rate_feedback,
            delay=spec.delay,
            jitter=spec.jitter,
        )

    @classmethod
    def draw(
        cls,
        spec: PlantSpec,
        rng: np.random.Generator | int,
        ranges: dict[str, tuple[float, float]] | None = None,
    ) -> EpisodeParams:
        """Draw from `ranges` (default: the preset's randomization section) with a seed or Generator.

        Every range is drawn, in a fixed order, whether or not it is used, so the same seed gives the
        same parameters on every machine and in single or vector envs.
        """
        rng = np.random.default_rng(rng) if not isinstance(rng, np.random.Generator) else rng
        r = dict(spec.randomization if ranges is None else ranges)

        def u(key: str, default: float) -> float:
            lo, hi = r.get(key, (default, default))
            return float(rng.uniform(lo, hi))

        base = cls.nominal(spec)
        inertia_scale = u("inertia_scale", 1.0)
        spring_scale = u("spring_scale", 1.0)
        delay = u("delay_s", spec.delay)
        noise = u("noise_scale", 1.0)
        friction = []
        for p in base.friction:
            level, shift = u("friction_scale", 1.0), u("asymmetry_shift", 0.0)
            s0, vs, visc = u("sigma0_scale", 1.0), u("stribeck_velocity_scale", 1.0), u("viscous_scale", 1.0)
            friction.append(
                p.scaled(level=level, sigma0=s0, vs=vs, viscous=visc, extra_bias=shift * p.fc * level)
            )
        return replace(
            base,
            friction=tuple(friction),
            inertia=tuple(x * inertia_scale for x in base.inertia),
            spring_stiffness=tuple(x * spring_scale for x in base.spring_stiffness),
            delay=delay,
            noise_scale=noise,
            jitter=u("jitter_s", spec.jitter),  # drawn last: earlier draws keep their values
        )

    def validate(self, spec: PlantSpec) -> None:
        """Reject unphysical values and (σ, J, h, integrator) combinations outside the admissible region."""
        names = friction_joints(spec)
        if len(self.friction) != len(names) or len(self.inertia) != len(spec.joints):
            raise ConfigError("params", "sizes do not match the plant")
        for i, x in enumerate(self.inertia):
            positive(x, f"params.inertia[{spec.joints[i].name}]")
        for i, x in enumerate(self.viscous):
            nonneg(x, f"params.viscous[{spec.joints[i].name}]")
        for i, x in enumerate(self.spring_stiffness):
            positive(x, f"params.spring_stiffness[{i}]")
        for i, x in enumerate(self.spring_damping):
            nonneg(x, f"params.spring_damping[{i}]")
        positive(self.actuator_gain, "params.actuator_gain")
        nonneg(self.rate_feedback, "params.rate_feedback")
        number(self.delay, "params.delay", 0.0, spec.control_period)
        number(self.jitter, "params.jitter", 0.0, spec.control_period - self.delay)
        nonneg(self.noise_scale, "params.noise_scale")
        scaled = spec_with(spec, self)
        for name, p in zip(names, self.friction, strict=True):
            p.validate(f"params.friction[{name}]")
            if spec.friction_model == "lugre":
                check_numerics(
                    p,
                    scaled.reflected_inertia(name),
                    spec.timestep,
                    spec.integrator,
                    f"params.friction[{name}]",
                )

    def delay_steps(self, spec: PlantSpec) -> int:
        """Actuation delay in whole physics steps (the delay is resolved to the timestep grid)."""
        return round(self.delay / spec.timestep)

    def jitter_steps(self, spec: PlantSpec) -> int:
        """Largest extra delay from jitter, in whole physics steps (rounded down)."""
        return int(self.jitter / spec.timestep + 1e-9)


def spec_with(spec: PlantSpec, p: EpisodeParams) -> PlantSpec:
    """The spec with p's joint inertias/viscous/friction (for derived quantities such as J_d)."""
    it = iter(p.friction)
    joints = tuple(
        replace(
            j,
            inertia=p.inertia[i],
            viscous=p.viscous[i],
            friction=next(it) if j.friction is not None else None,
        )
        for i, j in enumerate(spec.joints)
    )
    return replace(
        spec, joints=joints, actuator_gain=p.actuator_gain, rate_feedback=p.rate_feedback, delay=p.delay
    )


@dataclass(frozen=True)
class ModelIndex:
    """Where each parameter lives in the compiled model."""

    drive: int  # actuator id of the drive motor
    drive_ctrl: int  # its ctrl index
    friction: tuple[int, ...]  # friction actuator ids
    rate: int  # rate-feedback actuator id or -1
    dofs: tuple[int, ...]
    tendons: tuple[int, ...]

    @classmethod
    def of(cls, model: mujoco.MjModel, spec: PlantSpec) -> ModelIndex:
        aid = lambda n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n)  # noqa: E731
        drive = aid("drive")
        return cls(
            drive=drive,
            drive_ctrl=int(model.actuator_ctrladr[drive]),
            friction=tuple(aid(f"friction_{n}") for n in friction_joints(spec)),
            rate=aid("rate_feedback"),
            dofs=tuple(
                int(model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j.name)])
                for j in spec.joints
            ),
            tendons=tuple(
                mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, f"spring_{s.a}_{s.b}")
                for s in spec.springs
            ),
        )


def _fields(spec: PlantSpec, idx: ModelIndex, p: EpisodeParams) -> dict[str, list[tuple[tuple, float]]]:
    """(field, index, value) writes that put p into a model."""
    w: dict[str, list[tuple[tuple, float]]] = {
        k: []
        for k in (
            "dof_armature",
            "dof_damping",
            "dof_frictionloss",
            "actuator_dynprm",
            "actuator_biasprm",
            "actuator_damping",
            "actuator_gear",
            "actuator_gainprm",
            "actuator_delay",
            "tendon_stiffness",
            "tendon_damping",
        )
    }
    for d, J, c in zip(idx.dofs, p.inertia, p.viscous, strict=True):
        w["dof_armature"].append(((d,), J))
        w["dof_damping"].append(((d,), c))
    fdofs = [idx.dofs[spec.joint_index(n)] for n in friction_joints(spec)]
    for a, d, f in zip(idx.friction, fdofs, p.friction, strict=True):
        w["actuator_biasprm"] += [((a, 0), f.bias), ((a, 1), 0.0), ((a, 2), math.pi / 2)]
        if spec.friction_model == "lugre":
            w["actuator_dynprm"] += [((a, 5), f.sigma0), ((a, 6), f.sigma1)]
            w["actuator_biasprm"] += [((a, 3), f.fc), ((a, 4), f.fs), ((a, 5), f.vs)]
            w["actuator_damping"].append(((a,), f.sigma2))
        elif spec.friction_model == "coulomb":
            w["dof_frictionloss"].append(((d,), f.fc))
    w["actuator_gear"].append(((idx.drive, 0), p.actuator_gain))
    w["actuator_delay"].append(((idx.drive,), p.delay_steps(spec) * spec.timestep))
    if idx.rate >= 0:
        kv = max(p.rate_feedback, 1e-12)
        w["actuator_gainprm"].append(((idx.rate, 0), kv))
        w["actuator_biasprm"].append(((idx.rate, 2), -kv))
    for t, k, c in zip(idx.tendons, p.spring_stiffness, p.spring_damping, strict=True):
        w["tendon_stiffness"].append(((t,), k))
        w["tendon_damping"].append(((t,), c))
    return {k: v for k, v in w.items() if v}


def apply(
    model: mujoco.MjModel, data: mujoco.MjData, spec: PlantSpec, idx: ModelIndex, p: EpisodeParams
) -> None:
    """Write p into a compiled model (validated first) and refresh derived constants (mj_setConst)."""
    p.validate(spec)
    for name, writes in _fields(spec, idx, p).items():
        arr = getattr(model, name)
        for i, value in writes:
            arr[i] = value
    mujoco.mj_setConst(model, data)


def apply_batch(
    batch: mujoco.batch.Batch,
    spec: PlantSpec,
    idx: ModelIndex,
    params: list[EpisodeParams],
    ids: np.ndarray | None = None,
) -> None:
    """Write each simulation's parameters into a Batch (per-simulation model fields), then set_const."""
    ids = np.arange(batch.nsim) if ids is None else np.asarray(ids)
    for p in params:
        p.validate(spec)
    writes = [_fields(spec, idx, p) for p in params]
    for name in writes[0]:
        arr = batch.expand(name)
        for sim, w in zip(ids, writes, strict=True):
            for i, value in w[name]:
                arr[(sim, *i)] = value
    batch.set_const(ids)
