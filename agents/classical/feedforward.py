"""Coulomb + viscous friction feed-forward from identified parameters (Iurian et al. 2005 §2.3 for the M220)
on top of the PD position loop of pid.py (`CoulombViscousFF`) or of its PID loop (`PIDCoulombViscousFF`), for
tracking a previewed reference."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from frictiongym.envs.scenario import TRACKING, Scenario

from ..base import EpisodeContext, drive_friction_reason
from .pid import PID


class CoulombViscousFF(PID):
    """u = u_fb + (F_C^± sgn(v_r) + σ2 v_r)/k_act with v_r the reference velocity (backward difference of
    the reference), the identified levels of the plant preset. Needs a reference preview (a tracking
    scenario with preview_steps > 0)."""

    name: ClassVar[str] = "CoulombViscousFF"
    sensor_kinds: ClassVar[tuple[str, ...]] = ("encoder",)
    tasks: ClassVar[tuple[str, ...]] = (TRACKING,)
    integral: ClassVar[bool] = False

    def why_not(self, scenario: Scenario) -> str | None:
        reason = super().why_not(scenario) or drive_friction_reason(scenario)
        if reason is None and scenario.preview_steps == 0:
            return "needs a reference preview (reference.preview_steps > 0)"
        return reason

    def start(self, ctx: EpisodeContext) -> None:
        super().start(ctx)
        self.p = ctx.plant.drive_friction
        self.levels = self.p.levels()
        self.r_prev: np.ndarray | None = None

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        vr = np.zeros_like(r) if self.r_prev is None else (r - self.r_prev) / self.h
        self.r_prev = r
        u_fb = super().commands(y, r)
        lv = self.levels
        coulomb = np.where(vr > 0, lv["coulomb_pos"], np.where(vr < 0, -lv["coulomb_neg"], 0.0))
        ff = coulomb + self.p.sigma2 * vr
        limit = self.sc.action_scale
        return np.clip(u_fb + ff / self.ctx.plant.actuator_gain, -limit, limit)


class PIDCoulombViscousFF(CoulombViscousFF):
    """The same feed-forward on the PID loop of pid.py: the integrator removes what the identified levels
    miss (a drawn friction scale, asymmetry, drift) and the feed-forward takes the Coulomb step at a
    reversal off the integrator, which otherwise has to wind through it. The integrator's anti-windup
    sees the feedback part of the command (pid.PID.command); the applied total, measured against it, is in
    docs/research.md ("PID+FF")."""

    name: ClassVar[str] = "PID+FF"
    integral: ClassVar[bool] = True
