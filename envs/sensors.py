"""Sensor models sampled at the control instants: encoder quantisation, tachometer gain and ripple,
additive Gaussian noise (seeded). Inputs are true joint angles/velocities (rad, rad/s)."""

from __future__ import annotations

import numpy as np

from .plants import PlantSpec, SensorSpec


def measure(
    sensor: SensorSpec, theta: float, omega: float, rng: np.random.Generator, noise_scale: float
) -> float:
    """One reading. Encoder: angle in rad, floor-quantised to the resolution (an incremental counter
    counts whole lines passed), noise added before quantisation.
    Tacho: gain·ω + ripple·sin(n·θ) + noise (V)."""
    noise = (
        float(rng.normal(0.0, sensor.noise_std * noise_scale)) if sensor.noise_std * noise_scale > 0 else 0.0
    )
    if sensor.kind == "encoder":
        return float(np.floor((theta + noise) / sensor.resolution) * sensor.resolution)
    ripple = (
        sensor.ripple_amplitude * np.sin(sensor.ripple_periods_per_rad * theta)
        if sensor.ripple_amplitude
        else 0.0
    )
    return float(sensor.gain * omega + ripple + noise)


def measure_all(
    spec: PlantSpec,
    qpos: np.ndarray,
    qvel: np.ndarray,
    dofs: tuple[int, ...],
    rng: np.random.Generator,
    noise_scale: float,
) -> np.ndarray:
    """All sensors of the plant, in spec order."""
    out = np.empty(len(spec.sensors))
    for k, s in enumerate(spec.sensors):
        d = dofs[spec.joint_index(s.joint)]
        out[k] = measure(s, float(qpos[d]), float(qvel[d]), rng, noise_scale)
    return out
