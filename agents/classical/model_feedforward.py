"""Two-degree-of-freedom control: model-based feed-forward from the reference preview on top of a feedback
loop, as a servo engineer would field it (Ellis 2012, *Control System Design Guide*, 4th ed., ch. 17
"Command feed-forward"; Åström and Murray 2008, *Feedback Systems*, §12.1-12.2 "Feedforward design").

The feed-forward is the nominal plant's inverse applied to the reference: on a rigid drive (every joint
coupled by belts, the rigid_position_plant of design.py)

    u_ff = (J·r̈ + c·ṙ)/b + Σ_j r_j·(tanh(r_j·ṙ/v_ε)·g_j(r_j·ṙ) - β_j·|tanh(r_j·ṙ/v_ε)|)/b

with J, c the inertia and linear damping reflected to the drive, b the actuator gain, r_j each friction
joint's speed ratio, g_j its Stribeck curve (Iurian et al. 2005 eq. 2) and β_j its asymmetry bias: the
friction model's steady state (Coulomb, Stribeck, asymmetry) with a smooth zero-velocity transition of width
v_ε in place of sgn (a discontinuous sign on the reference's rounding chatters at reversals). On the flexible
servo (speed tracking on the motor tacho, Wallenborg 1987 eq. 3.1) the inverse is the two-mass one: the load's
motion under the reference speed ω1_r is simulated (exact zero-order-hold discretisation of the shaft and
load, its friction from the simulated speed) and the motor torque is J1·ω̇1_r + (d1 + d)·ω1_r - d·ω2 - k·(θ2 -
θ1) + F1(ω1_r).

The reference's rate and acceleration are central differences of the previewed samples (r(k+1) from the
preview), evaluated `lead_steps` periods ahead to cover the drive's delay; without a preview (the flexible
servo's scenarios) backward differences of the references seen so far.

Families (registry names):

- `PID+MFF`: the feed-forward on the PID loop of pid.py (a PI speed loop on a tachometer); the loop's
  anti-windup judges the applied total.
- `Cascade+MFF`: the structure industrial drives use, a P position loop over a PI velocity loop with
  velocity and acceleration feed-forward (Ellis 2012 §17.2; ch. 6-7 for the PI velocity loop): the
  velocity command is ṙ + K_p·(r - y), the velocity loop's output plus u_ff is the command. Position
  tracking only (on a speed reading it is PID+MFF).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import numpy as np
from scipy.signal import cont2discrete

from frictiongym.envs.plants import PlantSpec
from frictiongym.envs.plants.flexible_servo import state_space
from frictiongym.envs.plants.identified import speed_ratios
from frictiongym.envs.scenario import TRACKING, Scenario

from .. import settings as cfg
from ..base import ArrayController, EpisodeContext, drive_friction_reason, elementwise
from .design import PIDGains, rigid_position_plant
from .pid import PID


@dataclass(frozen=True)
class FeedForwardEntry:
    """One plant's feed-forward choices (controllers.yaml `model_feedforward.<plant>`).

    smoothing_speed_per_s: v_ε, the width of the smooth Coulomb transition (drive units/s: rad/s or m/s).
    lead_steps: periods ahead at which the reference's derivatives are taken (the drive's delay).
    inertia_scale, friction_scale: shares of the nominal inertia/damping and friction terms fed forward.
    feedback_gain_scale: factor on the feedback loop's designed gains (1: the design of pid.py).
    """

    smoothing_speed_per_s: float
    lead_steps: int
    inertia_scale: float
    friction_scale: float
    feedback_gain_scale: float


@dataclass(frozen=True)
class FeedForwardSettings(cfg.PerPlantSettings):
    """Model feed-forward choices per plant preset (controllers.yaml `model_feedforward`)."""

    SECTION: ClassVar[str] = "model_feedforward"
    ENTRY: ClassVar[type] = FeedForwardEntry
    KNOBS: ClassVar[dict[str, cfg.Knob]] = {
        "smoothing_speed_per_s": cfg.Knob(1e-5, 1.0, log=True),
        "lead_steps": cfg.Knob(0, 3, whole=True),
        "inertia_scale": cfg.Knob(0.0, 2.0),
        "friction_scale": cfg.Knob(0.0, 2.0),
        "feedback_gain_scale": cfg.Knob(0.1, 4.0, log=True),
    }
    plants: dict[str, Any]

    @classmethod
    @cache
    def defaults(cls) -> FeedForwardSettings:
        return cfg.read(cls.SECTION, lambda s: cls(cls.read_section(s)))


def tracked_joint_reason(scenario: Scenario) -> str | None:
    """Why the model feed-forward cannot be built for the scenario's tracked reading, or None: it needs the
    reading on the actuated joint and friction there."""
    spec = scenario.spec
    sensor = spec.sensors[scenario.tracked_sensor]
    if sensor.joint != spec.actuator_joint:
        return f"tracks {sensor.name} on {sensor.joint}, not the driven joint {spec.actuator_joint}"
    return drive_friction_reason(scenario)


class ReferenceWindow:
    """The reference samples a controller has seen, r(k-2), r(k-1), r(k), and the preview r(k+1..k+P),
    with its derivatives at k + lead: central differences where the preview reaches, else backward. Each
    row an episode's."""

    def __init__(self, h: float):
        self.h = h
        self.past: np.ndarray | None = None  # (n, 2): r(k-2), r(k-1)

    def derivatives(
        self, r: np.ndarray, preview: np.ndarray, lead: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(value, rate, acceleration) of the references (n,) at k + lead (units, units/s, units/s²), from
        the references now and their previews (n, P)."""
        if self.past is None:
            self.past = np.stack([r, r], axis=1)
        s = np.concatenate([self.past, r[:, None], preview.astype(np.float64)], axis=1)
        self.past = s[:, 1:3]
        m = 2 + min(lead, s.shape[1] - 3)  # index of k + lead, leaving room for the backward stencil
        h = self.h
        if m + 1 < s.shape[1]:
            now, ahead, back = s[:, m], s[:, m + 1], s[:, m - 1]
            return now, (ahead - back) / (2 * h), (ahead - 2 * now + back) / (h * h)
        now, back, back2 = s[:, m], s[:, m - 1], s[:, m - 2]
        return now, (now - back) / h, (now - 2 * back + back2) / (h * h)


def smooth_friction(spec: PlantSpec, joint: str, speeds: np.ndarray, width: float) -> np.ndarray:
    """The steady friction torque of the named joint at these speeds (rad/s or m/s), the sign replaced by
    tanh(v/width): N·m or N on the joint, not reflected (zero on a joint without friction)."""
    p = spec.joints[spec.joint_index(joint)].friction
    if p is None:
        return np.zeros_like(speeds)
    s = elementwise(math.tanh, speeds / width)
    return 0.0 + (s * p.g(speeds) - p.bias * np.abs(s))


class ModelFeedForward:
    """The nominal plant's inverse on the reference (module docstring), in command units: rigid on a
    position reading, two-mass on a speed reading of a spring-coupled drive, rigid on any other speed
    reading. Each row an episode's (ctx.episodes)."""

    def __init__(self, ctx: EpisodeContext, entry: FeedForwardEntry):
        spec, sc = ctx.plant, ctx.scenario
        self.spec, self.entry, self.h = spec, entry, sc.control_period
        sensor = spec.sensors[sc.tracked_sensor]
        self.gain = sensor.gain  # reading per drive unit (1 for an encoder, V per rad/s for a tacho)
        self.speed = sensor.kind == "tacho"
        self.window = ReferenceWindow(self.h)
        self.b = spec.actuator_gain
        self.two_mass = self.speed and bool(spec.springs)
        if self.two_mass:
            self._two_mass_start(spec, ctx.episodes)
        elif self.speed:
            self.J = sum(j.inertia for j in spec.joints)
            self.c = sum(j.viscous + (j.friction.sigma2 if j.friction else 0.0) for j in spec.joints)
            self.ratios = {j.name: 1.0 for j in spec.joints}
        else:
            self.J, self.c, _ = rigid_position_plant(spec)
            self.ratios = speed_ratios(spec)
        self.rate = np.zeros(ctx.episodes)  # the references' drive speeds at the last call (units/s)
        self.friction = np.zeros(ctx.episodes)  # the friction part of the last u_ff (command units)

    def _two_mass_start(self, spec: PlantSpec, episodes: int) -> None:
        """The load's model under the reference speed: x = (ω2, θ2 - θ1), driven by ω1 and the load
        friction, exact ZOH over the control period (Wallenborg 1987 eq. 3.1)."""
        A, _, _ = state_space(spec)
        J1, J2 = (j.inertia for j in spec.joints)
        d1 = spec.joints[0].viscous
        self.k, self.d = spec.springs[0].stiffness, spec.springs[0].damping
        self.J1, self.d1 = J1, d1
        Al = A[1:, 1:]  # ω2' and φ' rows on (ω2, φ)
        Bl = np.array([[A[1, 0], -1.0 / J2], [A[2, 0], 0.0]])  # inputs (ω1, F2)
        Ad, Bd, *_ = cont2discrete((Al, Bl, np.eye(2), np.zeros((2, 2))), self.h)
        self.Ad, self.Bd = Ad, Bd
        self.x = np.zeros((episodes, 2))
        self.load = spec.joints[1].name

    def command(self, r: np.ndarray, preview: np.ndarray) -> np.ndarray:
        """u_ff (command units) for the references now (n,) and their previews (n, P)."""
        e = self.entry
        value, rate, accel = self.window.derivatives(r, preview, e.lead_steps)
        if self.speed:  # the reading is a speed: its value is the speed, its rate the acceleration
            v, a = value / self.gain, rate / self.gain
        else:
            v, a = rate / self.gain, accel / self.gain
        self.rate = v
        width = e.smoothing_speed_per_s
        if self.two_mass:
            w2, phi = self.x[:, 0], self.x[:, 1]
            f1 = smooth_friction(self.spec, self.spec.joints[0].name, v, width)
            f2 = smooth_friction(self.spec, self.load, w2, width)
            tau = e.inertia_scale * (self.J1 * a + (self.d1 + self.d) * v - self.d * w2 - self.k * phi)
            drive = np.stack([v, e.friction_scale * f2], axis=1)
            self.x = np.matvec(self.Ad, self.x) + np.matvec(self.Bd, drive)
            self.friction = e.friction_scale * f1 / self.b
            return tau / self.b + self.friction
        fr = np.zeros_like(v)  # each joint's friction reflected to the drive through its speed ratio
        for n, rj in self.ratios.items():
            fr = fr + rj * smooth_friction(self.spec, n, rj * v, width)
        self.friction = e.friction_scale * fr / self.b
        return e.inertia_scale * (self.J * a + self.c * v) / self.b + self.friction


def scaled(g: PIDGains, k: float) -> PIDGains:
    """Every gain times k."""
    return PIDGains(kp=k * g.kp, ki=k * g.ki, kd=k * g.kd)


class PIDModelFF(PID):
    """PID (a PI speed loop on a tachometer) plus the model feed-forward (module docstring): u = u_fb +
    u_ff, saturated, the integrator's anti-windup judging the total. Tracking tasks; needs the reading on
    the driven joint and friction there."""

    name: ClassVar[str] = "PID+MFF"
    tunes: ClassVar[tuple[str, type]] = ("ff", FeedForwardSettings)  # agents/tuning/search.py
    tasks: ClassVar[tuple[str, ...]] = (TRACKING,)

    def __init__(self, ff: FeedForwardSettings | None = None, **overrides: Any):
        super().__init__(**overrides)
        self.ff_settings = ff or FeedForwardSettings.defaults()

    def why_not(self, scenario: Scenario) -> str | None:
        return super().why_not(scenario) or tracked_joint_reason(scenario)

    def start(self, ctx: EpisodeContext) -> None:
        super().start(ctx)
        entry = self.ff_settings.of(ctx.plant.name)
        self.gains = scaled(self.gains, entry.feedback_gain_scale)
        self.ff = ModelFeedForward(ctx, entry)

    def feedforward(self, r: np.ndarray) -> np.ndarray:
        """u_ff now (command units); a subclass adds its own correction."""
        return self.ff.command(r, self.preview)

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        return self.feedback(y, r, self.feedforward(r))

    def params(self) -> dict[str, Any]:
        return (
            {**super().params(), **vars(self.ff_settings.of(self.ctx.plant.name))}
            if hasattr(self, "ctx")
            else {}
        )


@dataclass(frozen=True)
class CascadeEntry:
    """One plant's cascade (controllers.yaml `cascade.<plant>`).

    velocity_bandwidth_rad_s: ω_v of the PI velocity loop, closed loop s² + 2ζω_v s + ω_v² on the rigid
    model (rad/s). zeta: its damping. position_ratio: K_p/ω_v, the P position loop's bandwidth as a share
    of the velocity loop's (Ellis 2012 §17.2: a quarter to a third). velocity_filter_s: first-order filter
    on the encoder-difference velocity (s; 0 none).
    """

    velocity_bandwidth_rad_s: float
    zeta: float
    position_ratio: float
    velocity_filter_s: float


@dataclass(frozen=True)
class CascadeSettings(cfg.PerPlantSettings):
    """The P/PI cascade's design per plant preset (controllers.yaml `cascade`)."""

    SECTION: ClassVar[str] = "cascade"
    ENTRY: ClassVar[type] = CascadeEntry
    KNOBS: ClassVar[dict[str, cfg.Knob]] = {
        "velocity_bandwidth_rad_s": cfg.Knob(1.0, 2000.0, log=True),
        "zeta": cfg.Knob(0.3, 2.0),
        "position_ratio": cfg.Knob(0.05, 0.6),
        "velocity_filter_s": cfg.Knob(0.0, 0.05),
    }
    plants: dict[str, Any]

    @classmethod
    @cache
    def defaults(cls) -> CascadeSettings:
        return cfg.read(cls.SECTION, lambda s: cls(cls.read_section(s)))


class CascadeModelFF(ArrayController):
    """P position loop over a PI velocity loop with the model feed-forward (module docstring):
    v* = ṙ + K_p·(r - y), u = K_v·(v* - v̂) + K_i·∫(v* - v̂) + u_ff, saturated, the integrator held while the
    total is saturated and the error would push it further. K_v = (2ζω_v J - c)/b, K_i = J·ω_v²/b,
    K_p = position_ratio·ω_v; v̂ the encoder difference, filtered if velocity_filter_s > 0."""

    name: ClassVar[str] = "Cascade+MFF"
    tunes: ClassVar[tuple[str, type]] = ("settings", CascadeSettings)  # agents/tuning/search.py
    sensor_kinds: ClassVar[tuple[str, ...]] = ("encoder",)
    tasks: ClassVar[tuple[str, ...]] = (TRACKING,)

    def __init__(
        self, settings: CascadeSettings | None = None, ff: FeedForwardSettings | None = None
    ) -> None:
        self.settings = settings or CascadeSettings.defaults()
        self.ff_settings = ff or FeedForwardSettings.defaults()

    def why_not(self, scenario: Scenario) -> str | None:
        return super().why_not(scenario) or tracked_joint_reason(scenario)

    def start(self, ctx: EpisodeContext) -> None:
        e = self.settings.of(ctx.plant.name)
        J, c, b = rigid_position_plant(ctx.plant)
        w = e.velocity_bandwidth_rad_s
        self.kv = max(0.0, (2 * e.zeta * w * J - c) / b)
        self.ki, self.kp = J * w * w / b, e.position_ratio * w
        self.alpha = 1.0 - math.exp(-self.h / e.velocity_filter_s) if e.velocity_filter_s > 0 else 1.0
        self.ff = ModelFeedForward(ctx, self.ff_settings.of(ctx.plant.name))
        self.y_prev: np.ndarray | None = None
        self.v_hat, self.i_term = np.zeros(self.episodes), np.zeros(self.episodes)

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        u_ff = self.ff.command(r, self.preview)
        v = np.zeros_like(y) if self.y_prev is None else (y - self.y_prev) / self.h
        self.y_prev = y
        self.v_hat = self.v_hat + self.alpha * (v - self.v_hat)
        ev = self.ff.rate * self.ff.gain + self.kp * (r - y) - self.v_hat
        u = self.kv * ev + self.i_term + u_ff
        limit = self.sc.action_scale
        grow = (np.abs(u) < limit) | (u * ev < 0)
        self.i_term = np.where(grow, self.i_term + self.ki * ev * self.h, self.i_term)
        return np.clip(u, -limit, limit)

    def params(self) -> dict[str, Any]:
        return {"kp": self.kp, "kv": self.kv, "ki": self.ki} if hasattr(self, "kp") else {}
