"""LuGre-observer friction compensation (Canudas de Wit et al. 1995, reference [3] of Iurian et al. 2005) on
top of the PD (position) / PI (speed) loop of pid.py, acting on the drive joint with the nominal LuGre
parameters of the plant preset."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.config import Node
from frictiongym.envs.scenario import Scenario

from .. import settings as cfg
from ..base import EpisodeContext, drive_friction_reason, elementwise
from .pid import PID, PIDSettings

# Below this a·h the observer's exact update drive/a + (ẑ - drive/a)·e^{-ah} loses ẑ in the rounding of
# drive/a (a filtered velocity decays through values small enough for drive/a ~ 1e300: ẑ jumped, measured),
# so there it is computed in expm1 form. Unfiltered, an encoder's velocity is 0 or at least a count per
# period and never comes near it (the M220, Kang and EMPS baselines bit for bit the exact form's); a
# tachometer's can (the flexible servo's speed loop moved at the 1e-8 level, measured).
SMALL_DECAY = 1e-6


@dataclass(frozen=True)
class LuGreObserverSettings(cfg.FamilySettings):
    """observer_gain: k per plant preset, coupling the loop error into the observer (rad/s per rad, or
    per V·s/rad for a speed loop); the trade-off measured is in controllers.yaml. velocity_filter_s: time
    constant (s) of a first-order filter on the measured velocity the observer runs on; 0 (the baseline's)
    is none."""

    SECTION: ClassVar[str] = "lugre_observer"
    observer_gain: Mapping[str, float]
    velocity_filter_s: float

    @classmethod
    @cache
    def defaults(cls) -> LuGreObserverSettings:
        def build(s: Node) -> LuGreObserverSettings:
            g = s.section("observer_gain")
            return cls(
                {plant: g.nonneg(plant, 1e6) for plant in list(g.keys())}, s.nonneg("velocity_filter_s", 1.0)
            )

        return cfg.read(cls.SECTION, build)


class LuGreObserver(PID):
    """u = u_fb + (F̂ - b)/k_act: F̂ from the observer ẑ(k+1) = v/a + (ẑ - v/a)·e^{-a h}, a = σ0|v|/g(v)
    (exact for v held over the period; ẑ += v h at v = 0), with v the measured drive velocity (encoder
    difference or tachometer), low-pass filtered when velocity_filter_s > 0 (v_f += (1 - e^{-h/τ})(v - v_f),
    from v_f = v at the first reading). PD for a position loop, PI for a speed loop."""

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
        self.z = np.zeros(self.episodes)
        self.k_speed = spec.sensors[self.sc.tracked_sensor].gain if self.speed_loop else 1.0
        tau = self.observer.velocity_filter_s
        self.v_gain = 1.0 - math.exp(-self.h / tau) if tau > 0 else None
        self.v_f: np.ndarray | None = None

    def velocity(self, y: np.ndarray, y_prev: np.ndarray | None) -> np.ndarray:
        """The velocities the observer runs on (rad/s): measured, then filtered if asked."""
        if self.speed_loop:
            v = y / self.k_speed
        elif y_prev is None:
            v = np.zeros_like(y)
        else:
            v = (y - y_prev) / self.h
        if self.v_gain is None:
            return v
        self.v_f = v if self.v_f is None else self.v_f + self.v_gain * (v - self.v_f)
        return self.v_f

    def friction_estimate(self, v: np.ndarray, e: np.ndarray) -> np.ndarray:
        """F̂ (N·m, opposing motion) and the observer update over one period."""
        p, h = self.p, self.h
        a = p.sigma0 * np.abs(v) / p.g(v)
        # σ1·ẑ' is left out: from sampled velocities it is a velocity feedback of gain σ1, and h·σ1/J is
        # 17 for the flexible servo's motor at 40 ms (it destabilised the loop, measured); σ0 ẑ + σ2 v remain
        F = p.sigma0 * self.z + p.sigma2 * v
        drive = v - self.k_obs * e
        ah = a * h
        decay = elementwise(math.exp, -ah)
        exact = ah >= SMALL_DECAY  # exact for v held over the period
        with np.errstate(divide="ignore", invalid="ignore"):  # each branch where it applies
            held = drive / a + (self.z - drive / a) * decay
            # the same update as ẑ + drive·h·(1 - e^{-ah})/(ah), which tends to ẑ + drive·h as a → 0
            ratio = np.where(ah > 0, elementwise(math.expm1, -ah) / ah, -1.0)
        self.z = np.where(exact, held, self.z * decay - drive * h * ratio)
        return F

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        v = self.velocity(y, self.y_prev)
        u_fb = super().commands(y, r)
        comp = (
            self.friction_estimate(v, (y - r) / self.k_speed) - self.p.bias
        ) / self.ctx.plant.actuator_gain
        limit = self.sc.action_scale
        return np.clip(u_fb + comp, -limit, limit)

    def params(self) -> dict[str, Any]:
        return {
            **super().params(),
            "observer_gain": getattr(self, "k_obs", None),
            "velocity_filter_s": self.observer.velocity_filter_s,
        }
