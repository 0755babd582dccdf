"""Tuning a classical family on the `validation` suite with the learned side's budget, and its tuned twin.

A family that can be tuned declares `tunes = (keyword, settings class)`: the constructor keyword taking
its per-plant settings (settings.PerPlantSettings) whose knobs (range, log scale, whole numbers) are the
search space. `tune` searches one plant's entry with Optuna's TPE sampler (seeded; the document's design
is the first trial, so the result is never worse than it on the objective) under a wall-time budget and a
trial cap, evaluating `workers` trials at a time in worker processes, on the first `episodes` validation
episodes of every validation scenario of the plant the family applies to: the episodes that select
learned models (agents/training/, `validation.episodes`), never `test` or `generalisation`.

The objective is the rule that selects learned models: the geometric mean over the scenarios of the main
metric relative to the design's (lower is better), plus 1 for every scenario on which the candidate is
not a result (stats.why_not_result against the scenario's reference point on the same episodes: the rule
every leaderboard row meets) and 100 if an episode diverged.

The tuned values go to configs/tuned.yaml (one entry per family and plant, with its manifest: budget,
trials, seed, the exact command, commit, version, wall time, objective of the design and of the tuned
values per scenario), written atomically; the registry lists `<family>[tuned]` for every family there
(agents/tuning/tuned.py).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from tqdm import tqdm

from frictiongym.agents import registry
from frictiongym.agents.evaluation import stats
from frictiongym.agents.evaluation.engine import provenance
from frictiongym.agents.evaluation.evaluate import EnvCache, EpisodeResult, evaluate
from frictiongym.agents.tuning.tuned import build, tunable, tuned_entries
from frictiongym.envs.records import atomic_text, package_version
from frictiongym.envs.scenario import Scenario, load_scenario
from frictiongym.envs.suites import Episode, load_suite

DIVERGED_COST = 100.0


@dataclass(frozen=True)
class Trial:
    """One evaluated candidate: per scenario its mean main metric and what the rule reads of it."""

    values: dict[str, Any]
    main: dict[str, float]
    conduct: dict[str, stats.Conduct]
    diverged: int


def summarize(values: dict[str, Any], results: list[EpisodeResult], scenarios: dict[str, Scenario]) -> Trial:
    """A candidate's per-scenario means over its episodes."""

    def mean(sc: str, metric: str) -> float:
        return float(np.mean([r.metrics[metric] for r in results if r.scenario == sc]))

    return Trial(
        values,
        {sc: mean(sc, s.main_metric) for sc, s in scenarios.items()},
        {sc: stats.Conduct.of({m: mean(sc, m) for m in CONDUCT_METRICS}) for sc in scenarios},
        sum(r.diverged for r in results),
    )


CONDUCT_METRICS = ("command_roughness", "saturated_share", "rest_oscillation")


def reference_points(loop: Trial, episodes: list[Episode], scenarios: dict[str, Scenario]) -> dict:
    """Each scenario's reference point (stats.reference_point): the uncompensated loop's trial and the
    friction-free linear design (TrackingLimit, Ideal where it does not apply) on the same episodes."""
    rows: list[EpisodeResult] = []
    for name in stats.POINT_LIMITS:  # each on the scenarios no earlier one applies to
        done = {r.scenario for r in rows}
        todo = [e for e in episodes if e.scenario not in done]
        rows += evaluate([registry.make(name)], todo, progress=False)
    out = {}
    for sc in scenarios:
        mine = [r for r in rows if r.scenario == sc]
        limits = {
            name: stats.Conduct.of({m: float(np.mean([r.metrics[m] for r in of])) for m in CONDUCT_METRICS})
            for name in stats.POINT_LIMITS
            if (of := [r for r in mine if r.controller == name])
        }
        out[sc] = stats.point_with(loop.conduct[sc], limits)
    return out


def run_candidate(
    family: str, plant: str, values: dict[str, Any] | None, episodes: list[Episode]
) -> list[EpisodeResult]:
    """The family with one plant's values (None: the design; a registry name when family is a built-in
    loop) on the episodes, in this process (a worker's job)."""
    factory = registry.BUILTIN[family]
    c = factory() if values is None else build(factory, {plant: values})
    return evaluate([c], episodes, progress=False)


@dataclass(frozen=True)
class Objective:
    """The tuning objective against the design and each scenario's reference point (module docstring)."""

    design: Trial
    points: dict[str, stats.Conduct]
    scenarios: dict[str, Scenario]

    def failures(self, t: Trial) -> list[str]:
        """The scenarios on which the candidate is not a result, with why."""
        out = []
        for sc in t.main:
            s = self.scenarios[sc]
            why = stats.why_not_result(t.conduct[sc], self.points[sc], s.action_scale, s.settle_band)
            if why:
                out.append(f"{sc}: {'; '.join(why)}")
        return out

    def cost(self, t: Trial) -> float:
        if t.diverged or not all(math.isfinite(m) for m in t.main.values()):
            return DIVERGED_COST
        ratios = [t.main[sc] / self.design.main[sc] for sc in t.main if self.design.main[sc] > 0]
        return float(np.exp(np.mean(np.log(np.maximum(ratios, 1e-12))))) + len(self.failures(t))


def validation_episodes(family: str, plant: str, episodes: int) -> list[Episode]:
    """The first `episodes` of every validation scenario of the plant the family applies to."""
    c = registry.BUILTIN[family]()
    out: list[Episode] = []
    by: dict[str, int] = {}
    envs = EnvCache()
    for e in load_suite("validation"):
        sc = envs.scenario(e)
        if sc.spec.name == plant and c.applies_to(sc) and by.get(e.scenario, 0) < episodes:
            by[e.scenario] = by.get(e.scenario, 0) + 1
            out.append(e)
    if not out:
        raise ValueError(f"{family} applies to no validation scenario of plant {plant!r}")
    return out


def tune(
    family: str,
    plant: str,
    budget_s: float,
    trials: int,
    seed: int = 0,
    episodes: int = 10,
    workers: int = 2,
    progress: bool = True,
    log: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Search one plant's entry of a family (module docstring); returns {"values", "manifest"}."""
    import optuna  # the tuning's own dependency: imported when a tuning runs

    if family not in registry.BUILTIN or tunable(registry.BUILTIN[family]) is None:
        names = [n for n, f in registry.BUILTIN.items() if tunable(f) is not None]
        raise ValueError(f"{family!r} cannot be tuned; tunable families: {names}")
    cls = registry.BUILTIN[family]
    _, settings_cls = cls.tunes
    design_values = asdict(settings_cls.defaults().of(plant))
    eps = validation_episodes(family, plant, episodes)
    scenarios = {e.scenario: load_scenario(e.scenario) for e in eps}
    loops = {s.uncompensated for s in scenarios.values()}
    if len(loops) != 1:
        raise ValueError(f"the plant's scenarios have several uncompensated loops {sorted(loops)}")
    t0 = time.monotonic()
    with ProcessPoolExecutor(workers) as pool:
        design_f = pool.submit(run_candidate, family, plant, None, eps)
        loop_f = pool.submit(run_candidate, loops.pop(), plant, None, eps)
        design = summarize(design_values, design_f.result(), scenarios)
        loop = summarize({}, loop_f.result(), scenarios)
        objective = Objective(design, reference_points(loop, eps, scenarios), scenarios)
        study = optuna.create_study(sampler=optuna.samplers.TPESampler(seed=seed))
        optuna.logging.set_verbosity(optuna.logging.WARNING)
        knobs = settings_cls.KNOBS
        best, best_cost, done = design, objective.cost(design), 1
        log(f"{family} on {plant}: {len(eps)} validation episodes, design cost {best_cost:.4f}")
        bar = tqdm(total=trials, desc=f"tune {family} {plant}", unit="trial", disable=not progress)
        bar.update(1)
        while done < trials and time.monotonic() - t0 < budget_s:
            batch = [study.ask() for _ in range(min(workers, trials - done))]
            cands = [_suggest(tr, knobs) for tr in batch]
            futures = [pool.submit(run_candidate, family, plant, v, eps) for v in cands]
            for tr, v, f in zip(batch, cands, futures, strict=True):
                t = summarize(v, f.result(), scenarios)
                cost = objective.cost(t)
                study.tell(tr, cost)
                if cost < best_cost:
                    best, best_cost = t, cost
            done += len(batch)
            bar.update(len(batch))
            bar.set_postfix(best=f"{best_cost:.4f}")
        bar.close()
    wall = time.monotonic() - t0
    manifest = {
        "family": family,
        "plant": plant,
        "settings_section": settings_cls.SECTION,
        "design_values": design_values,
        "sampler": f"optuna {optuna.__version__} TPESampler(seed={seed}); the design is trial 0",
        "budget_s": budget_s,
        "trials_cap": trials,
        "trials": done,
        "env_steps": done * sum(scenarios[e.scenario].episode_steps for e in eps),  # control periods
        "wall_s": round(wall, 1),
        "workers": workers,
        "validation": {sc: [e.seed for e in eps if e.scenario == sc] for sc in scenarios},
        "objective": {
            "rule": "geometric mean of main metric / design's + 1 per scenario that is not a result",
            "design": round(objective.cost(design), 6),
            "tuned": round(best_cost, 6),
            "design_main": design.main,
            "tuned_main": best.main,
            "not_a_result_design": objective.failures(design),
            "not_a_result_tuned": objective.failures(best),
        },
        "command": f"frictiongym tune {family!r} --plant {plant} --budget-min {budget_s / 60:g} "
        f"--trials {trials} --seed {seed} --episodes {episodes} --workers {workers}",
        "version": package_version(),
        "commit": _commit(),
    }
    design_cost = objective.cost(design)
    log(f"{family} on {plant}: {done} trials in {wall:.0f} s, cost {design_cost:.4f} -> {best_cost:.4f}")
    return {"values": {k: _plain(v) for k, v in best.values.items()}, "manifest": manifest}


def _suggest(trial: Any, knobs: dict[str, Any]) -> dict[str, Any]:
    """A candidate from the knobs' ranges."""
    out: dict[str, Any] = {}
    for name, k in knobs.items():
        if k.whole:
            out[name] = trial.suggest_int(name, int(k.low), int(k.high))
        else:
            low = max(k.low, 1e-12) if k.log else k.low
            out[name] = trial.suggest_float(name, low, k.high, log=k.log)
    return out


def _plain(v: Any) -> Any:
    return int(v) if isinstance(v, int | np.integer) else float(v)


def _commit() -> str:
    return provenance()["git_commit"]


def write_tuned(path: Path, family: str, plant: str, entry: dict[str, Any]) -> None:
    """Merge one family's plant entry into the tuned-settings file, atomically."""
    data = dict(tuned_entries.__wrapped__(path)) if path.is_file() else {}
    data.setdefault(family, {})[plant] = entry
    header = (
        "# Tuned classical settings (agents/tuning/search.py, `frictiongym tune`); each entry's manifest says"
        " how.\n"
    )
    atomic_text(path, header + yaml.safe_dump(data, sort_keys=True, allow_unicode=True, width=100))
