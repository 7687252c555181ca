"""`barsynth listen report`: the statistics of a results file as text, CSV and a box plot."""

from __future__ import annotations

import csv
from pathlib import Path

from .stats import ab_summary, pairwise_rank_sum, summarize
from .store import ResultsStore


def report_text(store: ResultsStore, *, holm_correction: bool = False) -> str:
    """Per-clip summary, the pairwise significance table and the A/B summary."""
    ratings = store.ratings_by_clip()
    lines = []
    if ratings:
        lines.append(f"{'clip':<16} {'n':>4} {'mean':>6} {'median':>7} {'q1':>6} {'q3':>6}")
        for s in summarize(ratings):
            lines.append(f"{s.clip:<16} {s.count:>4} {s.mean:>6.2f} {s.median:>7.2f} {s.q1:>6.2f} {s.q3:>6.2f}")
        if len(ratings) > 1:
            lines += ["", pairwise_rank_sum(ratings, holm_correction=holm_correction).to_text()]
    else:
        lines.append("no ratings yet")
    trials = store.ab_trials()
    if trials:
        lines += ["", f"{'A/B model':<16} {'trials':>6} {'real picked':>12} {'median difficulty':>18}"]
        for a in ab_summary(trials):
            lines.append(f"{a.model:<16} {a.trials:>6} {a.correct_share:>11.0%} {a.median_difficulty:>18g}")
    return "\n".join(lines) + "\n"


CSV_NAMES = ("ratings.csv", "ab.csv", "summary.csv", "pairwise.csv")  # the files csv_tables makes, in order


def csv_tables(store: ResultsStore, *, holm_correction: bool = False) -> dict[str, tuple[list[str], list]]:
    """The CSV exports by file name: ratings.csv and ab.csv (raw answers), summary.csv
    and pairwise.csv (statistics), each as ``(header, rows)``."""
    tables = {}
    for table, name in (("mushra_ratings", "ratings.csv"), ("ab_answers", "ab.csv")):
        tables[name] = store.rows(table)
    ratings = store.ratings_by_clip()
    summary = [(s.clip, s.count, s.mean, s.median, s.q1, s.q3) for s in summarize(ratings)] if ratings else []
    tables["summary.csv"] = (["clip", "n", "mean", "median", "q1", "q3"], summary)
    pairs = []
    if len(ratings) > 1:
        table = pairwise_rank_sum(ratings, holm_correction=holm_correction)
        for i in range(len(table.clips)):
            for j in range(i):
                pairs.append((table.clips[i], table.clips[j], table.p[i][j], table.mark(i, j)))
    tables["pairwise.csv"] = (["clip_a", "clip_b", "p_value", "mark"], pairs)
    return tables


def write_table(path: str | Path, header: list[str], rows: list) -> None:
    """One CSV file."""
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)


def box_plot(ratings: dict[str, list[float]], path: str | Path, *, title: str = "ratings per clip") -> Path:
    """A box plot of the ratings per clip (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(max(6.0, 0.9 * len(ratings) + 2), 4.5))
    ax.boxplot(list(ratings.values()), tick_labels=list(ratings), showmeans=True)
    ax.set_ylim(0, 10)
    ax.set_ylabel("realism rating (0 to 9.99)")
    ax.set_title(title)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=100)
    plt.close(fig)
    return Path(path)
