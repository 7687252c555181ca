"""Listening tests (spec 4): statistics now; the test server and report command come next."""

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
