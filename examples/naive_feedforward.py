"""The naive feed-forward a new user writes in ten lines (issue 58's yardstick): `PID+FF`'s loop plus the
nominal rigid model's J·r̈ + c·ṙ from the reference preview by central differences, untuned. The
classical side of the leaderboard must be at least as good on every tracking scenario:

    frictiongym leaderboard --suite test --controllers examples/naive_feedforward.py:NaiveFeedForward ...

(every default entry runs beside it when --controllers also names them; see docs/classical.md).
"""

from __future__ import annotations

from typing import ClassVar

from frictiongym.agents.base import EpisodeContext
from frictiongym.agents.classical import PIDCoulombViscousFF
from frictiongym.agents.classical.design import rigid_position_plant


class NaiveFeedForward(PIDCoulombViscousFF):
    """PID+FF plus (J·r̈ + c·ṙ)/b, r̈ and ṙ central differences over r(k-1), r(k), r(k+1)."""

    name: ClassVar[str] = "NaiveFF"

    def start(self, ctx: EpisodeContext) -> None:
        super().start(ctx)
        self.model = rigid_position_plant(ctx.plant)
        self.r_last: float | None = None

    def command(self, y: float, r: float) -> float:
        J, c, b = self.model
        r0 = r if self.r_last is None else self.r_last
        r1 = float(self.preview[0])
        self.r_last = r
        ff = (J * (r1 - 2 * r + r0) / self.h**2 + c * (r1 - r0) / (2 * self.h)) / b
        limit = self.sc.action_scale
        return max(-limit, min(limit, super().command(y, r) + ff))
