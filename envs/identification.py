"""Friction and plant identification from data, as in seed 000 §2.2-2.3, applied to real or simulated data."""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from .sim import PlantSim


def two_point_step_id(t: tuple[float, float], y: tuple[float, float], v: float) -> dict[str, float]:
    """Seed 000 §2.2: the line through two late step-response points gives θ ≈ α1·t + α2 with
    a = -α1/α2 and k = α1·a/v (it ignores the exponential term, ERRATA 000)."""
    alpha1 = (y[1] - y[0]) / (t[1] - t[0])
    alpha2 = y[0] - alpha1 * t[0]
    a = -alpha1 / alpha2
    return {"alpha1": alpha1, "alpha2": alpha2, "a": a, "k": alpha1 * a / v}


def coulomb_viscous_fit(
    velocity: np.ndarray, control: np.ndarray, min_speed: float = 0.0
) -> tuple[float, float]:
    """Seed 000 §2.3: least-squares line control = F_C + F_v·velocity over points with |v| >= min_speed.
    Returns (F_C, F_v) in the data's units."""
    sel = np.abs(velocity) >= min_speed
    slope, intercept = np.polyfit(velocity[sel], control[sel], 1)
    return float(intercept), float(slope)


def m220_step_counts(
    gain: float, times: tuple[float, ...], v: float = 0.25, overrides: dict | None = None
) -> np.ndarray:
    """Drive-encoder counts of the simulated M220 open-loop step of v volts at the given times."""
    ov = {"identified": {"gain_counts_per_v_s2": float(gain)}}
    for key, value in (overrides or {}).items():
        ov.setdefault(key, {}).update(value)
    sim = PlantSim("m220", ov)
    sim.reset()
    dt, out, t_now = sim.spec.timestep, [], 0.0
    rpc = sim.spec.info["rad_per_count"]
    for t in times:
        n = round((t - t_now) / dt)
        sim.step(v, nstep=n)
        t_now += n * dt
        out.append(np.floor(sim.data.qpos[sim.dofs[0]] / rpc))
    return np.array(out)


def fit_m220_gain(
    times: tuple[float, float] = (4.44, 4.91), counts: tuple[float, float] = (100080, 118992), v: float = 0.25
) -> float:
    """Plant gain (counts/(V·s²)) whose simulated step best matches the measured points (relative LSQ)."""
    target = np.asarray(counts, dtype=float)

    def cost(g: float) -> float:
        return float(np.sum((m220_step_counts(g, times, v) / target - 1.0) ** 2))

    res = minimize_scalar(cost, bounds=(5e4, 2e5), method="bounded", options={"xatol": 1.0})
    return float(res.x)
