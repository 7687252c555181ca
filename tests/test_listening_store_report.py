"""The results file (real SQLite) and `barsynth listen report`."""

from __future__ import annotations

import csv
import sqlite3

import pytest
from click.testing import CliRunner

from barsynth import ParameterError
from barsynth.errors import BarsynthError
from barsynth.cli import main
from barsynth.listening import paper_like_ratings
from barsynth.listening.report import CSV_NAMES
from barsynth.listening.store import AnswerRefused, ResultsStore


def fill_like_the_paper(path):
    """21 listeners rating 8 clips (the paper's means), and A/B answers at 89 % / 90 %."""
    ratings = paper_like_ratings(seed=1)
    with ResultsStore(path) as store:
        listeners = [store.new_participant() for _ in range(21)]
        for clip, values in ratings.items():
            page = 0 if clip.endswith("1") else 1
            for position, (pid, rating) in enumerate(zip(listeners, values)):
                store.add_rating(pid, page, clip, round(rating, 12), shown_position=position % 4, play_count=2)
        for k, pid in enumerate(listeners):
            store.add_ab(pid, "pair-farnell", "farnell", picked_real=k < 19, difficulty=4)
            store.add_ab(pid, "pair-proposed", "proposed", picked_real=k < 19 or k == 20, difficulty=4)
    return ratings


def test_answers_survive_a_killed_connection(tmp_path):
    db = tmp_path / "results.db"
    store = ResultsStore(db)
    pid = store.new_participant()
    store.add_rating(pid, 0, "real1", 8.5, shown_position=0, play_count=1, comment="crisp")
    # no close(): a killed server; another process opens the file
    with sqlite3.connect(db) as other:
        assert other.execute("SELECT clip, rating, comment FROM mushra_ratings").fetchall() == [("real1", 8.5, "crisp")]
    assert len(pid) == 32 and int(pid, 16) >= 0


def test_bad_and_repeated_answers_are_refused_and_not_stored(tmp_path):
    with ResultsStore(tmp_path / "r.db") as store:
        pid = store.new_participant()
        for bad in (-0.1, 10.0, float("nan"), "7"):
            with pytest.raises(ParameterError, match="rating"):
                store.add_rating(pid, 0, "a", bad, shown_position=0, play_count=0)
        store.add_rating(pid, 0, "a", 5.0, shown_position=0, play_count=0)
        with pytest.raises(AnswerRefused, match="already answered"):
            store.add_rating(pid, 0, "a", 6.0, shown_position=0, play_count=0)
        with pytest.raises(AnswerRefused, match="unknown participant"):
            store.add_rating("forged", 0, "a", 6.0, shown_position=0, play_count=0)
        for bad in (0, 6, True):
            with pytest.raises(ParameterError, match="difficulty"):
                store.add_ab(pid, "p", "m", True, bad)
        assert store.ratings_by_clip() == {"a": [5.0]}


def test_report_reproduces_the_paper_from_its_means(tmp_path):
    db = tmp_path / "paper.db"
    fill_like_the_paper(db)
    out = tmp_path / "csv"
    png = tmp_path / "box.png"
    r = CliRunner().invoke(main, ["listen", "report", str(db), "--csv", str(out), "--plot", str(png)])
    assert r.exit_code == 0, r.output
    assert "Real1" in r.stdout and "8.10" in r.stdout and "0.61" in r.stdout
    assert "uncorrected" in r.stdout and "****" in r.stdout
    assert "farnell" in r.stdout and "90%" in r.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in out.iterdir()) == sorted(CSV_NAMES)  # the names the CLI checks first
    with open(out / "summary.csv") as handle:
        rows = {row["clip"]: row for row in csv.DictReader(handle)}
    assert float(rows["Proposed2"]["mean"]) == pytest.approx(6.02, abs=1e-9)
    with open(out / "ratings.csv") as handle:
        assert sum(1 for _ in handle) == 1 + 8 * 21
    with open(out / "pairwise.csv") as handle:
        assert sum(1 for _ in handle) == 1 + 28
    holm = CliRunner().invoke(main, ["listen", "report", str(db), "--holm"])
    assert "Holm-corrected" in holm.stdout


def test_report_bad_input(tmp_path):
    runner = CliRunner()
    r = runner.invoke(main, ["listen", "report", str(tmp_path / "none.db")])
    assert r.exit_code == 2 and "no such file" in r.stderr
    junk = tmp_path / "junk.db"
    junk.write_text("this is not sqlite " * 100)
    r = runner.invoke(main, ["listen", "report", str(junk)])
    assert r.exit_code == 2 and "not a barsynth results database" in r.stderr
    empty = tmp_path / "empty.db"
    ResultsStore(empty).close()
    r = runner.invoke(main, ["listen", "report", str(empty), "--plot", str(tmp_path / "p.png")])
    assert r.exit_code == 2 and "no ratings" in r.stderr
    assert not (tmp_path / "p.png").exists()
    assert "no ratings yet" in runner.invoke(main, ["listen", "report", str(empty)]).stdout


class _CommitFailsOnce:
    """A connection whose next COMMIT fails as if another process held the file."""

    def __init__(self, db):
        self.db, self.failures = db, 1

    def execute(self, sql, *args):
        if sql == "COMMIT" and self.failures:
            self.failures -= 1
            raise sqlite3.OperationalError("database is locked")
        return self.db.execute(sql, *args)

    def __getattr__(self, name):
        return getattr(self.db, name)


def test_a_failed_commit_leaves_no_open_transaction_for_later_answers(tmp_path):
    db = tmp_path / "r.db"
    with ResultsStore(db) as store:
        pid = store.new_participant()
        store._db = _CommitFailsOnce(store._db)
        answer = {"clip": "a", "rating": 5.0, "shown_position": 0, "play_count": 1}
        with pytest.raises(sqlite3.OperationalError):
            store.add_page(pid, 0, [answer])
        store.add_ab(pid, "real/proposed", "proposed", True, 4)  # must be committed, not swallowed
        with sqlite3.connect(db) as other:
            assert other.execute("SELECT COUNT(*) FROM ab_answers").fetchone() == (1,)
            assert other.execute("SELECT COUNT(*) FROM mushra_ratings").fetchone() == (0,)
        store.add_page(pid, 0, [answer])  # the page can be given again
        with sqlite3.connect(db) as other:
            assert other.execute("SELECT COUNT(*) FROM mushra_ratings").fetchone() == (1,)


def test_a_results_file_in_a_missing_folder_is_named_as_such(tmp_path):
    with pytest.raises(BarsynthError, match="folder .* does not exist"):
        ResultsStore(tmp_path / "no" / "such" / "r.db")
