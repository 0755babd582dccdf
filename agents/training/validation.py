"""Selection on the validation suite: the classical baselines on the validation episodes, snapshots of a
model evaluated through the leaderboard's loop (in this process or a validation worker), bit for bit
the same either way."""

from __future__ import annotations

import contextlib
import io
import math
import pickle
import random
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from frictiongym.agents.evaluation import stats
from frictiongym.agents.evaluation.evaluate import EnvCache, run_episodes
from frictiongym.agents.learned.folder import sha256_bytes, write_policy
from frictiongym.agents.learned.manifest import MODEL, NORMALIZER
from frictiongym.agents.learned.policy import (
    LayerNetwork,
    LearnedPolicy,
    Normalizer,
    algorithm_class,
    network_of,
)
from frictiongym.envs.config import (
    ConfigError,
)
from frictiongym.envs.records import atomic_write
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import load_suite, suite_held_out

from ..base import ZERO, Controller
from ..registry import BUILTIN, LIMITS, base_controller
from .config import VALIDATION_SUITE, RunConfig


# ------------------------------------------------------------------------------------------- validation
@dataclass
class Baseline:
    """The best classical controller of a scenario on the validation episodes (by its main metric)."""

    name: str
    main: float
    effort_rms: float


def validation_episodes(scenario: str, suite: str = VALIDATION_SUITE) -> list:
    """The selection episodes of a scenario: never from a held-out suite."""
    if suite_held_out(suite):
        raise ConfigError("suite", f"{suite} is held out: models are never selected on it")
    return [e for e in load_suite(suite) if e.scenario == scenario]


def episode_metrics(controller: Controller, episodes: list, envs: EnvCache) -> list[dict[str, float]]:
    """Every metric of every episode, in the episodes' order, through the one evaluation loop."""
    return [r.metrics for r in run_episodes(controller, episodes, envs=envs)]


def means(rows: list[dict[str, float]]) -> dict[str, float]:
    """Means of every metric over episode rows."""
    return {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}


def evaluate_controller(controller: Controller, episodes: list, envs: EnvCache) -> dict[str, float]:
    """Means of every metric over the episodes, through the one evaluation loop."""
    return means(episode_metrics(controller, episodes, envs))


def classical_rows(episodes: list, envs: EnvCache) -> dict[str, list[dict[str, float]]]:
    """Episode rows of every applicable built-in controller (Zero included) on the episodes."""

    out = {}
    for name, factory in BUILTIN.items():
        c = factory()
        if c.applies_to(envs.scenario(episodes[0])):
            out[name] = episode_metrics(c, episodes, envs)
    return out


def classical_on(episodes: list, envs: EnvCache) -> dict[str, dict[str, float]]:
    """Metric means of every applicable built-in controller (Zero included) on the episodes."""
    return {name: means(rows) for name, rows in classical_rows(episodes, envs).items()}


def best_classical(scenario: str, results: dict[str, dict[str, float]]) -> Baseline:
    """The best classical baseline by the scenario's main metric (Zero is not a baseline)."""
    main = load_scenario(scenario).main_metric
    name = min((n for n in results if n != ZERO), key=lambda n: results[n][main])
    m = results[name]
    return Baseline(name, m[main], m["effort_rms"])


def reference_point(scenario: str, rows: dict[str, list[dict[str, float]]], episodes: list, envs: EnvCache):
    """The scenario's reference point on the episodes (stats.reference_point, the rule's): its
    uncompensated loop's rows (among `rows`, classical_rows's) and the friction-free linear design's
    (TrackingLimit, Ideal where it does not apply), run here."""
    sc = load_scenario(scenario)
    here = envs.scenario(episodes[0])
    limit = next(c for c in (LIMITS[n]() for n in stats.POINT_LIMITS) if c.applies_to(here))
    return stats.point_with(
        stats.Conduct.of(means(rows[sc.uncompensated])),
        {limit.name: stats.Conduct.of(means(episode_metrics(limit, episodes, envs)))},
    )


def gradient_steps(model: Any) -> int:
    """The gradient steps a model has taken (PPO's _n_updates counts epochs of minibatches)."""
    n = int(getattr(model, "_n_updates", 0))
    if hasattr(model, "n_epochs"):
        return n * math.ceil(model.n_steps * model.n_envs / model.batch_size)
    return n


@dataclass(frozen=True)
class Snapshot:
    """A model at one step. For resuming (the run's checkpoint): its SB3 zip and its VecNormalize's
    pickle (None without one), written and read by this run only. For evaluating and keeping as the
    selected model: its network as layers (LayerNetwork, None for a policy the safe format cannot hold:
    then the zip is evaluated) and its frozen observation statistics."""

    model: bytes
    normalizer: bytes | None
    network: LayerNetwork | None
    stats: Normalizer | None

    @classmethod
    def of(cls, model: Any) -> Snapshot:
        from stable_baselines3.common.vec_env import VecNormalize

        buf = io.BytesIO()
        model.save(buf)
        venv = model.get_env()  # a VecNormalize pickles without the env it wraps
        norm = venv if isinstance(venv, VecNormalize) else None
        network = network_of(model)
        return cls(
            buf.getvalue(),
            pickle.dumps(norm) if norm is not None else None,
            network if isinstance(network, LayerNetwork) else None,
            Normalizer.of(norm),
        )

    @classmethod
    def read(cls, folder: Path, algorithm: str) -> Snapshot:
        """The snapshot this run checkpointed into folder (its own files: SB3's and pickle's loaders)."""
        norm = folder / NORMALIZER
        model = (folder / MODEL).read_bytes()
        normalizer = norm.read_bytes() if norm.exists() else None
        with _generators_kept():
            network = network_of(algorithm_class(algorithm).load(io.BytesIO(model), device="cpu"))
        stats = Normalizer.of(pickle.loads(normalizer)) if normalizer is not None else None
        return cls(model, normalizer, network if isinstance(network, LayerNetwork) else None, stats)

    def write(self, folder: Path) -> None:
        """The checkpoint's files: the SB3 zip and the VecNormalize pickle."""
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write(folder / MODEL, lambda p: p.write_bytes(self.model))
        if self.normalizer is not None:
            atomic_write(folder / NORMALIZER, lambda p: p.write_bytes(self.normalizer))

    def write_model(self, folder: Path) -> dict[str, Any]:
        """The model folder's policy (learned.folder.write_policy: the safe format), or, for a policy it
        cannot hold, the SB3 zip (then only convert-model --trust-pickle can read it); returns the
        manifest's fields for it."""
        if self.network is None:
            atomic_write(folder / MODEL, lambda p: p.write_bytes(self.model))
            return {"model": MODEL, "sha256": {MODEL: sha256_bytes(self.model)}}
        return write_policy(folder, self.network, self.stats)


@dataclass
class PendingEvaluation:
    """An evaluation started and not yet recorded: its row's step and clocks, the snapshot, the result."""

    meta: dict[str, Any]
    snapshot: Snapshot
    result: Future


_EVAL_ENVS = EnvCache()  # the validation envs of this process (a worker's, or the training process')


def evaluate_snapshot(
    cfg: RunConfig, name: str, snap: Snapshot, groups: dict[str, list]
) -> dict[str, list[dict[str, float]]]:
    """Episode rows of a saved model on each group of episodes (scenario -> its validation episodes)
    through the leaderboard's loop (episode_metrics), deterministic, its observation statistics frozen
    (LearnedPolicy, of the training scenario's plant: a regulation scenario gets its preview filled): in the
    validation worker or in the training process, the same numbers (picklable for the worker). The global
    random generators are left as they were (SB3's load reseeds them), so validation in the training
    process does not change the training."""

    with _generators_kept():
        network = snap.network
        if network is None:  # a policy the safe format cannot hold: this run's own zip, through SB3
            network = algorithm_class(cfg.algorithm).load(io.BytesIO(snap.model), device="cpu")
        base = base_controller(cfg.base) if cfg.base is not None else None
        plants = (load_scenario(cfg.scenario).spec.name,)
        policy = LearnedPolicy(
            network, plants, name, inputs=cfg.inputs, base=base, alpha=cfg.alpha, normalizer=snap.stats
        )
        return {sc: episode_metrics(policy, episodes, _EVAL_ENVS) for sc, episodes in groups.items()}


@contextlib.contextmanager
def _generators_kept() -> Any:
    """Python's, numpy's and torch's global random generators restored on exit."""

    import torch

    saved = random.getstate(), np.random.get_state(), torch.get_rng_state()
    try:
        yield
    finally:
        random.setstate(saved[0])
        np.random.set_state(saved[1])
        torch.set_rng_state(saved[2])
