"""Statistics of listening tests (barsynth spec 4.3), as the twang paper reported them.

Source: Selfridge et al., AES Convention Paper 10553 (2022), sections on the MUSHRA-style
rating test (after ITU-R BS.1534) and the A/B identification test.

* per clip: count, mean, median and quartiles of the 0-10 ratings;
* between every pair of clips: the two-sided Wilcoxon rank-sum test (Mann-Whitney U,
  normal approximation with tie and continuity corrections, as for the paper's 21
  listeners), as a lower-triangular table of marks ns / * / ** / *** / ****;
  uncorrected like the paper, or Holm-corrected on request;
* per model of the A/B test: the share of correct identifications and the median
  difficulty (5-point Likert).

Pure functions over plain data; the report command and plots sit on top.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError

MARK_LEVELS = ((1e-4, "****"), (1e-3, "***"), (1e-2, "**"), (5e-2, "*"))
RATING_MIN = 0.0
RATING_MAX = 10.0

# The paper's mean ratings (spec 4.3), for the synthetic reference data set.
PAPER_MEANS = {
    "Anchor1": 0.61, "Anchor2": 0.51, "Farnell1": 3.04, "Farnell2": 4.56,
    "Proposed1": 4.12, "Proposed2": 6.02, "Real1": 8.10, "Real2": 7.07,
}
PAPER_LISTENERS = 21


@dataclass(frozen=True)
class ClipSummary:
    """Ratings of one clip: count, mean, median, first and third quartiles."""

    clip: str
    count: int
    mean: float
    median: float
    q1: float
    q3: float


@dataclass(frozen=True)
class PairwiseTable:
    """p-values (two-sided rank-sum) between clips; ``p[i][j]`` for ``i > j`` only."""

    clips: tuple[str, ...]
    p: tuple[tuple[float, ...], ...]
    holm: bool

    def mark(self, i: int, j: int) -> str:
        return significance_mark(self.p[i][j])

    def to_text(self) -> str:
        """The lower-triangular table of marks, one row per clip."""
        width = max(len(c) for c in self.clips)
        lines = [f"{'':<{width}}  " + "  ".join(f"{c:>{max(4, len(c))}}" for c in self.clips[:-1])]
        for i in range(1, len(self.clips)):
            cells = [f"{self.mark(i, j):>{max(4, len(self.clips[j]))}}" for j in range(i)]
            lines.append(f"{self.clips[i]:<{width}}  " + "  ".join(cells))
        note = "Holm-corrected" if self.holm else "uncorrected (as in the paper)"
        lines.append(f"two-sided Wilcoxon rank-sum, p-values {note}: "
                     "ns p>0.05, * <0.05, ** <0.01, *** <0.001, **** <0.0001")
        return "\n".join(lines)


def _ratings(name: str, values: Sequence[float]) -> np.ndarray:
    x = np.asarray(values, dtype=np.float64)
    if x.ndim != 1 or x.size == 0:
        raise ParameterError(f"parameter ratings[{name!r}] has no ratings; allowed: 1 or more")
    bad = ~(np.isfinite(x) & (x >= RATING_MIN) & (x <= RATING_MAX))
    if bad.any():
        raise ParameterError(
            f"parameter ratings[{name!r}] = {float(x[bad][0])!r} is out of range; "
            f"allowed: {RATING_MIN:g} to {RATING_MAX:g} (rating)"
        )
    return x


def summarize(ratings: Mapping[str, Sequence[float]]) -> list[ClipSummary]:
    """Count, mean, median and quartiles (linear interpolation) of each clip's ratings."""
    out = []
    for clip, values in ratings.items():
        x = _ratings(clip, values)
        q1, median, q3 = np.percentile(x, [25, 50, 75])
        out.append(ClipSummary(clip, int(x.size), float(x.mean()), float(median), float(q1), float(q3)))
    return out


def rank_sum_p(a: Sequence[float], b: Sequence[float]) -> float:
    """Two-sided p-value of the Wilcoxon rank-sum (Mann-Whitney U) test.

    Normal approximation of U with the tie correction of the variance and a
    continuity correction of 0.5; 1.0 when every value is tied.
    """
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    n1, n2 = x.size, y.size
    if n1 == 0 or n2 == 0:
        raise ParameterError("parameter ratings has an empty clip; allowed: 1 or more ratings each")
    both = np.concatenate([x, y])
    order = np.argsort(both, kind="mergesort")
    ranks = np.empty(both.size)
    sorted_values = both[order]
    i = 0
    tie_term = 0.0
    while i < both.size:  # average ranks over ties
        j = i
        while j + 1 < both.size and sorted_values[j + 1] == sorted_values[i]:
            j += 1
        ranks[order[i:j + 1]] = 0.5 * (i + j) + 1.0
        t = j - i + 1
        tie_term += t ** 3 - t
        i = j + 1
    u1 = ranks[:n1].sum() - n1 * (n1 + 1) / 2.0
    n = n1 + n2
    mean_u = n1 * n2 / 2.0
    var_u = n1 * n2 / 12.0 * ((n + 1) - tie_term / (n * (n - 1)))
    if var_u <= 0.0:
        return 1.0
    z = (abs(u1 - mean_u) - 0.5) / math.sqrt(var_u)
    return float(min(1.0, math.erfc(max(z, 0.0) / math.sqrt(2.0))))


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm's step-down adjustment of a family of p-values (same order as given)."""
    p = np.asarray(p_values, dtype=np.float64)
    m = p.size
    order = np.argsort(p, kind="mergesort")
    adjusted = np.empty(m)
    running = 0.0
    for rank, index in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[index]))
        adjusted[index] = running
    return adjusted.tolist()


def significance_mark(p: float) -> str:
    """ns, *, **, *** or **** (p < 0.05, 0.01, 0.001, 0.0001)."""
    for level, mark in MARK_LEVELS:
        if p < level:
            return mark
    return "ns"


def pairwise_rank_sum(ratings: Mapping[str, Sequence[float]], *, holm_correction: bool = False) -> PairwiseTable:
    """Every pair of clips compared with :func:`rank_sum_p` (Holm over all pairs if asked)."""
    clips = tuple(ratings)
    data = [_ratings(c, ratings[c]) for c in clips]
    pairs = [(i, j) for i in range(len(clips)) for j in range(i)]
    raw = [rank_sum_p(data[i], data[j]) for i, j in pairs]
    values = holm(raw) if holm_correction else raw
    table = [[math.nan] * len(clips) for _ in clips]
    for (i, j), p in zip(pairs, values):
        table[i][j] = p
    return PairwiseTable(clips, tuple(tuple(row) for row in table), holm_correction)


@dataclass(frozen=True)
class ABSummary:
    """A/B identification of one model against recordings."""

    model: str
    trials: int
    correct_share: float
    median_difficulty: float


def ab_summary(trials: Iterable[tuple[str, bool, int]]) -> list[ABSummary]:
    """Per model: share of trials where the real recording was picked, median difficulty.

    ``trials`` holds ``(model, picked_the_real_one, difficulty 1..5)``.
    """
    by_model: dict[str, list[tuple[bool, int]]] = {}
    for model, correct, difficulty in trials:
        if not (isinstance(difficulty, (int, np.integer)) and 1 <= difficulty <= 5):
            raise ParameterError(f"parameter difficulty = {difficulty!r} is out of range; allowed: 1 to 5 (Likert)")
        by_model.setdefault(model, []).append((bool(correct), int(difficulty)))
    return [
        ABSummary(model, len(rows), sum(c for c, _ in rows) / len(rows), float(np.median([d for _, d in rows])))
        for model, rows in by_model.items()
    ]


def paper_like_ratings(*, seed: int = 0, listeners: int = PAPER_LISTENERS) -> dict[str, list[float]]:
    """A synthetic data set whose clip means are exactly the paper's (spec 4.3).

    Each clip draws ``listeners`` ratings around its mean (spread 1.2, clipped to
    0..9.99), then every rating is shifted, and re-clipped, until the mean is the
    paper's to 1e-9: a stand-in for the paper's raw data, which was not published.
    """
    rng = np.random.default_rng(seed)
    out: dict[str, list[float]] = {}
    for clip, mean in PAPER_MEANS.items():
        x = np.clip(rng.normal(mean, 1.2, listeners), 0.0, 9.99)
        for _ in range(200):
            x = np.clip(x + (mean - x.mean()), 0.0, 9.99)
            if abs(x.mean() - mean) < 1e-12:
                break
        out[clip] = x.tolist()
    return out
