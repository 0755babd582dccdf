"""Seed 000 part 2 (Iurian et al. 2005), the ECP M220: reflected inertia (eq. 22) in four configurations,
the §2.2 open-loop step through its two measured points, the two-point identification on simulated
data, and the plant-gain fit."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from frictiongym.agents.lab.fits import two_point_step_id
from frictiongym.envs.config import Node
from frictiongym.envs.plants import m220, plant_config, plant_spec
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.records import pyplot

from ..figures import save_figure
from .report import Section, row

CONFIGS = {
    "default": {},
    "npd72_npl18_4wl": {"configuration": {"n_pd": 72, "n_pl": 18, "brass_weights_load": 4}},
    "npd18_npl72_2wd_backlash": {
        "configuration": {"n_pd": 18, "n_pl": 72, "brass_weights_drive": 2, "backlash_device": True}
    },
    "npd36_npl36_4wd_4wl": {
        "configuration": {"n_pd": 36, "n_pl": 36, "brass_weights_drive": 4, "brass_weights_load": 4}
    },
}


def rows(_: None) -> Iterator[dict]:
    for name, ov in CONFIGS.items():
        yield row(
            f"m220.reflected_inertia.{name}",
            eq22_of(ov),
            reflected_inertia_sim(ov),
            0.005,
            note="kg·m², eq. (22)",
        )
    doc = plant_spec("m220").document
    t, y = doc.step_points_t_s, doc.step_points_counts
    sim = step_counts(doc.gain_counts_per_v_s2, t, doc.step_input_v)
    for k in range(2):
        yield row(f"m220.step_point.{k + 1}", y[k], sim[k], 0.02, note=f"counts at t = {t[k]} s, §2.2")
    ident = two_point_step_id(t, tuple(sim), doc.step_input_v)
    yield row("m220.step_id.a", doc.document_a_per_s, ident["a"], 0.05, note="1/s, two-point method on sim")
    yield row("m220.step_id.k", doc.document_k_counts_per_v_s2, ident["k"], 0.05, note="counts/(V·s²)")
    yield row(
        "m220.gain_fit.reproducible",
        doc.gain_counts_per_v_s2,
        fit_gain(t, y, doc.step_input_v),
        1e-3,
        note="config value vs a fresh fit",
    )


def figures(_: None, out: Path) -> list[str]:
    """The simulated 0.25 V step against the measured points and the document's model k/(s(s+a))."""
    plt = pyplot()

    doc = plant_spec("m220").document
    t = np.linspace(0.05, 5.0, 100)
    y = step_counts(doc.gain_counts_per_v_s2, tuple(t), doc.step_input_v)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(t, y, label="simulated 0.25 V step (drive encoder)")
    measured = "measured points, Iurian et al. 2005 §2.2"
    ax.plot(doc.step_points_t_s, doc.step_points_counts, "o", label=measured)
    a, k, v = doc.document_a_per_s, doc.document_k_counts_per_v_s2, doc.step_input_v
    ax.plot(t, k * v / a * t - k * v / a**2 * (1 - np.exp(-a * t)), "--", label="document model k/(s(s+a))")
    ax.set(xlabel="t (s)", ylabel="counts", title="M220 open-loop step")
    ax.legend()
    return [save_figure(fig, out, "m220_step.png")]


PLANT = Section("m220", "iurian2005", lambda: None, rows, figures)


# ----------------------------------------------------------------------------------------------------
# the plant's simulated checks: eq. (22) against the simulated motion, §2.2's open-loop step and gain fit


def eq22_of(overrides: dict | None = None) -> float:
    """eq22 for the preset with YAML-level overrides (e.g. another pulley configuration)."""
    return m220.eq22(Node(plant_config("m220", overrides), "m220.yaml"))


def reflected_inertia_sim(overrides: dict, torque_nm: float = 0.01, duration: float = 0.3) -> float:
    """Drive inertia (kg·m²) measured from the simulated motion of the belt-coupled model without
    friction: θ(t) = T·t²/(2·J) fitted over the second half of a constant-torque run from rest."""
    sim = PlantSim("m220", overrides, friction_model="none")
    sim.reset()
    u = torque_nm / sim.spec.actuator_gain
    n = round(duration / sim.spec.timestep)
    t, th = np.empty(n), np.empty(n)
    for k in range(n):
        sim.step(u, nstep=1)
        t[k], th[k] = sim.data.time, sim.data.qpos[sim.dofs[0]]
    half = slice(n // 2, n)
    curvature = np.polyfit(t[half], th[half], 2)[0]  # = T/(2J)
    return torque_nm / (2.0 * curvature)


def step_counts(gain: float, times: tuple[float, ...], v: float, overrides: dict | None = None) -> np.ndarray:
    """Drive-encoder counts of the simulated M220 open-loop step of v volts at the given times."""
    # a nominal experiment: no randomization, so other gains do not trip the range checks (σ0 ∝ gain)
    ov = {
        "identified": {"gain_counts_per_v_s2": float(gain)},
        "randomization": {k: [1.0, 1.0] for k in ("sigma0_scale", "inertia_scale")},
    }
    for key, value in (overrides or {}).items():
        ov.setdefault(key, {}).update(value)
    sim = PlantSim("m220", ov)
    sim.reset()
    dt, out, t_now = sim.spec.timestep, [], 0.0
    rpc = sim.spec.document.rad_per_count
    for t in times:
        n = round((t - t_now) / dt)
        sim.step(v, nstep=n)
        t_now += n * dt
        out.append(np.floor(sim.data.qpos[sim.dofs[0]] / rpc))
    return np.array(out)


def fit_gain(times: tuple[float, float], counts: tuple[float, float], v: float) -> float:
    """Plant gain (counts/(V·s²)) whose simulated step of v volts best matches the measured points
    (times s, counts; §2.2's are in m220.yaml's identified section), relative least squares."""
    target = np.asarray(counts, dtype=float)

    def cost(g: float) -> float:
        return float(np.sum((step_counts(g, times, v) / target - 1.0) ** 2))

    res = minimize_scalar(cost, bounds=(5e4, 2e5), method="bounded", options={"xatol": 1.0})
    return float(res.x)
