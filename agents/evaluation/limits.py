"""The physical-limit references: two rows the leaderboard runs on every episode beside Zero, never ranked.

Each scenario declares its uncompensated loop (`benchmark.uncompensated`, e.g. PD on Kang's rotor):

- `Ideal`: that loop on the friction-free twin of the same episode (scenario key nonlinear_friction
  false): every draw the same, the Coulomb, static, Stribeck and presliding friction and the asymmetry
  bias removed; the viscous term stays, it is part of the linear plant the loop is designed on.
- `TrackingLimit`: the friction-free twin under the plant's best linear two-degree-of-freedom loop (model
  feed-forward plus the loop): how well the drive could track with no friction at all and a servo
  engineer's linear design; `Ideal` only removes the friction under the uncompensated loop, so a
  controller with feed-forward can read g > 1 there without removing any friction.
- `Oracle`: that loop plus the true nonlinear friction torque of the episode, read at each control
  instant and held over the period (through the drive's own delay): a perfect friction observer with the
  loop's own sampling, reflected to the drive joint through the belt ratios and divided by the episode's
  true actuator gain; the sum of loop and compensation is clipped as any action is.

What the loop would do without friction (Ideal) is the reference of the leaderboard's score g
(agents/evaluation/leaderboard.py); the Oracle shows how much of it a perfect friction estimate recovers.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar

import numpy as np

from frictiongym.agents.base import Controller, EpisodeContext
from frictiongym.envs.plants.mjcf import friction_joints
from frictiongym.envs.plants.params import EpisodeParams
from frictiongym.envs.scenario import TRACKING, Scenario


class LimitReference(Controller):
    """The scenario's uncompensated loop (built by `make_loop` from its name), with this row's change."""

    def __init__(self, make_loop: Callable[[str], Controller]):
        self._make_loop = make_loop
        self._loops: dict[str, Controller] = {}
        self.loop: Controller | None = None

    def loop_of(self, scenario: Scenario) -> Controller:
        """The uncompensated loop of the scenario (one instance per loop name, kept)."""
        name = scenario.uncompensated
        if name not in self._loops:
            self._loops[name] = self._make_loop(name)
        return self._loops[name]

    def why_not(self, scenario: Scenario) -> str | None:
        return self.loop_of(scenario).why_not(scenario)

    def plant_overrides(self, scenario: Scenario) -> dict:
        return self.loop_of(scenario).plant_overrides(scenario)

    def reset(self, ctx: EpisodeContext) -> None:
        self.loop = self.loop_of(ctx.scenario)
        self.loop.reset(ctx)

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.loop.act(obs)

    def acting(self) -> Controller:
        return self.loop.acting()

    def params(self) -> dict:
        return {"uncompensated": self.loop.name if self.loop is not None else None}


class Ideal(LimitReference):
    """The uncompensated loop on the friction-free twin of the episode (module docstring)."""

    name: ClassVar[str] = "Ideal"

    def scenario_overrides(self) -> dict:
        return {"nonlinear_friction": False}


class TrackingLimit(LimitReference):
    """The friction-free twin of the episode under the plant's linear two-degree-of-freedom loop: on a
    tracking task `Cascade+MFF` where it applies, else `PID+MFF`, their model feed-forward without its
    friction term (the design's settings, agents/classical/model_feedforward.py). Tracking tasks only: at
    a set-point the feed-forward is zero and the row would be Ideal's, which stands for it there."""

    name: ClassVar[str] = "TrackingLimit"
    LOOPS: ClassVar[tuple[str, ...]] = ("Cascade+MFF", "PID+MFF")

    def __init__(self, make_loop: Callable[[str], Controller], make_linear: Callable[[str], Controller]):
        super().__init__(make_loop)
        self._make_linear = make_linear

    def why_not(self, scenario: Scenario) -> str | None:
        if scenario.task != TRACKING:
            return "a set-point: the tracking limit is the Ideal row"
        return super().why_not(scenario)

    def loop_of(self, scenario: Scenario) -> Controller:
        for name in self.LOOPS:
            if name not in self._loops:
                self._loops[name] = self._make_linear(name)
            if self._loops[name].applies_to(scenario):
                return self._loops[name]
        return super().loop_of(scenario)

    def scenario_overrides(self) -> dict:
        return {"nonlinear_friction": False}


class Oracle(LimitReference):
    """The uncompensated loop plus the episode's true nonlinear friction torque (module docstring), on every
    episode of a lockstep at once (its loop steps arrays)."""

    name: ClassVar[str] = "Oracle"
    reads_truth: ClassVar[bool] = True
    steps_arrays: ClassVar[bool] = True

    def reset(self, ctx: EpisodeContext) -> None:
        super().reset(ctx)
        self.actor = self.loop.acting()
        if not self.actor.steps_arrays:
            raise TypeError(f"Oracle: the uncompensated loop {self.loop.name} does not step arrays")
        sc = ctx.scenario
        spec = sc.spec
        ratios = spec.kinematic_ratios()  # belt-coupled joints; a shaft-coupled load turns with its motor
        drive = ratios.get(spec.actuator_joint, 1.0)
        self.ratio = np.array([ratios.get(j, drive) / drive for j in friction_joints(spec)])
        self.action_scale = sc.action_scale
        self.compensation = np.zeros(ctx.episodes)  # command units (V or N·m), per episode

    def observe_truth(self, truth: dict[str, np.ndarray], params: EpisodeParams, row: int = 0) -> None:
        torque = float(np.dot(self.ratio, truth["nonlinear_friction_torque"]))  # at the drive joint, N·m
        self.compensation[row] = -torque / params.actuator_gain

    def acting(self) -> Controller:
        return self  # the loop's action plus the compensation

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.act_episodes(obs[None])[0]

    def act_episodes(self, obs: np.ndarray) -> np.ndarray:
        a = self.actor.act_episodes(obs)
        return np.asarray(a, dtype=float) + (self.compensation / self.action_scale)[:, None]
