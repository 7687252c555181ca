"""Where listening-test answers live: one SQLite file (spec 4.4).

Every answer is committed the moment it is given (autocommit, WAL journal, full
sync), so a participant closing the tab or the server being killed loses nothing
already answered. Participants are random ids; nothing personal is stored.
Constraints in the schema itself refuse out-of-range ratings and a second answer
to the same question, so nothing invalid can be stored by any route.

Other people's files stay untouched: a results file barsynth creates is marked with
SQLite's ``PRAGMA application_id`` (``APPLICATION_ID``), and an existing file is
opened only if it carries that mark, read from its header before SQLite opens it
(:func:`check_results_file`). An empty file, a FIFO or device, a file that is not
SQLite, and an SQLite database of anything else are refused with one line and left
byte for byte as they were. A results file made by a barsynth from before the mark
(application_id 0 and exactly barsynth's tables) is accepted and stamped.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
import os
import sqlite3
import stat
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..checks import file_kind, show_text
from ..errors import BarsynthError, ParameterError

RATING_MAX = 9.99
APPLICATION_ID = 0x42415253  # "BARS": PRAGMA application_id of every barsynth results file
_SQLITE_MAGIC = b"SQLite format 3\x00"
_TABLES = frozenset({"participants", "mushra_ratings", "ab_answers", "test_info", "sessions", "plays"})
SCHEMA = """
CREATE TABLE IF NOT EXISTS participants (
    id TEXT PRIMARY KEY,
    created_at REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS mushra_ratings (
    participant TEXT NOT NULL REFERENCES participants(id),
    page INTEGER NOT NULL CHECK (page >= 0),
    clip TEXT NOT NULL,
    rating REAL NOT NULL CHECK (rating >= 0 AND rating <= 9.99),
    shown_position INTEGER NOT NULL CHECK (shown_position >= 0),
    play_count INTEGER NOT NULL CHECK (play_count >= 0),
    comment TEXT NOT NULL DEFAULT '',
    answered_at REAL NOT NULL,
    PRIMARY KEY (participant, page, clip)
);
CREATE TABLE IF NOT EXISTS ab_answers (
    participant TEXT NOT NULL REFERENCES participants(id),
    pair TEXT NOT NULL,
    model TEXT NOT NULL,
    picked_real INTEGER NOT NULL CHECK (picked_real IN (0, 1)),
    difficulty INTEGER NOT NULL CHECK (difficulty BETWEEN 1 AND 5),
    answered_at REAL NOT NULL,
    PRIMARY KEY (participant, pair)
);
CREATE TABLE IF NOT EXISTS test_info (
    key TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS sessions (
    participant TEXT PRIMARY KEY REFERENCES participants(id),
    token_sha256 TEXT NOT NULL,
    plan TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS plays (
    participant TEXT NOT NULL REFERENCES participants(id),
    step INTEGER NOT NULL CHECK (step >= 0),
    clip TEXT NOT NULL,
    played_at REAL NOT NULL
);
"""


class AnswerRefused(BarsynthError, ValueError):
    """An answer that cannot be stored: unknown participant, out of range, or a repeat."""


def _not_ours(path: Path, why: str) -> BarsynthError:
    return BarsynthError(f"results file {show_text(path)} is not a barsynth results database ({why}); it was "
                         "left untouched: give a new file name (barsynth creates it) or a results file barsynth made")


def check_results_file(path: str | Path) -> str:
    """What ``path`` is, checked without writing a byte: ``"new"`` (missing: it will be created),
    ``"ours"`` (marked with ``APPLICATION_ID``) or ``"legacy"`` (an unmarked results file of an
    earlier barsynth: application_id 0 and exactly our tables). Anything else is refused with one
    line (:class:`~barsynth.errors.BarsynthError`)."""
    path = Path(path)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        if not path.parent.is_dir():
            raise BarsynthError(f"results file {show_text(path)}: folder {show_text(path.parent)} does not exist") \
                from None
        return "new"
    except OSError as exc:
        raise BarsynthError(f"results file {show_text(path)}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        raise _not_ours(path, f"it is {file_kind(mode)}, not a regular file")
    try:
        with open(path, "rb") as handle:
            header = handle.read(100)
    except OSError as exc:
        raise BarsynthError(f"results file {show_text(path)}: cannot be read ({exc.strerror or exc})") from None
    if not header:
        raise _not_ours(path, "an empty file")
    if len(header) < 100 or not header.startswith(_SQLITE_MAGIC):
        raise _not_ours(path, "not an SQLite file")
    application_id = int.from_bytes(header[68:72], "big")
    if application_id == APPLICATION_ID:
        return "ours"
    if application_id != 0:
        raise _not_ours(path, f"an SQLite database of another application, id {application_id:#x}")
    tables = _tables(path, "immutable=1")  # without locks, journals or a -shm file beside it
    if not tables and Path(f"{path}-wal").is_file():  # an earlier barsynth killed before a checkpoint:
        tables = _tables(path, "mode=ro")  # its tables are still in the write-ahead log
    if tables != _TABLES:
        found = ", ".join(sorted(tables)) or "none"
        raise _not_ours(path, f"an SQLite database with other tables: {show_text(found)}")
    return "legacy"


def _tables(path: Path, mode: str) -> set[str]:
    """The names of the tables in the SQLite file ``path``, opened read-only (``mode``: URI options)."""
    try:
        probe = sqlite3.connect(f"{path.resolve().as_uri()}?{mode}", uri=True)
        try:
            return {row[0] for row in probe.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        finally:
            probe.close()
    except sqlite3.DatabaseError as exc:
        raise _not_ours(path, f"an unreadable SQLite file: {exc}") from None


class ResultsStore:
    """A listening test's answers in one SQLite file: created (and marked) if missing; an existing
    one only if it is barsynth's (see :func:`check_results_file`)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._lock = threading.RLock()
        self._depth = 0
        found = check_results_file(self.path)
        self._db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False)
        try:
            if found != "ours":  # new (before WAL, so the mark is in the file's header at once) or legacy
                self._db.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.execute("PRAGMA foreign_keys=ON")
            self._db.executescript(SCHEMA)
        except sqlite3.DatabaseError as exc:
            self._db.close()
            raise BarsynthError(f"results file {show_text(self.path)}: not a barsynth results database ({exc})") \
                from None

    def close(self) -> None:
        with self._lock:
            self._db.close()

    def __enter__(self) -> ResultsStore:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _run(self, sql: str, values: tuple = ()) -> list[tuple]:
        with self._lock:
            return self._db.execute(sql, values).fetchall()

    @contextmanager
    def _transaction(self) -> Iterator[None]:
        """All or nothing, committed before it returns (a page is stored whole or not at all).

        Nested uses join the outer transaction. A failed COMMIT is rolled back, so no
        later write can land in a transaction that will never be committed.
        """
        with self._lock:
            if self._depth:
                self._depth += 1
                try:
                    yield
                finally:
                    self._depth -= 1
                return
            if self._db.in_transaction:  # left open by a failure elsewhere: never write into it
                self._db.execute("ROLLBACK")
            self._db.execute("BEGIN IMMEDIATE")
            self._depth = 1
            try:
                yield
                self._db.execute("COMMIT")
            except BaseException:
                if self._db.in_transaction:
                    self._db.execute("ROLLBACK")
                raise
            finally:
                self._depth = 0

    def new_participant(self) -> str:
        """A fresh random participant id (128 bits, hex)."""
        pid = secrets.token_hex(16)
        with self._transaction():
            self._run("INSERT INTO participants VALUES (?, ?)", (pid, time.time()))
        return pid

    def _insert(self, sql: str, values: tuple) -> None:
        try:
            with self._transaction():
                self._run(sql, values)
        except sqlite3.IntegrityError as exc:
            text = str(exc)
            if "UNIQUE" in text or "PRIMARY KEY" in text:
                raise AnswerRefused("this question was already answered; answers cannot be changed") from None
            if "FOREIGN KEY" in text:
                raise AnswerRefused("unknown participant id") from None
            raise AnswerRefused(f"answer refused: {text}") from None

    def add_rating(self, participant: str, page: int, clip: str, rating: float, *,
                   shown_position: int, play_count: int, comment: str = "") -> None:
        """Store one MUSHRA rating (0 to 9.99) at once; a repeat is refused."""
        if not (isinstance(rating, (int, float)) and not isinstance(rating, bool)
                and 0.0 <= float(rating) <= RATING_MAX):
            raise ParameterError(f"parameter rating = {rating!r} is out of range; allowed: 0 to {RATING_MAX} (rating)")
        self._insert("INSERT INTO mushra_ratings VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                     (participant, page, clip, float(rating), shown_position, play_count, comment, time.time()))

    def add_page(self, participant: str, page: int, answers: list[dict]) -> None:
        """Store a whole MUSHRA page at once (every rating or none).

        ``answers`` holds dicts with ``clip``, ``rating``, ``shown_position``,
        ``play_count`` and ``comment``.
        """
        with self._transaction():
            for answer in answers:
                self.add_rating(participant, page, answer["clip"], answer["rating"],
                                shown_position=answer["shown_position"], play_count=answer["play_count"],
                                comment=answer.get("comment", ""))

    def add_ab(self, participant: str, pair: str, model: str, picked_real: bool, difficulty: int) -> None:
        """Store one A/B answer (which was real? difficulty 1 to 5) at once."""
        if not (isinstance(difficulty, int) and not isinstance(difficulty, bool) and 1 <= difficulty <= 5):
            raise ParameterError(f"parameter difficulty = {difficulty!r} is out of range; allowed: 1 to 5 (Likert)")
        self._insert("INSERT INTO ab_answers VALUES (?, ?, ?, ?, ?, ?)",
                     (participant, pair, model, int(bool(picked_real)), difficulty, time.time()))

    # -- the web server's sessions -------------------------------------------------

    def bind_test(self, fingerprint: str) -> None:
        """Tie this file to one test; a file made for another test is refused."""
        with self._transaction():
            rows = self._run("SELECT value FROM test_info WHERE key = 'fingerprint'")
            if not rows:
                self._run("INSERT INTO test_info VALUES ('fingerprint', ?)", (fingerprint,))
            elif rows[0][0] != fingerprint:
                raise BarsynthError(f"results file {self.path} holds answers to another test (other clips, "
                                    "pages or pairs); give a new results file")

    def start_session(self, plan: str) -> tuple[str, str]:
        """A new participant with its plan (JSON); returns ``(participant, secret token)``."""
        token = secrets.token_urlsafe(24)
        with self._transaction():
            pid = self.new_participant()
            self._run("INSERT INTO sessions VALUES (?, ?, ?)", (pid, _digest(token), plan))
        return pid, token

    def session_plan(self, participant: str, token: str) -> str | None:
        """The plan of a session whose token matches, else None."""
        rows = self._run("SELECT token_sha256, plan FROM sessions WHERE participant = ?", (participant,))
        if rows and hmac.compare_digest(rows[0][0], _digest(token)):
            return rows[0][1]
        return None

    def add_play(self, participant: str, step: int, clip: str) -> int:
        """Record one play of a clip; returns how often it has been played in that step."""
        with self._transaction():
            self._run("INSERT INTO plays VALUES (?, ?, ?, ?)", (participant, step, clip, time.time()))
            return self.play_counts(participant, step).get(clip, 0)

    def play_counts(self, participant: str, step: int) -> dict[str, int]:
        """How often each clip was played in one step of a session."""
        return dict(self._run("SELECT clip, COUNT(*) FROM plays WHERE participant = ? AND step = ? "
                              "GROUP BY clip", (participant, step)))

    def answered_pages(self, participant: str) -> set[int]:
        return {row[0] for row in self._run("SELECT DISTINCT page FROM mushra_ratings WHERE participant = ?",
                                            (participant,))}

    def answered_pairs(self, participant: str) -> set[str]:
        return {row[0] for row in self._run("SELECT pair FROM ab_answers WHERE participant = ?", (participant,))}

    # -- reading results ------------------------------------------------------------

    def ratings_by_clip(self) -> dict[str, list[float]]:
        """Every rating, grouped by clip (clips in order of first appearance)."""
        out: dict[str, list[float]] = {}
        for clip, rating in self._run("SELECT clip, rating FROM mushra_ratings ORDER BY rowid"):
            out.setdefault(clip, []).append(rating)
        return out

    def ab_trials(self) -> list[tuple[str, bool, int]]:
        """Every A/B answer as ``(model, picked_real, difficulty)``."""
        return [(m, bool(p), d) for m, p, d in
                self._run("SELECT model, picked_real, difficulty FROM ab_answers ORDER BY rowid")]

    def rows(self, table: str) -> tuple[list[str], list[tuple]]:
        """Column names and rows of ``mushra_ratings`` or ``ab_answers`` (for CSV export)."""
        if table not in ("mushra_ratings", "ab_answers"):
            raise ParameterError(f"parameter table = {table!r} is not allowed; allowed: mushra_ratings, ab_answers")
        with self._lock:
            cursor = self._db.execute(f"SELECT * FROM {table} ORDER BY rowid")  # noqa: S608 - name checked above
            return [d[0] for d in cursor.description], cursor.fetchall()


def _digest(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


def open_existing(path: str | Path) -> ResultsStore:
    """Open a results file that must already exist (for reports)."""
    p = Path(path)
    if check_results_file(p) == "new":
        raise BarsynthError(f"results file {show_text(p)}: no such file")
    return ResultsStore(p)
