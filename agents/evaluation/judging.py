"""The episodes that judge a leaderboard's rows besides the ones they are ranked on, and what they say.

- **Selection**: the first SELECTION_EPISODES episodes of each scenario from the `validation` seed range
  (the episodes that select learned models, agents/training/) choose the scenario's baseline, the best
  classical row that is a result there, so the reported episodes never choose what they judge. A held-out
  scenario's validation-range episodes are run here and nowhere else: no training, tuning or model
  selection reads them.
- **Robustness**: the first ROBUSTNESS_SEEDS of those episodes, each perturbed as a real loop or drive
  would perturb it (VARIANTS: one more control period of actuation delay, twice the sensor noise, the
  inertia INERTIA_MARGIN heavier, the resonance SPRING_MARGIN softer) and as drawn (NOMINAL), run by
  every entry and the scenario's uncompensated loop. A row that diverges there, saturates beyond the
  loop's share or falls behind the loop's main metric on a variant where it is not behind it as drawn is
  fragile: not a result, as a servo engineer rejects a design without margins. (A row behind the loop as
  drawn is a weak row, not a fragile one: it keeps no lead a perturbation could take.)

The variants pin values of the episode's own draw (envs/plants/params.py `EpisodeParams.draw_values`), so
each is the same episode with one thing changed.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from frictiongym.agents.evaluation import stats
from frictiongym.agents.evaluation.evaluate import EpisodeResult, params_text
from frictiongym.envs.plants.params import EpisodeParams
from frictiongym.envs.scenario import Scenario
from frictiongym.envs.suites import Episode, seed_range

SELECTION_EPISODES = 10  # validation episodes per scenario that choose the baseline (validation.episodes)
ROBUSTNESS_SEEDS = 3  # of them, the episodes each robustness variant perturbs
NOISE_FACTOR = 2.0  # x the episode's drawn noise scale
INERTIA_MARGIN = 0.2  # the inertia this much heavier (a load of a fifth of the drive's own)
SPRING_MARGIN = 0.2  # the spring this much softer: the resonance sqrt(0.8) = 0.89x as high
NOMINAL = "nominal"  # the robustness seeds as drawn: what each variant's loss of lead is read against
VARIANTS = {
    "delay": "one more control period of delay",
    "noise": f"{NOISE_FACTOR:g}x the sensor noise",
    "inertia": f"the inertia {100 * INERTIA_MARGIN:g} % heavier",
    "resonance": f"the spring {100 * SPRING_MARGIN:g} % softer",
}


def validation_seeds(n: int) -> list[int]:
    """The first n seeds of the validation range (configs/suites.yaml)."""
    first, last = seed_range("validation")
    return list(range(first, min(first + n, last + 1)))


def selection_episodes(episodes: list[Episode]) -> list[Episode]:
    """The selection episodes of each scenario of `episodes` (with its randomize flag), scenario-major."""
    flags = {e.scenario: e.randomize for e in episodes}
    return [Episode(sc, s, flag) for sc, flag in flags.items() for s in validation_seeds(SELECTION_EPISODES)]


def variants(scenario: Scenario, seed: int, randomize: bool) -> dict[str, dict[str, float]]:
    """The pinned values of each robustness variant that applies to the scenario (noise only where a
    sensor has noise to double, the resonance only where the plant has a spring), from the episode's own
    draw."""
    spec = scenario.spec
    drawn = EpisodeParams.draw_values(spec, seed) if randomize else {}
    out = {"delay": {"delay_s": drawn.get("delay_s", spec.delay) + scenario.control_period}}
    if any(s.noise_std > 0 for s in spec.sensors):
        out["noise"] = {"noise_scale": NOISE_FACTOR * drawn.get("noise_scale", 1.0)}
    out["inertia"] = {"inertia_scale": drawn.get("inertia_scale", 1.0) * (1 + INERTIA_MARGIN)}
    if spec.springs:
        out["resonance"] = {"spring_scale": drawn.get("spring_scale", 1.0) * (1 - SPRING_MARGIN)}
    return out


def robustness_episodes(episodes: list[Episode], scenarios: dict[str, Scenario]) -> dict[Episode, str]:
    """The robustness set of each scenario of `episodes`: {episode: its variant, or NOMINAL for the seed
    as drawn}, scenario-major."""
    flags = {e.scenario: e.randomize for e in episodes}
    out = {}
    for sc, flag in flags.items():
        for seed in validation_seeds(ROBUSTNESS_SEEDS):
            out[Episode(sc, seed, flag)] = NOMINAL
            for name, pinned in variants(scenarios[sc], seed, flag).items():
                out[Episode(sc, seed, flag, tuple(sorted(pinned.items())))] = name
    return out


def fragile(
    results: list[EpisodeResult], robustness: dict[Episode, str], scenarios: dict[str, Scenario]
) -> dict[tuple[str, str], str]:
    """{(scenario, controller): why it is fragile} for the rows that are ("" never appears): on some
    variant it diverges, saturates beyond SATURATION_RATIO times the uncompensated loop's share plus
    SATURATION_FLOOR, or its mean main metric is above the loop's on the same episodes where, as drawn
    (NOMINAL), it is not."""
    by_text = {(e.scenario, e.seed, params_text(e)): v for e, v in robustness.items()}
    rows: dict[tuple[str, str, str], list[EpisodeResult]] = defaultdict(list)
    for r in results:
        rows[r.scenario, r.controller, by_text[(r.scenario, r.seed, r.params)]].append(r)
    out: dict[tuple[str, str], list[str]] = defaultdict(list)
    for (sc, name, variant), mine in rows.items():
        s = scenarios[sc]
        loop = rows.get((sc, s.uncompensated, variant))
        if name == s.uncompensated or loop is None or variant == NOMINAL:
            continue
        what = VARIANTS[variant]
        if any(r.diverged for r in mine):
            out[sc, name].append(f"diverges with {what}")
            continue
        main = _mean(mine, s.main_metric)
        drawn = _mean(rows[sc, name, NOMINAL], s.main_metric)
        ahead = drawn <= _mean(rows[sc, s.uncompensated, NOMINAL], s.main_metric)  # as drawn
        if ahead and main > _mean(loop, s.main_metric):
            out[sc, name].append(f"behind the uncompensated loop with {what}")
        sat, sat_loop = _mean(mine, "saturated_share"), _mean(loop, "saturated_share")
        if sat > stats.SATURATION_RATIO * sat_loop + stats.SATURATION_FLOOR:
            out[sc, name].append(f"saturates {100 * sat:.3g} % of periods with {what}")
    return {k: "fragile: " + "; ".join(v) for k, v in out.items()}


def _mean(rows: list[EpisodeResult], metric: str) -> float:
    x = np.array([r.metrics[metric] for r in rows], dtype=float)
    return float(np.mean(x)) if np.isfinite(x).all() else math.inf
