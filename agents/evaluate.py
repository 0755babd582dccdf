"""One evaluation loop for every controller over identical episodes (suites)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from tqdm import tqdm

from frictiongym.envs import env_id
from frictiongym.envs.plants import PlantSpec
from frictiongym.envs.scenario import Scenario, load_scenario
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.suites import STRUCTURAL, Episode

from .base import Controller, EpisodeContext
from .settings import knowledge_defaults


@dataclass
class EpisodeResult:
    """One controller on one episode: the one row type from run_episode through the engine's
    episodes.csv (engine.csv_fields / engine.parse_row) to the leaderboard's tables. score and g are the
    per-episode scores stats.attach_scores fills in from the same episode's reference rows."""

    controller: str
    scenario: str
    seed: int
    metrics: dict[str, float]
    episode_return: float
    diverged: bool
    log: dict[str, np.ndarray] | None = None
    score: float = math.nan  # 1 - m / m_Zero of the scenario's main metric m
    g: float = math.nan  # the friction penalty removed on the main metric (stats.limit_score)
    randomize: bool = False  # the episode's randomisation flag
    params: str = ""  # the episode's pinned parameters as sorted JSON ("" = none): params_text
    controller_params: str = "{}"  # the controller's params() as sorted JSON
    env_id: str = ""  # the versioned Gymnasium id of the episode's plant
    provenance: dict[str, str] = field(default_factory=dict)  # the run's package version and git commit

    def key(self) -> tuple[str, str, int, bool, str]:
        """The job's identity: (controller, scenario, seed, randomize, params)."""
        return (self.controller, self.scenario, self.seed, self.randomize, self.params)

    def episode(self) -> tuple[str, int, bool, str]:
        """The episode's identity, shared by every controller's row on it."""
        return (self.scenario, self.seed, self.randomize, self.params)


def params_text(e: Episode) -> str:
    """An episode's pinned parameters as results hold them: sorted JSON, or "" for none."""
    return json.dumps(dict(e.params), sort_keys=True) if e.params else ""


def _jsonable(x: Any) -> Any:
    return x.tolist() if hasattr(x, "tolist") else str(x)


class EnvCache:
    """Envs by (scenario, randomize, the controller's hardware, env arguments): an evaluation builds each
    once and resets it per episode (every random quantity comes from the episode's seed)."""

    def __init__(self) -> None:
        self._envs: dict[str, ServoEnv] = {}
        self._scenarios: dict[str, Scenario] = {}

    def scenario(self, episode: Episode, **env_kwargs: Any) -> Scenario:
        """The scenario as the user configured it, with the episode's structural keys (without any
        controller's hardware)."""
        env_kwargs = _with_structure(episode, env_kwargs)
        key = json.dumps([episode.scenario, episode.randomize, env_kwargs], sort_keys=True, default=str)
        if key not in self._scenarios:
            user = env_kwargs.get("overrides")
            kw = {k: v for k, v in env_kwargs.items() if k != "overrides"}
            self._scenarios[key] = load_scenario(episode.scenario, user, randomize=episode.randomize, **kw)
        return self._scenarios[key]

    def env(self, controller: Controller, episode: Episode, **env_kwargs: Any) -> ServoEnv:
        """The env for this controller on this episode's scenario, with the hardware it brings and the
        observation it reads."""
        kw = _with_structure(episode, env_kwargs)
        overrides = controller_overrides(
            controller, self.scenario(episode, **env_kwargs), kw.pop("overrides", None)
        )
        key = json.dumps([episode.scenario, episode.randomize, overrides, kw], sort_keys=True, default=str)
        if key not in self._envs:
            self._envs[key] = ServoEnv(
                episode.scenario, randomize=episode.randomize, overrides=overrides, **kw
            )
        return self._envs[key]


def _with_structure(episode: Episode, env_kwargs: dict[str, Any]) -> dict[str, Any]:
    """env_kwargs with the episode's structural overrides (Episode.overrides) added to the user's."""
    structure = episode.overrides()
    if structure is None:
        return dict(env_kwargs)
    return {**env_kwargs, "overrides": {**(env_kwargs.get("overrides") or {}), **structure}}


def controller_overrides(controller: Controller, scenario: Scenario, user: dict | None) -> dict | None:
    """The scenario overrides for running `controller`: the user's, plus the hardware the controller brings
    (plant_overrides), the observation blocks it reads (observation_overrides) and, for the
    physical-limit references, the scenario keys their row changes (scenario_overrides)."""
    out = {**(user or {}), **controller.scenario_overrides()}
    hw, obs = controller.plant_overrides(scenario), controller.observation_overrides()
    if hw:
        out["plant_overrides"] = {**out.get("plant_overrides", {}), **hw}
    if obs:
        out["observation"] = {**out.get("observation", {}), **obs}
    return out or None


def run_episode(
    controller: Controller,
    episode: Episode,
    keep_log: bool = False,
    knowledge: dict | None = None,
    envs: EnvCache | None = None,
    design: PlantSpec | None = None,
    **env_kwargs: Any,
) -> EpisodeResult:
    """Run one suite episode. The controller's own hardware (plant_overrides) is added to the scenario;
    everything random comes from the episode's seed, so every controller sees the same episode. With
    `envs`, the env is taken from (and kept in) that cache. `design`: the plant model the controller is
    designed on (default: the scenario's nominal preset, with the scenario's own friction structure when
    the episode pins another: controllers are designed on the plant they were written for), e.g. an
    identified one."""
    cache = envs or EnvCache()
    env = cache.env(controller, episode, **env_kwargs)
    sc = env.scenario  # its spec holds the nominal (document) plant; the episode's draw is hidden
    if design is None:
        own = replace(episode, params=tuple(kv for kv in episode.params if kv[0] not in STRUCTURAL))
        design = cache.scenario(own, **env_kwargs).spec if episode.overrides() else sc.spec
    know = {**knowledge_defaults(), **(knowledge or {})}
    obs, _ = env.reset(seed=episode.seed, options=episode.options())
    controller.reset(EpisodeContext(sc, design, know))
    total, done, info = 0.0, False, {}
    truth = controller.reads_truth
    while not done:
        if truth:
            controller.observe_truth(env.ground_truth(), env.core.params[0])
        obs, reward, term, trunc, info = env.step(controller.act(obs))
        total += reward
        done = term or trunc
    log = {k: v.copy() for k, v in env.core.episode_log(0).items()} if keep_log else None
    return EpisodeResult(
        controller.name,
        episode.scenario,
        episode.seed,
        env.core.metrics(0),  # every metric (info leaves the undefined ones out; results write n/a)
        total,
        bool(info.get("diverged", False)),
        log,
        randomize=episode.randomize,
        params=params_text(episode),
        controller_params=json.dumps(controller.params(), sort_keys=True, default=_jsonable),
        env_id=env_id(sc.spec.name),
    )


def evaluate(
    controllers: list[Controller],
    episodes: list[Episode],
    keep_logs: bool = False,
    progress: bool = True,
    **kw: Any,
) -> list[EpisodeResult]:
    """Every applicable controller on every episode, in order, in this process, with a progress bar."""
    envs = EnvCache()
    jobs = [(c, e) for e in episodes for c in controllers if c.applies_to(envs.scenario(e))]
    return [
        run_episode(c, e, keep_log=keep_logs, envs=envs, **kw)
        for c, e in tqdm(jobs, desc="episodes", unit="ep", disable=not progress)
    ]
