"""agents/evaluation/stats.py: intervals, the IQM, paired comparisons, performance profiles and the
scores (the normalised score, g, and their attachment to a scenario's episodes), each on values with a
known answer."""

import math

import numpy as np
import pytest

from frictiongym.agents.evaluation import stats
from frictiongym.agents.evaluation.evaluate import EpisodeResult


def test_bootstrap_interval_brackets_the_mean_and_is_reproducible():
    x = np.array([1.0, 2.0, 3.0, 4.0, 10.0])
    m, lo, hi = stats.mean_ci(x)
    assert m == pytest.approx(4.0) and lo < m < hi
    assert stats.mean_ci(x) == (m, lo, hi)
    assert stats.mean_ci(np.array([np.nan, 2.0])) == (2.0, 2.0, 2.0)


def test_statistics_agree_with_hand_computed_values():
    assert stats.normalized_score(0.5, 2.0) == 0.75 and np.isnan(stats.normalized_score(1.0, 0.0))
    assert stats.iqm(np.arange(1.0, 9.0)) == pytest.approx(4.5)  # mean of 3, 4, 5, 6
    # pooled 1..8 and 10..13: the middle half is 4..8 and 10, mean 40/6
    iqm, lo, hi = stats.iqm_ci([np.arange(1.0, 9.0), np.arange(10.0, 14.0)])
    assert iqm == pytest.approx(40 / 6) and lo <= iqm <= hi
    p = stats.paired([1.0, 2.0, 3.0], [2.0, 2.0, 5.0])  # differences -1, 0, -2
    assert p["diff"] == pytest.approx(-1.0) and p["p_improve"] == pytest.approx(2.5 / 3)  # a tie counts 1/2
    assert p["diff_lo"] <= -1.0 <= p["diff_hi"]
    prof = stats.performance_profile([0.1, 0.5, 0.9, -0.2], np.array([0.0, 0.5]))
    assert list(prof) == [0.75, 0.25]  # scores > 0: 3 of 4; > 0.5: 1 of 4


def test_limit_score_cases():
    # linear: half the penalty removed; all of it; worse than the loop; no penalty
    assert stats.limit_score(3.0, 4.0, 2.0, "linear", 0.1) == pytest.approx(0.5)
    assert stats.limit_score(2.0, 4.0, 2.0, "linear", 0.1) == pytest.approx(1.0)
    assert stats.limit_score(5.0, 4.0, 2.0, "linear", 0.1) == pytest.approx(-0.5)
    assert math.isnan(stats.limit_score(3.0, 2.0, 2.5, "linear", 0.1))  # friction helps: not scored
    # log: 1e-1 -> 1e-3 is 2 of the 3 decades down to the floor (1e-4, the ideal 1e-8 is below it)
    assert stats.limit_score(1e-3, 1e-1, 1e-8, "log", 1e-4) == pytest.approx(2 / 3)
    assert stats.limit_score(0.0, 1e-1, 1e-8, "log", 1e-4) == pytest.approx(6 / 3)  # floored 3 decades
    assert math.isnan(stats.limit_score(1.0, 1.0, 0.0, "none", 1e-4))
    assert math.isnan(stats.limit_score(1.0, math.nan, 0.0, "linear", 1e-4))


def test_scores_are_attached_from_the_same_episodes_reference_rows():
    """stats.attach_scores on constructed results: per episode, score = 1 - m/m_Zero and g between the
    uncompensated loop and Ideal; an episode without its Ideal row leaves g nan, not another episode's."""
    scoring = {"s": stats.Scoring("iae", "PID", "linear", 0.0)}

    def r(c: str, seed: int, iae: float) -> EpisodeResult:
        return EpisodeResult(c, "s", seed, {"iae": iae}, 0.0, False, randomize=True)

    results = [r("Zero", 1, 2.0), r("PID", 1, 1.0), r("Ideal", 1, 0.5), r("FF", 1, 0.75)]
    results += [r("Zero", 2, 4.0), r("PID", 2, 2.0), r("FF", 2, 1.0)]
    stats.attach_scores(results, scoring)
    got = {(x.controller, x.seed): (x.score, x.g) for x in results}
    assert got[("FF", 1)] == (1 - 0.75 / 2.0, (1.0 - 0.75) / (1.0 - 0.5))
    assert got[("PID", 1)] == (0.5, 0.0) and got[("Ideal", 1)] == (0.75, 1.0) and got[("Zero", 1)][0] == 0.0
    assert got[("FF", 2)][0] == 0.75 and math.isnan(got[("FF", 2)][1])
