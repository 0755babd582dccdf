"""An example compensator from outside the package: PID with a smooth Coulomb + viscous feed-forward from
the reference's speed, written on the controller interface and run on the leaderboard without packaging:

    frictiongym leaderboard --scenarios kang_ramp m220_random --seeds 5000-5004 --randomize \
        --controllers PID examples/smooth_coulomb_pid.py:SmoothCoulombPID --models

or from Python: leaderboard.run(controllers=["PID", SmoothCoulombPID], ...). The feed-forward is
u_ff = Fc·tanh(v_r / v_s) + Fv·v_r with v_r the reference's speed (a backward difference of the reference,
per control period), Fc and Fv the nominal plant preset's Coulomb level and viscous coefficient over the
actuator gain (the controller knows the preset, not the episode's drawn friction), and v_s a smoothing
speed: a tanh instead of a sign keeps the command continuous where the reference reverses. The suite's
PID+FF is the same idea with a sign; this file shows the interface in a dozen lines.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from frictiongym.agents.base import EpisodeContext, PhysicalController
from frictiongym.agents.classical import PID


class SmoothCoulombPID(PhysicalController):
    """PID (the suite's design for the plant) plus u_ff = Fc·tanh(v_r/v_s) + Fv·v_r (module docstring).
    Tracking tasks only: at a set-point the reference's speed is zero and this is PID."""

    name: ClassVar[str] = "SmoothCoulombPID"
    sensor_kinds: ClassVar[tuple[str, ...]] = ("encoder",)  # position loops
    tasks: ClassVar[tuple[str, ...]] = ("tracking",)
    smoothing_fraction = 0.05  # v_s as a fraction of the scenario's output scale per second

    def why_not(self, scenario) -> str | None:
        if scenario.spec.drive_friction is None:
            return "needs friction on the driven joint"
        return super().why_not(scenario) or PID().why_not(scenario)

    def start(self, ctx: EpisodeContext) -> None:
        self.pid = PID()
        self.pid.reset(ctx)
        f, gain = ctx.plant.drive_friction, ctx.plant.actuator_gain  # the nominal preset's
        levels = f.levels()
        self.fc = 0.5 * (levels["coulomb_pos"] + levels["coulomb_neg"]) / gain  # command units (V)
        self.fv = f.sigma2 / gain
        self.v_s = self.smoothing_fraction * ctx.scenario.output_scale
        self.r_prev: float | None = None

    def command(self, y: float, r: float) -> float:
        v_r = 0.0 if self.r_prev is None else (r - self.r_prev) / self.h
        self.r_prev = r
        u = self.pid.command(y, r) + self.fc * math.tanh(v_r / self.v_s) + self.fv * v_r
        return max(-self.sc.action_scale, min(self.sc.action_scale, u))

    def params(self) -> dict[str, Any]:
        return {"coulomb": getattr(self, "fc", None), "viscous": getattr(self, "fv", None)}
