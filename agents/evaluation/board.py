"""A leaderboard as computed (agents/evaluation/leaderboard.py): what report.py and page.py render. Its
own module, so that the leaderboard imports its renderers and they import only this (no circle)."""

from __future__ import annotations

from dataclasses import dataclass, field

from frictiongym.agents.evaluation.evaluate import EpisodeResult
from frictiongym.agents.registry import Budget
from frictiongym.envs.scenario import Scenario


@dataclass
class Board:
    """A leaderboard as computed: what the report and the page render."""

    suite: str
    scenarios: dict[str, Scenario]
    results: list[EpisodeResult]
    table: dict[str, list[dict]]  # leaderboard.summarize
    aggregate: list[dict]  # leaderboard.aggregate
    verdicts: list[dict]  # leaderboard.verdicts
    penalties: dict[str, float]  # leaderboard.penalty, per scenario
    responses: dict[str, list[EpisodeResult]]  # per scenario: best learned, best classical, loop, Ideal
    about: dict[str, str] = field(default_factory=dict)  # a saved model's id -> what it is (registry)
    budgets: dict[tuple[str, str], Budget] = field(default_factory=dict)  # (entry, plant): registry.budgets
    judged: bool = True  # the judging sets ran (leaderboard.run's judge)
