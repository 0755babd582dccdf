"""Southward's nonlinear compensator (Kang eq. 7-8) and Kang's robust digital friction compensator RDFC
(eq. 11-12), both for set-point regulation of a position loop, designed from the nominal plant."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs import units
from frictiongym.envs.scenario import REGULATION, Scenario

from .. import settings as cfg
from ..base import ArrayController, EpisodeContext, drive_friction_reason
from .pid import PIDSettings, design_pid

EQ12B_READINGS = ("printed", "symmetric")


@dataclass(frozen=True)
class SouthwardSettings(cfg.FamilySettings):
    """static_friction_margin: T̃_s = margin·T_s (Kang §6: 1.2)."""

    SECTION: ClassVar[str] = "southward"
    static_friction_margin: float

    @classmethod
    @cache
    def defaults(cls) -> SouthwardSettings:
        return cfg.read(cls.SECTION, lambda s: cls(s.positive("static_friction_margin", 10.0)))


@dataclass(frozen=True)
class RDFCSettings(cfg.FamilySettings):
    """static_friction_margin (Kang §6: 1.2); delta_deg: dead band δ_H = -δ_L (deg, §6: 0.02 and 0.04);
    eq12b_reading: "printed" or "symmetric" third line of eq. (12b) (ERRATA 001, controllers.yaml)."""

    SECTION: ClassVar[str] = "rdfc"
    static_friction_margin: float
    delta_deg: float
    eq12b_reading: str

    @classmethod
    @cache
    def defaults(cls) -> RDFCSettings:
        return cfg.read(
            cls.SECTION,
            lambda s: cls(
                s.positive("static_friction_margin", 10.0),
                s.positive("delta_deg", 90.0),
                s.choice("eq12b_reading", EQ12B_READINGS),
            ),
        )


def static_bounds(ctx: EpisodeContext) -> tuple[float, float]:
    """(T_s^+, |T_s^-|) the compensator believes (N·m at the drive): the nominal plant's static levels
    scaled by knowledge.static_friction_scale (1.0 = the document's values)."""
    lv = ctx.plant.drive_friction.levels()
    k = ctx.knowledge.get("static_friction_scale", 1.0)
    return k * lv["static_pos"], k * lv["static_neg"]


class Southward(ArrayController):
    """Southward et al. (Kang eq. 7-8): T_c = -K_d ω - T_n, with T_n the bang-bang compensation
    -T̃_s^∓ inside [θ̃_L, θ̃_H] and K_p θ outside (θ = position error y - r), T̃_s = margin·T_s.
    ω from the backward difference of the encoder (digital D)."""

    name: ClassVar[str] = "Southward"
    sensor_kinds: ClassVar[tuple[str, ...]] = ("encoder",)
    tasks: ClassVar[tuple[str, ...]] = (REGULATION,)

    def __init__(
        self, settings: SouthwardSettings | None = None, pid: PIDSettings | None = None, **overrides: Any
    ):
        self.settings = cfg.with_overrides(settings or SouthwardSettings.defaults(), overrides)
        self.pid = pid or PIDSettings.defaults()

    def why_not(self, scenario: Scenario) -> str | None:
        return super().why_not(scenario) or drive_friction_reason(scenario)

    def start(self, ctx: EpisodeContext) -> None:
        pd = design_pid(ctx, False, self.pid)
        b = ctx.plant.actuator_gain
        self.kp, self.kd = pd.kp * b, pd.kd * b  # N·m/rad, N·m·s/rad
        margin = self.settings.static_friction_margin
        ts_pos, ts_neg = static_bounds(ctx)
        self.ts_pos, self.ts_neg = margin * ts_pos, -margin * ts_neg  # T̃_s^+ > 0, T̃_s^- < 0
        self.theta_h, self.theta_l = -self.ts_neg / self.kp, -self.ts_pos / self.kp  # eq. (8b)-(8c)
        self.y_prev: np.ndarray | None = None

    def omega(self, y: np.ndarray) -> np.ndarray:
        w = np.zeros_like(y) if self.y_prev is None else (y - self.y_prev) / self.h
        self.y_prev = y
        return w

    def compensation(self, theta: np.ndarray, w: np.ndarray) -> np.ndarray:
        """T_n of eq. (8a)."""
        bands = [(theta > 0) & (theta <= self.theta_h), theta == 0, (self.theta_l <= theta) & (theta < 0)]
        return np.select(bands, [-self.ts_neg, 0.0, -self.ts_pos], self.kp * theta)

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        w = self.omega(y)
        torque = -self.kd * w - self.compensation(y - r, w)
        limit = self.sc.action_scale
        return np.clip(torque / self.ctx.plant.actuator_gain, -limit, limit)

    def params(self) -> dict[str, Any]:
        return {
            k: getattr(self, k)
            for k in ("kp", "kd", "ts_pos", "ts_neg", "theta_h", "theta_l")
            if hasattr(self, k)
        }


class RDFC(Southward):
    """Kang's robust digital friction compensator (eq. 11-12): digital P + hysteresis compensation with
    dead band [δ_L, δ_H] = [-δ, δ], and an analog D loop (the plant's rate feedback, K_d, at physics rate),
    so it needs a rig with an analog rate loop. "K_n θ" in (12b) is read as K_p θ (ERRATA 001); for
    (12b)'s third line see compensation()."""

    name: ClassVar[str] = "RDFC"

    def __init__(
        self,
        delta_deg: float | None = None,
        eq12b_reading: str | None = None,
        *,
        settings: RDFCSettings | None = None,
        pid: PIDSettings | None = None,
    ):
        given = {"delta_deg": delta_deg, "eq12b_reading": eq12b_reading}
        self.settings = cfg.with_overrides(
            settings or RDFCSettings.defaults(), {k: v for k, v in given.items() if v is not None}
        )
        if self.settings.eq12b_reading not in EQ12B_READINGS:
            raise ValueError(f"eq12b_reading {self.settings.eq12b_reading!r} not in {list(EQ12B_READINGS)}")
        self.pid = pid or PIDSettings.defaults()
        self.delta_deg, self.reading = self.settings.delta_deg, self.settings.eq12b_reading

    def why_not(self, scenario: Scenario) -> str | None:
        reason = super().why_not(scenario)
        if reason is None and not scenario.spec.rate_loop:
            return "needs the rig's analog rate-feedback loop (Kang §4, Fig. 4); this plant has none"
        return reason

    def plant_overrides(self, scenario: Scenario) -> dict:
        ctx = EpisodeContext(scenario, scenario.spec)
        kd = design_pid(ctx, False, self.pid).kd * scenario.spec.actuator_gain
        return {"actuator": {"rate_feedback_nm_s_per_deg": units.per_rad_to_per_deg(kd)}}

    def start(self, ctx: EpisodeContext) -> None:
        super().start(ctx)
        self.delta = units.deg_to_rad(self.delta_deg)

    def compensation(self, theta: np.ndarray, w: np.ndarray) -> np.ndarray:
        """T_n of eq. (12), K_p θ outside the listed bands. `reading` selects eq. (12b)'s third line:
        "printed" (θ̃_L ≤ θ ≤ δ_L) or "symmetric" (θ̃_L ≤ θ < 0, ERRATA 001's suggested typo fix)."""
        d_h, d_l, t = self.delta, -self.delta, theta
        rising, falling = w > 0, w < 0
        still = ~rising & ~falling
        below = t <= d_l if self.reading == "printed" else t < 0
        bands = [  # the first that holds applies
            rising & (t > 0) & (t <= self.theta_h),  # (12a)
            rising & (self.theta_l <= t) & (t <= d_l),
            rising & (d_l <= t) & (t <= 0),
            falling & (d_h < t) & (t <= self.theta_h),  # (12b)
            falling & (t >= 0) & (t <= d_h),
            falling & (self.theta_l <= t) & below,
            still & (d_h < t) & (t <= self.theta_h),  # (12c)
            still & (d_l <= t) & (t <= d_h),
            still & (self.theta_l <= t) & (t < d_l),
        ]
        levels = [
            -self.ts_neg,
            -self.ts_pos,
            0.0,
            -self.ts_neg,
            0.0,
            -self.ts_pos,
            -self.ts_neg,
            0.0,
            -self.ts_pos,
        ]
        return np.select(bands, levels, self.kp * t)

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        w = self.omega(y)  # its sign selects the hysteresis branch; D itself is analog
        torque = -self.compensation(y - r, w)
        limit = self.sc.action_scale
        return np.clip(torque / self.ctx.plant.actuator_gain, -limit, limit)

    def params(self) -> dict[str, Any]:
        return {**super().params(), "delta_deg": self.delta_deg, "eq12b_reading": self.reading}
