"""Other people's files stay untouched: results files must be barsynth's, FIFOs and devices are
refused at once (a subprocess with a timeout, so a hang fails instead of blocking), and no error
line echoes more than about 80 characters of what was typed."""

from __future__ import annotations

import os
import sqlite3
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from barsynth.listening.store import APPLICATION_ID, ResultsStore, check_results_file

CONFIG = """
[[clips]]
id = "a"
model = "twang"
duration_s = 0.2

[[clips]]
id = "b"
model = "farnell"
duration_s = 0.2

[[mushra]]
clips = ["a", "b"]
"""


def barsynth(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "barsynth", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=90, stdin=subprocess.DEVNULL)


def assert_refused(proc: subprocess.CompletedProcess, *needles: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    line = proc.stderr.strip()
    assert line.startswith("barsynth: error: ") and "\n" not in line and len(line) < 600, proc.stderr
    for needle in needles:
        assert needle in line, (needle, line)


def application_id(path: Path) -> int:
    return int.from_bytes(path.read_bytes()[68:72], "big")


@pytest.fixture
def foreign(tmp_path) -> dict[str, Path]:
    """Files that are not barsynth results databases: someone's SQLite database (in WAL mode, as
    barsynth's own are), an empty file and a text file."""
    db = tmp_path / "someone.db"
    with sqlite3.connect(db) as con:
        con.execute("PRAGMA journal_mode=WAL")
        con.execute("CREATE TABLE accounts (name TEXT, balance REAL)")
        con.executemany("INSERT INTO accounts VALUES (?, ?)", [("ada", 1.5), ("bob", -2.0)])
    con.close()
    empty = tmp_path / "empty.db"
    empty.touch()
    text = tmp_path / "notes.db"
    text.write_text("shopping list\n" * 20)
    return {"sqlite": db, "empty": empty, "text": text}


@pytest.mark.parametrize("kind", ["sqlite", "empty", "text"])
def test_serve_and_report_refuse_a_file_that_is_not_ours_and_leave_it_byte_identical(tmp_path, foreign, kind):
    (tmp_path / "test.toml").write_text(CONFIG)
    path = foreign[kind]
    before, listing = path.read_bytes(), sorted(os.listdir(tmp_path))
    assert_refused(barsynth("listen", "serve", "test.toml", "--results", path.name, "--port", "0", cwd=tmp_path),
                   "not a barsynth results database", path.name)
    assert_refused(barsynth("listen", "report", path.name, cwd=tmp_path), "not a barsynth results database")
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == listing  # no -wal, -shm or journal beside it either


def test_the_store_refuses_a_foreign_database_before_writing(foreign):
    from barsynth.errors import BarsynthError

    before = foreign["sqlite"].read_bytes()
    with pytest.raises(BarsynthError, match="other tables: accounts"):
        ResultsStore(foreign["sqlite"])
    assert foreign["sqlite"].read_bytes() == before


def test_a_new_results_file_is_marked_and_an_earlier_barsynths_file_is_accepted_and_stamped(tmp_path):
    new = tmp_path / "new.db"
    with ResultsStore(new) as store:
        store.new_participant()
    assert application_id(new) == APPLICATION_ID and check_results_file(new) == "ours"
    # a file of a barsynth from before the mark: our tables, application_id 0
    with sqlite3.connect(new) as con:
        con.execute("PRAGMA application_id = 0")
    con.close()
    assert application_id(new) == 0 and check_results_file(new) == "legacy"
    proc = barsynth("listen", "report", new.name, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert application_id(new) == APPLICATION_ID


def test_an_earlier_barsynths_file_killed_before_a_checkpoint_is_accepted(tmp_path):
    """Its tables are still only in the write-ahead log beside it, which an immutable look misses."""
    from barsynth.listening.store import SCHEMA

    old = tmp_path / "old.db"
    killed = (f"import os, sqlite3; db = sqlite3.connect({str(old)!r}, isolation_level=None); "
              f"db.execute('PRAGMA journal_mode=WAL'); db.execute('PRAGMA wal_autocheckpoint=0'); "
              f"db.executescript({SCHEMA!r}); os._exit(0)")
    subprocess.run([sys.executable, "-c", killed], check=True, timeout=60)
    assert Path(f"{old}-wal").stat().st_size > 0 and application_id(old) == 0
    assert check_results_file(old) == "legacy"


# -- FIFOs and devices ------------------------------------------------------------------------------
@pytest.fixture
def fifo(tmp_path):
    def make(name: str) -> Path:
        path = tmp_path / name
        os.mkfifo(path)
        return path
    return make


def assert_still_a_fifo(path: Path) -> None:
    assert stat.S_ISFIFO(os.stat(path).st_mode), f"{path} was replaced"


def test_a_fifo_preset_or_output_is_refused_at_once(tmp_path, fifo):
    preset, out, plot = fifo("mine.toml"), fifo("out.wav"), fifo("pic.png")
    assert_refused(barsynth("render", "twang", "--preset", preset.name, "-o", "x.wav", cwd=tmp_path),
                   "preset file", "FIFO")
    assert_refused(barsynth("describe", "twang", "--preset", preset.name, cwd=tmp_path), "FIFO")
    assert_refused(barsynth("render", "twang", "--duration", "0.1", "-o", out.name, cwd=tmp_path), "FIFO")
    assert_refused(barsynth("render", "twang", "--duration", "0.1", "--plot", plot.name, "-o", "x.wav",
                            cwd=tmp_path), "FIFO")
    assert_refused(barsynth("bow-map", "banded", "--velocities", "2", "--forces", "2", "-o", plot.name,
                            cwd=tmp_path), "FIFO")
    for path in (preset, out, plot):
        assert_still_a_fifo(path)
    assert not (tmp_path / "x.wav").exists()


def test_fifo_and_device_inputs_of_analyze_and_listen_are_refused_at_once(tmp_path, fifo):
    recording, config, clip, results = fifo("rec.wav"), fifo("test.toml"), fifo("clip.wav"), fifo("r.db")
    assert_refused(barsynth("analyze", recording.name, cwd=tmp_path), "not a regular file")
    assert_refused(barsynth("analyze", "/dev/zero", cwd=tmp_path), "not a regular file")
    assert_refused(barsynth("listen", "serve", config.name, "--port", "0", cwd=tmp_path), "config", "FIFO")
    (tmp_path / "clips.toml").write_text('[[clips]]\nid = "a"\nfile = "clip.wav"\n[[clips]]\nid = "b"\n'
                                         'model = "twang"\nduration_s = 0.2\n[[mushra]]\nclips = ["a", "b"]\n')
    assert_refused(barsynth("listen", "serve", "clips.toml", "--results", "new.db", "--port", "0", cwd=tmp_path),
                   "clip.wav", "not a regular file")
    (tmp_path / "ok.toml").write_text(CONFIG)
    for target in (results.name, "/dev/null"):
        assert_refused(barsynth("listen", "serve", "ok.toml", "--results", target, "--port", "0", cwd=tmp_path),
                       "not a barsynth results database")
        assert_refused(barsynth("listen", "report", target, cwd=tmp_path), "not a barsynth results database")
    for path in (recording, config, clip, results):
        assert_still_a_fifo(path)
    assert not (tmp_path / "new.db").exists()


def test_a_fifo_among_the_csv_files_or_as_the_plot_of_a_report_is_refused(tmp_path, fifo):
    with ResultsStore(tmp_path / "r.db") as store:
        store.new_participant()
    (tmp_path / "csv").mkdir()
    ratings = tmp_path / "csv" / "ratings.csv"
    os.mkfifo(ratings)
    plot = fifo("box.png")
    assert_refused(barsynth("listen", "report", "r.db", "--csv", "csv", cwd=tmp_path), "ratings.csv", "FIFO")
    assert_refused(barsynth("listen", "report", "r.db", "--plot", plot.name, cwd=tmp_path), "FIFO")
    assert_still_a_fifo(ratings)
    assert_still_a_fifo(plot)
    assert sorted(os.listdir(tmp_path / "csv")) == ["ratings.csv"]


# -- long values ----------------------------------------------------------------------------------
LONG = "x" * 10_000


@pytest.mark.parametrize("args", [
    ("render", LONG, "-o", "x.wav"),
    ("render", "twang", "--set", f"q={LONG}", "-o", "x.wav"),
    ("render", "twang", "--set", f"{LONG}=1", "-o", "x.wav"),
    ("render", "twang", "--set", LONG, "-o", "x.wav"),
    ("render", "twang", "--preset", LONG, "-o", "x.wav"),
    ("render", "twang", "--preset", LONG[:200] + ".toml", "-o", "x.wav"),
    ("render", "twang", "--duration", LONG, "-o", "x.wav"),
    ("render", "twang", "-o", LONG[:300] + ".wav"),  # too long a file name
    ("render", "twang", "-o", "x." + LONG[:200]),
    ("modes", "--material", LONG, "--length", "0.3", "--thickness", "0.003", "--bc", "free-free"),
    ("modes", "--count", LONG, "--material", "steel", "--length", "0.3", "--thickness", "0.003", "--bc", "free-free"),
    ("analyze", LONG[:200] + ".wav"),
    ("presets", LONG),
    ("params", LONG),
    ("listen", "report", LONG[:200] + ".db"),
    ("listen", "serve", LONG[:200] + ".toml"),
    ("studio", "--host", LONG[:200], "--port", "0"),
])
def test_error_lines_quote_at_most_80_characters_of_a_value(tmp_path, args):
    proc = barsynth(*args, cwd=tmp_path)
    assert_refused(proc)
    assert "x" * 81 not in proc.stderr, proc.stderr


def test_the_studio_and_its_stream_quote_at_most_80_characters(tmp_path):
    from fastapi.testclient import TestClient

    from barsynth.studio.server import create_app
    from barsynth.studio.stream import Stream, StreamError, parse_message

    client = TestClient(create_app(), base_url="http://127.0.0.1:8000")
    for body in ({"model": LONG}, {"model": "twang", "parameters": {LONG: 1}},
                 {"model": "twang", "parameters": {"q": LONG}}, {"model": "twang", LONG[:5000]: 1}):
        r = client.post("/api/describe", json=body)
        assert 400 <= r.status_code < 500 and "x" * 81 not in r.json()["error"], r.json()
    assert client.get(f"/api/models/twang/presets/{LONG[:4000]}").status_code == 404
    assert "x" * 81 not in client.get(f"/api/models/twang/presets/{LONG[:4000]}").json()["error"]
    for text in ('{"type": "%s"}' % LONG, '{"type": "stop", "%s": 1}' % LONG):
        with pytest.raises(StreamError) as caught:
            parse_message(text)
        assert "x" * 81 not in str(caught.value)
    with pytest.raises(Exception) as caught:
        Stream().prepare_start({"model": LONG})
    assert "x" * 81 not in str(caught.value)
