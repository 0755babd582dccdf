"""Iterative learning control on references that repeat within an episode, run as repetitive control
(Arimoto, Kawamura and Miyazaki 1984, "Bettering operation of robots by learning", J. Robotic Systems
1(2): the P-type update; Bristow, Tharayil and Alleyne 2006, "A survey of iterative learning control",
IEEE Control Systems Magazine 26(3), eq. 8-11: the Q-filtered update and its robustness): over each period
of N samples the loop stores its tracking error e_j, and at the period's end the correction it adds to the
next period's command is

    c_{j+1}(i) = Q[c_j(i) + γ·k_p·e_j(i + λ)],  i = 0 .. N-1 (indices modulo N),

with k_p the loop's proportional gain (so γ is a dimensionless share of what the loop itself would
command), λ a phase lead of a few samples (the command acts on the error a sample or more later) and Q a
zero-phase moving average over `filter_s` (the robustness filter: it stops the learning at frequencies
where the loop's phase would make it diverge). The loop is `PID+MFF` (model_feedforward.py): the learning
removes what the feed-forward and the integrator leave repeating.

Defined where the reference repeats: sine and triangle references with a whole number of control periods
per cycle (the M220's reversals, Wallenborg's speed reversals); `why_not` elsewhere (random, recorded,
point-to-point and chirp references do not repeat).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import numpy as np

from frictiongym.envs.scenario import Scenario

from .. import settings as cfg
from ..base import EpisodeContext
from .model_feedforward import PIDModelFF

PERIODIC = ("sine", "triangle")  # Reference types that repeat


def period_steps(scenario: Scenario) -> int | None:
    """Control periods per cycle of the scenario's reference, or None if it does not repeat on the grid."""
    ref = scenario.reference
    if ref.type not in PERIODIC or ref.frequency_hz <= 0:
        return None
    n = 1.0 / (ref.frequency_hz * scenario.control_period)
    steps = round(n)
    return steps if steps >= 2 and abs(n - steps) < 1e-6 * n else None


@dataclass(frozen=True)
class LearningEntry:
    """One plant's learning (controllers.yaml `iterative_learning.<plant>`).

    learning_gain: γ, the share of the loop's proportional action learned per period (dimensionless).
    lead_steps: λ, the phase lead (control periods). filter_s: the robustness filter's window (s).
    """

    learning_gain: float
    lead_steps: int
    filter_s: float


@dataclass(frozen=True)
class LearningSettings(cfg.PerPlantSettings):
    """Iterative learning per plant preset (controllers.yaml `iterative_learning`)."""

    SECTION: ClassVar[str] = "iterative_learning"
    ENTRY: ClassVar[type] = LearningEntry
    KNOBS: ClassVar[dict[str, cfg.Knob]] = {
        "learning_gain": cfg.Knob(0.0, 1.5),
        "lead_steps": cfg.Knob(0, 20, whole=True),
        "filter_s": cfg.Knob(0.0, 1.0),
    }
    plants: dict[str, Any]

    @classmethod
    @cache
    def defaults(cls) -> LearningSettings:
        return cfg.read(cls.SECTION, lambda s: cls(cls.read_section(s)))


class IterativeLearning(PIDModelFF):
    """PID+MFF plus the learned correction of the previous periods (module docstring)."""

    name: ClassVar[str] = "ILC"
    tunes: ClassVar[tuple[str, type]] = ("learning", LearningSettings)  # agents/tuning/search.py

    def __init__(self, learning: LearningSettings | None = None, **kw: Any):
        super().__init__(**kw)
        self.learning = learning or LearningSettings.defaults()

    def why_not(self, scenario: Scenario) -> str | None:
        reason = super().why_not(scenario)
        if reason is None and period_steps(scenario) is None:
            return "the reference does not repeat (sine or triangle with whole control periods per cycle)"
        return reason

    def start(self, ctx: EpisodeContext) -> None:
        super().start(ctx)
        e = self.learning.of(ctx.plant.name)
        self.n = period_steps(ctx.scenario)
        self.gamma = e.learning_gain * self.gains.kp
        self.lead = e.lead_steps
        self.window = max(1, 2 * round(e.filter_s / self.h / 2) + 1)  # odd: zero phase
        self.correction = np.zeros((self.episodes, self.n))  # each episode's stored period
        self.errors = np.zeros((self.episodes, self.n))
        self.k = 0

    def filtered(self, x: np.ndarray) -> np.ndarray:
        """The zero-phase moving average over `window` samples of each row, a periodic sequence."""
        if self.window == 1:
            return x
        half = self.window // 2
        kernel = np.ones(self.window) / self.window
        padded = np.concatenate([x[:, -half:], x, x[:, :half]], axis=1)
        return np.stack([np.convolve(row, kernel, mode="valid") for row in padded])

    def feedforward(self, r: np.ndarray) -> np.ndarray:
        return super().feedforward(r) + self.correction[:, self.k % self.n]

    def commands(self, y: np.ndarray, r: np.ndarray) -> np.ndarray:
        self.errors[:, self.k % self.n] = r - y
        u = super().commands(y, r)
        self.k += 1
        if self.k % self.n == 0:  # a period ended: learn from it
            learned = self.correction + self.gamma * np.roll(self.errors, -self.lead, axis=1)
            self.correction = self.filtered(learned)
        return u
