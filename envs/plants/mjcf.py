"""MJCF text of a PlantSpec (see plants/spec.py for the modelling choices)."""

from __future__ import annotations

import math

from ..friction import Element, elements
from .spec import MAX_DELAY_PERIODS, JointSpec, PlantSpec

# The bodies' geoms are visual only: they touch nothing (no contact in any plant), so collision detection
# is switched off (the contact flag), which removes ~10 % of each step and changes no result.
# Each shaft (or carriage) body carries a tiny explicit inertia (MuJoCo needs one on moving bodies) and
# visual geoms with no mass; the joint's armature is the shaft inertia (or carriage mass) minus what the
# body adds to its dof (its rotational inertia for a hinge, its mass for a slide), so the total is the
# preset's J (or M).
VISUAL_MASS_KG, VISUAL_INERTIA = 1e-9, 1e-12  # kg, kg·m²
BODY_SPACING, DISK_RADIUS = 0.25, 0.08  # m: the bodies side by side along x, a hinge's disk (visual)


# A belt's constraint impedance: MuJoCo's default solimp rises from 0.9 to 0.95 as the constraint is
# violated, which made the M220's response depend on its amplitude (a few parts per million of the motion:
# the friction-free twin failed superposition, tests/test_optimum.py); held at its small-stretch 0.9, a
# belt is a linear spring-damper.
BELT_IMPEDANCE = 0.9

def body_share(j: JointSpec) -> float:
    """What the joint's body adds to its dof's inertia: kg·m² for a hinge, kg for a slide."""
    return VISUAL_MASS_KG if j.kind == "slide" else VISUAL_INERTIA


def _lugre(e: Element) -> str:
    return f'lugre="{e.sigma0!r} {e.sigma1!r} {e.fc!r} {e.fs!r} {e.vs!r}"'


def friction_joints(spec: PlantSpec) -> list[str]:
    """Joints that carry a friction actuator, in actuator order."""
    return [j.name for j in spec.joints if j.friction is not None]


def to_mjcf(spec: PlantSpec) -> str:
    """MJCF text of the plant. Actuator order: drive motor, each frictional joint's first friction element
    (friction_<joint>), the structure's further elements (friction_<joint>_<k>), rate feedback, load-side
    disturbance motor (its command is a torque in N·m)."""
    nsample = MAX_DELAY_PERIODS * spec.substeps + 2  # history for delays up to MAX_DELAY_PERIODS periods
    bodies, actuators, extra = [], [], []
    for j in spec.joints:
        coulomb = j.friction is not None and spec.friction_model == "coulomb"
        fl = j.friction.fc if coulomb else 0.0
        damping = j.viscous + j.friction.sigma2 if coulomb else j.viscous  # Coulomb + viscous
        slide = j.kind == "slide"
        shape = (
            '<geom type="box" size="0.04 0.03 0.02" mass="0" rgba="0.6 0.6 0.7 1"/>'
            '<geom type="box" pos="0 0 0.022" size="0.01 0.03 0.002" mass="0" rgba="0.9 0.3 0.2 1"/>'
            if slide
            else f'<geom type="cylinder" size="{DISK_RADIUS} 0.01" mass="0" rgba="0.6 0.6 0.7 1"/>'
            '<geom type="box" pos="0.05 0 0.012" size="0.03 0.005 0.002" mass="0" rgba="0.9 0.3 0.2 1"/>'
        )
        bodies.append(
            f'<body name="{j.name}" pos="{body_x(spec, j.name)} 0 0"><joint name="{j.name}" type="{j.kind}" '
            f'axis="{"1 0 0" if slide else "0 0 1"}" armature="{j.inertia - body_share(j)!r}" '
            f'damping="{damping!r}" frictionloss="{fl!r}"/><inertial pos="0 0 0" mass="{VISUAL_MASS_KG!r}" '
            f'diaginertia="{VISUAL_INERTIA!r} {VISUAL_INERTIA!r} {VISUAL_INERTIA!r}"/>{shape}</body>'
        )
    actuators.append(
        f'<motor name="drive" joint="{spec.actuator_joint}" gear="{spec.actuator_gain!r}" ctrllimited="true" '
        f'ctrlrange="{-spec.command_limit!r} {spec.command_limit!r}" nsample="{nsample}" interp="zoh" '
        f'delay="{spec.delay!r}"/>'
    )
    extras = []  # a structure's further elements, after every joint's first (which keeps its id)
    for j in spec.joints:
        p = j.friction
        if p is None:
            continue
        els = elements(spec.friction_model, p)
        lugre = f'{_lugre(els[0])} damping="{p.sigma2!r}" ' if els else ""
        actuators.append(
            f'<dcmotor name="friction_{j.name}" joint="{j.name}" input="none" resistance="1" '
            f'motorconst="0 0" {lugre}cogging="{p.bias!r} 0 {math.pi / 2!r}"/>'
        )
        extras += [
            f'<dcmotor name="friction_{j.name}_{k}" joint="{j.name}" input="none" resistance="1" '
            f'motorconst="0 0" {_lugre(e)}/>'
            for k, e in enumerate(els[1:], start=1)
        ]
    actuators += extras
    if spec.rate_feedback > 0 or spec.rate_loop:
        actuators.append(
            f'<velocity name="rate_feedback" joint="{spec.actuator_joint}" '
            f'kv="{max(spec.rate_feedback, 1e-12)!r}"/>'
        )
    if spec.disturbance_joint is not None:  # last, so the other actuators keep their ids
        actuators.append(f'<motor name="disturbance" joint="{spec.disturbance_joint}" gear="1"/>')
    for b in spec.belts:  # a constant impedance (solimp's small-stretch 0.9): a linear spring-damper
        extra.append(
            f'<equality><joint joint1="{b.driven}" joint2="{b.driver}" polycoef="0 {b.ratio!r} 0 0 0" '
            f'solimp="{BELT_IMPEDANCE} {BELT_IMPEDANCE} 0.001 0.5 2" solref="{spec.belt_timeconst!r} 1"/>'
            "</equality>"
        )
    for s in spec.springs:
        extra.append(
            f'<tendon><fixed name="spring_{s.a}_{s.b}" stiffness="{s.stiffness!r}" damping="{s.damping!r}">'
            f'<joint joint="{s.b}" coef="1"/><joint joint="{s.a}" coef="-1"/></fixed></tendon>'
        )
    return (
        f'<mujoco model="{spec.name}"><option timestep="{spec.timestep!r}" integrator="{spec.integrator}" '
        f'gravity="0 0 0"><flag contact="disable"/></option>{SCENERY_ASSETS}'
        f'<worldbody>{scenery(spec)}{"".join(bodies)}</worldbody>'
        f"<actuator>{''.join(actuators)}</actuator>{''.join(extra)}</mujoco>"
    )


# What a rendered frame shows besides the moving parts: a sky, a floor, a stand under each disk (a rail
# under the EMPS's carriage), the belts and the shaft spring, a light and a camera centred on the
# mechanism. All of it is fixed to the world and massless, touches nothing (contact is off): the dynamics
# are those of the bodies above alone.
SCENERY_ASSETS = (
    '<visual><global offwidth="640" offheight="480"/><headlight ambient="0.35 0.35 0.35"/></visual>'
    '<asset><texture name="sky" type="skybox" builtin="gradient" rgb1="0.92 0.94 0.97" rgb2="0.6 0.66 0.75" '
    'width="64" height="64"/><texture name="grid" type="2d" builtin="checker" rgb1="0.82 0.82 0.8" '
    'rgb2="0.74 0.74 0.72" width="256" height="256"/><material name="floor" texture="grid" '
    'texrepeat="8 8"/></asset>'
)
FLOOR_Z = -0.12  # m, below the disks (at z = 0)
STEEL, BELT = 'rgba="0.45 0.47 0.5 1"', 'rgba="0.15 0.15 0.15 1"'


def body_x(spec: PlantSpec, joint: str) -> float:
    """Where a joint's body sits along x (m): the bodies side by side in the spec's order."""
    return BODY_SPACING * spec.joint_index(joint)


def scenery(spec: PlantSpec) -> str:
    """The fixed, massless world geoms and the camera of a plant's frame (see SCENERY_ASSETS)."""
    span = BODY_SPACING * (len(spec.joints) - 1)  # m, from the first body to the last
    mid = span / 2
    parts = [
        f'<light pos="{mid} -0.3 1.0" dir="0 0.3 -1"/>',
        f'<geom type="plane" pos="{mid} 0 {FLOOR_Z}" size="{span / 2 + 0.35} 0.35 0.01" material="floor" '
        'mass="0"/>',
        f'<camera name="top" pos="{mid} {-0.42 - 0.55 * span} {0.32 + 0.35 * span}" '
        f'xyaxes="1 0 0 0 0.6 0.8"/>',
    ]
    h = (-FLOOR_Z - 0.01) / 2  # half height of a stand, floor to disk
    for j in spec.joints:
        x = body_x(spec, j.name)
        if j.kind == "slide":  # a rail along the carriage's travel
            parts.append(f'<geom type="box" pos="{x} 0 -0.03" size="0.3 0.02 0.01" mass="0" {STEEL}/>')
        else:
            parts.append(f'<geom type="cylinder" pos="{x} 0 {-0.01 - h}" size="0.012 {h}" mass="0" {STEEL}/>')
    for b in spec.belts:  # two straight runs between the pulleys
        x0, x1 = body_x(spec, b.driver), body_x(spec, b.driven)
        for y in (-0.07, 0.07):
            parts.append(
                f'<geom type="box" pos="{(x0 + x1) / 2} {y} 0" size="{abs(x1 - x0) / 2} 0.004 0.008" '
                f'mass="0" {BELT}/>'
            )
    for sp in spec.springs:  # the shaft between the two inertias
        x0, x1 = body_x(spec, sp.a), body_x(spec, sp.b)
        parts.append(
            f'<geom type="capsule" fromto="{x0 + DISK_RADIUS} 0 0 {x1 - DISK_RADIUS} 0 0" size="0.006" '
            'mass="0" '
            'rgba="0.95 0.6 0.1 1"/>'
        )
    return "".join(parts)
