"""LuGre-observer friction compensation (Canudas de Wit et al. 1995, reference [3] of seed 000) on top of
the PD (position) / PI (speed) loop of pid.py, acting on the drive joint with the nominal LuGre
parameters of the plant preset."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

from frictiongym.envs.config import Node
from frictiongym.envs.scenario import Scenario

from .. import settings as cfg
from ..base import EpisodeContext, drive_friction_reason
from .pid import PID, PIDSettings


@dataclass(frozen=True)
class LuGreObserverSettings(cfg.FamilySettings):
    """observer_gain: k per plant preset, coupling the loop error into the observer (rad/s per rad, or
    per V·s/rad for a speed loop); the trade-off measured is in controllers.yaml."""

    SECTION: ClassVar[str] = "lugre_observer"
    observer_gain: Mapping[str, float]

    @classmethod
    @cache
    def defaults(cls) -> LuGreObserverSettings:
        def build(s: Node) -> LuGreObserverSettings:
            g = s.section("observer_gain")
            return cls({plant: g.nonneg(plant, 1e6) for plant in list(g.keys())})

        return cfg.read(cls.SECTION, build)


class LuGreObserver(PID):
    """u = u_fb + (F̂ - b)/k_act: F̂ from the observer ẑ(k+1) = v/a + (ẑ - v/a)·e^{-a h}, a = σ0|v|/g(v)
    (exact for v held over the period; ẑ += v h at v = 0), with v the measured drive velocity (encoder
    difference or tachometer). PD for a position loop, PI for a speed loop."""

    name: ClassVar[str] = "LuGreObserver"

    def __init__(
        self,
        settings: LuGreObserverSettings | None = None,
        pid: PIDSettings | None = None,
        **overrides: Any,
    ):
        super().__init__(pid)
        self.observer = cfg.with_overrides(settings or LuGreObserverSettings.defaults(), overrides)

    def why_not(self, scenario: Scenario) -> str | None:
        return super().why_not(scenario) or drive_friction_reason(scenario)

    def start(self, ctx: EpisodeContext) -> None:
        spec = ctx.plant
        self.speed_loop = spec.sensors[self.sc.tracked_sensor].kind == "tacho"
        self.integral = self.speed_loop  # PI for the speed loop, PD for position
        super().start(ctx)
        self.p = spec.drive_friction
        gains = self.observer.observer_gain
        if spec.name not in gains:
            raise ValueError(f"no observer gain for plant {spec.name!r}; settings have {sorted(gains)}")
        self.k_obs = gains[spec.name]
        self.z = 0.0
        self.k_speed = spec.sensors[self.sc.tracked_sensor].gain if self.speed_loop else 1.0

    def velocity(self, y: float, y_prev: float | None) -> float:
        if self.speed_loop:
            return y / self.k_speed
        return 0.0 if y_prev is None else (y - y_prev) / self.h

    def friction_estimate(self, v: float, e: float) -> float:
        """F̂ (N·m, opposing motion) and the observer update over one period."""
        p, h = self.p, self.h
        a = p.sigma0 * abs(v) / p.g(v)
        # σ1·ẑ' is left out: from sampled velocities it is a velocity feedback of gain σ1, and h·σ1/J is
        # 17 for the flexible servo's motor at 40 ms (it destabilised the loop, measured); σ0 ẑ + σ2 v remain
        F = p.sigma0 * self.z + p.sigma2 * v
        drive = v - self.k_obs * e
        self.z = drive / a + (self.z - drive / a) * math.exp(-a * h) if a > 0 else self.z + drive * h
        return F

    def command(self, y: float, r: float) -> float:
        v = self.velocity(y, self.y_prev)
        u_fb = super().command(y, r)
        comp = (
            self.friction_estimate(v, (y - r) / self.k_speed) - self.p.bias
        ) / self.ctx.plant.actuator_gain
        limit = self.sc.action_scale
        return max(-limit, min(limit, u_fb + comp))

    def params(self) -> dict[str, Any]:
        return {**super().params(), "observer_gain": getattr(self, "k_obs", None)}
