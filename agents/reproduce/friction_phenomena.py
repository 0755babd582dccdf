"""The friction phenomena of Iurian et al. 2005 §1.3, measured on the simulator for each friction structure
(on Kang's rotor: its preset's static curve and bristles, envs/friction.py's structures), one row per
structure and phenomenon with a criterion explained by the structure's equations, a figure per phenomenon, and
the survey-style table of who shows what (the findings).

- presliding (§1.3.1): torque 0.5·F_s·sin(π t) for 4 s; displacement peak to peak in presliding lengths
  F_s/σ0 and the F-θ loop's area over its bounding box (last cycle).
- frictional lag (§1.3.2): velocity servoed to v_s·(1.5 + sin(2π f t)); mean friction accelerating minus
  decelerating at equal speed, over F_c (last cycle), at f = 1 and 10 Hz.
- varying break-away (§1.3.3): peak friction while |ω| <= v_s under torque ramps at 0.2 and 20 F_s per s,
  over the direction's static level.
- stick-slip (§1.3.4): the rotor pulled through a K_p spring at 1 deg/s (slip onsets, agents/lab/radau.py).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from frictiongym.agents.lab import radau
from frictiongym.envs.friction import STRUCTURES, joint_levels
from frictiongym.envs.plants import PlantSpec, plant_spec
from frictiongym.envs.records import pyplot
from frictiongym.envs.units import deg_to_rad

from ..figures import save_figure
from .report import Section, row

# native (envs.friction.STRUCTURES): the simulator's plants
REFERENCE = tuple(radau.REFERENCE_STRUCTURES)  # reference implementations only (never a plant)
ALL = STRUCTURES + REFERENCE
LAG_FREQUENCIES_HZ = (1.0, 10.0)
RAMP_RATES = (0.2, 20.0)  # F_s per second
PRESLIDING_BOUNDS = (0.1, 10.0)  # a bounded, spring-like displacement, in presliding lengths F_s/σ0
LIGHT_SIGMA1 = 0.1  # LuGre with σ1 = 0.1·g(v̄)/v̄: the damping term no longer outweighs the lag of z


def rig_spec(structure: str, sigma1: float | None = None) -> PlantSpec:
    """Kang's rotor with a structure (a reference-only one: the LuGre preset, whose levels it takes)."""
    spec = plant_spec("kang_robot", friction_model="lugre" if structure in REFERENCE else structure)
    if sigma1 is None:
        return spec
    j = replace(spec.joints[0], friction=replace(spec.joints[0].friction, sigma1=sigma1))
    return replace(spec, joints=(j,))


def _levels(structure: str, spec: PlantSpec) -> tuple[float, float, float]:
    """(F_c, F_s, b) of the structure: the native elements' sums; the reference ones take the preset's."""
    p = spec.drive_friction
    return (p.fc, p.fs, p.bias) if structure in REFERENCE else joint_levels(structure, p)


def _run(structure: str, spec: PlantSpec, torque: radau.Torque, t_end: float) -> dict[str, np.ndarray]:
    """The rotor under T(t, θ) from rest: MuJoCo for a native structure, the reference implementation else."""
    if structure in REFERENCE:
        return radau.reference_run(structure, spec.drive_friction, rig_inertia(spec), torque, t_end)
    return radau.Rig(spec, "rotor").run(torque, t_end)


def presliding(structure: str, spec: PlantSpec) -> dict[str, np.ndarray | float]:
    p = spec.drive_friction
    fs = _levels(structure, spec)[1]
    sim = _run(structure, spec, lambda t, th: 0.5 * fs * np.sin(np.pi * t), 4.0)
    last = sim["t"] > 2.0
    th, f = sim["theta"][last], -sim["friction"][last]
    pp = float(th.max() - th.min())
    area = abs(float(np.trapezoid(f, th))) / ((f.max() - f.min()) * pp)
    return {"theta": th, "friction": f, "lengths": pp / (fs / p.sigma0), "area": area}


def lag(structure: str, spec: PlantSpec, f_hz: float) -> dict[str, np.ndarray | float]:
    p = spec.drive_friction
    fc = _levels(structure, spec)[0]
    t_end = 2.0 + 1.0 / f_hz

    def velocity(t: float) -> float:
        return p.vs * (1.5 + np.sin(2 * np.pi * f_hz * t))

    if structure in REFERENCE:
        r = radau.reference_friction_along(structure, p, velocity, t_end)
        o = np.column_stack([r["t"], r["v"], -r["friction"], np.cos(2 * np.pi * f_hz * r["t"])])
    else:
        rig = radau.Rig(spec, "rotor", velocity_servo_gain=0.8 * rig_inertia(spec) / spec.timestep)
        m, d = rig.model, rig.data
        out = []
        for _ in range(round(t_end / spec.timestep)):
            d.ctrl[1] = velocity(d.time)
            mujoco.mj_step(m, d)
            out.append((d.time, d.qvel[0], -rig.friction(), np.cos(2 * np.pi * f_hz * d.time)))
        o = np.array(out)
    o = o[o[:, 0] > 2.0]
    up, down = o[o[:, 3] > 0], o[o[:, 3] < 0]
    grid = np.linspace(0.7, 2.3, 30) * p.vs
    fu = np.interp(grid, *up[np.argsort(up[:, 1])][:, 1:3].T)
    fd = np.interp(grid, *down[np.argsort(down[:, 1])][:, 1:3].T)
    return {"v": o[:, 1], "friction": o[:, 2], "width": float(np.mean(fu - fd)) / fc}


def rig_inertia(spec: PlantSpec) -> float:
    return spec.reflected_inertia("rotor")


def breakaway(structure: str, spec: PlantSpec, rate: float) -> float:
    """Peak |friction| while |ω| <= v_s under a torque ramp of rate·F_s per s, over F_s - b."""
    fs, bias = _levels(structure, spec)[1:]
    sim = _run(structure, spec, lambda t, th: rate * fs * t, 1.5 / rate)
    stick = np.abs(sim["omega"]) <= spec.drive_friction.vs
    return float(np.max(np.abs(sim["friction"][stick]))) / (fs - bias)


def stickslip(structure: str, spec: PlantSpec) -> dict[str, np.ndarray | float]:
    kp, pull = spec.document.kp_nm_per_rad, deg_to_rad(1.0)
    sim = _run(structure, spec, lambda t, th: kp * (pull * t - th), 25.0)
    every = max(1, len(sim["t"]) // 50_000)  # the figure's points
    period = radau._period(sim["t"], sim["omega"], pull)
    return {"t": sim["t"][::every], "omega": sim["omega"][::every], "period": period}


@dataclass
class Measured:
    presliding: dict[str, dict]
    lag: dict[tuple[str, float], dict]
    breakaway: dict[tuple[str, float], float]
    stickslip: dict[str, dict]
    light_lag: dict[float, float]
    light_sigma1: float


def run() -> Measured:
    specs = {s: rig_spec(s) for s in ALL}
    p = specs["lugre"].drive_friction
    vbar = 1.5 * p.vs
    light = LIGHT_SIGMA1 * float(p.g(vbar)) / vbar
    return Measured(
        presliding={s: presliding(s, specs[s]) for s in ALL},
        lag={(s, f): lag(s, specs[s], f) for s in ALL for f in LAG_FREQUENCIES_HZ},
        breakaway={(s, r): breakaway(s, specs[s], r) for s in ALL for r in RAMP_RATES},
        stickslip={s: stickslip(s, specs[s]) for s in ALL},
        light_lag={f: lag("lugre", rig_spec("lugre", light), f)["width"] for f in LAG_FREQUENCIES_HZ},
        light_sigma1=light,
    )


def _lag_sign(structure: str) -> float:
    """The sign of the lag the equations predict at v̄ = 1.5·v_s: F = g + (u - 1)·(g - σ1·v) with
    u = σ0·z/g > 1 while accelerating through the Stribeck drop, so the friction is higher accelerating
    only where σ1·v̄ < g(v̄); none where g is constant (Dahl; Kang's model, whose drop lies within its
    stick band, far below v̄), there is no state (Coulomb) or the law is rate independent in sliding (the
    reference-only Bliman-Sorine and reset integrator: F depends on the path, not the speed)."""
    if structure in ("dahl", "kang", "coulomb", *REFERENCE):
        return 0.0
    p = rig_spec(structure).drive_friction
    vbar = 1.5 * p.vs
    return float(np.sign(float(p.g(vbar)) - p.sigma1 * vbar))


def rows(m: Measured) -> Iterator[dict]:
    lo, hi = PRESLIDING_BOUNDS
    for s in ALL:
        x = m.presliding[s]["lengths"]
        bristles = s != "coulomb"  # the reference-only structures too: a spring up to their slip
        how = (
            "the spring of the bristles (the reference model's state), bounded in [0.1, 10]"
            if bristles
            else "MuJoCo's soft frictionloss constraint creeps, > 10 (no presliding spring, unbounded)"
        )
        yield row(
            f"phenomena.presliding.{s}",
            float("nan"),
            x,
            float("nan"),
            passed=(lo <= x <= hi) if bristles else x > hi,
            note=f"peak-to-peak displacement at 0.5 F_s, in F_s/σ0 (loop area {m.presliding[s]['area']:.2f} "
            f"of its box): {how}",
        )
    for s in ALL:
        sign = _lag_sign(s)
        for f in LAG_FREQUENCIES_HZ:
            w = m.lag[(s, f)]["width"]
            ok = abs(w) < 1e-3 if sign == 0 else (np.sign(w) == sign and abs(w) > 1e-3)
            yield row(
                f"phenomena.lag.{s}.{f:g}hz",
                float("nan"),
                w,
                float("nan"),
                passed=bool(ok),
                note=f"(F_up - F_down)/F_c; predicted sign {sign:+.0f} (sign of g - σ1·v̄; 0: none)",
            )
    for f in LAG_FREQUENCIES_HZ:
        w = m.light_lag[f]
        yield row(
            f"phenomena.lag.lugre_light_sigma1.{f:g}hz",
            float("nan"),
            w,
            float("nan"),
            passed=w > 1e-3,
            note=f"σ1 = {m.light_sigma1:.3g} N·m·s/rad (0.1 g/v̄): higher accelerating, the survey's lag",
        )
    for s in STRUCTURES:
        slow, fast = (m.breakaway[(s, r)] for r in RAMP_RATES)
        d = slow - fast
        if s in ("dahl", "coulomb"):
            ok, why = abs(d) < 0.01, "rate independent (Dahl's dF/dx depends on x alone; Coulomb: no state)"
        elif s == "maxwell_slip":
            ok, why = d > 0.05, "rises as the rate falls: the long elements reach their peak only when slow"
        elif s == "kang":
            ok, why = (
                d > 0.05,
                (
                    "rises as the rate falls: the presliding velocity (~ force rate / σ0) enters the narrow "
                    "stick band's drop before the bristle reaches F_s"
                ),
            )
        else:
            ok, why = abs(d) < 0.02, "within 2 %: no marked rate dependence with the preset's bristles"
        yield row(
            f"phenomena.breakaway.{s}",
            float("nan"),
            d,
            float("nan"),
            passed=bool(ok),
            note=f"break-away at 0.2 minus at 20 F_s/s, over F_s - b ({slow:.3f} vs {fast:.3f}): {why}",
        )
    for s in (*STRUCTURES, "reset_integrator"):  # Bliman-Sorine's stiction is a transient in space
        period = m.stickslip[s]["period"]
        drop = s in ("lugre", "maxwell_slip", "kang", "reset_integrator")  # static level above Coulomb
        yield row(
            f"phenomena.stickslip.{s}",
            float("nan"),
            period,
            float("nan"),
            passed=bool(np.isfinite(period)) if drop else bool(np.isnan(period)),
            note="period (s) of the spring-pulled cycle; "
            + ("F_s > F_c: a cycle" if drop else "F_s = F_c: none (nan)"),
        )


def figures(m: Measured, out: Path) -> list[str]:
    plt = pyplot()

    names = []
    fig, ax = plt.subplots(figsize=(6, 4))
    for s in ALL:
        r = m.presliding[s]
        ax.plot(r["theta"] * 1e6, r["friction"], label=s, ls="--" if s in REFERENCE else "-")
    ax.set(xlabel="θ (µrad)", ylabel="friction (N·m)", title="presliding at 0.5 F_s (Kang's rotor)")
    ax.legend()
    names.append(save_figure(fig, out, "phenomena_presliding.png"))
    fig, axes = plt.subplots(1, 2, figsize=(9, 4), sharey=True)
    for ax, f in zip(axes, LAG_FREQUENCIES_HZ, strict=True):
        for s in ALL:
            r = m.lag[(s, f)]
            ax.plot(r["v"], r["friction"], label=s, ls="--" if s in REFERENCE else "-")
        ax.set(xlabel="v (rad/s)", title=f"frictional lag, {f:g} Hz")
    axes[0].set_ylabel("friction (N·m)")
    axes[0].legend()
    names.append(save_figure(fig, out, "phenomena_lag.png"))
    fig, ax = plt.subplots(figsize=(6, 4))
    w = 0.8 / len(ALL)
    for k, s in enumerate(ALL):
        ax.bar(np.arange(len(RAMP_RATES)) + w * k, [m.breakaway[(s, r)] for r in RAMP_RATES], w, label=s)
    ax.set_xticks(np.arange(len(RAMP_RATES)) + 0.4 - w / 2, [f"{r:g} F_s/s" for r in RAMP_RATES])
    ax.set(ylabel="break-away / (F_s - b)", title="break-away against the force rate", ylim=(0.6, 1.5))
    ax.legend()
    names.append(save_figure(fig, out, "phenomena_breakaway.png"))
    fig, ax = plt.subplots(figsize=(7, 4))
    for s in ALL:
        r = m.stickslip[s]
        ax.plot(r["t"], np.degrees(r["omega"]), label=s, lw=0.8, ls="--" if s in REFERENCE else "-")
    ax.set(xlabel="t (s)", ylabel="ω (deg/s)", title="stick-slip, pulled through K_p at 1 deg/s")
    ax.legend()
    names.append(save_figure(fig, out, "phenomena_stickslip.png"))
    return names


def findings(m: Measured, rows_: list[dict]) -> str:
    def mark(s: str, phen: str) -> str:
        if phen == "presliding":
            lo, hi = PRESLIDING_BOUNDS
            return "yes" if lo <= m.presliding[s]["lengths"] <= hi else "no (creeps)"
        if phen == "lag":
            w = m.lag[(s, 1.0)]["width"]
            return "no" if abs(w) < 1e-3 else ("yes" if w > 0 else f"inverted ({w:+.3f} F_c)")
        if phen == "breakaway":
            d = m.breakaway[(s, RAMP_RATES[0])] - m.breakaway[(s, RAMP_RATES[1])]
            return f"yes ({d:+.3f})" if d > 0.01 else f"no ({d:+.3f})"
        return "yes" if np.isfinite(m.stickslip[s]["period"]) else "no"

    phens = ("presliding", "lag", "breakaway", "stickslip")
    lines = [
        "## Friction phenomena (Iurian et al. 2005 §1.3) by structure, measured on Kang's rotor",
        "",
        "| structure | presliding | frictional lag (1 Hz) | break-away rises as the rate falls "
        "| stick-slip |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| {s}{' (reference only)' if s in REFERENCE else ''} | "
        + " | ".join(mark(s, ph) for ph in phens)
        + " |"
        for s in ALL
    ]
    lines += [
        "",
        "The survey (§1.5) credits LuGre with frictional lag and varying break-away. With the presets' "
        "critically damped bristles (σ1 = 2·sqrt(σ0·J)) the damping term σ1·ż outweighs the lag of z "
        "wherever σ1·v > g(v), so the friction is *lower* while accelerating; with "
        f"σ1 = {m.light_sigma1:.3g} N·m·s/rad the survey's lag appears "
        f"({m.light_lag[1.0]:+.3f} F_c at 1 Hz). A study that needs the lag should lower σ1 (and the "
        "integrator then needs the admissibility check of docs/physics.md). The Coulomb structure's "
        "stick is MuJoCo's soft frictionloss constraint: it creeps under a held torque below the level.",
    ]
    return "\n".join(lines)


SECTION = Section("phenomena", "friction_phenomena", run, rows, figures, findings)
