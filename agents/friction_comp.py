"""Model-based friction compensation: a LuGre observer (Canudas de Wit et al. 1995, reference [3] of seed
000) and Coulomb + viscous feedforward from identified parameters (seed 000 §2.3), both on top of the
PD (position) / PI (speed) loops of agents.classical, all acting on the drive joint."""

from __future__ import annotations

import math
from typing import Any, ClassVar

from frictiongym.envs.scenario import Scenario

from .base import EpisodeContext
from .classical import PID
from .design import controller_config


class LuGreObserver(PID):
    """u = u_fb + (F̂ - b)/k_act: F̂ from the observer ẑ(k+1) = v/a + (ẑ - v/a)·e^{-a h}, a = σ0|v|/g(v)
    (exact for v held over the period; ẑ += v h at v = 0), with v the measured drive velocity (encoder
    difference or tachometer) and the nominal LuGre parameters of the plant preset."""

    name: ClassVar[str] = "LuGreObserver"
    plants: ClassVar[tuple[str, ...]] = ("kang_robot", "m220", "flexible_servo")

    def start(self, ctx: EpisodeContext) -> None:
        self.integral = ctx.plant.name == "flexible_servo"  # PI for the speed loop, PD for position
        super().start(ctx)
        spec = ctx.plant
        self.p = spec.joints[spec.joint_index(spec.actuator_joint)].friction
        self.k_obs = controller_config()["lugre_observer"]["observer_gain"][spec.name]
        self.z = 0.0
        self.speed_loop = spec.sensors[self.sc.tracked_sensor].kind == "tacho"
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
        if self.p is None:
            return u_fb
        comp = (
            self.friction_estimate(v, (y - r) / self.k_speed) - self.p.bias
        ) / self.ctx.plant.actuator_gain
        limit = self.sc.action_scale
        return max(-limit, min(limit, u_fb + comp))

    def params(self) -> dict[str, Any]:
        return {**super().params(), "observer_gain": getattr(self, "k_obs", None)}


class CoulombViscousFF(PID):
    """u = u_fb + (F_C^± sgn(v_r) + σ2 v_r)/k_act with v_r the reference velocity (from the preview), the
    identified levels of the plant preset (seed 000 §2.3 for the M220). For tracking scenarios."""

    name: ClassVar[str] = "CoulombViscousFF"
    plants: ClassVar[tuple[str, ...]] = ("kang_robot", "m220")
    integral: ClassVar[bool] = False

    def applies_to(self, scenario: Scenario) -> bool:
        return super().applies_to(scenario) and scenario.preview_steps > 0

    def start(self, ctx: EpisodeContext) -> None:
        super().start(ctx)
        spec = ctx.plant
        self.p = spec.joints[spec.joint_index(spec.actuator_joint)].friction
        self.r_prev: float | None = None

    def command(self, y: float, r: float) -> float:
        vr = 0.0 if self.r_prev is None else (r - self.r_prev) / self.h
        self.r_prev = r
        u_fb = super().command(y, r)
        lv = self.p.levels()
        ff = (lv["coulomb_pos"] if vr > 0 else -lv["coulomb_neg"] if vr < 0 else 0.0) + self.p.sigma2 * vr
        limit = self.sc.action_scale
        return max(-limit, min(limit, u_fb + ff / self.ctx.plant.actuator_gain))
