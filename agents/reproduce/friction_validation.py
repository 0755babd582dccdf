"""Each plant's native friction elements against an independent stiff-ODE (Radau) solution of the same
equations (agents/lab/radau.py), for every bristle structure (Iurian et al. 2005: LuGre §1.4.6, Dahl §1.4.1,
Maxwell-slip §1.4.7; Kang 1998's stick-slip model): break-away both ways, presliding, sliding at several
speeds both ways, and the stick-slip period on Kang's rotor (none for Dahl, which has no drop from static
to Coulomb level)."""

from __future__ import annotations

import math
from collections.abc import Iterator

from frictiongym.agents.lab import radau
from frictiongym.envs.friction import BRISTLE_MODELS
from frictiongym.envs.plants import plant_names, plant_spec
from frictiongym.envs.units import deg_to_rad

from .report import Section, row

# sliding speeds (multiples of v_s): LuGre at five, the other structures at three
SPEEDS = {
    "lugre": (0.5, 1.0, 2.0, 5.0, 20.0),
    "dahl": (0.5, 2.0, 20.0),
    "maxwell_slip": (0.5, 2.0, 20.0),
    "kang": (0.5, 2.0, 20.0),  # past its drop (within the stick band, 0.01 v_s): the Coulomb level
}


def _prefix(model: str) -> str:
    """Row ids: friction.<kind>... for LuGre (as before), friction.<model>.<kind>... for the others."""
    return "friction" if model == "lugre" else f"friction.{model}"


def rows(_: None) -> Iterator[dict]:
    for model in BRISTLE_MODELS:
        pre = _prefix(model)
        for plant in plant_names():  # each plant's friction elements, on its actuated joint
            spec = plant_spec(plant, friction_model=model)
            joint, p = spec.actuator_joint, spec.drive_friction
            for d, name in ((1, "pos"), (-1, "neg")):
                r = radau.breakaway(spec, joint, d)
                yield row(
                    f"{pre}.breakaway.{plant}.{name}",
                    r["reference"],
                    r["simulated"],
                    0.02,
                    note="N·m vs Radau",
                )
            r = radau.presliding(spec, joint)
            yield row(f"{pre}.presliding.{plant}", r["reference"], r["simulated"], 0.02, note="rad vs Radau")
            for mult in SPEEDS[model]:
                for sg in (1, -1):
                    r = radau.sliding(spec, joint, sg * mult * p.vs)
                    yield row(
                        f"{pre}.sliding.{plant}.{sg * mult:g}vs",
                        r["reference"],
                        r["simulated"],
                        0.02,
                        note=f"N·m at v = {r['velocity']:.4g} rad/s vs analytic steady state",
                    )
        spec = plant_spec("kang_robot", friction_model=model)
        r = radau.stickslip_period(spec, "rotor", spec.document.kp_nm_per_rad, deg_to_rad(1.0), 25.0)
        note = "s, Kang rotor pulled by a K_p spring at 1 deg/s, vs Radau"
        if model == "dahl":  # no stick-slip in either: the criterion is the absence of a cycle
            none = math.isnan(r["simulated"]) and math.isnan(r["reference"])
            yield row(
                f"{pre}.stickslip_period", math.nan, math.nan, math.nan, passed=none, note=note + ": no cycle"
            )
        else:
            yield row(f"{pre}.stickslip_period", r["reference"], r["simulated"], 0.02, note=note)


SECTION = Section("friction", "friction_validation", lambda: None, rows)
