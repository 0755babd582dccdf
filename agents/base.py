"""The one controller interface shared by classical and learned controllers."""

from __future__ import annotations

import copy
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.plants import PlantSpec
from frictiongym.envs.plants.params import EpisodeParams
from frictiongym.envs.scenario import TASKS, Scenario
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
    """Acts once per control period on the env's observation; returns the action in [-1, 1].

    A controller declares what it needs from a scenario: the kinds of tracked sensor it can close its
    loop on (`sensor_kinds`), the tasks it is defined for (`tasks`: "regulation" = constant reference,
    "tracking"), and any further requirement in `why_not`.
    """

    name: ClassVar[str] = "controller"
    reads_truth: ClassVar[bool] = False  # the evaluation loop calls observe_truth before every act
    sensor_kinds: ClassVar[tuple[str, ...]] = ("encoder", "tacho")
    tasks: ClassVar[tuple[str, ...]] = TASKS

    def why_not(self, scenario: Scenario) -> str | None:
        """None if this controller is defined for the scenario, else a one-line reason."""
        kind = scenario.spec.sensors[scenario.tracked_sensor].kind
        if kind not in self.sensor_kinds:
            return f"needs a tracked sensor of kind {list(self.sensor_kinds)}, the scenario tracks a {kind}"
        if scenario.task not in self.tasks:
            return f"defined for {list(self.tasks)} tasks, the scenario is {scenario.task}"
        return None

    def applies_to(self, scenario: Scenario) -> bool:
        """Whether this controller is defined for the scenario (see why_not)."""
        return self.why_not(scenario) is None

    def plant_overrides(self, scenario: Scenario) -> dict:
        """Hardware the controller brings into the plant (e.g. an analog rate loop); default none."""
        return {}

    def observation_overrides(self) -> dict:
        """Scenario `observation` settings the controller reads (history, privileged); default none. They
        change what the env reports, never the episode (its draws come from named streams)."""
        return {}

    def scenario_overrides(self) -> dict:
        """Scenario keys the controller's row changes (the Ideal reference: nonlinear_friction false);
        default none. Only the physical-limit references use it: an entry must run the scenario as is."""
        return {}

    def observe_truth(self, truth: dict[str, np.ndarray], params: EpisodeParams) -> None:
        """The episode's ground truth at this control instant (ServoEnv.ground_truth) and its drawn
        parameters, for controllers with reads_truth (the Oracle reference, never an entry)."""
        return None

    @abstractmethod
    def reset(self, ctx: EpisodeContext) -> None:
        """Prepare for an episode (design gains, clear states)."""

    @abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """Action for the observation at this sampling instant."""

    def params(self) -> dict[str, Any]:
        """The controller's own parameters (for reports)."""
        return {}

    def acting(self) -> Controller:
        """The controller whose act() this one's act() is, known after reset(): itself, or the loop a
        wrapper delegates to (a tuned twin's family, a task schedule's chosen loop). The lockstep steps that
        one, so a wrapper costs nothing per step."""
        return self

    def residual_share(self) -> float:
        """As a residual's base: the share in [0, 1] of the residual's authority α it grants at its last
        act (learned.residual_action). 1: the residual acts everywhere; a gated base keeps it off where
        its own loop should act alone (scheduled.SpeedScheduledFFGated)."""
        return 1.0

    def lockstep(self, n: int) -> Lockstep:
        """The controller for n episodes of one scenario run together (evaluate.run_episodes): this one
        for the first and a deep copy for each other, each acting on its own episode's observation. A
        controller that can act on every episode in one call overrides it (LearnedPolicy: one network
        call)."""
        return Lockstep([self, *(copy.deepcopy(self) for _ in range(n - 1))])


class Lockstep:
    """One controller per episode for n episodes stepped together: row i of an observation array is
    episode i's observation, and each episode's action is what its own controller gives for it alone.
    Where every episode's acting controller (Controller.acting) acts through command() alone
    (PhysicalController's act), the rows are decoded at once (physical_actions)."""

    def __init__(self, controllers: Sequence[Controller]):
        self.controllers = list(controllers)
        self.reads_truth = self.controllers[0].reads_truth
        self.physical: list[PhysicalController] | None = None

    def reset(self, ctx: EpisodeContext) -> None:
        """Every episode's start (they share a scenario and a design plant)."""
        for c in self.controllers:
            c.reset(ctx)
        actors = [c.acting() for c in self.controllers]
        if all(isinstance(a, PhysicalController) and type(a).act is PhysicalController.act for a in actors):
            self.physical = actors
            sc, lay = ctx.scenario, ctx.scenario.layout
            sensor = lay.slice("sensors").start + sc.spec.sensor_names.index(actors[0].sensor)
            self._columns = (sensor, lay.slice("reference").start, lay.slice("preview"))
        else:
            self.physical = None

    def observe_truth(self, row: int, truth: dict[str, np.ndarray], params: EpisodeParams) -> None:
        """Episode `row`'s ground truth now (controllers with reads_truth)."""
        self.controllers[row].observe_truth(truth, params)

    def act(self, obs: np.ndarray, rows: np.ndarray) -> list[Any] | np.ndarray:
        """The actions of episodes `rows` for their observations (one row each), as each controller
        returns it (or, decoded at once, one (rows, 1) float32 array of the same values)."""
        if self.physical is not None:
            return physical_actions(self.physical, self._columns, obs, rows)
        return [self.controllers[r].act(o) for r, o in zip(rows, obs, strict=True)]


def physical_actions(
    controllers: Sequence[PhysicalController],
    columns: tuple[int, int, slice],
    obs: np.ndarray,
    rows: np.ndarray,
) -> np.ndarray:
    """PhysicalController.act for observation rows of one scenario at once: every row's tracked reading,
    reference and preview (their observation columns, found once at the lockstep's reset) decoded in one
    operation per block (decode_observation's arithmetic: float32 times the output scale, so each row's
    values are those it decodes alone, bit for bit), then each episode's own command() in physical units,
    on the readings as Python floats (float64 arithmetic); the actions as one (rows, 1) float32 array."""
    sc = controllers[0].sc
    sensor, reference, preview = columns
    s = sc.output_scale
    ys = (obs[:, sensor] * s).tolist()
    refs = (obs[:, reference] * s).tolist()
    previews = obs[:, preview] * s
    out = np.empty((len(rows), 1), dtype=np.float32)
    scale = sc.action_scale
    for j, r in enumerate(rows.tolist()):
        c = controllers[r]
        c.preview = previews[j]
        out[j, 0] = c.command(ys[j], refs[j]) / scale
    return out


class PhysicalController(Controller):
    """A controller written in physical units: implement command(reading, reference) -> V or N·m. The
    reading and the reference are Python floats (the observation's float32 values, decoded), so the
    controller computes in float64 as a drive's floating-point controller does."""

    def reset(self, ctx: EpisodeContext) -> None:
        self.ctx = ctx
        self.sc = ctx.scenario
        self.sensor = self.sc.spec.sensors[self.sc.tracked_sensor].name
        self.h = self.sc.control_period
        self.start(ctx)

    def start(self, ctx: EpisodeContext) -> None:
        """Episode start in physical terms (override)."""

    def authority(self, share: float) -> None:
        """This sample's share (0-1) of the applied command, told before command() by a loop that blends
        this one's output with another's. A loop with an integrator integrates only its share, so that it
        does not wind up while the other loop commands (bumpless transfer); others ignore it."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        d = decode_observation(self.sc, obs, trusted=True)  # the env's own observation
        self.preview = d["preview"]  # r(t_{k+1}) ... r(t_{k+P}), for loops with feed-forward
        u = self.command(float(d["sensors"][self.sensor]), d["reference"])
        return np.array([u / self.sc.action_scale], dtype=np.float32)

    @abstractmethod
    def command(self, y: float, r: float) -> float:
        """Command (V or N·m) from the tracked reading y and the reference r."""


def drive_friction_reason(scenario: Scenario) -> str | None:
    """Why a friction compensator cannot act on the scenario's drive joint (no friction there), or None."""
    if scenario.spec.drive_friction is None:
        return "needs friction on the driven joint (friction_model is none or viscous)"
    return None


ZERO = "Zero"  # the reference controller's name: every score is relative to it (u = 0)


class Zero(Controller):
    """The do-nothing reference: always commands 0. Every table shows it, and the normalised score of an
    episode, s = 1 - m / m_Zero, measures a controller against it on the same episode."""

    name: ClassVar[str] = ZERO

    def reset(self, ctx: EpisodeContext) -> None:
        self.action = np.zeros(1, dtype=np.float32)

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.action
