"""Listening tests (spec 4): configs, the results store, statistics and reports.

The web server that runs the tests in a browser is not built yet.
"""

from .stats import (
    ABSummary,
    ClipSummary,
    PairwiseTable,
    ab_summary,
    holm,
    pairwise_rank_sum,
    paper_like_ratings,
    rank_sum_p,
    significance_mark,
    summarize,
)

__all__ = [
    "ABSummary",
    "ClipSummary",
    "PairwiseTable",
    "ab_summary",
    "holm",
    "pairwise_rank_sum",
    "paper_like_ratings",
    "rank_sum_p",
    "significance_mark",
    "summarize",
]
