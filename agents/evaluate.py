"""One evaluation loop for every controller over identical episodes (suites)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from tqdm import tqdm

from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.suites import Episode

from .base import Controller, EpisodeContext
from .settings import knowledge_defaults


@dataclass
class EpisodeResult:
    controller: str
    scenario: str
    seed: int
    metrics: dict[str, float]
    episode_return: float
    diverged: bool
    log: dict[str, np.ndarray] | None = None

    def row(self) -> dict[str, Any]:
        return {
            "controller": self.controller,
            "scenario": self.scenario,
            "seed": self.seed,
            "return": self.episode_return,
            "diverged": self.diverged,
            **self.metrics,
        }


def run_episode(
    controller: Controller,
    episode: Episode,
    keep_log: bool = False,
    knowledge: dict | None = None,
    **env_kwargs: Any,
) -> EpisodeResult:
    """Run one suite episode. The controller's own hardware (plant_overrides) is added to the scenario;
    everything random comes from the episode's seed, so every controller sees the same episode."""
    user = dict(env_kwargs.pop("overrides", None) or {})
    base = load_scenario(episode.scenario, user, randomize=episode.randomize, **env_kwargs)
    hw = controller.plant_overrides(base)
    overrides = {**user, "plant_overrides": {**user.get("plant_overrides", {}), **hw}} if hw else user
    env = ServoEnv(episode.scenario, randomize=episode.randomize, overrides=overrides or None, **env_kwargs)
    sc = env.scenario  # its spec holds the nominal (document) plant; the episode's draw is hidden
    know = {**knowledge_defaults(), **(knowledge or {})}
    obs, _ = env.reset(seed=episode.seed)
    controller.reset(EpisodeContext(sc, sc.spec, know))
    total, done, info = 0.0, False, {}
    while not done:
        obs, reward, term, trunc, info = env.step(controller.act(obs))
        total += reward
        done = term or trunc
    log = {k: v.copy() for k, v in env.core.episode_log(0).items()} if keep_log else None
    return EpisodeResult(
        controller.name,
        episode.scenario,
        episode.seed,
        info["episode_metrics"],
        total,
        bool(info.get("diverged", False)),
        log,
    )


def evaluate(
    controllers: list[Controller],
    episodes: list[Episode],
    keep_logs: bool = False,
    progress: bool = True,
    **kw: Any,
) -> list[EpisodeResult]:
    """Every applicable controller on every episode, in order, with a progress bar."""
    scenarios = {name: load_scenario(name) for name in {e.scenario for e in episodes}}
    jobs = [(c, e) for e in episodes for c in controllers if c.applies_to(scenarios[e.scenario])]
    return [
        run_episode(c, e, keep_log=keep_logs, **kw)
        for c, e in tqdm(jobs, desc="episodes", unit="ep", disable=not progress)
    ]
