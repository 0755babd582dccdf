"""The one controller interface shared by classical and learned controllers."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.plants import PlantSpec
from frictiongym.envs.scenario import Scenario
from frictiongym.envs.servo_env import decode_observation


@dataclass(frozen=True)
class EpisodeContext:
    """What a controller may know at the start of an episode.

    scenario: sampling period, scales, reference generator, tracked sensor (public task description).
    plant: the *nominal* plant preset (document values), not the episode's randomised truth.
    knowledge: controller-specific assumptions, e.g. static friction bounds (configs/controllers.yaml).
    """

    scenario: Scenario
    plant: PlantSpec
    knowledge: dict[str, Any] = field(default_factory=dict)


class Controller(ABC):
    """Acts once per control period on the env's observation; returns the action in [-1, 1]."""

    name: ClassVar[str] = "controller"
    plants: ClassVar[tuple[str, ...]] = ()

    def applies_to(self, scenario: Scenario) -> bool:
        """Whether this controller is defined for the scenario (plant and task)."""
        return scenario.spec.name in self.plants

    def plant_overrides(self, scenario: Scenario) -> dict:
        """Hardware the controller brings into the plant (e.g. an analog rate loop); default none."""
        return {}

    @abstractmethod
    def reset(self, ctx: EpisodeContext) -> None:
        """Prepare for an episode (design gains, clear states)."""

    @abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """Action for the observation at this sampling instant."""

    def params(self) -> dict[str, Any]:
        """The controller's own parameters (for reports)."""
        return {}


class PhysicalController(Controller):
    """A controller written in physical units: implement command(reading, reference) -> V or N·m."""

    def reset(self, ctx: EpisodeContext) -> None:
        self.ctx = ctx
        self.sc = ctx.scenario
        self.sensor = self.sc.spec.sensors[self.sc.tracked_sensor].name
        self.h = self.sc.control_period
        self.start(ctx)

    def start(self, ctx: EpisodeContext) -> None:
        """Episode start in physical terms (override)."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        d = decode_observation(self.sc, obs)
        u = self.command(d["sensors"][self.sensor], d["reference"])
        return np.array([u / self.sc.action_scale], dtype=np.float32)

    @abstractmethod
    def command(self, y: float, r: float) -> float:
        """Command (V or N·m) from the tracked reading y and the reference r."""
