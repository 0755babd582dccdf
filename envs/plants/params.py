"""Per-episode plant parameters: drawn from the preset's ranges with a seed, checked, and written into
an already compiled MjModel (or per simulation into a mujoco.batch.Batch) without recompiling."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from itertools import product
from typing import Any

import mujoco
import numpy as np

from ..config import ConfigError, nonneg, number, positive
from ..friction import BRISTLE_MODELS, LuGreParams, check_numerics, element_count, elements
from ..sampler import stream
from .mjcf import body_share, friction_joints
from .spec import MAX_DELAY_PERIODS, RANDOMIZATION_KEYS, PlantSpec

# keys drawn once per frictional joint
PER_JOINT = ("friction_scale", "asymmetry_shift", "sigma0_scale", "stribeck_velocity_scale", "viscous_scale")


def history_delay(steps: int, timestep: float) -> float:
    """The actuator_delay (s) that applies the command given `steps` physics steps ago. MuJoCo's
    zero-order hold reads its history at time − delay; a delay of exactly steps·timestep lands on a stored
    timestamp, where the rounding of the accumulated time picks the sample steps or steps + 1 back (on a
    0.5 ms step it switched from 3 to 4 after 32,000 steps, 16 s: tests/test_sim.py). Half a step less
    reads the same sample at every step."""
    return (steps - 0.5) * timestep if steps > 0 else 0.0


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
    def from_values(cls, spec: PlantSpec, values: Mapping[str, Any]) -> EpisodeParams:
        """The nominal parameters changed by randomization-key values (spec.RANDOMIZATION_KEYS): scales are
        factors, asymmetry_shift a fraction of the symmetric Coulomb level, delay_s / jitter_s seconds.
        The friction keys take one value for all frictional joints or a sequence, one per joint."""
        unknown = sorted(set(values) - set(RANDOMIZATION_KEYS))
        if unknown:
            raise ConfigError(
                "params", f"unknown parameter(s) {unknown}; allowed: {sorted(RANDOMIZATION_KEYS)}"
            )
        base = cls.nominal(spec)
        nf = len(base.friction)

        def per_joint(key: str, default: float) -> list[float]:
            v = values.get(key, default)
            v = list(v) if isinstance(v, list | tuple | np.ndarray) else [v] * nf
            if len(v) != nf:
                raise ConfigError(f"params.{key}", f"expected 1 or {nf} values (one per friction joint)")
            return [number(x, f"params.{key}") for x in v]

        def one(key: str, default: float) -> float:
            return number(values.get(key, default), f"params.{key}")

        level, shift = per_joint("friction_scale", 1.0), per_joint("asymmetry_shift", 0.0)
        s0, vs = per_joint("sigma0_scale", 1.0), per_joint("stribeck_velocity_scale", 1.0)
        visc = per_joint("viscous_scale", 1.0)
        friction = tuple(
            p.scaled(
                level=level[i], sigma0=s0[i], vs=vs[i], viscous=visc[i], extra_bias=shift[i] * p.fc * level[i]
            )
            for i, p in enumerate(base.friction)
        )
        inertia, spring = one("inertia_scale", 1.0), one("spring_scale", 1.0)
        return replace(
            base,
            friction=friction,
            inertia=tuple(x * inertia for x in base.inertia),
            spring_stiffness=tuple(x * spring for x in base.spring_stiffness),
            delay=one("delay_s", spec.delay),
            noise_scale=one("noise_scale", 1.0),
            jitter=one("jitter_s", spec.jitter),
        )

    @classmethod
    def draw_values(cls, spec: PlantSpec, seed: int) -> dict[str, Any]:
        """One value per randomization key of the preset (per friction joint for the friction keys), each
        from its own named stream of the seed (envs/sampler.py)."""
        nf = len(friction_joints(spec))
        out: dict[str, Any] = {}
        for key, (lo, hi) in spec.randomization.items():
            rng = stream(seed, key)
            out[key] = (
                tuple(float(x) for x in rng.uniform(lo, hi, nf))
                if key in PER_JOINT
                else float(rng.uniform(lo, hi))
            )
        return out

    @classmethod
    def draw(cls, spec: PlantSpec, seed: int, pinned: Mapping[str, Any] | None = None) -> EpisodeParams:
        """The episode's parameters: drawn from the preset's ranges with the seed, then `pinned` values
        (randomization keys, e.g. {"friction_scale": 1.3}) replace the drawn ones."""
        return cls.from_values(spec, {**cls.draw_values(spec, seed), **(pinned or {})})

    def friction_free(self) -> EpisodeParams:
        """The same episode on the friction-free twin (LuGreParams.friction_free on every joint)."""
        return replace(self, friction=tuple(f.friction_free() for f in self.friction))

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
        span = MAX_DELAY_PERIODS * spec.control_period
        number(self.delay, "params.delay", 0.0, span)
        number(self.jitter, "params.jitter", 0.0, span - self.delay)
        nonneg(self.noise_scale, "params.noise_scale")
        scaled = spec_with(spec, self)
        for name, p in zip(names, self.friction, strict=True):
            p.validate(f"params.friction[{name}]")
            if spec.friction_model in BRISTLE_MODELS:  # the elements' stiffness and damping sum to σ0, σ1
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
    friction: tuple[int, ...]  # each frictional joint's first friction actuator (bias, σ2, element 0)
    elements: tuple[tuple[int, int, int], ...]  # (actuator id, frictional joint, k) per LuGre element
    rate: int  # rate-feedback actuator id or -1
    disturbance_ctrl: int  # ctrl index of the load-side disturbance motor or -1
    dofs: tuple[int, ...]
    tendons: tuple[int, ...]

    @classmethod
    def of(cls, model: mujoco.MjModel, spec: PlantSpec) -> ModelIndex:
        aid = lambda n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n)  # noqa: E731
        drive = aid("drive")
        names, n = friction_joints(spec), element_count(spec.friction_model)
        first = tuple(aid(f"friction_{j}") for j in names)
        return cls(
            drive=drive,
            drive_ctrl=int(model.actuator_ctrladr[drive]),
            friction=first,
            elements=(tuple((a, i, 0) for i, a in enumerate(first)) if n else ())
            + tuple((aid(f"friction_{j}_{k}"), i, k) for k in range(1, n) for i, j in enumerate(names)),
            rate=aid("rate_feedback"),
            disturbance_ctrl=int(model.actuator_ctrladr[aid("disturbance")])
            if aid("disturbance") >= 0
            else -1,
            dofs=tuple(
                int(model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j.name)])
                for j in spec.joints
            ),
            tendons=tuple(
                mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, f"spring_{s.a}_{s.b}")
                for s in spec.springs
            ),
        )

    def joint_forces(self, force: np.ndarray) -> np.ndarray:
        """Per frictional joint, the sum of its friction actuators' forces from actuator forces (..., nu):
        the first element's (which carries the bias), then the structure's further elements in order."""
        out = force[..., list(self.friction)]
        extras = [(a, i) for a, i, k in self.elements if k > 0]
        if extras:
            out = out.copy()
            for a, i in extras:
                out[..., i] += force[..., a]
        return out


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
    for d, j, J, c in zip(idx.dofs, spec.joints, p.inertia, p.viscous, strict=True):
        w["dof_armature"].append(((d,), J - body_share(j)))
        w["dof_damping"].append(((d,), c))
    fdofs = [idx.dofs[spec.joint_index(n)] for n in friction_joints(spec)]
    els = [elements(spec.friction_model, f) for f in p.friction]
    for a, d, f in zip(idx.friction, fdofs, p.friction, strict=True):
        w["actuator_biasprm"] += [((a, 0), f.bias), ((a, 1), 0.0), ((a, 2), math.pi / 2)]
        if spec.friction_model in BRISTLE_MODELS:
            w["actuator_damping"].append(((a,), f.sigma2))
        elif spec.friction_model == "coulomb":  # Coulomb + viscous, as in the documents
            w["dof_frictionloss"].append(((d,), f.fc))
            w["dof_damping"].append(((d,), p.viscous[idx.dofs.index(d)] + f.sigma2))
    for a, i, k in idx.elements:
        e = els[i][k]
        w["actuator_dynprm"] += [((a, 5), e.sigma0), ((a, 6), e.sigma1)]
        w["actuator_biasprm"] += [((a, 3), e.fc), ((a, 4), e.fs), ((a, 5), e.vs)]
    w["actuator_gear"].append(((idx.drive, 0), p.actuator_gain))
    w["actuator_delay"].append(((idx.drive,), history_delay(p.delay_steps(spec), spec.timestep)))
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


def check_randomization(spec: PlantSpec) -> None:
    """Reject randomization ranges some draw of which fails the physical or numerics checks: every corner
    of the ranges (all low/high combinations of the keys the checks depend on; the checks are monotone in
    each key) is built and validated, so no seed can be rejected at reset. The error names the key alone
    when one key's range fails by itself, else the keys whose corner fails. A spec that passed is
    remembered by its repr (a PlantSpec holds plain numbers, tuples and dicts), so loading the same
    scenario again does not build its corners again."""
    memo = repr(spec)
    if memo in _ADMISSIBLE:
        return
    keys = [k for k in spec.randomization if k not in ("noise_scale", "delay_s", "jitter_s")]

    def fails(values: dict[str, float]) -> str | None:
        try:
            EpisodeParams.from_values(spec, values).validate(spec)
        except ConfigError as e:
            return str(e)
        return None

    for key in keys:
        for end in spec.randomization[key]:
            if (why := fails({key: end})) is not None:
                raise ConfigError(f"randomization.{key}", f"the draw at {end} fails a check ({why})")
    for corner in product(*(spec.randomization[k] for k in keys)):
        values = dict(zip(keys, corner, strict=True))
        if (why := fails(values)) is not None:
            raise ConfigError(
                "randomization", f"the draw at the corner {values} fails a check ({why}); narrow the ranges"
            )
    _ADMISSIBLE.add(memo)


_ADMISSIBLE: set[str] = set()  # reprs of the specs check_randomization passed, in this process


def rejected_draws(spec: PlantSpec, seeds: Iterable[int]) -> list[tuple[int, str]]:
    """The seeds whose drawn parameters fail validate() (what reset would refuse), with the reason.
    check_randomization makes this empty for any spec that loads; scripts/check_draws.py counts it over
    many seeds as an empirical check of that guarantee."""
    out = []
    for seed in seeds:
        try:
            EpisodeParams.draw(spec, seed).validate(spec)
        except ConfigError as e:
            out.append((seed, str(e)))
    return out
