"""Disturbance-observer (DOB) friction compensation (Ohnishi, Shibata and Murakami 1996, "Motion control
for advanced mechatronics", IEEE/ASME Trans. Mechatronics 1(1), §III; Sariyildiz, Oboe and Ohnishi 2020,
"Disturbance observer-based robust control and its applications: 35th anniversary overview", IEEE Trans.
Ind. Electron. 67(3), eq. 1-4): the lumped disturbance of the nominal rigid model J·v̇ + c·v = b·u + d
(friction, load, model error) is estimated through a first-order Q-filter of time constant τ and
cancelled, u = u_loop - d̂/b.

The estimate is computed from the drive's own readings and the commands it applied (held over each
period, so saturation does not wind it up):

- on a position reading (encoder), the second difference of the position over the last two periods is
  exactly the mean of the last two commands' accelerations for a zero-order-hold double integrator:
  d_raw(k) = J·(y(k) - 2y(k-1) + y(k-2))/T² + c·(y(k) - y(k-1))/T - b·(u(k-1) + u(k-2))/2;
- on a speed reading (tachometer), d_raw(k) = J·(v(k) - v(k-1))/T + c·v(k) - b·u(k-1);

and d̂(k) = a·d̂(k-1) + (1 - a)·d_raw(k), a = exp(-T/τ): Q(s) = 1/(τs + 1) sampled, so a constant
disturbance is estimated as d·(1 - exp(-t/τ)) (tests/test_toolbox.py).

The loop under it is the PD of pid.py on a position reading (the observer is the integral action) and the
P part of the PI speed loop on a tachometer; `MFF+DOB` adds the model feed-forward of
model_feedforward.py on tracking tasks, the observer fed the command without the friction feed-forward
(so it estimates only the friction that one misses, instead of cancelling it twice). J, c and b are the
nominal preset's (rigid_position_plant, or the sum of every shaft's inertia and damping for a speed
loop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.scenario import TRACKING, Scenario

from .. import settings as cfg
from ..base import EpisodeContext, drive_friction_reason
from .design import PIDGains, rigid_position_plant
from .model_feedforward import FeedForwardSettings, ModelFeedForward, scaled, tracked_joint_reason
from .pid import PID


@dataclass(frozen=True)
class ObserverEntry:
    """One plant's observer (controllers.yaml `disturbance_observer.<plant>`).

    q_time_constant_s: τ of the Q-filter (s): the estimate's bandwidth 1/τ, below the measurement noise
    that double differentiation amplifies and the drive's unmodelled dynamics.
    feedback_gain_scale: factor on the loop's designed gains (1: pid.py's design).
    """

    q_time_constant_s: float
    feedback_gain_scale: float


@dataclass(frozen=True)
class ObserverSettings(cfg.PerPlantSettings):
    """The disturbance observer per plant preset (controllers.yaml `disturbance_observer`)."""

    SECTION: ClassVar[str] = "disturbance_observer"
    ENTRY: ClassVar[type] = ObserverEntry
    KNOBS: ClassVar[dict[str, cfg.Knob]] = {
        "q_time_constant_s": cfg.Knob(1e-3, 2.0, log=True),
        "feedback_gain_scale": cfg.Knob(0.1, 4.0, log=True),
    }
    plants: dict[str, Any]

    @classmethod
    @cache
    def defaults(cls) -> ObserverSettings:
        return cfg.read(cls.SECTION, lambda s: cls(cls.read_section(s)))


class DisturbanceObserver(PID):
    """PD (position) or P (speed) loop plus the disturbance observer's cancellation (module docstring)."""

    name: ClassVar[str] = "DOB"
    tunes: ClassVar[tuple[str, type]] = ("observer", ObserverSettings)  # agents/tuning/search.py
    integral: ClassVar[bool] = False
    with_feedforward: ClassVar[bool] = False

    def __init__(
        self,
        observer: ObserverSettings | None = None,
        ff: FeedForwardSettings | None = None,
        **overrides: Any,
    ):
        super().__init__(**overrides)
        self.observer = observer or ObserverSettings.defaults()
        self.ff_settings = ff or FeedForwardSettings.defaults()

    def why_not(self, scenario: Scenario) -> str | None:
        reason = super().why_not(scenario) or drive_friction_reason(scenario)
        if reason is None and self.with_feedforward:
            reason = tracked_joint_reason(scenario)
        return reason

    def start(self, ctx: EpisodeContext) -> None:
        super().start(ctx)
        e = self.observer.of(ctx.plant.name)
        g = scaled(self.gains, e.feedback_gain_scale)
        self.gains = PIDGains(kp=g.kp, ki=0.0, kd=g.kd)  # the observer is the loop's integral action
        spec, sensor = ctx.plant, ctx.plant.sensors[ctx.scenario.tracked_sensor]
        self.speed = sensor.kind == "tacho"
        if self.speed:
            self.J = sum(j.inertia for j in spec.joints)
            self.c = sum(j.viscous + (j.friction.sigma2 if j.friction else 0.0) for j in spec.joints)
        else:
            self.J, self.c, _ = rigid_position_plant(spec)
        self.b, self.gain = spec.actuator_gain, sensor.gain
        self.a = math.exp(-self.h / e.q_time_constant_s)
        self.readings: list[np.ndarray] = []  # y(k-2), y(k-1) in drive units
        zero = np.zeros(self.episodes)
        self.u_prev = [zero, zero]  # u(k-1), u(k-2): the commands applied (saturated)
        self.d_hat = zero  # N·m (N on a carriage)
        tracking = self.with_feedforward and ctx.scenario.task == TRACKING
        self.ff = ModelFeedForward(ctx, self.ff_settings.of(spec.name)) if tracking else None

    def estimate(self, x: np.ndarray) -> np.ndarray:
        """d̂ after the readings x (drive units: rad, m or rad/s), from the commands applied before them."""
        T, (u1, u2) = self.h, self.u_prev
        self.readings = [*self.readings[-2:], x]
        if self.speed and len(self.readings) >= 2:
            v0, v1 = self.readings[-2:]
            raw = self.J * (v1 - v0) / T + self.c * v1 - self.b * u1
        elif not self.speed and len(self.readings) == 3:
            y2, y1, y0 = self.readings
            raw = self.J * (y0 - 2 * y1 + y2) / T**2 + self.c * (y0 - y1) / T - self.b * 0.5 * (u1 + u2)
        else:
            return self.d_hat
        self.d_hat = self.a * self.d_hat + (1.0 - self.a) * raw
        return self.d_hat

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        d_hat = self.estimate(y / self.gain)
        ff = self.ff.command(r, self.preview) if self.ff is not None else 0.0
        u = self.feedback(y, r, ff - d_hat / self.b)
        # the observer sees the command without the friction feed-forward: it estimates what that misses
        fric = self.ff.friction if self.ff is not None else 0.0
        self.u_prev = [u - fric, self.u_prev[0]]
        return u

    def params(self) -> dict[str, Any]:
        return {**super().params(), "q_filter_pole": getattr(self, "a", None)}


class ModelFFDisturbanceObserver(DisturbanceObserver):
    """The disturbance observer with the model feed-forward on tracking tasks (module docstring)."""

    name: ClassVar[str] = "MFF+DOB"
    with_feedforward: ClassVar[bool] = True
