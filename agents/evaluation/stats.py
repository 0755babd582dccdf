"""Statistics of the leaderboard, after Agarwal et al. 2021 ("Deep RL at the edge of the statistical
precipice", the rliable methods) with scipy.stats: bootstrap intervals, the interquartile mean (IQM) with
stratified-bootstrap intervals, paired comparisons on identical episodes, the probability of improvement,
and performance profiles.

Every metric is "lower is better"; the scores are "higher is better": g, the friction penalty removed
(limit_score: 1 as if friction were gone, 0 no better than the uncompensated loop) and the normalised
score s = 1 - m / m_Zero (1: perfect, 0: as bad as doing nothing, < 0: worse). Bootstraps use a fixed
seed, so the numbers are reproducible.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import astuple, dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.stats import bootstrap, mannwhitneyu, trim_mean

from frictiongym.agents.base import ZERO

if TYPE_CHECKING:
    from frictiongym.agents.evaluation.evaluate import EpisodeResult

CONFIDENCE = 0.95
N_RESAMPLES = 2000
SEED = 0


def normalized_score(m: float, m_zero: float) -> float:
    """s = 1 - m / m_Zero on one episode (nan if m_Zero is 0 or either is not finite)."""
    if not (math.isfinite(m) and math.isfinite(m_zero)) or m_zero == 0:
        return math.nan
    return 1.0 - m / m_zero


LOG_FLOOR_DECADES = 3.0  # a log score counts errors down to 1e-3 of the settling band (0 stays finite)


def limit_score(m: float, m_unc: float, m_ideal: float, kind: str, floor: float) -> float:
    """The friction penalty removed on one episode (docs/envs.md, "Scores"), higher is better:

    - linear: g = (m_unc - m) / (m_unc - m_ideal): 1 as if friction were gone, 0 no better than the
      uncompensated loop, < 0 worse, > 1 better than the friction-free loop; nan if the penalty
      m_unc - m_ideal is not positive on this episode.
    - log (the friction-free loop reaches ~0): the decades of the uncompensated error removed, over the
      decades down to the friction-free loop's error floored at `floor` (the scenario's settling band):
      log10(m_unc / m) / log10(m_unc / max(m_ideal, floor)); m is floored LOG_FLOOR_DECADES below it;
      nan if m_unc is not above that floor.
    - none: nan (friction costs the uncompensated loop nothing on this scenario).
    """
    if kind == "none" or not all(math.isfinite(x) for x in (m, m_unc, m_ideal)):
        return math.nan
    if kind == "linear":
        penalty = m_unc - m_ideal
        return (m_unc - m) / penalty if penalty > 0 else math.nan
    if kind == "log":
        ideal = max(m_ideal, floor)
        if not m_unc > ideal:
            return math.nan
        return math.log10(m_unc / max(m, floor * 10.0**-LOG_FLOOR_DECADES)) / math.log10(m_unc / ideal)
    raise ValueError(f"limit score kind {kind!r} not in ('linear', 'log', 'none')")


@dataclass(frozen=True)
class Scoring:
    """How a scenario's episodes are scored (from its YAML): main metric, uncompensated loop, the kind of
    limit score and its floor (the settling band, in the main metric's unit)."""

    main_metric: str
    uncompensated: str
    limit_score: str
    floor: float


def attach_scores(results: Sequence[EpisodeResult], scoring: dict[str, Scoring]) -> None:
    """Fill in each result's score = 1 - m / m_Zero, g, the friction penalty removed (limit_score)
    between the scenario's uncompensated loop and the Ideal row, and g_tracking, the same between the
    loop and the TrackingLimit row, on the main metric m and the same episode's reference rows (nan where
    a reference did not run)."""

    def metric(r: EpisodeResult) -> float:
        return r.metrics[scoring[r.scenario].main_metric]

    by = {(r.controller, *r.episode()): metric(r) for r in results}
    for r in results:
        s, e, m = scoring[r.scenario], r.episode(), metric(r)
        r.score = normalized_score(m, by.get((ZERO, *e), math.nan))
        m_unc, m_ideal = by.get((s.uncompensated, *e), math.nan), by.get(("Ideal", *e), math.nan)
        r.g = limit_score(m, m_unc, m_ideal, s.limit_score, s.floor)
        m_limit = by.get(("TrackingLimit", *e), m_ideal)  # Ideal stands for it at a set-point
        r.g_tracking = limit_score(m, m_unc, m_limit, s.limit_score, s.floor)


def _finite(x: Sequence[float]) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    return x[np.isfinite(x)]


def mean_ci(x: Sequence[float]) -> tuple[float, float, float]:
    """Mean and 95 % percentile-bootstrap interval of the finite values ((v, v, v) for a single value or
    identical values; nan if none)."""
    x = _finite(x)
    if len(x) == 0:
        return (math.nan,) * 3
    if len(x) == 1 or np.all(x == x[0]):
        return float(x.mean()), float(x.mean()), float(x.mean())
    res = bootstrap(
        (x,),
        np.mean,
        confidence_level=CONFIDENCE,
        n_resamples=N_RESAMPLES,
        method="percentile",
        rng=np.random.default_rng(SEED),
    )
    return float(x.mean()), float(res.confidence_interval.low), float(res.confidence_interval.high)


def iqm(x: Sequence[float]) -> float:
    """Interquartile mean: the mean of the middle 50 % (scipy's trim_mean, 25 % cut at each end)."""
    x = _finite(x)
    return float(trim_mean(x, 0.25)) if len(x) else math.nan


def iqm_ci(strata: Sequence[Sequence[float]]) -> tuple[float, float, float]:
    """IQM of the pooled scores and its 95 % stratified-bootstrap interval: each stratum (a scenario's
    episodes) is resampled on its own, so every scenario keeps its weight."""
    strata = [s for s in (_finite(x) for x in strata) if len(s)]
    if not strata:
        return (math.nan,) * 3
    point = iqm(np.concatenate(strata))
    varied = [s for s in strata if len(s) > 1 and not np.all(s == s[0])]
    if not varied:  # every stratum resamples to itself
        return point, point, point
    # a stratum of one value (or of equal values) resamples to itself: it enters as a constant
    fixed = np.concatenate([s for s in strata if not any(s is v for v in varied)] or [np.empty(0)])

    def stat(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
        const = np.broadcast_to(fixed, (*samples[0].shape[:-1], len(fixed)))
        return trim_mean(np.concatenate([*samples, const], axis=-1), 0.25, axis=-1)

    res = bootstrap(
        tuple(varied),
        stat,
        confidence_level=CONFIDENCE,
        n_resamples=N_RESAMPLES,
        method="percentile",
        rng=np.random.default_rng(SEED),
    )
    return point, float(res.confidence_interval.low), float(res.confidence_interval.high)


def paired(candidate: Sequence[float], baseline: Sequence[float]) -> dict[str, float]:
    """A candidate against a baseline on identical episodes (metric values, lower is better): the mean
    per-episode difference (candidate - baseline, negative = better) with its 95 % bootstrap interval,
    and the probability of improvement P(candidate < baseline), ties counting one half."""
    c, b = np.asarray(candidate, dtype=float), np.asarray(baseline, dtype=float)
    if c.shape != b.shape:
        raise ValueError(f"paired samples need the same episodes: {c.shape} vs {b.shape}")
    ok = np.isfinite(c) & np.isfinite(b)
    c, b = c[ok], b[ok]
    if len(c) == 0:
        return {"diff": math.nan, "diff_lo": math.nan, "diff_hi": math.nan, "p_improve": math.nan, "n": 0}
    mean, lo, hi = mean_ci(c - b)
    p = float(np.mean((c < b) + 0.5 * (c == b)))
    return {"diff": mean, "diff_lo": lo, "diff_hi": hi, "p_improve": p, "n": len(c)}


def probability_of_improvement(x: Sequence[Sequence[float]], y: Sequence[Sequence[float]]) -> float:
    """P(X > Y) of Agarwal et al. 2021 (rliable): per stratum (a scenario), the probability that a run of
    X scores higher than a run of Y, ties counting one half (the Mann-Whitney U statistic over n·m,
    scipy.stats.mannwhitneyu), averaged over the strata where both have finite scores (scores: higher is
    better)."""
    ps = []
    for a, b in zip(x, y, strict=True):
        a, b = _finite(a), _finite(b)
        if len(a) and len(b):
            ps.append(float(mannwhitneyu(a, b).statistic) / (len(a) * len(b)))
    return float(np.mean(ps)) if ps else math.nan


def performance_profile(scores: Sequence[float], taus: np.ndarray) -> np.ndarray:
    """Fraction of episodes whose score exceeds each threshold τ (the run-score distribution of Agarwal
    et al. 2021, Fig. 5)."""
    s = _finite(scores)
    if len(s) == 0:
        return np.full(len(taus), math.nan)
    return (s[None, :] > np.asarray(taus)[:, None]).mean(axis=1)


# The rule every row meets to be a result, classical and learned alike, against one reference point per
# scenario (reference_point: what the uncompensated loop and the friction-free linear design do on the same
# episodes). Chatter: the command's rms change per control period (metrics.command_roughness) at most
# CHATTER_RATIO times the point's plus CHATTER_FLOOR of the command's range; saturation: the share of
# saturated periods at most SATURATION_RATIO times the point's plus SATURATION_FLOOR; a limit cycle: the
# error's sustained oscillation at rest (metrics.rest_oscillation) at most CYCLE_RATIO times the point's
# plus the scenario's settling band.
CHATTER_RATIO, CHATTER_FLOOR = 3.0, 0.01
SATURATION_RATIO, SATURATION_FLOOR = 1.5, 0.02
CYCLE_RATIO = 1.2


@dataclass(frozen=True)
class Conduct:
    """What the rule reads of a row on a scenario, each a mean over its episodes: command_roughness
    (command unit), saturated_share (fraction), rest_oscillation (output unit; nan: the reference never
    rests)."""

    roughness: float
    saturated: float
    rest_cycle: float

    @classmethod
    def of(cls, means: dict[str, float]) -> Conduct:
        """From a row's metric means (or a results file's columns of the same names)."""
        return cls(means["command_roughness"], means["saturated_share"], means["rest_oscillation"])


def reference_point(loop: Conduct, limit: Conduct | None) -> Conduct:
    """The point every row of a scenario is held to: the larger of the uncompensated loop's and the
    friction-free linear design's (TrackingLimit, or Ideal at a set-point: what following the reference
    itself needs) of each measure; the loop's alone without the design."""
    if limit is None:
        return loop

    def larger(a: float, b: float) -> float:
        return b if math.isnan(a) else a if math.isnan(b) else max(a, b)

    return Conduct(*(larger(a, b) for a, b in zip(astuple(loop), astuple(limit), strict=True)))


POINT_LIMITS = ("TrackingLimit", "Ideal")  # the friction-free designs a point reads: the first that has rows


def point_with(loop: Conduct, limits: Mapping[str, Conduct]) -> Conduct:
    """reference_point with the first of POINT_LIMITS among `limits` (TrackingLimit on a tracking task,
    Ideal at a set-point, where TrackingLimit does not apply; the loop's alone with neither)."""
    return reference_point(loop, next((limits[n] for n in POINT_LIMITS if n in limits), None))


def why_not_result(row: Conduct, point: Conduct, scale: float, band: float) -> list[str]:
    """Why a row is not a result on its scenario (empty: it is one): it chatters, saturates or adds a
    limit cycle beyond the reference point (module constants); scale is the command's range (the
    scenario's action scale, V or N·m), band the settling band (output unit)."""
    why = []
    if not row.roughness <= CHATTER_RATIO * point.roughness + CHATTER_FLOOR * scale:
        why.append(f"chatters ({row.roughness:.3g} vs {point.roughness:.3g} rms change per period)")
    if not row.saturated <= SATURATION_RATIO * point.saturated + SATURATION_FLOOR:
        why.append(f"saturates ({100 * row.saturated:.3g} % vs {100 * point.saturated:.3g} % of periods)")
    at_rest = 0.0 if math.isnan(point.rest_cycle) else point.rest_cycle
    if not math.isnan(row.rest_cycle) and not row.rest_cycle <= CYCLE_RATIO * at_rest + band:
        why.append(f"limit cycle at rest ({row.rest_cycle:.3g} vs {at_rest:.3g})")
    return why


def why_not_beats(
    paired: dict[str, float], row: Conduct, point: Conduct, scale: float, band: float
) -> list[str]:
    """Why a candidate does not beat a baseline (empty: it beats it): `paired` is stats.paired(candidate,
    baseline) of the main metric, whose interval must lie below 0, and the candidate must be a result
    (why_not_result against the scenario's reference point). The leaderboard's verdicts, tuning and
    validation selection on several scenarios (agents/training/) apply this one rule."""
    why = []
    if not paired["diff_hi"] < 0:
        why.append("worse" if paired["diff_lo"] > 0 else "difference interval does not exclude 0")
    return why + why_not_result(row, point, scale, band)
