"""Reproduction rows {id, document, simulated, tolerance, pass} for the plant core (issue: plant core),
shared by scripts/reproduce.py and the tests. `document` is the document's number or, for the friction
rows, the stiff-ODE / analytic value of the same equations."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterator

import numpy as np

from . import checks, validation
from .identification import fit_m220_gain, m220_step_counts, two_point_step_id
from .plants import m220_eq22, plant_config, plant_spec

M220_CONFIGS = {
    "default": {},
    "npd72_npl18_4wl": {"configuration": {"n_pd": 72, "n_pl": 18, "brass_weights_load": 4}},
    "npd18_npl72_2wd_backlash": {
        "configuration": {"n_pd": 18, "n_pl": 72, "brass_weights_drive": 2, "backlash_device": True}
    },
    "npd36_npl36_4wd_4wl": {
        "configuration": {"n_pd": 36, "n_pl": 36, "brass_weights_drive": 4, "brass_weights_load": 4}
    },
}
FLEX_FREQS_HZ = (0.1, 0.3, 1.0, 1.78, 3.0, 10.0)
FRICTION_JOINTS = {"kang_robot": "rotor", "flexible_servo": "shaft1", "m220": "drive"}


def row(
    id_: str,
    document: float,
    simulated: float,
    tolerance: float,
    relative: bool = True,
    note: str = "",
    passed: bool | None = None,
) -> dict:
    """One report row; tolerance is relative (fraction) unless relative=False (absolute). `passed`
    overrides the distance test for rows whose criterion is stated in the note (nan: no printed number)."""
    if passed is None:
        err = abs(simulated - document) / abs(document) if relative else abs(simulated - document)
        passed = bool(np.isfinite(simulated) and err <= tolerance)
    return {
        "id": id_,
        "document": float(document),
        "simulated": float(simulated),
        "tolerance": f"{tolerance:g}{' rel' if relative else ' abs'}"
        if np.isfinite(tolerance)
        else "see note",
        "pass": bool(passed),
        "note": note,
    }


def m220_rows() -> Iterator[dict]:
    for name, ov in M220_CONFIGS.items():
        yield row(
            f"m220.reflected_inertia.{name}",
            m220_eq22(plant_config("m220", ov)),
            checks.m220_reflected_inertia_sim(ov),
            0.005,
            note="kg·m², eq. (22)",
        )
    idf = plant_config("m220")["identified"]
    t, y = tuple(idf["step_points_t_s"]), tuple(idf["step_points_counts"])
    sim = m220_step_counts(idf["gain_counts_per_v_s2"], t, idf["step_input_v"])
    for k in range(2):
        yield row(f"m220.step_point.{k + 1}", y[k], sim[k], 0.02, note=f"counts at t = {t[k]} s, §2.2")
    ident = two_point_step_id(t, tuple(sim), idf["step_input_v"])
    yield row(
        "m220.step_id.a", idf["document_a_per_s"], ident["a"], 0.05, note="1/s, two-point method on sim"
    )
    yield row("m220.step_id.k", idf["document_k_counts_per_v_s2"], ident["k"], 0.05, note="counts/(V·s²)")
    yield row(
        "m220.gain_fit.reproducible",
        idf["gain_counts_per_v_s2"],
        fit_m220_gain(t, y, idf["step_input_v"]),
        1e-3,
        note="config value vs a fresh fit",
    )


def flexible_rows() -> Iterator[dict]:
    spec = plant_spec("flexible_servo")
    f = np.array(FLEX_FREQS_HZ)
    G = np.array(checks.flexible_transfer(spec, 2j * np.pi * f)).T
    for label, resp in (("lin", checks.flexible_frf_linearized(f)), ("sine", checks.flexible_frf_sine(f))):
        for c, name in enumerate(("G1", "G2")):
            for i, fi in enumerate(f):
                yield row(
                    f"flexible.{name}.{fi:g}Hz.{label}.mag",
                    abs(G[i, c]),
                    abs(resp[i, c]),
                    0.01,
                    note="|G|, V/V",
                )
                yield row(
                    f"flexible.{name}.{fi:g}Hz.{label}.phase_deg",
                    0.0,
                    math.degrees(np.angle(resp[i, c] / G[i, c])),
                    1.0,
                    relative=False,
                    note="phase error vs G(jω), deg",
                )


def kang_rows() -> Iterator[dict]:
    spec = plant_spec("kang_robot")
    b = checks.kang_pd_bounds()
    # printed to 0.01 deg; K_p is the mean of the two printed bounds' implied values -> 0.05 deg
    yield row(
        "kang.theta_H_deg",
        spec.info["theta_H_deg"],
        b["theta_H_deg"],
        0.05,
        relative=False,
        note="simulated P-control ramp at 0.05 deg/s, §6",
    )
    yield row("kang.theta_L_deg", spec.info["theta_L_deg"], b["theta_L_deg"], 0.05, relative=False, note="")
    wn = math.sqrt(spec.info["kp_nm_per_rad"] / spec.joints[0].inertia) / (2 * math.pi)
    yield row("kang.natural_frequency_hz", spec.info["natural_frequency_hz"], wn, 0.01, note="sqrt(K_p/J)")
    lv = spec.joints[0].friction.levels()
    for key, rng in (("coulomb_pos", "coulomb_pos_range_nm"), ("coulomb_neg", "coulomb_neg_range_nm")):
        lo, hi = spec.info[rng]
        yield row(
            f"kang.{key}_nm",
            0.5 * (lo + hi),
            lv[key],
            0.5 * (hi - lo),
            relative=False,
            note="implied by the symmetric-LuGre + bias construction; document range",
        )


def friction_rows() -> Iterator[dict]:
    for plant, joint in FRICTION_JOINTS.items():
        spec = plant_spec(plant)
        p = spec.joints[spec.joint_index(joint)].friction
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
    r = validation.stickslip_period(spec, "rotor", spec.info["kp_nm_per_rad"], math.radians(1.0), 25.0)
    yield row(
        "friction.stickslip_period",
        r["reference"],
        r["simulated"],
        0.02,
        note="s, Kang rotor pulled by a K_p spring at 1 deg/s, vs Radau",
    )


SECTIONS: dict[str, Callable[[], Iterator[dict]]] = {
    "m220": m220_rows,
    "flexible": flexible_rows,
    "kang": kang_rows,
    "friction": friction_rows,
}


def all_rows(sections: list[str] | None = None) -> list[dict]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # scipy's numerical Jacobian on stiff LuGre
        return [r for s in (sections or list(SECTIONS)) for r in SECTIONS[s]()]
