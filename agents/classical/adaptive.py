"""Adaptive Coulomb friction compensation (Friedland and Park 1992, "On adaptive friction compensation",
IEEE Trans. Automatic Control 37(10), eq. 9-12): the Coulomb level a of the nominal model
(J/b)·v̇ = u - a·sgn(v) - (c/b)·v (command units) is estimated without differentiating the velocity,

    â = z - k·|v|,   ż = k·sgn(v)·(b/J)·(u - â·sgn(v) - (c/b)·v),

so that the estimation error obeys d(â - a)/dt = -k·(b/J)·(â - a) while the drive moves: a first-order
convergence at the rate λ = k·b/J (the exponent μ of the paper is 1 here). The update runs only while
|v| exceeds min_speed_per_s in one direction (at rest sgn(v) is undefined and an encoder's velocity is
its quantisation); elsewhere â holds. â starts at the identified mean Coulomb level and scales the
friction part of the model feed-forward (model_feedforward.py) on the PID loop, so a level that drifts
over the episode is followed: it is defined on the scenarios whose friction drifts (the *_drift ones).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.plants.identified import drive_friction
from frictiongym.envs.scenario import Scenario

from .. import settings as cfg
from ..base import EpisodeContext
from .design import rigid_position_plant
from .model_feedforward import PIDModelFF

MAX_LEVEL_RATIO = 3.0  # â is kept within [0, 3x] the identified level: a bound on a misled estimate


@dataclass(frozen=True)
class AdaptiveEntry:
    """One plant's adaptation (controllers.yaml `adaptive_coulomb.<plant>`).

    adaptation_rate_per_s: λ = k·b/J, the estimate's convergence rate in motion (1/s).
    min_speed_per_s: |v| below which the estimate holds (drive units/s: rad/s or m/s).
    """

    adaptation_rate_per_s: float
    min_speed_per_s: float


@dataclass(frozen=True)
class AdaptiveSettings(cfg.PerPlantSettings):
    """The adaptive Coulomb estimate per plant preset (controllers.yaml `adaptive_coulomb`)."""

    SECTION: ClassVar[str] = "adaptive_coulomb"
    ENTRY: ClassVar[type] = AdaptiveEntry
    KNOBS: ClassVar[dict[str, cfg.Knob]] = {
        "adaptation_rate_per_s": cfg.Knob(0.01, 20.0, log=True),
        "min_speed_per_s": cfg.Knob(1e-5, 1.0, log=True),
    }
    plants: dict[str, Any]

    @classmethod
    @cache
    def defaults(cls) -> AdaptiveSettings:
        return cfg.read(cls.SECTION, lambda s: cls(cls.read_section(s)))


class AdaptiveCoulomb(PIDModelFF):
    """PID+MFF with the friction feed-forward scaled by the adapted Coulomb level (module docstring)."""

    name: ClassVar[str] = "AdaptiveFF"
    tunes: ClassVar[tuple[str, type]] = ("adaptive", AdaptiveSettings)  # agents/tuning/search.py

    def __init__(self, adaptive: AdaptiveSettings | None = None, **kw: Any):
        super().__init__(**kw)
        self.adaptive = adaptive or AdaptiveSettings.defaults()

    def why_not(self, scenario: Scenario) -> str | None:
        reason = super().why_not(scenario)
        if reason is None and scenario.friction_drift is None:
            return "defined where the friction drifts within the episode (the scenario's friction_drift)"
        return reason

    def start(self, ctx: EpisodeContext) -> None:
        super().start(ctx)
        e = self.adaptive.of(ctx.plant.name)
        spec, sensor = ctx.plant, ctx.plant.sensors[ctx.scenario.tracked_sensor]
        self.speed, self.gain = sensor.kind == "tacho", sensor.gain
        if self.speed:
            J = sum(j.inertia for j in spec.joints)
            c = sum(j.viscous + (j.friction.sigma2 if j.friction else 0.0) for j in spec.joints)
        else:
            J, c, _ = rigid_position_plant(spec)
        b = spec.actuator_gain
        self.rate_b_over_j, self.c_over_b = b / J, c / b
        self.k_obs = e.adaptation_rate_per_s * J / b  # k (command units·s per drive unit)
        self.min_speed = e.min_speed_per_s
        nominal = drive_friction(spec)
        self.level0 = 0.5 * (nominal.coulomb_pos + nominal.coulomb_neg)  # command units
        n = self.episodes
        self.level = np.full(n, self.level0)
        self.z = np.zeros(n)
        self.anchored = np.zeros(n, dtype=bool)  # whether z holds an estimate (re-anchored at each motion)
        self.x_prev: np.ndarray | None = None
        self.v_prev = np.zeros(n)
        self.u_prev = np.zeros(n)

    def adapt(self, v: np.ndarray) -> None:
        """The Friedland-Park update over the last period, at the velocities v (drive units/s) read now."""
        vp = self.v_prev
        moving = (np.abs(v) > self.min_speed) & (np.abs(vp) > self.min_speed) & (v * vp > 0)
        z = np.where(self.anchored, self.z, self.level + self.k_obs * np.abs(vp))
        s = np.copysign(1.0, v)
        drive = self.u_prev - self.level * s - self.c_over_b * vp
        z = z + self.h * self.k_obs * s * self.rate_b_over_j * drive
        level = np.minimum(MAX_LEVEL_RATIO * self.level0, np.maximum(0.0, z - self.k_obs * np.abs(v)))
        # at rest â holds and the estimate is dropped, to be re-anchored at the next motion
        self.z, self.anchored = np.where(moving, z, 0.0), moving
        self.level = np.where(moving, level, self.level)

    def feedforward(self, r: np.ndarray) -> np.ndarray:
        u = super().feedforward(r)
        return u + (self.level / self.level0 - 1.0) * self.ff.friction

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        x = y / self.gain
        if self.speed:
            v = x
        else:
            v = np.zeros_like(x) if self.x_prev is None else (x - self.x_prev) / self.h
            self.x_prev = x
        self.adapt(v)
        self.v_prev = v
        u = super().commands(y, r)
        self.u_prev = u
        return u

    def params(self) -> dict[str, Any]:
        return {**super().params(), "nominal_coulomb_level": getattr(self, "level0", None)}
