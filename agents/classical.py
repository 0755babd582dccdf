"""Classical baselines: PD/PID, Southward's nonlinear compensator (Kang eq. 7-8) and Kang's RDFC
(eq. 11-12), all digital at the scenario's sampling period and designed from the nominal plant."""

from __future__ import annotations

import math
from typing import Any, ClassVar

from frictiongym.envs import units
from frictiongym.envs.scenario import Scenario

from .base import EpisodeContext, PhysicalController
from .design import (
    PIDGains,
    controller_config,
    kang_pd,
    pd_by_pole_placement,
    pi_speed_loop,
    pid_by_pole_placement,
    rigid_position_plant,
)


def design_pid(ctx: EpisodeContext, integral: bool) -> PIDGains:
    """Gains for the scenario's plant from configs/controllers.yaml choices and the nominal plant."""
    cfg = controller_config()
    spec = ctx.plant
    J, c, b = rigid_position_plant(spec)
    if spec.name == "flexible_servo":
        f = cfg["pid"]["flexible_servo"]
        Jt = sum(j.inertia for j in spec.joints)
        ct = sum(j.viscous for j in spec.joints)
        return pi_speed_loop(Jt, ct, b, spec.info["k_w1"], f["natural_frequency_rad_s"], f["zeta"])
    if spec.name == "kang_robot":
        zeta = cfg["pd"]["kang_robot"]["zeta"]
        pd = kang_pd(spec, zeta)
        wn = math.sqrt(pd.kp * b / J)
    else:
        f = cfg["pd"][spec.name]
        zeta, wn = f["zeta"], 2 * math.pi * f["natural_frequency_hz"]
        pd = pd_by_pole_placement(J, c, b, wn, zeta)
    return pid_by_pole_placement(J, c, b, wn, zeta, cfg["pid"]["integrator_pole_ratio"]) if integral else pd


class PID(PhysicalController):
    """u = kp·e + ki·∫e + kd·d(-y)/dt, e = r - y: derivative on the measurement (no set-point kick),
    backward differences at T_s; conditional-integration anti-windup (the integrator holds while the
    command is saturated and the error would push it further)."""

    name: ClassVar[str] = "PID"
    plants: ClassVar[tuple[str, ...]] = ("kang_robot", "m220", "flexible_servo")
    integral: ClassVar[bool] = True

    def start(self, ctx: EpisodeContext) -> None:
        self.gains = design_pid(ctx, self.integral)
        self.i_term, self.y_prev = 0.0, None

    def command(self, y: float, r: float) -> float:
        g, h, limit = self.gains, self.h, self.sc.action_scale
        e = r - y
        d = 0.0 if self.y_prev is None else -(y - self.y_prev) / h
        self.y_prev = y
        u = g.kp * e + self.i_term + g.kd * d
        if abs(u) < limit or u * e < 0:
            self.i_term += g.ki * e * h
        return max(-limit, min(limit, u))

    def params(self) -> dict[str, Any]:
        return vars(self.gains) if hasattr(self, "gains") else {}


class PD(PID):
    """PD (PID without the integrator); not defined for the flexible servo's speed loop."""

    name: ClassVar[str] = "PD"
    plants: ClassVar[tuple[str, ...]] = ("kang_robot", "m220")
    integral: ClassVar[bool] = False


def static_bounds(ctx: EpisodeContext) -> tuple[float, float]:
    """(T_s^+, |T_s^-|) the compensator believes (N·m at the drive): the nominal plant's static levels
    scaled by knowledge.static_friction_scale (1.0 = the document's values)."""
    spec = ctx.plant
    lv = spec.joints[spec.joint_index(spec.actuator_joint)].friction.levels()
    k = ctx.knowledge.get("static_friction_scale", 1.0)
    return k * lv["static_pos"], k * lv["static_neg"]


class Southward(PhysicalController):
    """Southward et al. (Kang eq. 7-8): T_c = -K_d ω - T_n, with T_n the bang-bang compensation
    -T̃_s^∓ inside [θ̃_L, θ̃_H] and K_p θ outside (θ = position error y - r), T̃_s = margin·T_s.
    ω from the backward difference of the encoder (digital D)."""

    name: ClassVar[str] = "Southward"
    plants: ClassVar[tuple[str, ...]] = ("kang_robot", "m220")

    def applies_to(self, scenario: Scenario) -> bool:
        return super().applies_to(scenario) and scenario.reference.type == "constant"

    def start(self, ctx: EpisodeContext) -> None:
        pd = design_pid(ctx, integral=False)
        b = ctx.plant.actuator_gain
        self.kp, self.kd = pd.kp * b, pd.kd * b  # N·m/rad, N·m·s/rad
        margin = controller_config()[self.config_key]["static_friction_margin"]
        ts_pos, ts_neg = static_bounds(ctx)
        self.ts_pos, self.ts_neg = margin * ts_pos, -margin * ts_neg  # T̃_s^+ > 0, T̃_s^- < 0
        self.theta_h, self.theta_l = -self.ts_neg / self.kp, -self.ts_pos / self.kp  # eq. (8b)-(8c)
        self.y_prev = None

    config_key: ClassVar[str] = "southward"

    def omega(self, y: float) -> float:
        w = 0.0 if self.y_prev is None else (y - self.y_prev) / self.h
        self.y_prev = y
        return w

    def compensation(self, theta: float, w: float) -> float:
        """T_n of eq. (8a)."""
        if 0 < theta <= self.theta_h:
            return -self.ts_neg
        if theta == 0:
            return 0.0
        if self.theta_l <= theta < 0:
            return -self.ts_pos
        return self.kp * theta

    def command(self, y: float, r: float) -> float:
        w = self.omega(y)
        torque = -self.kd * w - self.compensation(y - r, w)
        limit = self.sc.action_scale
        return max(-limit, min(limit, torque / self.ctx.plant.actuator_gain))

    def params(self) -> dict[str, Any]:
        return {
            k: getattr(self, k)
            for k in ("kp", "kd", "ts_pos", "ts_neg", "theta_h", "theta_l")
            if hasattr(self, k)
        }


class RDFC(Southward):
    """Kang's robust digital friction compensator (eq. 11-12): digital P + hysteresis compensation with
    dead band [δ_L, δ_H] = [-δ, δ], and an analog D loop (the plant's rate feedback, K_d, at physics rate).
    "K_n θ" in (12b) is read as K_p θ (ERRATA 001); for (12b)'s third line see compensation()."""

    name: ClassVar[str] = "RDFC"
    plants: ClassVar[tuple[str, ...]] = ("kang_robot",)
    config_key: ClassVar[str] = "rdfc"

    def __init__(self, delta_deg: float | None = None, reading: str | None = None):
        cfg = controller_config()["rdfc"]
        self.delta_deg = delta_deg if delta_deg is not None else cfg["delta_deg"]
        self.reading = reading or cfg["eq12b_reading"]
        if self.reading not in ("printed", "symmetric"):
            raise ValueError(f"reading {self.reading!r} not in ['printed', 'symmetric']")

    def plant_overrides(self, scenario: Scenario) -> dict:
        ctx = EpisodeContext(scenario, scenario.spec)
        kd = design_pid(ctx, integral=False).kd * scenario.spec.actuator_gain
        return {"actuator": {"rate_feedback_nm_s_per_deg": units.per_rad_to_per_deg(kd)}}

    def start(self, ctx: EpisodeContext) -> None:
        super().start(ctx)
        self.delta = units.deg_to_rad(self.delta_deg)

    def compensation(self, theta: float, w: float) -> float:
        """T_n of eq. (12), K_p θ outside the listed bands. `reading` selects eq. (12b)'s third line:
        "printed" (θ̃_L ≤ θ ≤ δ_L) or "symmetric" (θ̃_L ≤ θ < 0, ERRATA 001's suggested typo fix)."""
        d_h, d_l = self.delta, -self.delta
        if w > 0:  # (12a)
            if 0 < theta <= self.theta_h:
                return -self.ts_neg
            if self.theta_l <= theta <= d_l:
                return -self.ts_pos
            if d_l <= theta <= 0:
                return 0.0
        elif w < 0:  # (12b)
            if d_h < theta <= self.theta_h:
                return -self.ts_neg
            if 0 <= theta <= d_h:
                return 0.0
            if self.theta_l <= theta and (theta <= d_l if self.reading == "printed" else theta < 0):
                return -self.ts_pos
        else:  # (12c)
            if d_h < theta <= self.theta_h:
                return -self.ts_neg
            if d_l <= theta <= d_h:
                return 0.0
            if self.theta_l <= theta < d_l:
                return -self.ts_pos
        return self.kp * theta

    def command(self, y: float, r: float) -> float:
        w = self.omega(y)  # its sign selects the hysteresis branch; D itself is analog
        torque = -self.compensation(y - r, w)
        limit = self.sc.action_scale
        return max(-limit, min(limit, torque / self.ctx.plant.actuator_gain))

    def params(self) -> dict[str, Any]:
        return {**super().params(), "delta_deg": self.delta_deg, "eq12b_reading": self.reading}
