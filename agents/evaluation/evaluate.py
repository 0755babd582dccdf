"""One evaluation loop for every controller over identical episodes (suites)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from tqdm import tqdm

from frictiongym.agents.base import Controller, EpisodeContext
from frictiongym.agents.settings import knowledge_defaults
from frictiongym.envs import env_id
from frictiongym.envs.core import ActionError, ServoCore, check_action, check_options
from frictiongym.envs.plants import PlantSpec
from frictiongym.envs.scenario import Scenario, load_scenario
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.suites import STRUCTURAL, Episode


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
    g_tracking: float = math.nan  # the same against the tracking limit (the TrackingLimit row)
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


LOCKSTEP = 20  # episodes of one controller and env stepped together at most (evaluate, the engine's chunks)


class EnvCache:
    """Envs by (scenario, randomize, the controller's hardware, env arguments): an evaluation builds each
    once and resets it per episode (every random quantity comes from the episode's seed)."""

    def __init__(self) -> None:
        self._envs: dict[str, ServoEnv] = {}
        self._scenarios: dict[str, Scenario] = {}
        self._cores: dict[tuple[int, int], ServoCore] = {}  # by (id of the env, kept in _envs; n)

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

    def key(self, controller: Controller, episode: Episode, **env_kwargs: Any) -> str:
        """The identity of the env this controller runs this episode on: episodes with equal keys can be
        stepped together."""
        return json.dumps(self._env_args(controller, episode, env_kwargs), sort_keys=True, default=str)

    def _env_args(self, controller: Controller, episode: Episode, env_kwargs: dict[str, Any]) -> list:
        kw = _with_structure(episode, env_kwargs)
        overrides = controller_overrides(
            controller, self.scenario(episode, **env_kwargs), kw.pop("overrides", None)
        )
        return [episode.scenario, episode.randomize, overrides, kw]

    def env(self, controller: Controller, episode: Episode, **env_kwargs: Any) -> ServoEnv:
        """The env for this controller on this episode's scenario, with the hardware it brings and the
        observation it reads."""
        args = self._env_args(controller, episode, env_kwargs)
        key = json.dumps(args, sort_keys=True, default=str)
        if key not in self._envs:
            scenario, randomize, overrides, kw = args
            self._envs[key] = ServoEnv(scenario, randomize=randomize, overrides=overrides, **kw)
        return self._envs[key]

    def core(self, env: ServoEnv, n: int) -> ServoCore:
        """A batched core of n simulations of the env's scenario (one thread: the engine's processes are
        the parallelism), kept per env and n."""
        key = (id(env), n)
        if key not in self._cores:
            self._cores[key] = ServoCore(env.scenario, n, nthread=1, batch=True)
        return self._cores[key]


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
    """Run one suite episode (run_episodes with one episode: the single env)."""
    return run_episodes(controller, [episode], keep_log, knowledge, envs, design, **env_kwargs)[0]


def run_episodes(
    controller: Controller,
    episodes: list[Episode],
    keep_log: bool = False,
    knowledge: dict | None = None,
    envs: EnvCache | None = None,
    design: PlantSpec | None = None,
    steps: int | None = None,
    **env_kwargs: Any,
) -> list[EpisodeResult]:
    """Run suite episodes of one controller, the one evaluation loop. The controller's own hardware
    (plant_overrides) is added to the scenario; everything random comes from the episode's seed, so every
    controller sees the same episode. Episodes that share an env (scenario, randomisation, structure) run
    together, stepped as one batch with one Lockstep of the controller (a learned one calls its network
    once per step for all of them); a single episode runs on the single env. Either way each result is
    the episode's alone, bit for bit (the vector core equals the single env, a Lockstep acts on each row
    as its controller alone would: tests). With `envs`, envs are taken from (and kept in) that cache.
    `design`: the plant model the controller is designed on (default: the scenario's nominal preset, with
    the scenario's own friction structure when the episode pins another: controllers are designed on the
    plant they were written for), e.g. an identified one. `steps`: stop after this many control periods
    (a check of a controller before a run; the results then cover those periods). A controller that
    raises or gives an action that is not one finite real ends the run in one line naming the
    controller, the scenario, the seed and the step (ControllerError). Results in the episodes' order."""
    cache = envs or EnvCache()
    groups: dict[str, list[int]] = {}
    for i, e in enumerate(episodes):
        groups.setdefault(cache.key(controller, e, **env_kwargs), []).append(i)
    results: list[EpisodeResult | None] = [None] * len(episodes)
    for members in groups.values():
        together = _run_together(
            controller, [episodes[i] for i in members], keep_log, knowledge, cache, design, env_kwargs, steps
        )
        for i, r in zip(members, together, strict=True):
            results[i] = r
    return results  # type: ignore[return-value]  # every index filled


class ControllerError(ValueError):
    """A controller that raised, or gave an action that is not one finite real, during an episode: one
    line naming the controller, the scenario, the episode's seed and the control period (step); a plain
    message, so that it crosses a process pool as it is."""


def controller_error(
    controller: Controller, scenario: str, seeds: list[int], step: int, error: Exception
) -> ControllerError:
    """The ControllerError of `error` raised by (or about) the controller's act at that step."""
    seed = f"seed {seeds[0]}" if len(seeds) == 1 else f"seeds {seeds[0]}..{seeds[-1]}"
    cause = " ".join(str(error).split())[:300]  # one line, bounded: a message is no traceback
    where = f"controller {controller.name} on {scenario}, {seed}, step {step}"
    return ControllerError(f"{where}: {type(error).__name__}: {cause}")


def _bad_rows(actions: np.ndarray | list, live: np.ndarray) -> list[int]:
    """The rows of `live` whose action check_action refuses (all of them if none alone is refused: the
    lockstep's whole array was the wrong shape)."""
    bad = []
    for i, u in zip(live, actions, strict=False):
        try:
            check_action(u, 1)
        except ActionError:
            bad.append(int(i))
    return bad or [int(i) for i in live]


def lockstep_actions(actions: np.ndarray | list, n: int) -> np.ndarray:
    """A lockstep's actions as one array for the core's step, which checks it (check_action): its array
    (one row per episode) as it is, a list of one action per episode stacked when the entries share a real
    dtype and a shape (the same values), any other list entry by entry through check_action, whose error
    names the bad entry."""
    if isinstance(actions, np.ndarray):
        return actions
    try:
        stacked = np.asarray(actions)
    except ValueError:  # entries of unequal shapes
        stacked = None
    if stacked is None or stacked.dtype.kind not in "fiu" or stacked.shape not in ((n,), (n, 1)):
        return np.array([check_action(u, 1)[0] for u in actions])
    return stacked


def _run_together(
    controller: Controller,
    episodes: list[Episode],
    keep_log: bool,
    knowledge: dict | None,
    cache: EnvCache,
    design: PlantSpec | None,
    env_kwargs: dict[str, Any],
    steps: int | None = None,
) -> list[EpisodeResult]:
    """Episodes sharing one env (see run_episodes), stepped together until each has ended (or `steps`)."""
    first = episodes[0]
    env = cache.env(controller, first, **env_kwargs)
    sc = env.scenario  # its spec holds the nominal (document) plant; the episode's draw is hidden
    if design is None:
        own = replace(first, params=tuple(kv for kv in first.params if kv[0] not in STRUCTURAL))
        design = cache.scenario(own, **env_kwargs).spec if first.overrides() else sc.spec
    know = {**knowledge_defaults(), **(knowledge or {})}
    n = len(episodes)
    rows = np.arange(n)
    obs = np.zeros((n, env.core.obs_dim), dtype=np.float32)
    if n == 1:
        core = env.core
        obs[0] = env.reset(seed=first.seed, options=first.options())[0]
    else:
        core = cache.core(env, n)
        for i, e in enumerate(episodes):
            obs[i] = core.reset(rows[i : i + 1], [e.seed], check_options(e.options()))[0]
    if controller.plans:
        controller.plan(episodes)
    team = controller.lockstep(n)
    team.reset(EpisodeContext(sc, design, know))
    totals, diverged, live = np.zeros(n), np.zeros(n, dtype=bool), rows
    k = 0  # the control period
    while len(live) and (steps is None or k < steps):
        if team.reads_truth:
            for i in live:
                team.observe_truth(int(i), core.ground_truth(int(i)), core.params[i])
        try:
            actions = team.act(obs[live], live)
        except Exception as e:  # the controller's own code, e.g. a plug-in's wrong signature
            raise controller_error(controller, sc.name, [episodes[i].seed for i in live], k, e) from e
        try:
            if n == 1:
                o, reward, term, trunc, info = env.step(actions[0])
                o, r, ended = o[None], [reward], np.array([term or trunc])
                flags = [info.get("diverged", False)]
            else:
                a = lockstep_actions(actions, len(live))
                o, r, term, trunc, info = core.step(a, live)
                ended, flags = term | trunc, info["diverged"]
        except ActionError as e:  # the action is not one finite real
            seeds = [episodes[i].seed for i in _bad_rows(actions, live)]
            # named as the ValueError (ActionError's base) any caller of an env's step sees
            raise controller_error(controller, sc.name, seeds, k, ValueError(str(e))) from e
        k += 1
        obs[live] = o
        totals[live] += r
        diverged[live] = flags
        live = live[~ended]
    return [
        EpisodeResult(
            controller.name,
            e.scenario,
            e.seed,
            core.metrics(i),  # every metric (info leaves the undefined ones out; results write n/a)
            float(totals[i]),
            bool(diverged[i]),
            {k: v.copy() for k, v in core.episode_log(i).items()} if keep_log else None,
            randomize=e.randomize,
            params=params_text(e),
            controller_params=json.dumps(controller.params(), sort_keys=True, default=_jsonable),
            env_id=env_id(sc.spec.name),
        )
        for i, e in enumerate(episodes)
    ]


def evaluate(
    controllers: list[Controller],
    episodes: list[Episode],
    keep_logs: bool = False,
    progress: bool = True,
    **kw: Any,
) -> list[EpisodeResult]:
    """Every applicable controller on every episode, in this process, with a progress bar; each
    controller's episodes run LOCKSTEP at a time (run_episodes). Results episode-major, controllers in the
    given order."""
    envs = EnvCache()
    runs = []
    for j, c in enumerate(controllers):
        mine = [i for i, e in enumerate(episodes) if c.applies_to(envs.scenario(e))]
        runs += [(j, c, mine[k : k + LOCKSTEP]) for k in range(0, len(mine), LOCKSTEP)]
    out: dict[tuple[int, int], EpisodeResult] = {}  # by (episode, controller)
    with tqdm(total=sum(len(m) for *_, m in runs), desc="episodes", unit="ep", disable=not progress) as bar:
        for j, c, members in runs:
            results = run_episodes(c, [episodes[i] for i in members], keep_logs, envs=envs, **kw)
            out.update({(i, j): r for i, r in zip(members, results, strict=True)})
            bar.update(len(members))
    return [out[k] for k in sorted(out)]
