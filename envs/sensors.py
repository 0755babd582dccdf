"""Sensor models sampled at the control instants: encoder quantisation, tachometer gain and ripple,
additive Gaussian noise (seeded). Vectorised over a leading axis of simulations."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .plants.spec import PlantSpec
from .step import ARRAY, encoder_reading, tacho_reading


@dataclass(frozen=True)
class SensorArrays:
    """The plant's sensors as arrays (one entry per sensor, spec order)."""

    dofs: np.ndarray  # dof index read by each sensor
    encoder: np.ndarray  # bool: encoder (else tachometer)
    resolution: np.ndarray  # rad (encoders)
    gain: np.ndarray  # V per rad/s (tachometers)
    ripple_n: np.ndarray  # ripple periods per revolution: sin(n·θ), θ in rad
    ripple_amp: np.ndarray  # V
    noise_std: np.ndarray  # rad or V

    @classmethod
    def of(cls, spec: PlantSpec, dofs: tuple[int, ...]) -> SensorArrays:
        s = spec.sensors
        return cls(
            dofs=np.array([dofs[spec.joint_index(x.joint)] for x in s], dtype=int),
            encoder=np.array([x.kind == "encoder" for x in s]),
            resolution=np.array([x.resolution if x.kind == "encoder" else 1.0 for x in s]),
            gain=np.array([x.gain for x in s]),
            ripple_n=np.array([x.ripple_periods_per_rev for x in s]),
            ripple_amp=np.array([x.ripple_amplitude for x in s]),
            noise_std=np.array([x.noise_std for x in s]),
        )

    def __post_init__(self) -> None:
        object.__setattr__(self, "all_encoders", bool(self.encoder.all()))
        object.__setattr__(self, "any_noise", bool(np.any(self.noise_std > 0)))
        object.__setattr__(self, "any_ripple", bool(np.any(self.ripple_amp)))

    def noise(self, rngs: list[np.random.Generator], scale: np.ndarray) -> np.ndarray:
        """(n, nsensor) noise; each simulation draws from its own stream, only when its noise is on."""
        out = np.zeros((len(rngs), len(self.dofs)))
        if not self.any_noise:
            return out
        for i, rng in enumerate(rngs):
            std = self.noise_std * scale[i]
            if np.any(std > 0):
                out[i] = rng.normal(0.0, 1.0, len(std)) * std
        return out

    def measure(self, qpos: np.ndarray, qvel: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """(n, nsensor) readings. Encoder: floor((θ + noise)/resolution)·resolution (an incremental counter
        counts whole lines passed). Tacho: gain·ω + ripple·sin(n·θ) + noise (V)."""
        th = qpos[:, self.dofs]
        enc = encoder_reading(th + noise if self.any_noise else th, self.resolution, ARRAY)
        if self.all_encoders:
            return enc
        tacho = tacho_reading(qvel[:, self.dofs], self.gain, noise)
        if self.any_ripple:
            tacho += self.ripple_amp * np.sin(self.ripple_n * th)
        return np.where(self.encoder, enc, tacho)

    def truth(self, qpos: np.ndarray, qvel: np.ndarray, sensor: int) -> np.ndarray:
        """(n,) noise- and quantisation-free value of one sensor: θ (rad) or gain·ω (V)."""
        d = self.dofs[sensor]
        return qpos[:, d].copy() if self.encoder[sensor] else self.gain[sensor] * qvel[:, d]
