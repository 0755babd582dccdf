"""Each plant's MuJoCo LuGre element against an independent stiff-ODE (Radau) solution of the same
equations (seed 000 §1.4.6; envs/validation.py): break-away both ways, presliding, sliding at five
speeds both ways, and a stick-slip period on Kang's rotor."""

from __future__ import annotations

from collections.abc import Iterator

from frictiongym.envs import validation
from frictiongym.envs.plants import plant_names, plant_spec
from frictiongym.envs.units import deg_to_rad

from . import Section, row


def rows(_: None) -> Iterator[dict]:
    for plant in plant_names():  # each plant's friction element, on its actuated joint
        spec = plant_spec(plant)
        joint, p = spec.actuator_joint, spec.drive_friction
        for d, name in ((1, "pos"), (-1, "neg")):
            r = validation.breakaway(spec, joint, d)
            yield row(
                f"friction.breakaway.{plant}.{name}",
                r["reference"],
                r["simulated"],
                0.02,
                note="N·m vs Radau",
            )
        r = validation.presliding(spec, joint)
        yield row(f"friction.presliding.{plant}", r["reference"], r["simulated"], 0.02, note="rad vs Radau")
        for mult in (0.5, 1.0, 2.0, 5.0, 20.0):
            for sg in (1, -1):
                r = validation.sliding(spec, joint, sg * mult * p.vs)
                yield row(
                    f"friction.sliding.{plant}.{sg * mult:g}vs",
                    r["reference"],
                    r["simulated"],
                    0.02,
                    note=f"N·m at v = {r['velocity']:.4g} rad/s vs analytic steady state",
                )
    spec = plant_spec("kang_robot")
    r = validation.stickslip_period(spec, "rotor", spec.document.kp_nm_per_rad, deg_to_rad(1.0), 25.0)
    yield row(
        "friction.stickslip_period",
        r["reference"],
        r["simulated"],
        0.02,
        note="s, Kang rotor pulled by a K_p spring at 1 deg/s, vs Radau",
    )


SECTION = Section("friction", "friction_validation", lambda: None, rows)
