"""Wallenborg's state feedback + observer for the flexible servo (seed 002 §4, Appendix B CSFNL/DSFNL),
with the friction compensation variants of §6.3: none, relay with dead zone, high gain with saturation."""

from __future__ import annotations

from typing import Any, ClassVar

import control
import numpy as np

from frictiongym.envs.servo_env import decode_observation

from .base import Controller, EpisodeContext
from .design import controller_config, state_feedback_design

COMPENSATION = ("none", "relay", "highgain")


class StateFeedback(Controller):
    """u = u0 + u_f, u0 = clip(l_r·y_r - L x̂, ±u_max); the observer is fed u0 (as in CSFNL/DSFNL) and the
    friction torque estimate u_f = M_f/(k_m k_i) acts on the estimated output ŷ = C x̂:
    high gain: M_f = F·ŷ/ε (|ŷ| < ε) else F·sgn(ŷ); relay: 0 (|ŷ| < ε) else F·sgn(ŷ).
    Continuous design (§4.1, its observer discretised exactly over the hold period) when the scenario
    samples fast, else the digital design (§4.2) with the latest-measurement observer."""

    name: ClassVar[str] = "SF"
    plants: ClassVar[tuple[str, ...]] = ("flexible_servo",)

    def __init__(self, compensation: str = "none", w_cl: float | None = None, sensor: str = "y1"):
        if compensation not in COMPENSATION:
            raise ValueError(f"compensation {compensation!r} not in {COMPENSATION}")
        if sensor not in ("y1", "y2"):
            raise ValueError(f"sensor {sensor!r} not in ['y1', 'y2']")
        cfg = controller_config()["state_feedback"]
        self.cfg, self.compensation, self.sensor = cfg, compensation, sensor
        self.w_cl = w_cl if w_cl is not None else cfg["w_cl"]
        suffix = {"none": "", "relay": "+relay", "highgain": "+highgain"}[compensation]
        self.name = (
            f"SF{suffix}" if (w_cl is None and sensor == "y1") else f"SF(w{self.w_cl:g},{sensor}){suffix}"
        )

    def reset(self, ctx: EpisodeContext) -> None:
        sc = self.sc = ctx.scenario
        h = sc.control_period
        self.continuous = h <= self.cfg["continuous_max_period_s"]
        c = self.cfg
        d = self.design = state_feedback_design(
            ctx.plant, self.w_cl, c["zeta"], c["alpha"], self.sensor, 0.0 if self.continuous else h
        )
        if self.continuous:  # exact ZOH of x̂' = (A - KC) x̂ + [B K] [u0; y] over one period
            obs = control.c2d(
                control.ss(d.A - d.K @ d.C, np.hstack([d.B, d.K]), np.eye(3), 0), h, method="zoh"
            )
            self.Ad, self.Bd = np.asarray(obs.A), np.asarray(obs.B)
        spec = ctx.plant
        F = (
            spec.joints[0].friction.levels()
            if spec.joints[0].friction
            else {"static_pos": 0.0, "static_neg": 0.0}
        )
        scale = ctx.knowledge.get("static_friction_scale", 1.0)
        self.F_pos, self.F_neg = scale * F["static_pos"], scale * F["static_neg"]
        self.gain = spec.actuator_gain  # k_m·k_i, N·m/V
        self.x = np.zeros(3)  # x̂(k|k-1) (digital) or x̂(t_k) (continuous)
        self.tacho = "tacho1" if self.sensor == "y1" else "tacho2"

    def friction_command(self, y_est: float) -> float:
        """u_f (V) from the estimated output (V), eq. (6.13)/(6.14) as coded in CSFNL/DSFNL."""
        eps = self.cfg["eps_v"]
        F = self.F_pos if y_est > 0 else self.F_neg
        if self.compensation == "none":
            return 0.0
        if abs(y_est) < eps:
            return F * y_est / eps / self.gain if self.compensation == "highgain" else 0.0
        return float(np.sign(y_est)) * F / self.gain

    def act(self, obs: np.ndarray) -> np.ndarray:
        o = decode_observation(self.sc, obs)
        y, yr = o["sensors"][self.tacho], o["reference"]
        d = self.design
        umax = self.cfg["u_max_v"]
        if self.continuous:
            xe = self.x
            u0 = float(np.clip(d.lr * yr - (d.L @ xe).item(), -umax, umax))
            self.x = self.Ad @ xe + self.Bd @ np.array([u0, y])
        else:
            xe = self.x + d.K.ravel() * (y - (d.C @ self.x).item())
            u0 = float(np.clip(d.lr * yr - (d.L @ xe).item(), -umax, umax))
            self.x = d.Phi @ xe + d.Gamma.ravel() * u0
        u = u0 + self.friction_command((d.C @ xe).item())
        return np.array([u / self.sc.action_scale], dtype=np.float32)

    def params(self) -> dict[str, Any]:
        d = getattr(self, "design", None)
        return (
            {}
            if d is None
            else {
                "L": d.L.ravel().tolist(),
                "K": d.K.ravel().tolist(),
                "lr": d.lr,
                "continuous": self.continuous,
                "compensation": self.compensation,
            }
        )
