"""The sim-to-real friction study (scripts/sim2real.py): controllers designed or trained on the nominal plant
(or on randomised ones) evaluated on shifted plants, with the foundation's per-episode parameter pinning.

- One axis at a time: each of AXES is pinned to a grid over its shift range (scales ×0.5…×1.5, the
  asymmetry shift ±0.25 of the Coulomb level, the delay 0…one control period), the others nominal.
- Structures: the nominal plant with each friction structure (envs/friction.py: LuGre, Dahl, Maxwell-slip,
  Kang's stick-slip model, Coulomb + viscous), the same static levels, bristle stiffness and episodes; the
  controllers are designed (and the agents were trained) on the scenario's own structure.
- Joint shifts: every axis drawn at once, in two separate sets: in-distribution (inside the plant preset's
  randomisation ranges, what the `nominal` agents trained on) and out-of-distribution (inside the study's
  wide box, outside the preset's ranges on at least one axis). Draws the plant's checks reject (e.g. a
  LuGre stiffness too high for the timestep at a small inertia) are left out and counted.

Every episode is an engine job (resumable episodes.csv); the summary is computed from the results.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np
from tqdm import tqdm

from frictiongym.agents import registry
from frictiongym.agents.evaluation import stats
from frictiongym.agents.evaluation.evaluate import EnvCache, EpisodeResult, run_episode
from frictiongym.agents.lab import experiments as ex
from frictiongym.agents.lab.fits import identify_simulated
from frictiongym.envs.config import ConfigError
from frictiongym.envs.friction import STRUCTURES
from frictiongym.envs.plants.identified import IdentifiedFriction, apply_identified
from frictiongym.envs.plants.params import EpisodeParams, spec_with
from frictiongym.envs.sampler import stream
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode, seed_range

SEEDS, _LAST = seed_range("sim2real")  # configs/suites.yaml's range: disjoint from every suite and training
SET_SPAN = (_LAST + 1 - SEEDS) // 3  # seeds per set: one-axis and structure episodes, joint sets, model error
SEED_RANGE = (SEEDS, _LAST + 1)  # every seed the study uses, [first, end)


@dataclass(frozen=True)
class Axis:
    """A shifted parameter: a randomization key over [low, high] (delay: fractions of the period), and
    its value on the nominal plant (None: the preset's own, the delay)."""

    key: str
    low: float
    high: float
    label: str
    nominal: float | None = None

    def values(self, points: int, period: float) -> list[float]:
        grid = np.linspace(self.low, self.high, points)
        return [float(x * period) if self.key == "delay_s" else float(x) for x in grid]

    def box(self, period: float) -> tuple[float, float]:
        k = period if self.key == "delay_s" else 1.0
        return self.low * k, self.high * k


AXES = (
    Axis("friction_scale", 0.5, 1.5, "friction level (x nominal)", 1.0),
    Axis("asymmetry_shift", -0.25, 0.25, "asymmetry (shift / Coulomb level)", 0.0),
    Axis("stribeck_velocity_scale", 0.5, 1.5, "Stribeck velocity (x nominal)", 1.0),
    Axis("sigma0_scale", 0.5, 1.5, "bristle stiffness σ0 (x nominal)", 1.0),
    Axis("viscous_scale", 0.5, 1.5, "viscous friction (x nominal)", 1.0),
    Axis("inertia_scale", 0.5, 1.5, "inertia (x nominal)", 1.0),
    Axis("delay_s", 0.0, 1.0, "delay (s; up to one control period)"),
)


def _pinned(values: dict[str, float]) -> tuple[tuple[str, float], ...]:
    return tuple(sorted(values.items()))


def _admissible(scenario: str, values: dict[str, float]) -> bool:
    """Whether the plant's checks accept the pinned values (numerics, physical ranges)."""
    spec = load_scenario(scenario).spec
    try:
        EpisodeParams.from_values(spec, values).validate(spec)  # as the env builds a non-random episode
    except (ConfigError, ValueError):
        return False
    return True


# the structural axis (friction_model): envs.friction.STRUCTURES


def runnable_structures(scenario: str, structures: tuple[str, ...]) -> tuple[tuple[str, ...], dict[str, str]]:
    """The structures of `structures` the scenario can be built with, and why each other one cannot (a
    drift scenario's levels drift through bristle elements, which Coulomb + viscous does not have)."""
    ok, why = [], {}
    for model in structures:
        try:
            load_scenario(scenario, {"friction_model": model})
        except ConfigError as e:
            why[model] = str(e)
        else:
            ok.append(model)
    return tuple(ok), why


def plan(
    scenario: str, seeds: int, points: int, joint: int, structures: tuple[str, ...] = STRUCTURES
) -> tuple[list[Episode], dict[str, int]]:
    """The study's episodes (nominal plant + pins; randomize off so only the pinned values move) and the
    number of rejected joint draws per set. `structures` must be runnable on the scenario
    (runnable_structures)."""
    if max(seeds, joint) > SET_SPAN:
        raise ValueError(f"--seeds, --joint at most {SET_SPAN} (the study's seed sets: configs/suites.yaml)")
    sc = load_scenario(scenario)
    h, ranges = sc.control_period, sc.spec.randomization
    episodes: list[Episode] = []
    for model in structures:  # the same episodes (seeds) as every shift, on another friction structure
        episodes += [Episode(scenario, SEEDS + i, False, (("friction_model", model),)) for i in range(seeds)]
    for axis in AXES:
        if axis.key not in ranges and axis.key != "delay_s":
            continue
        for v in axis.values(points, h):
            if _admissible(scenario, {axis.key: v}):
                episodes += [
                    Episode(scenario, SEEDS + i, False, _pinned({axis.key: v})) for i in range(seeds)
                ]
    rejected = {}
    axes = [a for a in AXES if a.key in ranges]
    for k, name in enumerate(("in_distribution", "out_of_distribution")):
        rng, n, bad = stream(SEEDS + k, f"sim2real_{name}"), 0, 0
        while n < joint:
            if name == "in_distribution":
                values = {a.key: float(rng.uniform(*ranges[a.key])) for a in axes}
            else:
                values = {a.key: float(rng.uniform(*a.box(h))) for a in axes}
                if all(ranges[a.key][0] <= values[a.key] <= ranges[a.key][1] for a in axes):
                    continue  # inside the training ranges: not out of distribution
            if not _admissible(scenario, values):
                bad += 1
                continue
            episodes.append(Episode(scenario, SEEDS + SET_SPAN * (k + 1) + n, False, _pinned(values)))
            n += 1
        rejected[name] = bad
    return episodes, rejected


def condition(e: Episode | EpisodeResult, ranges: dict[str, tuple[float, float]]) -> tuple[str, float | str]:
    """(axis or joint set, shift value; for the structural axis the structure's name) of an episode or of
    a result on one."""

    params = dict(e.params) if isinstance(e, Episode) else json.loads(e.params or "{}")
    if "friction_model" in params:
        return "friction_model", params["friction_model"]
    if len(params) == 1:
        ((key, value),) = params.items()
        return key, value
    inside = all(ranges[k][0] <= v <= ranges[k][1] for k, v in params.items())
    return ("joint_in_distribution" if inside else "joint_out_of_distribution"), math.nan


def summarize(results: list[EpisodeResult], scenario: str) -> list[dict[str, Any]]:
    """sim2real.csv rows: controller, axis, shift, main metric and score means with 95 % intervals."""
    sc = load_scenario(scenario)
    main, groups = sc.main_metric, defaultdict(list)
    for r in results:
        axis, shift = condition(r, sc.spec.randomization)
        groups[(r.controller, axis, shift)].append(r)
    out = []
    for (name, axis, shift), rs in groups.items():
        m = stats.mean_ci([r.metrics[main] for r in rs])
        s = stats.mean_ci([r.score for r in rs])
        e = stats.mean_ci([r.metrics["effort_rms"] for r in rs])
        out.append(
            {
                "controller": name,
                "axis": axis,
                "shift": shift,
                "episodes": len(rs),
                "metric": main,
                "mean": m[0],
                "ci_low": m[1],
                "ci_high": m[2],
                "score": s[0],
                "score_ci_low": s[1],
                "score_ci_high": s[2],
                "effort_rms": e[0],
            }
        )
    return out


DEGRADED = 1.5  # "breaks": the main metric exceeds 1.5x the controller's own value on the nominal plant


# ------------------------------------------------------------------------------------------- model error
MODEL_ERROR_SEEDS = SEEDS + SET_SPAN  # "true" plants of the closing-the-loop study (a randomised draw each)
DESIGNS = ("nominal", "identified", "true")


def model_error(
    scenario: str, controllers: list[str], draws: int = 10, progress: bool = True
) -> list[dict[str, Any]]:
    """Closing the identification loop. For each randomised "true" plant (the scenario's draw of seed
    MODEL_ERROR_SEEDS + i), run the LuGre identification experiments on it (noise and quantisation on),
    then run each controller on that same episode designed on three models: the nominal preset, the
    identified plant (nominal preset + identified friction) and the true plant. Rows: controller, design,
    seed, main metric."""

    if draws > SET_SPAN:
        raise ValueError(f"--model-error at most {SET_SPAN} (the study's seed sets, configs/suites.yaml)")
    envs = EnvCache()
    rows = []
    for i in tqdm(range(draws), desc="model error", unit="plant", disable=not progress):
        seed = MODEL_ERROR_SEEDS + i
        episode = Episode(scenario, seed, True)
        sc = envs.scenario(episode)
        p = ex.protocol(sc.spec)
        rig = ex.Rig.of(sc.spec, seed, True)
        fid = identify_simulated(ex.run_all(rig, p, ("holds", "breakaway", "presliding")), p)
        values = {k: v for k, v in fid.values().items() if k not in fid.unidentified}
        # the scenario's plant with the identified friction (the friction_identified mechanism), checked as
        # a plant's parameters are; a design model, so the randomisation ranges are not re-checked
        identified = apply_identified(sc.spec, IdentifiedFriction.from_values(values))
        EpisodeParams.nominal(identified).validate(identified)
        true = spec_with(sc.spec, EpisodeParams.draw(sc.spec, seed))
        for name in controllers:
            c = registry.make(name)
            if not c.applies_to(sc):
                continue
            for design, spec in zip(DESIGNS, (sc.spec, identified, true), strict=True):
                r = run_episode(c, episode, envs=envs, design=spec)
                rows.append(
                    {"controller": name, "design": design, "seed": seed, "main": r.metrics[sc.main_metric]}
                )
    return rows


def model_error_table(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per controller and design: the mean main metric with 95 % CI; for `identified` and `nominal`, the
    paired loss against the true-parameter design (positive = worse)."""
    by = defaultdict(dict)
    for r in rows:
        by[(r["controller"], r["design"])][r["seed"]] = r["main"]
    out = []
    for (name, design), vals in sorted(by.items()):
        m = stats.mean_ci(list(vals.values()))
        row = {"controller": name, "design": design, "mean": m[0], "ci_low": m[1], "ci_high": m[2]}
        true = by.get((name, "true"), {})
        if design != "true" and true:
            seeds = sorted(set(vals) & set(true))
            d = stats.paired([vals[s] for s in seeds], [true[s] for s in seeds])
            row |= {"loss": d["diff"], "loss_low": d["diff_lo"], "loss_high": d["diff_hi"]}
        out.append(row)
    return out
