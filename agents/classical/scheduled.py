"""A speed-scheduled blend of two classical loops, for use as a residual base (not a baseline: no source
document describes it, so the leaderboard does not rank it unless asked by name).

On the M220 no classical loop is best everywhere (validation suite, docs/research.md "Generalists"): PID
at set-points and on the 0.05 Hz reversals, where the LuGre observer's velocity estimate is the encoder's
quantisation (one count per 5 ms period is 0.0785 rad/s) and its compensation chatters; the LuGre observer
on faster motion. This loop runs both on every sample and applies u = (1 - w)·u_low + w·u_high, with the
weight w rising from 0 to 1 as the reference's speed envelope s goes from speed_low to speed_high:
s(k) = max(|r(k) - r(k-1)|/h, s(k-1)·exp(-h/hold_s)), so that a motion keeps its weight through the
moment of its reversal (where the reference speed passes through zero) and a hold returns to the low
loop within a few hold_s.

One class, SpeedScheduled, with every option a setting of its plant's schedule (controllers.yaml
`speed_scheduled.<plant>`): bumpless transfer, a filter on the high loop's velocity, another low loop on
tracking tasks, and the share of a residual's authority it grants (gate none / motion / rest / floor).
What each option did on the M220's validation suite follows.

Without bumpless transfer neither loop is told its share of the applied command, so PID's integrator keeps
integrating the error while the observer (a PD loop on a position drive) commands, and hands it back as w
falls (the fifth M220 generalist set was trained over it; docs/research.md keeps its figures). With
`bumpless: true` each loop is told its share before it computes (authority(1 - w), authority(w)), and PID
integrates only share·e. Measured on the validation suite (10 episodes, 500000-500009), against
SpeedScheduled: 0.2 Hz reversal peak 0.0087 rad against 0.0157, jittered reversals 0.0139 against 0.0205,
drifting friction 0.0092 against 0.0161, point-to-point IAE 0.234 against 0.236, random references 0.419
against 0.425, set-points and 0.05 Hz reversals unchanged (PID's), at the same or lower effort. The textbook
alternative, back-calculation (the low loop's integrator made to track the applied command), was worse than no
transfer (0.035 rad at the 0.2 Hz reversals): it stores the observer's friction compensation in PID's
integrator and hands it back at the next standstill.

`high_velocity_filter_s` low-pass filters the observer's velocity. Under the jittered reversals' 2-count
encoder noise the bumpless schedule's effort (0.318 V rms, 1.9x the feed-forward's 0.171; validation
500000-500029) comes through the observer's velocity, not its error coupling (filtering the error at 10-50 ms
left it at 0.31-0.32). Measured on the same 30 episodes per scenario, τ = 0 / 5 / 7.5 / 10 ms: jittered
reversal peak 0.0143 / 0.0100 / 0.0089 / 0.0088 rad at 0.318 / 0.206 / 0.189 / 0.185 V rms (10 ms: 1.08x the
feed-forward's effort, 5 ms 1.21x, over the leaderboard's 1.2x); 0.2 Hz reversals 0.0084 / 0.0087 / 0.0087 /
0.0085; drifting friction 0.0085 / 0.0086 / 0.0086 / 0.0084; random references 0.394 / 0.399 / 0.404 / 0.409
IAE (the lag the filter adds); on 10 episodes, point-to-point IAE 0.234 / 0.247 / 0.254 / 0.261, set-points
and 0.05 Hz reversals unchanged (PID's). Chosen: 10 ms. (Before the observer's update was computed in expm1
form at small a·h, lugre_observer.py, τ of 2.5-7.5 ms gave errors of hundreds of rad on some episodes: not the
loop but the update's rounding, as the filtered velocity decayed through values of 1e-300.)

`low_tracking` runs another low loop on tracking tasks (controllers.yaml, with its validation figures): on
the M220 the identified feed-forward on PID, which takes the Coulomb step at the 0.05 Hz reversals and as
a 0.2 Hz motion's weight decays; at set-points the low loop stays `low` (PID), where a feed-forward of a
constant reference is zero.

`residual_gate` changes no command, only the share of its authority a residual over the schedule gets
(Controller.residual_share): `none` all of it; `motion` the high loop's share w (a residual acts on fast
motion, where the observer's compensation leaves a reversal glitch to learn; the ninth M220 generalists,
at full authority, put a limit cycle on the 0.05 Hz reversals, and the tenth, gated so, gave up the
set-points); `rest` all of it while the reference is at rest (this sample's reference equals the last
one's: a set-point, a hold; a slow reversal moves on every sample, so the two are told apart exactly) and
w otherwise (the eleventh and twelfth attempts); `floor` as `rest`, and at least `residual_floor` in
motion (under the rest gate w is 0 through the 0.05 Hz reversals, so the twelfth generalists tied PID+FF
there; the thirteenth, committed, trained with the floor). docs/research.md has each attempt.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.config import ConfigError, Node
from frictiongym.envs.scenario import TASKS, TRACKING, Scenario

from .. import settings as cfg
from ..base import ArrayController, Controller, EpisodeContext
from .lugre_observer import LuGreObserver

GATES = ("none", "motion", "rest", "floor")  # the share of a residual's authority (module docstring)


@dataclass(frozen=True)
class Schedule:
    """One plant's blend: the loop below speed_low and the one above speed_high (built-in controller
    names), the speeds in the tracked reference's units per second, the envelope's hold (s); and its
    options (module docstring): bumpless transfer, the high loop's velocity filter (s; None: none), the
    low loop on tracking tasks (None: `low`), the residual gate and its floor (share of the authority)."""

    low: str
    high: str
    speed_low: float
    speed_high: float
    hold_s: float
    bumpless: bool = False
    high_velocity_filter_s: float | None = None
    low_tracking: str | None = None
    residual_gate: str = "none"
    residual_floor: float = 0.0


@dataclass(frozen=True)
class SpeedScheduledSettings(cfg.FamilySettings):
    """schedules: the blend per plant preset (controllers.yaml `speed_scheduled`, with the measurements
    that chose it)."""

    SECTION: ClassVar[str] = "speed_scheduled"
    schedules: Mapping[str, Schedule]

    @classmethod
    @cache
    def defaults(cls) -> SpeedScheduledSettings:
        def build(s: Node) -> SpeedScheduledSettings:
            out = {}
            for plant in list(s.keys()):
                p = s.section(plant)
                lo, hi = p.positive("speed_low_per_s"), p.positive("speed_high_per_s")
                if hi <= lo:
                    raise p.error("speed_high_per_s", f"must exceed speed_low_per_s ({lo})")
                gate = p.choice("residual_gate", GATES, default="none")
                floor = p.number("residual_floor", 0.0, 1.0, default=0.0)
                if gate != "floor" and floor:
                    raise p.error("residual_floor", f"applies to residual_gate: floor, not {gate}")
                tau = p.get("high_velocity_filter_s")
                out[plant] = Schedule(
                    p.string("low"),
                    p.string("high"),
                    lo,
                    hi,
                    p.positive("hold_s"),
                    p.boolean("bumpless", default=False),
                    p.positive("high_velocity_filter_s", 1.0) if tau is not None else None,
                    p.string("low_tracking") if p.get("low_tracking") is not None else None,
                    gate,
                    floor,
                )
                p.done()
            return cls(out)

        return cfg.read(cls.SECTION, build)


class SpeedScheduled(ArrayController):
    """u = (1 - w)·u_low + w·u_high, w = clip((s - speed_low)/(speed_high - speed_low), 0, 1) with s the
    reference's speed envelope (module docstring). Both loops run every sample on the same reading, so
    each keeps its own state (integrator, observer) as if it were acting alone on this trajectory; at
    w = 0 the command is the low loop's, at w = 1 the high loop's, bit for bit. Every option is a setting
    of the plant's Schedule; the residual gate changes no command."""

    name: ClassVar[str] = "SpeedScheduled"
    sensor_kinds: ClassVar[tuple[str, ...]] = ("encoder",)  # a reference speed: position loops only

    def __init__(
        self,
        loops: Callable[[str], Controller],
        settings: SpeedScheduledSettings | None = None,
        **overrides: Any,
    ):
        """loops: a built-in controller by name (the registry's), for the schedule's two loops."""
        self.settings = cfg.with_overrides(settings or SpeedScheduledSettings.defaults(), overrides)
        self.loops = loops

    def schedule(self, plant: str) -> Schedule | None:
        return self.settings.schedules.get(plant)

    def loop_names(self, scenario: Scenario) -> dict[str, tuple[str, str]]:
        """The low and high loops of the scenario's plant by name, each with the controllers.yaml entry
        that names it (for errors): on a tracking task the low loop is low_tracking where it is set."""
        plant = scenario.spec.name
        s, entry = self.settings.schedules[plant], f"{self.settings.SECTION}.{plant}"
        if scenario.task == TRACKING and s.low_tracking is not None:
            low = (s.low_tracking, f"{entry}.low_tracking")
        else:
            low = (s.low, f"{entry}.low")
        return {"low": low, "high": (s.high, f"{entry}.high")}

    def pair(self, scenario: Scenario) -> tuple[ArrayController, ArrayController]:
        """The low and high loops of the scenario's plant, new (the high loop's velocity filtered where
        the schedule says so)."""
        out = []
        for name, entry in self.loop_names(scenario).values():
            c = self.loops(name)
            if not (isinstance(c, ArrayController) and c.steps_arrays):
                raise ConfigError(entry, f"{name} is not a loop on physical units that steps as arrays")
            out.append(c)
        low, high = out
        plant = scenario.spec.name
        tau = self.settings.schedules[plant].high_velocity_filter_s
        if tau is not None:
            if not isinstance(high, LuGreObserver):
                raise ConfigError(
                    f"{self.settings.SECTION}.{plant}.high", f"{high.name} is not a LuGre observer to filter"
                )
            high.observer = cfg.with_overrides(high.observer, {"velocity_filter_s": tau})
        return low, high

    def why_not(self, scenario: Scenario) -> str | None:
        reason = super().why_not(scenario)
        if reason is not None:
            return reason
        plant = scenario.spec.name
        if self.schedule(plant) is None:
            return f"no schedule for plant {plant!r} in controllers.yaml {self.settings.SECTION}"
        for c in self.pair(scenario):
            if (reason := c.why_not(scenario)) is not None:
                return f"{c.name}: {reason}"
        return None

    def start(self, ctx: EpisodeContext) -> None:
        self.s = self.settings.schedules[ctx.plant.name]
        self.low, self.high = self.pair(ctx.scenario)
        self.low.reset(ctx)
        self.high.reset(ctx)
        self.decay = math.exp(-self.h / self.s.hold_s)
        n = self.episodes
        self.speed, self.r_prev, self.w = np.zeros(n), None, np.zeros(n)
        self.at_rest = np.zeros(n, dtype=bool)

    def weight(self, r: np.ndarray) -> np.ndarray:
        """The high loop's weights after this sample's references (updates the speed envelopes and
        whether each reference is at rest)."""
        if self.r_prev is None:
            self.at_rest, v = np.zeros(len(r), dtype=bool), np.zeros_like(r)
        else:
            self.at_rest, v = r == self.r_prev, np.abs(r - self.r_prev) / self.h
        self.r_prev = r
        self.speed = np.maximum(v, self.speed * self.decay)
        return np.minimum(
            1.0, np.maximum(0.0, (self.speed - self.s.speed_low) / (self.s.speed_high - self.s.speed_low))
        )

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        self.w = w = self.weight(r)
        if self.s.bumpless:
            self.low.authority(1.0 - w)
            self.high.authority(w)
        return (1.0 - w) * self.low.commands(y, r) + w * self.high.commands(y, r)

    def residual_share(self) -> float | np.ndarray:
        gate = self.s.residual_gate
        if gate == "none":
            return 1.0
        if gate == "motion":
            return self.w
        at_gate = self.w if gate == "rest" else np.maximum(self.w, self.s.residual_floor)
        return np.where(self.at_rest, 1.0, at_gate)

    def params(self) -> dict[str, Any]:
        s = getattr(self, "s", None)
        if s is None:
            return {}
        return {**vars(s), "low_params": self.low.params(), "high_params": self.high.params()}


@dataclass(frozen=True)
class TaskScheduledSettings(cfg.FamilySettings):
    """loops: per plant preset, the built-in loop (by name) for each task of Scenario.task (controllers.yaml
    `task_scheduled`, with the reason for each choice)."""

    SECTION: ClassVar[str] = "task_scheduled"
    loops: Mapping[str, Mapping[str, str]]

    @classmethod
    @cache
    def defaults(cls) -> TaskScheduledSettings:
        def build(s: Node) -> TaskScheduledSettings:
            out = {}
            for plant in list(s.keys()):
                p = s.section(plant)
                out[plant] = {task: p.string(task) for task in list(p.keys())}
                if unknown := set(out[plant]) - set(TASKS):
                    raise p.error(sorted(unknown)[0], f"not a task; one of {list(TASKS)}")
            return cls(out)

        return cfg.read(cls.SECTION, build)


class TaskScheduled(Controller):
    """One loop per task, chosen at the episode's start from the scenario's task (Scenario.task): e.g. the
    identified feed-forward (PID+FF, defined for tracking) on moving references and PID at set-points,
    where the feed-forward of a constant reference is zero and PID+FF would be PID. A residual base that
    applies to every position scenario of a plant whose best loop depends on the task; not a baseline.
    Each episode runs the chosen loop alone, bit for bit (its commands, its hardware)."""

    name: ClassVar[str] = "TaskScheduled"

    def __init__(
        self,
        loops: Callable[[str], Controller],
        settings: TaskScheduledSettings | None = None,
        **overrides: Any,
    ):
        """loops: a built-in controller by name (the registry's), for the schedule's loops."""
        self.settings = cfg.with_overrides(settings or TaskScheduledSettings.defaults(), overrides)
        self.loops = loops

    def loop_for(self, scenario: Scenario) -> Controller | str:
        """A new loop for the scenario's plant and task, or why there is none."""
        name, section = scenario.spec.name, self.settings.SECTION
        plant = self.settings.loops.get(name)
        if plant is None:
            return f"no schedule for plant {name!r} in controllers.yaml {section}"
        if scenario.task not in plant:
            return f"no loop for {scenario.task} tasks in controllers.yaml {section}.{name}"
        return self.loops(plant[scenario.task])

    def why_not(self, scenario: Scenario) -> str | None:
        loop = self.loop_for(scenario)
        if isinstance(loop, str):
            return loop
        reason = loop.why_not(scenario)
        return None if reason is None else f"{loop.name}: {reason}"

    def plant_overrides(self, scenario: Scenario) -> dict:
        loop = self.loop_for(scenario)
        return {} if isinstance(loop, str) else loop.plant_overrides(scenario)

    def reset(self, ctx: EpisodeContext) -> None:
        loop = self.loop_for(ctx.scenario)
        if isinstance(loop, str):
            raise ValueError(f"{self.name}: {loop}")
        self.loop = loop
        self.loop.reset(ctx)

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.loop.act(obs)

    def acting(self) -> Controller:
        return self.loop.acting()

    def params(self) -> dict[str, Any]:
        loop = getattr(self, "loop", None)
        return {} if loop is None else {"loop": loop.name, **loop.params()}
