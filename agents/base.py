"""The one controller interface shared by classical and learned controllers."""

from __future__ import annotations

import copy
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
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
    episodes: how many episodes of the scenario a controller that steps arrays (Controller.steps_arrays)
    acts on at once (the lockstep's); every other controller acts on one.
    """

    scenario: Scenario
    plant: PlantSpec
    knowledge: dict[str, Any] = field(default_factory=dict)
    episodes: int = 1


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
    steps_arrays: ClassVar[bool] = False  # act_episodes acts on ctx.episodes episodes at once
    plans: ClassVar[bool] = False  # the evaluation loop calls plan with the episodes before they start

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

    def observe_truth(self, truth: dict[str, np.ndarray], params: EpisodeParams, row: int = 0) -> None:
        """The episode's ground truth at this control instant (ServoEnv.ground_truth) and its drawn
        parameters, for controllers with reads_truth (the Oracle reference, never an entry); `row`: which
        of the episodes a controller that steps arrays acts on."""
        return None

    def plan(self, episodes: Sequence[Any]) -> None:
        """For controllers with plans (the friction-free optimum, a reference row, never an entry): the
        episodes (envs.suites.Episode, in the order of the rows it will act on) before they start, to
        compute their commands from each whole episode."""
        return None

    @abstractmethod
    def reset(self, ctx: EpisodeContext) -> None:
        """Prepare for an episode (design gains, clear states)."""

    @abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """Action for the observation at this sampling instant."""

    def act_episodes(self, obs: np.ndarray) -> np.ndarray:
        """With steps_arrays: the actions (n, 1) float32 of the ctx.episodes episodes it was reset for,
        from their observation rows (n, d), each row's what the episode gets alone (act is n = 1)."""
        raise NotImplementedError(f"{self.name} acts on one episode at a time")

    def params(self) -> dict[str, Any]:
        """The controller's own parameters (for reports)."""
        return {}

    def acting(self) -> Controller:
        """The controller whose act() this one's act() is, known after reset(): itself, or the loop a
        wrapper delegates to (a tuned twin's family, a task schedule's chosen loop). The lockstep steps that
        one, so a wrapper costs nothing per step."""
        return self

    def residual_share(self) -> float | np.ndarray:
        """As a residual's base: the share in [0, 1] of the residual's authority α it grants at its last
        act (learned.residual_action), one per episode for a controller that steps arrays. 1: the
        residual acts everywhere; a gated base keeps it off where its own loop should act alone
        (scheduled.SpeedScheduled with a residual gate)."""
        return 1.0

    def lockstep(self, n: int) -> Lockstep:
        """The controller for n episodes of one scenario run together (evaluate.run_episodes): this one,
        acting on every episode at once if it acts through one that steps arrays (Controller.acting), else
        this one for the first episode and a deep copy for each other. A controller that acts on every
        episode in one call of its own overrides it (LearnedPolicy: one network call)."""
        return Lockstep(self, n)


class Lockstep:
    """n episodes of one scenario stepped together: row i of an observation array is episode i's
    observation, and each episode's action is what it gets alone. Where the controller acts through one
    that steps arrays (Controller.acting, known after reset), that one acts on every row in one call;
    otherwise each episode has its own controller (`first` for the first, `other()` for each other; a deep
    copy unless given), and where each of those acts through command() alone (PhysicalController's act),
    the rows are decoded at once (physical_actions)."""

    def __init__(self, first: Controller, n: int, other: Callable[[], Controller] | None = None):
        self.first, self.n = first, n
        self.other = other or (lambda: copy.deepcopy(first))
        self.controllers = [first]
        self.reads_truth = first.reads_truth
        self.array: Controller | None = None
        self.physical: list[PhysicalController] | None = None

    def reset(self, ctx: EpisodeContext) -> None:
        """Every episode's start (they share a scenario and a design plant); each controller is reset
        once. Whether the controller acts through one that steps arrays is known after a reset (a
        wrapper's loop depends on the scenario), so for several episodes a copy is reset first to tell."""
        many = replace(ctx, episodes=self.n)
        if self.n == 1:
            arrays = None
        else:
            trial = copy.deepcopy(self.first)
            trial.reset(many)
            arrays = trial.acting().steps_arrays
        if arrays is not False:
            self.first.reset(many)
            actor = self.first.acting()
            if actor.steps_arrays:
                self.array, self.full = actor, None
                return
        self.array = None
        self.controllers = [self.first, *(self.other() for _ in range(self.n - 1))]
        for c in self.controllers if arrays is not None else self.controllers[1:]:  # n = 1: reset above
            c.reset(ctx)
        actors = [c.acting() for c in self.controllers]
        if all(acts_by_command(a) for a in actors):
            self.physical = actors
            self._columns = observation_columns(ctx.scenario, actors[0].sensor)
        else:
            self.physical = None

    def observe_truth(self, row: int, truth: dict[str, np.ndarray], params: EpisodeParams) -> None:
        """Episode `row`'s ground truth now (controllers with reads_truth)."""
        if self.array is not None:
            self.array.observe_truth(truth, params, row)
        else:
            self.controllers[row].observe_truth(truth, params)

    def act(self, obs: np.ndarray, rows: np.ndarray) -> list[Any] | np.ndarray:
        """The actions of episodes `rows` for their observations (one row each), as each controller
        returns it (or, decoded at once, one (rows, 1) float32 array of the same values). An array
        controller acts on every episode: one that has ended keeps its last observation, and its action
        is dropped."""
        if self.array is not None:
            if len(rows) == self.n:
                self.full = obs
                return self.array.act_episodes(obs)
            self.full = self.full.copy()
            self.full[rows] = obs
            return self.array.act_episodes(self.full)[rows]
        if self.physical is not None:
            return physical_actions(self.physical, self._columns, obs, rows)
        return [self.controllers[r].act(o) for r, o in zip(rows, obs, strict=True)]

    def shares(self, rows: np.ndarray) -> np.ndarray:
        """As a residual's base: each episode's residual_share at its last act, (rows, 1)."""
        if self.array is not None:
            share = np.broadcast_to(np.asarray(self.first.residual_share(), dtype=np.float64), (self.n,))
            return share[rows][:, None]
        return np.array([[self.controllers[r].residual_share()] for r in rows])


def acts_by_command(controller: Controller) -> bool:
    """Whether the controller's act() is PhysicalController's: decode, then command() on one episode."""
    if not isinstance(controller, PhysicalController) or controller.steps_arrays:
        return False
    return type(controller).act in (PhysicalController.act, ArrayController.act)


def observation_columns(scenario: Scenario, sensor: str) -> tuple[int, int, slice]:
    """The observation's columns of the tracked reading, the reference and the preview."""
    lay = scenario.layout
    start = lay.slice("sensors").start + scenario.spec.sensor_names.index(sensor)
    return start, lay.slice("reference").start, lay.slice("preview")


def decoded_rows(
    scenario: Scenario, columns: tuple[int, int, slice], obs: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tracked readings, references and previews of observation rows (their columns: see
    observation_columns), decoded in one operation per block with decode_observation's arithmetic
    (float32 times the output scale), so each row's values are those it decodes alone, bit for bit."""
    sensor, reference, preview = columns
    s = scenario.output_scale
    return obs[:, sensor] * s, obs[:, reference] * s, obs[:, preview] * s


def physical_actions(
    controllers: Sequence[PhysicalController],
    columns: tuple[int, int, slice],
    obs: np.ndarray,
    rows: np.ndarray,
) -> np.ndarray:
    """PhysicalController.act for observation rows of one scenario at once: the rows decoded at once
    (decoded_rows, the columns found once at the lockstep's reset), then each episode's own command() in
    physical units, on the readings as Python floats (float64 arithmetic); the actions as one (rows, 1)
    float32 array."""
    sc = controllers[0].sc
    ys, refs, previews = decoded_rows(sc, columns, obs)
    ys, refs = ys.tolist(), refs.tolist()
    out = np.empty((len(rows), 1), dtype=np.float32)
    scale = sc.action_scale
    for j, r in enumerate(rows.tolist()):
        c = controllers[r]
        c.preview = previews[j]
        out[j, 0] = c.command(ys[j], refs[j]) / scale
    return out


def array_actions(controller: ArrayController, obs: np.ndarray) -> np.ndarray:
    """ArrayController.act for the observation rows of every episode it acts on: the rows decoded at
    once (decoded_rows), one commands() call on float64 readings and references, the actions (n, 1)
    float32: each row's the same as the episode's alone."""
    sc = controller.sc
    y, r, controller.preview = decoded_rows(sc, controller.columns, obs)
    u = controller.commands(y.astype(np.float64), r.astype(np.float64))
    return (u / sc.action_scale).astype(np.float32)[:, None]


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


class ArrayController(PhysicalController):
    """A loop in physical units that acts on every episode of a lockstep at once: commands(y, r) takes the
    tracked readings and references of the ctx.episodes episodes as float64 arrays (n,), with the previews
    in self.preview (n, P), and returns the n commands; its state holds the episode axis first. Each
    row's arithmetic is the float64 operations a scalar loop would do for that episode alone (math's
    functions where numpy's differ in the last bit: elementwise), so no row depends on another and one
    episode is n = 1.

    command(y, r) is the same loop on one episode's floats (reset for one), for a controller that uses it
    inside its own per-episode code (a plug-in's PID). A subclass that overrides command() is written for
    one episode (PhysicalController's contract) and runs as one, a copy per episode."""

    steps_arrays: ClassVar[bool] = True

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls.steps_arrays = cls.command is ArrayController.command

    def reset(self, ctx: EpisodeContext) -> None:
        self.episodes = ctx.episodes  # start() sizes the state arrays by it
        super().reset(ctx)
        self.columns = observation_columns(self.sc, self.sensor)

    def act(self, obs: np.ndarray) -> np.ndarray:
        if not self.steps_arrays:  # a subclass's command() for one episode
            return super().act(obs)
        return array_actions(self, obs[None])[0]

    def act_episodes(self, obs: np.ndarray) -> np.ndarray:
        return array_actions(self, obs)

    @abstractmethod
    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Commands (V or N·m), (n,), from the tracked readings y and the references r, (n,)."""

    def command(self, y: float, r: float) -> float:
        """The command (V or N·m) of one episode's loop (reset for one) from its reading and reference;
        the preview, where set, is the episode's (P,)."""
        flat = getattr(self, "preview", None)
        if flat is not None:
            self.preview = np.reshape(flat, (1, -1))
        try:
            return float(self.commands(np.array([y], dtype=float), np.array([r], dtype=float))[0])
        finally:
            if flat is not None:
                self.preview = flat


def elementwise(f: Callable[[float], float], x: np.ndarray) -> np.ndarray:
    """f (a math function) on each element of x, float64: the values a scalar loop gets (numpy's own
    exp and tanh differ from math's in the last bit on some arguments)."""
    return np.fromiter(map(f, x.tolist()), dtype=np.float64, count=x.size).reshape(x.shape)


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
    steps_arrays: ClassVar[bool] = True

    def reset(self, ctx: EpisodeContext) -> None:
        pass

    def act(self, obs: np.ndarray) -> np.ndarray:
        return np.zeros(1, dtype=np.float32)

    def act_episodes(self, obs: np.ndarray) -> np.ndarray:
        return np.zeros((len(obs), 1), dtype=np.float32)
