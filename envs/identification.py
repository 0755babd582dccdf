"""Friction and plant identification from data, as in seed 000 §2.2-2.3, applied to real or simulated data.
The M220-specific simulated step and gain fit live in plants/m220.py."""

from __future__ import annotations

import numpy as np


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
