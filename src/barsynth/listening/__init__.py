"""Listening tests (spec 4): configs, sessions, the web server, the results store,
statistics and reports.

``barsynth listen serve`` (:mod:`barsynth.listening.server`) runs a test in the browser;
``barsynth listen report`` summarises its results file. The server module imports
FastAPI and uvicorn, so it is loaded only when a test is served.
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
