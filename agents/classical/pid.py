"""PD and PID (derivative on the measurement, conditional-integration anti-windup), digital at the
scenario's sampling period and designed from the nominal plant by pole placement; on a speed reading
(tachometer) the same loop is a PI speed controller."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.config import Node
from frictiongym.envs.plants import PlantSpec
from frictiongym.envs.scenario import Scenario

from .. import settings as cfg
from ..base import ArrayController, EpisodeContext
from .design import (
    PIDGains,
    pd_by_pole_placement,
    pd_from_stiffness,
    pi_speed_loop,
    pid_by_pole_placement,
    rigid_position_plant,
)


@dataclass(frozen=True)
class LoopDesign:
    """Closed-loop choice for one plant: damping ζ and natural frequency ω_n (rad/s); ω_n None means
    "from the plant document's position stiffness K_p" (Kang §6). lab_controller: the plant's own lab
    controller instead (its document's gains and velocity filter, EMPS eq. 6); ζ and ω_n then follow."""

    zeta: float | None
    natural_frequency_rad_s: float | None = None
    lab_controller: bool = False


@dataclass(frozen=True)
class PIDSettings(cfg.FamilySettings):
    """PD/PID design choices (controllers.yaml `pid`): integrator pole a = integrator_pole_ratio·ω_n, and
    the loop design per plant preset (sources in the YAML)."""

    SECTION: ClassVar[str] = "pid"
    integrator_pole_ratio: float
    loops: Mapping[str, LoopDesign]

    @classmethod
    @cache
    def defaults(cls) -> PIDSettings:
        def build(s: Node) -> PIDSettings:
            loops = {}
            ls = s.section("loops")
            for plant in list(ls.keys()):
                p = ls.section(plant)
                if p.boolean("lab_controller", default=False):
                    loops[plant] = LoopDesign(None, None, lab_controller=True)
                    continue
                hz, rad = p.get("natural_frequency_hz"), p.get("natural_frequency_rad_s")
                if hz is not None and rad is not None:
                    raise p.error("natural_frequency_hz", "give natural_frequency_hz or _rad_s, not both")
                wn = (
                    2 * math.pi * p.positive("natural_frequency_hz", 1e4)
                    if hz is not None
                    else p.positive("natural_frequency_rad_s", 1e5)
                    if rad is not None
                    else None
                )
                loops[plant] = LoopDesign(p.positive("zeta", 10.0), wn)
            return cls(s.positive("integrator_pole_ratio", 100.0), loops)

        return cfg.read(cls.SECTION, build)

    def loop(self, spec: PlantSpec) -> LoopDesign:
        if spec.name not in self.loops:
            raise ValueError(
                f"no PID loop design for plant {spec.name!r}; settings have {sorted(self.loops)}"
            )
        return self.loops[spec.name]


def design_pid(ctx: EpisodeContext, integral: bool, settings: PIDSettings | None = None) -> PIDGains:
    """Gains for the scenario's tracked reading from the settings and the nominal plant."""
    settings = settings or PIDSettings.defaults()
    spec = ctx.plant
    loop = settings.loop(spec)
    sensor = spec.sensors[ctx.scenario.tracked_sensor]
    J, c, b = rigid_position_plant(spec)
    if sensor.kind == "tacho":  # PI speed loop on the rigid-body model of all shafts
        Jt = sum(j.inertia for j in spec.joints)
        ct = sum(j.viscous for j in spec.joints)
        return pi_speed_loop(Jt, ct, b, sensor.gain, loop.natural_frequency_rad_s, loop.zeta)
    zeta = loop.zeta
    if loop.lab_controller:
        pd = lab_gains(spec)
        wn = math.sqrt(pd.kp * b / J)
        zeta = (c + b * pd.kd) / (2 * wn * J)  # the lab's loop, J s² + (c + b·kd) s + b·kp
    elif loop.natural_frequency_rad_s is None:
        pd = pd_from_stiffness(J, c, b, spec.document.kp_nm_per_rad, zeta)
        wn = math.sqrt(pd.kp * b / J)
    else:
        wn = loop.natural_frequency_rad_s
        pd = pd_by_pole_placement(J, c, b, wn, zeta)
    return pid_by_pole_placement(J, c, b, wn, zeta, settings.integrator_pole_ratio) if integral else pd


def lab_gains(spec: PlantSpec) -> PIDGains:
    """The PD gains of the plant's own lab controller, ν = kp·kv·(r - q) - kv·q̇ (EMPS eq. 6): kp·kv per
    unit of position, kv per unit/s (V per m, V·s/m)."""
    doc = spec.document
    kp, kv = doc.lab_kp_per_s, doc.lab_kv_v_per_m_s
    return PIDGains(kp=kp * kv, ki=0.0, kd=kv)


def has_lab_controller(spec: PlantSpec) -> bool:
    """Whether the plant's document gives a lab controller (EMPS eq. 6)."""
    return hasattr(spec.document, "lab_kp_per_s")


class PID(ArrayController):
    """u = kp·e + ki·∫e + kd·d(-y)/dt, e = r - y: derivative on the measurement (no set-point kick),
    backward differences at T_s (or, on a plant whose loop is its lab controller, the lab's velocity
    FIR: EMPS §2.2's 2-tap average, i.e. (y(k) - y(k-2))/(2 T_s)); conditional-integration anti-windup
    (the integrator holds while the command is saturated and the error would push it further). In a
    blend (authority(share)) it integrates share·e: only its part of the applied command."""

    name: ClassVar[str] = "PID"
    integral: ClassVar[bool] = True

    def __init__(self, settings: PIDSettings | None = None, **overrides: Any):
        self.settings = cfg.with_overrides(settings or PIDSettings.defaults(), overrides)

    def start(self, ctx: EpisodeContext) -> None:
        self.gains = design_pid(ctx, self.integral, self.settings)
        lab = self.settings.loop(ctx.plant).lab_controller
        self.fir = ctx.plant.document.lab_fir if lab else None
        self.i_term = np.zeros(self.episodes)
        self.y_prev: np.ndarray | None = None  # the last readings, none before the first
        self.qf_prev: np.ndarray | None = None
        self.share: float | np.ndarray = 1.0

    def authority(self, share: float | np.ndarray) -> None:
        self.share = share

    def loop_velocity(self, y: np.ndarray) -> np.ndarray:
        """The loop's velocity estimate (units/s) from these readings and the previous ones."""
        if self.fir is not None:  # qf(k) = a·y(k) + b·y(k-1); v = (qf(k) - qf(k-1))/h
            prev = y if self.y_prev is None else self.y_prev
            qf = self.fir[0] * y + self.fir[1] * prev
            v = np.zeros_like(y) if self.qf_prev is None else (qf - self.qf_prev) / self.h
            self.qf_prev = qf
            return v
        return np.zeros_like(y) if self.y_prev is None else (y - self.y_prev) / self.h

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        return self.feedback(y, r, 0.0)

    def feedback(self, y: np.ndarray, r: np.ndarray, offset: float | np.ndarray) -> np.ndarray:
        """The loop's command plus `offset` (a feed-forward, command units), saturated; the integrator's
        anti-windup judges the applied total (0.0 added to a float leaves it unchanged: PID alone)."""
        g, h, limit = self.gains, self.h, self.sc.action_scale
        e = r - y
        d = -self.loop_velocity(y)
        self.y_prev = y
        u = g.kp * e + self.i_term + g.kd * d + offset
        grow = (np.abs(u) < limit) | (u * e < 0)
        self.i_term = np.where(grow, self.i_term + self.share * g.ki * e * h, self.i_term)
        return np.clip(u, -limit, limit)

    def params(self) -> dict[str, Any]:
        return vars(self.gains) if hasattr(self, "gains") else {}


class PD(PID):
    """PD (PID without the integrator), for position loops."""

    name: ClassVar[str] = "PD"
    sensor_kinds: ClassVar[tuple[str, ...]] = ("encoder",)
    integral: ClassVar[bool] = False

    def why_not(self, scenario: Scenario) -> str | None:
        if self.name == "PD" and self.settings.loop(scenario.spec).lab_controller:
            return "the plant's PD loop is its lab controller: see LabPD"
        return super().why_not(scenario)


class LabPD(PD):
    """The plant's own lab controller, as the lab ran it: the EMPS PD of eq. (6) with the 2-tap FIR
    velocity of §2.2, ν = kp·kv·(r - q) - kv·q̇m, saturated at the action scale (±10 V)."""

    name: ClassVar[str] = "LabPD"

    def why_not(self, scenario: Scenario) -> str | None:
        if not has_lab_controller(scenario.spec):
            return f"plant {scenario.spec.name} has no lab controller in its document"
        if not self.settings.loop(scenario.spec).lab_controller:
            return f"controllers.yaml pid.loops.{scenario.spec.name} is not lab_controller: true"
        return super(PD, self).why_not(scenario)
