"""Listening-test statistics checked against SciPy and on a data set with the paper's means."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from barsynth import ParameterError
from barsynth.listening import (
    ab_summary,
    holm,
    pairwise_rank_sum,
    paper_like_ratings,
    rank_sum_p,
    significance_mark,
    summarize,
)
from barsynth.listening.stats import PAPER_MEANS


@pytest.mark.parametrize("seed", range(8))
def test_rank_sum_equals_scipy_asymptotic_with_ties_and_continuity(seed):
    rng = np.random.default_rng(seed)
    a = np.round(rng.uniform(0, 10, rng.integers(5, 30)), 1)  # slider steps of 0.1 make ties
    b = np.round(rng.uniform(0, 10, rng.integers(5, 30)) * rng.uniform(0.5, 1.0), 1)
    expected = stats.mannwhitneyu(a, b, alternative="two-sided", method="asymptotic", use_continuity=True).pvalue
    assert rank_sum_p(a, b) == pytest.approx(expected, rel=1e-10, abs=1e-300)


def test_rank_sum_edge_cases():
    assert rank_sum_p([5.0, 5.0], [5.0, 5.0, 5.0]) == 1.0
    assert rank_sum_p([9.0] * 21, [1.0] * 21) < 1e-8
    with pytest.raises(ParameterError):
        rank_sum_p([], [1.0])


def test_holm_matches_a_worked_example():
    # Holm (1979) step-down: sorted p 0.01, 0.02, 0.03, 0.04 with m = 4
    assert holm([0.04, 0.01, 0.03, 0.02]) == pytest.approx([0.06, 0.04, 0.06, 0.06])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])


@pytest.mark.parametrize("p,mark", [(0.2, "ns"), (0.05, "ns"), (0.049, "*"), (0.009, "**"),
                                    (0.0009, "***"), (0.00009, "****")])
def test_marks(p, mark):
    assert significance_mark(p) == mark


def test_summaries_against_numpy():
    data = {"a": [1.0, 2.0, 3.0, 4.0], "b": [9.99, 0.0, 5.0]}
    a, b = summarize(data)
    assert (a.count, a.mean, a.median, a.q1, a.q3) == (4, 2.5, 2.5, 1.75, 3.25)
    assert b.median == 5.0 and b.mean == pytest.approx(14.99 / 3)
    for bad in ({"a": []}, {"a": [10.5]}, {"a": [float("nan")]}):
        with pytest.raises(ParameterError):
            summarize(bad)


def test_report_on_a_data_set_with_the_papers_means():
    ratings = paper_like_ratings(seed=3)
    summary = {s.clip: s for s in summarize(ratings)}
    for clip, mean in PAPER_MEANS.items():
        assert summary[clip].mean == pytest.approx(mean, abs=1e-9)
        assert summary[clip].count == 21
    table = pairwise_rank_sum(ratings)
    clips = list(ratings)
    real1, anchor1 = clips.index("Real1"), clips.index("Anchor1")
    assert table.mark(real1, anchor1) == "****"  # 8.10 against 0.61
    corrected = pairwise_rank_sum(ratings, holm_correction=True)
    for i in range(len(clips)):
        for j in range(i):
            assert corrected.p[i][j] >= table.p[i][j]
    text = table.to_text()
    assert "uncorrected" in text and "****" in text
    assert "Holm-corrected" in corrected.to_text()


def test_ab_summary():
    trials = [("farnell", True, 4)] * 17 + [("farnell", False, 2)] * 2 + [("proposed", True, 4)] * 9 + \
             [("proposed", False, 3)]
    result = {r.model: r for r in ab_summary(trials)}
    assert result["farnell"].correct_share == pytest.approx(17 / 19)
    assert result["proposed"].correct_share == pytest.approx(0.9)
    assert result["proposed"].median_difficulty == 4.0
    with pytest.raises(ParameterError, match="difficulty"):
        ab_summary([("x", True, 6)])
