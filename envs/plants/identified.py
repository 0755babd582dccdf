"""Friction identified from data, as a plant sees it: the drive-referred steady-state friction of a plant
(`drive_friction`, the truth of a simulated plant) and the override that replaces a preset's friction by
identified values (`IdentifiedFriction`, the preset's `friction_identified` section, `apply_identified`).
The lab (agents/lab/fits.py) fits these values; the plants only read them.

Units: command units "cu" (V or N·m, the plant's command), rad/s; every level is a magnitude.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

from ..config import ConfigError, Node, positive
from ..friction import LuGreParams
from .spec import PlantSpec


@dataclass(frozen=True)
class DriveFriction:
    """Drive-referred steady-state friction in command units (magnitudes) and rad/s: what the friction
    experiments measure, computed from a PlantSpec (the truth of a simulated plant)."""

    coulomb_pos: float
    coulomb_neg: float
    static_pos: float
    static_neg: float
    stribeck_velocity: float
    viscous: float
    sigma0: float  # drive-referred bristle stiffness (cu/rad)


def speed_ratios(spec: PlantSpec) -> dict[str, float]:
    """Each joint's steady-state speed per drive speed: belt ratios, 1 for spring-coupled joints."""
    belt = spec.kinematic_ratios()
    r0 = belt.get(spec.actuator_joint, 1.0)
    return {j.name: belt.get(j.name, 1.0) / r0 for j in spec.joints}


def drive_friction(spec: PlantSpec) -> DriveFriction:
    """The truth: u_ss(v)·G = Σ_j r_j·(sgn(v)·g_j(r_j·v) - b_j) + Σ_j (σ2_j + c_j)·r_j²·v over the joints
    (speed ratio r_j)."""
    r, g = speed_ratios(spec), spec.actuator_gain
    fr = [(j, r[j.name]) for j in spec.joints if j.friction is not None]
    if not fr:
        raise ConfigError("friction", f"plant {spec.name} has no friction to identify")
    f = [(j.friction, rj) for j, rj in fr]
    drops = [rj * (p.fs - p.fc) for p, rj in f]
    # the Stribeck velocity of the lumped map: exact for one friction joint or equal vs_j/r_j; otherwise
    # the drop-weighted mean (nan without a Stribeck drop, where it does not matter)
    vs = (
        sum(d * p.vs / rj for d, (p, rj) in zip(drops, f, strict=True)) / sum(drops)
        if sum(drops) > 0
        else math.nan
    )
    return DriveFriction(
        stribeck_velocity=vs,
        coulomb_pos=sum(rj * (p.fc - p.bias) for p, rj in f) / g,
        coulomb_neg=sum(rj * (p.fc + p.bias) for p, rj in f) / g,
        static_pos=sum(rj * (p.fs - p.bias) for p, rj in f) / g,
        static_neg=sum(rj * (p.fs + p.bias) for p, rj in f) / g,
        viscous=sum(
            (j.viscous + (j.friction.sigma2 if j.friction else 0.0)) * r[j.name] ** 2 for j in spec.joints
        )
        / g,
        sigma0=sum(p.sigma0 * rj**2 for p, rj in f) / g,
    )


@dataclass(frozen=True)
class IdentifiedFriction:
    """Identified drive-referred friction (command units, rad/s), the preset's `friction_identified`
    section: Coulomb levels and the viscous slope are required; static levels default to the Coulomb
    ones, the Stribeck velocity and σ0 to the preset's (None)."""

    coulomb_pos: float
    coulomb_neg: float
    viscous_per_rad_s: float  # cu·s/rad
    static_pos: float | None = None
    static_neg: float | None = None
    stribeck_velocity_rad_s: float | None = None
    sigma0_per_rad: float | None = None  # cu/rad

    REQUIRED = ("coulomb_pos", "coulomb_neg", "viscous_per_rad_s")

    @classmethod
    def from_values(cls, values: Mapping[str, float], node: Node | None = None) -> IdentifiedFriction:
        """Checked values (positive, static levels not below the Coulomb ones); errors name the key
        (and `node`'s file, when read from a preset)."""
        names = [f.name for f in fields(cls)]

        def error(key: str, message: str) -> ConfigError:
            return node.error(key, message) if node is not None else ConfigError(key, message)

        for key in values:
            if key not in names:
                raise error(key, f"unknown identified value; known: {names}")
        for key in cls.REQUIRED:
            if key not in values:
                raise error(key, "required")
        if node is None:
            out = {key: positive(v, key) for key, v in values.items()}
        else:
            out = {key: node.check(positive, v, node.field(key)) for key, v in values.items()}
        ident = cls(**out)
        for d in ("pos", "neg"):
            static, coulomb = getattr(ident, f"static_{d}"), getattr(ident, f"coulomb_{d}")
            if static is not None and static < coulomb:
                raise error(f"static_{d}", f"{static} is below coulomb_{d} {coulomb}")
        return ident

    @classmethod
    def from_section(cls, cfg: Node) -> IdentifiedFriction | None:
        """The preset's optional `friction_identified` section (scripts/identify.py writes it), or None."""
        node = cfg.section("friction_identified", optional=True)
        if not list(node.keys()):
            return None
        names = [f.name for f in fields(cls)]
        values = {k: node.get(k) for k in names if k in node}  # checked once, by from_values
        node.get("source")  # provenance, kept in the file
        node.done()
        return cls.from_values(values, node)

    def as_dict(self) -> dict[str, float]:
        """The values that are set (what identified.yaml holds)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}


def apply_identified(spec: PlantSpec, ident: IdentifiedFriction) -> PlantSpec:
    """The spec with its friction replaced by identified drive-referred values.
    The levels are shared among the friction joints as in the preset (a lumped measurement cannot split
    them: the flexible servo keeps its F1 = F2 of §3.2); σ1 keeps the preset's damping ratio; joint
    damping c_j is kept and σ2 takes the rest of the viscous slope."""
    nominal, r, g = drive_friction(spec), speed_ratios(spec), spec.actuator_gain
    fr = [j for j in spec.joints if j.friction is not None]
    share = {
        j.name: r[j.name] * j.friction.fc / g / (0.5 * (nominal.coulomb_pos + nominal.coulomb_neg))
        for j in fr
    }
    damping = sum(j.viscous * r[j.name] ** 2 for j in spec.joints) / g
    sigma2_total = max(ident.viscous_per_rad_s - damping, 0.0) * g  # N·m·s/rad at the drive
    s0 = ident.sigma0_per_rad
    static_pos = ident.coulomb_pos if ident.static_pos is None else ident.static_pos
    static_neg = ident.coulomb_neg if ident.static_neg is None else ident.static_neg
    vs = ident.stribeck_velocity_rad_s
    if vs is None and math.isfinite(nominal.stribeck_velocity):
        vs = nominal.stribeck_velocity
    joints = []
    for j in spec.joints:
        if j.friction is None:
            joints.append(j)
            continue
        w, rj, p = share[j.name], r[j.name], j.friction
        sigma0 = p.sigma0 if s0 is None else s0 * g * w / rj**2
        new = LuGreParams.from_levels(
            fc_pos=w * ident.coulomb_pos * g / rj,
            fc_neg=w * ident.coulomb_neg * g / rj,
            fs_pos=w * static_pos * g / rj,
            fs_neg=w * static_neg * g / rj,
            vs=p.vs if vs is None else vs * rj,
            sigma0=sigma0,
            sigma1=p.sigma1 * math.sqrt(sigma0 / p.sigma0),
            sigma2=w * sigma2_total / rj**2,
        )
        joints.append(replace(j, friction=new))
    return replace(spec, joints=tuple(joints))
