"""The listening-test server over real HTTP semantics (FastAPI's TestClient) and a real SQLite file.

A participant's whole session through the API; random orders and sides; resuming after
a restart; and every kind of bad or forged answer refused with a 4xx and nothing stored.
"""

from __future__ import annotations

import io
import json
import random
import sqlite3
from collections import Counter

import numpy as np
import pytest
import soundfile
from fastapi.testclient import TestClient

from barsynth.errors import BarsynthError
from barsynth.listening.config import load_test
from barsynth.listening.server import COOKIE, create_app
from barsynth.listening.session import make_plan
from barsynth.listening.store import ResultsStore

from conftest import CLIP_TONES_HZ, tone


def local_client(app) -> TestClient:
    """A client that reaches the app as a browser on this machine does (Host: 127.0.0.1)."""
    return TestClient(app, base_url="http://127.0.0.1")


@pytest.fixture
def served(listening_config, tmp_path):
    """(test, store, client factory, results path) for one test, with a fixed random order."""
    test = load_test(listening_config)
    db = tmp_path / "results.db"
    store = ResultsStore(db)
    app = create_app(test, store, rng=random.Random(1))
    yield test, store, (lambda: local_client(app)), db
    store.close()


def stored(db) -> dict[str, int]:
    """Row counts, read through a second connection (what survives is what was committed)."""
    with sqlite3.connect(db) as con:
        return {table: con.execute(f"SELECT COUNT(*) FROM {table}").fetchone()[0]
                for table in ("participants", "mushra_ratings", "ab_answers", "plays")}


def start(client) -> dict:
    response = client.post("/api/session", json={})
    assert response.status_code == 201, response.text
    return response.json()


def play_all(client, state) -> None:
    for clip in state["step"]["clips"]:
        assert client.post("/api/play", json={"handle": clip["handle"]}).status_code == 200


def page_answer(state, ratings) -> dict:
    return {"ratings": [{"handle": c["handle"], "rating": r, "comment": f"c{i}"}
                        for i, (c, r) in enumerate(zip(state["step"]["clips"], ratings))]}


def test_a_whole_session_is_stored_as_answered(served):
    test, store, client_for, db = served
    client = client_for()
    state = start(client)
    assert state["steps_total"] == 4 and state["steps_done"] == 0
    participant = state["participant"]
    plan = json.loads(store.session_plan(participant, client.cookies[COOKIE].split(".")[1]))
    given: dict[tuple[int, str], float] = {}
    for step_index, step in enumerate(plan["steps"]):
        assert state["step"]["index"] == step_index and state["step"]["kind"] == step["kind"]
        play_all(client, state)
        client.post("/api/play", json={"handle": state["step"]["clips"][0]["handle"]})  # a replay: 2 plays
        if step["kind"] == "mushra":
            ratings = [round(1.25 + 2.5 * k + step_index, 2) for k in range(len(step["clips"]))]
            for c, r in zip(step["clips"], ratings):
                given[(step["page"], c["clip"])] = r
            response = client.post(f"/api/steps/{step_index}/answer", json=page_answer(state, ratings))
        else:
            response = client.post(f"/api/steps/{step_index}/answer", json={"picked": "B", "difficulty": 4})
        assert response.status_code == 200, response.text
        state = response.json()
    assert state["step"] is None and state["steps_done"] == 4

    names, rows = store.rows("mushra_ratings")
    got = {(r[names.index("page")], r[names.index("clip")]): r for r in rows}
    assert {k: v[names.index("rating")] for k, v in got.items()} == given
    for step in plan["steps"]:
        if step["kind"] != "mushra":
            continue
        for position, c in enumerate(step["clips"]):
            row = got[(step["page"], c["clip"])]
            assert row[names.index("shown_position")] == position
            assert row[names.index("play_count")] == (2 if position == 0 else 1)
            assert row[names.index("comment")] == f"c{position}"
            assert row[names.index("participant")] == participant
    ab = store.ab_trials()
    assert sorted(m for m, _, _ in ab) == ["anchor", "proposed"]
    for step in plan["steps"]:
        if step["kind"] == "ab":
            pair = test.ab_pairs[step["pair"]]
            picked_real = step["clips"][1]["clip"] == pair.real
            assert (pair.label, picked_real, 4) in ab
    assert stored(db)["participants"] == 1


def test_orders_and_sides_are_random_per_participant(listening_config, tmp_path):
    test = load_test(listening_config)
    rng = random.Random(7)
    plans = [make_plan(test, rng) for _ in range(60)]
    first_page = Counter((k, c["clip"]) for p in plans for k, c in enumerate(p["steps"][0]["clips"]))
    assert set(first_page) == {(k, c) for k in range(3) for c in test.pages[0]}  # every clip in every place
    assert min(first_page.values()) >= 10
    real_on_a = Counter(step["clips"][0]["clip"] == test.ab_pairs[step["pair"]].real
                        for p in plans for step in p["steps"] if step["kind"] == "ab")
    assert real_on_a[True] >= 40 and real_on_a[False] >= 40
    pair_orders = Counter(tuple(s["pair"] for s in p["steps"] if s["kind"] == "ab") for p in plans)
    assert set(pair_orders) == {(0, 1), (1, 0)}
    handles = [c["handle"] for p in plans for s in p["steps"] for c in s["clips"]]
    assert len(set(handles)) == len(handles)
    # Without an rng (as the server runs) the system's randomness is used: orders and sides vary.
    drawn = {json.dumps([[c["clip"] for c in step["clips"]] for step in make_plan(test)["steps"]])
             for _ in range(30)}
    assert len(drawn) > 10


def test_the_page_never_tells_which_clip_is_which(served):
    test, _, client_for, _ = served
    client = client_for()
    state = start(client)
    seen = json.dumps(state) + client.get("/").text + client.get("/static/app.js").text
    for clip_id in test.clips:
        assert clip_id not in seen
    assert "real" not in json.dumps(state["step"]).lower()


def test_audio_is_the_clip_as_16_bit_wav(served):
    test, store, client_for, _ = served
    client = client_for()
    state = start(client)
    plan = json.loads(store.session_plan(state["participant"], client.cookies[COOKIE].split(".")[1]))
    for shown in plan["steps"][0]["clips"]:
        response = client.get(f"/api/audio/{shown['handle']}")
        assert response.status_code == 200 and response.headers["content-type"] == "audio/wav"
        info = soundfile.info(io.BytesIO(response.content))
        assert (info.format, info.subtype, info.channels) == ("WAV", "PCM_16", 1)
        samples, rate = soundfile.read(io.BytesIO(response.content))
        clip = test.clips[shown["clip"]]
        assert rate == clip.sample_rate and samples.size == clip.samples.size
        assert np.max(np.abs(samples - clip.samples)) <= 1 / 32768 + 1e-9
        if shown["clip"] in CLIP_TONES_HZ:
            peak_hz = np.argmax(np.abs(np.fft.rfft(samples, 8 * samples.size))) * rate / (8 * samples.size)
            assert peak_hz == pytest.approx(CLIP_TONES_HZ[shown["clip"]], abs=2)
    assert client.get("/api/audio/not-a-handle").status_code == 404
    assert local_client(client.app).get(f"/api/audio/{state['step']['clips'][0]['handle']}").status_code == 401


def test_a_session_resumes_after_a_restart(served, listening_config):
    test, store, client_for, db = served
    client = client_for()
    state = start(client)
    play_all(client, state)
    client.post("/api/steps/0/answer", json=page_answer(state, [1.0, 2.0, 3.0]))
    cookie = client.cookies[COOKIE]
    before = client.get("/api/session").json()
    store.close()

    # A new server process: the config loaded again, the same results file.
    with ResultsStore(db) as again:
        client2 = local_client(create_app(load_test(listening_config), again))
        client2.cookies.set(COOKIE, cookie)
        after = client2.get("/api/session").json()
        assert after == before and after["steps_done"] == 1
        assert stored(db)["mushra_ratings"] == 3
        # Asking to start again does not make a second participant while the session lives...
        assert client2.post("/api/session", json={}).json()["participant"] == before["participant"]
        # ...unless a new one is asked for (the next participant at the same computer).
        fresh = client2.post("/api/session", json={"new": True})
        assert fresh.status_code == 201 and fresh.json()["participant"] != before["participant"]
        assert fresh.json()["steps_done"] == 0 and stored(db)["participants"] == 2
    store.__init__(db)  # the fixture closes it again


def test_a_results_file_of_another_test_is_refused(served, listening_config, tmp_path):
    test, store, _, db = served
    other = load_test(listening_config)
    fewer_pages = type(other)(other.title, other.clips, other.pages[:1], other.ab_pairs)
    with ResultsStore(db) as again, pytest.raises(BarsynthError, match="another test"):
        create_app(fewer_pages, again)
    # The same ids and pages over other audio are another test too.
    soundfile.write(listening_config.parent / "rec" / "proposed1.wav", 0.5 * tone(1234.0), 22050, subtype="PCM_16")
    with ResultsStore(db) as again, pytest.raises(BarsynthError, match="another test"):
        create_app(load_test(listening_config), again)
    soundfile.write(listening_config.parent / "rec" / "proposed1.wav", tone(CLIP_TONES_HZ["proposed1"]), 22050,
                    subtype="PCM_16")
    with ResultsStore(db) as again:
        create_app(load_test(listening_config), again)  # the very same test again is welcome


# -- refusals: each a 4xx, and nothing stored ------------------------------------------------

def _ready_page(served):
    """A participant on the first page with every clip played once."""
    _, _, client_for, db = served
    client = client_for()
    state = start(client)
    play_all(client, state)
    return client, state, db


BAD_PAGE_ANSWERS = [
    ("rating too high", lambda s: page_answer(s, [1.0, 9.991, 2.0]), 422, "rating = 9.991 is out of range"),
    ("rating negative", lambda s: page_answer(s, [1.0, -0.01, 2.0]), 422, "allowed: 0 to 9.99"),
    ("rating a bool", lambda s: page_answer(s, [1.0, True, 2.0]), 422, "rating = True"),
    ("rating a string", lambda s: page_answer(s, [1.0, "5", 2.0]), 422, "rating = '5'"),
    ("rating missing", lambda s: {"ratings": [{"handle": c["handle"]} for c in s["step"]["clips"]]}, 422,
     "rating = None"),
    ("a clip left out", lambda s: page_answer(s, [1.0, 2.0]), 422, "all 3 sounds"),
    ("an unknown clip", lambda s: {"ratings": page_answer(s, [1.0, 2.0])["ratings"]
                                   + [{"handle": "anchor1", "rating": 1.0}]}, 422, "not a sound of this page"),
    ("a clip twice", lambda s: {"ratings": page_answer(s, [1.0, 2.0])["ratings"]
                                + [page_answer(s, [1.0])["ratings"][0]]}, 422, "rated twice"),
    ("an extra field", lambda s: {**page_answer(s, [1.0, 2.0, 3.0]), "participant": "x"}, 422,
     "unknown field 'participant'"),
    ("a field in a rating", lambda s: {"ratings": [{**r, "clip": "real1"}
                                                   for r in page_answer(s, [1.0, 2.0, 3.0])["ratings"]]}, 422,
     "unknown field 'clip'"),
    ("a long comment", lambda s: {"ratings": [{**r, "comment": "x" * 2001}
                                              for r in page_answer(s, [1.0, 2.0, 3.0])["ratings"]]}, 422,
     "at most 2000"),
    ("not an object", lambda s: [1, 2, 3], 400, "JSON object"),
    ("a huge whole number", lambda s: page_answer(s, [1.0, 10 ** 400, 2.0]), 422, "rating = 1000000000"),
    ("a lone surrogate in a comment", lambda s: {"ratings": [{**r, "comment": "\ud800"}
                                                            for r in page_answer(s, [1.0, 2.0, 3.0])["ratings"]]},
     422, "parameter comment"),
    ("an A/B answer on a page", lambda s: {"picked": "A", "difficulty": 3}, 422, "unknown field"),
]


@pytest.mark.parametrize("name,make,status,needle", BAD_PAGE_ANSWERS, ids=[b[0] for b in BAD_PAGE_ANSWERS])
def test_bad_page_answers_are_refused_and_nothing_is_stored(served, name, make, status, needle):
    client, state, db = _ready_page(served)
    before = stored(db)
    response = client.post("/api/steps/0/answer", content=json.dumps(make(state)),  # ASCII: lone surrogates too
                           headers={"Content-Type": "application/json"})
    assert response.status_code == status and needle in response.json()["error"], response.text
    assert "\n" not in response.json()["error"]
    assert stored(db) == before
    # The participant can still answer properly afterwards.
    assert client.post("/api/steps/0/answer", json=page_answer(state, [1.0, 2.0, 3.0])).status_code == 200


def test_raw_requests_that_are_not_answers_are_refused(served):
    client, state, db = _ready_page(served)
    before = stored(db)
    good = json.dumps(page_answer(state, [1.0, 2.0, 3.0]))
    nan = good.replace("2.0", "NaN", 1)
    cases = [
        (client.post("/api/steps/0/answer", content=nan, headers={"Content-Type": "application/json"}), 400),
        (client.post("/api/steps/0/answer", content="{", headers={"Content-Type": "application/json"}), 400),
        (client.post("/api/steps/0/answer", content="[" * 30000 + "]" * 30000,
                     headers={"Content-Type": "application/json"}), 400),
        (client.post("/api/steps/0/answer", content=(b"[" * 1000 for _ in range(100)),  # chunked, no length
                     headers={"Content-Type": "application/json"}), 413),
        (client.post("/api/steps/0/answer", content=good, headers={"Content-Type": "text/plain"}), 415),
        (client.post("/api/steps/0/answer", data={"ratings": "1"}), 415),  # a form post from another site
        (client.post("/api/steps/0/answer", content=good + " " * 70000,
                     headers={"Content-Type": "application/json"}), 413),
        (client.post("/api/steps/9/answer", content=good, headers={"Content-Type": "application/json"}), 404),
        (client.post("/api/steps/x/answer", content=good, headers={"Content-Type": "application/json"}), 422),
        (client.post("/api/steps/1/answer", content=good, headers={"Content-Type": "application/json"}), 409),
        (client.post("/api/play", json={"handle": "nope"}), 404),
        (client.post("/api/play", json={"handle": state["step"]["clips"][0]["handle"], "x": 1}), 422),
        (client.post("/api/session", json={"new": "yes"}), 422),
        (client.get("/static/secrets.py"), 404),
    ]
    for response, status in cases:
        assert response.status_code == status, (status, response.text)
        assert "error" in response.json()
    assert stored(db) == before


def test_forged_and_replayed_submissions_are_refused(served):
    test, store, client_for, db = served
    client, state, _ = _ready_page(served)
    answer = page_answer(state, [1.0, 2.0, 3.0])
    participant, _, token = client.cookies[COOKIE].partition(".")
    before = stored(db)

    for cookie in (None, f"{participant}.{'x' * len(token)}", f"{'0' * 32}.{token}", participant, "garbage"):
        forger = client_for()
        if cookie is not None:
            forger.cookies.set(COOKIE, cookie)
        for response in (forger.post("/api/steps/0/answer", json=answer),
                         forger.post("/api/play", json={"handle": state["step"]["clips"][0]["handle"]}),
                         forger.get("/api/session")):
            assert response.status_code == 401, response.text
    # Another participant cannot answer with, or play, this participant's sounds.
    other = client_for()
    other_state = start(other)
    play_all(other, other_state)
    response = other.post("/api/steps/0/answer", json=answer)
    assert response.status_code == 422 and "not a sound of this page" in response.json()["error"]
    assert other.post("/api/play", json={"handle": state["step"]["clips"][0]["handle"]}).status_code == 404
    assert stored(db)["mushra_ratings"] == before["mushra_ratings"]

    # The real answer once; the same request again (a replay) is refused and changes nothing.
    assert client.post("/api/steps/0/answer", json=answer).status_code == 200
    snapshot = store.rows("mushra_ratings")
    replay = client.post("/api/steps/0/answer", json=page_answer(state, [9.0, 9.0, 9.0]))
    assert replay.status_code == 409 and "already answered" in replay.json()["error"]
    assert store.rows("mushra_ratings") == snapshot
    # Plays of an answered page's sounds are refused too.
    assert client.post("/api/play", json={"handle": state["step"]["clips"][0]["handle"]}).status_code == 409


def test_a_page_cannot_be_answered_before_every_sound_is_played(served):
    _, _, client_for, db = served
    client = client_for()
    state = start(client)
    client.post("/api/play", json={"handle": state["step"]["clips"][0]["handle"]})
    before = stored(db)
    response = client.post("/api/steps/0/answer", json=page_answer(state, [1.0, 2.0, 3.0]))
    assert response.status_code == 409 and "not played yet: Sound 2, Sound 3" in response.json()["error"]
    assert stored(db) == before


def _to_ab_step(client, state):
    while state["step"]["kind"] == "mushra":
        play_all(client, state)
        n = len(state["step"]["clips"])
        state = client.post(f"/api/steps/{state['step']['index']}/answer",
                            json=page_answer(state, [5.0] * n)).json()
    return state


@pytest.mark.parametrize("payload,needle", [
    ({"picked": "C", "difficulty": 3}, "picked = 'C'"),
    ({"picked": "A", "difficulty": 0}, "difficulty = 0 is out of range"),
    ({"picked": "A", "difficulty": 6}, "allowed: 1 to 5"),
    ({"picked": "A", "difficulty": 2.5}, "difficulty = 2.5"),
    ({"picked": "A", "difficulty": True}, "difficulty = True"),
    ({"picked": "A"}, "difficulty = None"),
    ({"picked": "A", "difficulty": 3, "real": "A"}, "unknown field 'real'"),
])
def test_bad_ab_answers_are_refused_and_nothing_is_stored(served, payload, needle):
    _, _, client_for, db = served
    client = client_for()
    state = _to_ab_step(client, start(client))
    play_all(client, state)
    before = stored(db)
    response = client.post(f"/api/steps/{state['step']['index']}/answer", json=payload)
    assert response.status_code == 422 and needle in response.json()["error"], response.text
    assert stored(db) == before


def test_an_ab_answer_needs_both_sounds_played(served):
    _, _, client_for, db = served
    client = client_for()
    state = _to_ab_step(client, start(client))
    client.post("/api/play", json={"handle": state["step"]["clips"][1]["handle"]})
    response = client.post(f"/api/steps/{state['step']['index']}/answer", json={"picked": "A", "difficulty": 2})
    assert response.status_code == 409 and "not played yet: A" in response.json()["error"]
    assert stored(db)["ab_answers"] == 0


def test_security_headers_and_no_caching_of_answers(served):
    _, _, client_for, _ = served
    client = client_for()
    page = client.get("/")
    assert "default-src 'self'" in page.headers["content-security-policy"]
    assert page.headers["x-content-type-options"] == "nosniff"
    response = client.post("/api/session", json={})
    cookie = response.headers["set-cookie"].lower()
    assert "httponly" in cookie and "samesite=strict" in cookie
    assert response.headers["cache-control"] == "no-store"


# -- `barsynth listen serve`: every start-up problem is one line, exit 2, and no results file ------

def _serve(*args):
    """Run the command; should it get as far as serving, the test fails instead of hanging."""
    from unittest import mock

    from click.testing import CliRunner

    from barsynth.cli import main
    from barsynth.listening import server

    with mock.patch.object(server.QuietStop, "run", side_effect=AssertionError("the server started")):
        return CliRunner().invoke(main, ["listen", "serve", *map(str, args)])


def test_serve_refuses_a_bad_config_before_anything_is_written(listening_config, tmp_path):
    text = listening_config.read_text()
    cases = [
        (text.replace('file = "rec/real2.wav"', 'file = "rec/missing.wav"'), "no such file"),
        (text.replace("[[mushra]]", "[[mushra]]\nshuffle = true", 1), "unknown key 'shuffle'"),
        (text.replace('preset = "anchor"', 'preset = "anchor"\nparameters = { frequency_hz = -3 }'),
         "frequency_hz"),
        (text + "\n[oops\n", "not valid TOML"),
    ]
    for bad, needle in cases:
        listening_config.write_text(bad)
        result = _serve(listening_config, "--port", 0)
        assert result.exit_code == 2 and needle in result.output, result.output
        assert len(result.output.strip().splitlines()) == 1
        assert not (tmp_path / "test-results.db").exists()
    listening_config.write_text(text)
    (tmp_path / "rec" / "real1.wav").write_bytes(b"RIFF\x00\x00\x00\x00WAVEjunk")  # an unsupported WAV
    result = _serve(listening_config, "--port", 0)
    assert result.exit_code == 2 and "real1.wav" in result.output and "cannot be read" in result.output
    assert not (tmp_path / "test-results.db").exists()


def test_serve_refuses_a_taken_port_a_bad_port_and_a_file_that_is_not_a_database(listening_config, tmp_path):
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        result = _serve(listening_config, "--port", taken.getsockname()[1])
    assert result.exit_code == 2 and "cannot listen on 127.0.0.1" in result.output
    assert not (tmp_path / "test-results.db").exists()
    result = _serve(listening_config, "--port", 70000)
    assert result.exit_code == 2 and "port = 70000 is out of range; allowed: 0 to 65535" in result.output
    notes = tmp_path / "notes.db"
    notes.write_text("my notes, not a database\n")
    result = _serve(listening_config, "--results", notes, "--port", 0)
    assert result.exit_code == 2 and "not a barsynth results database" in result.output
    assert notes.read_text() == "my notes, not a database\n"


def test_serve_refuses_the_results_of_another_test(listening_config, tmp_path):
    db = tmp_path / "old.db"
    with ResultsStore(db) as store:
        store.bind_test("0" * 64)
    result = _serve(listening_config, "--results", db, "--port", 0)
    assert result.exit_code == 2 and "holds answers to another test" in result.output


def test_a_good_config_gets_as_far_as_serving(listening_config, tmp_path):
    result = _serve(listening_config, "--port", 0)
    assert isinstance(result.exception, AssertionError) and "the server started" in str(result.exception)
    assert "'Ruler realism' at http://127.0.0.1:" in result.output
    assert (tmp_path / "test-results.db").exists()  # the default: beside the config


def test_audio_answers_byte_ranges(served):
    _, _, client_for, _ = served
    client = client_for()
    handle = start(client)["step"]["clips"][0]["handle"]
    whole = client.get(f"/api/audio/{handle}")
    size = len(whole.content)
    assert whole.headers["accept-ranges"] == "bytes"
    for wanted, first, last in [("bytes=0-1", 0, 1), ("bytes=100-", 100, size - 1), ("bytes=-10", size - 10, size - 1),
                                (f"bytes=10-{size + 50}", 10, size - 1)]:
        part = client.get(f"/api/audio/{handle}", headers={"Range": wanted})
        assert part.status_code == 206 and part.content == whole.content[first:last + 1]
        assert part.headers["content-range"] == f"bytes {first}-{last}/{size}"
    for unsatisfiable in (f"bytes={size}-", "bytes=-0", "bytes=9-3"):
        refused = client.get(f"/api/audio/{handle}", headers={"Range": unsatisfiable})
        assert refused.status_code == 416 and refused.headers["content-range"] == f"bytes */{size}"
    for ignored in ("bytes=0-1,5-6", "items=0-1", "bytes=" + "9" * 5000 + "-"):
        full = client.get(f"/api/audio/{handle}", headers={"Range": ignored})
        assert full.status_code == 200 and full.content == whole.content


def test_requests_for_another_host_name_are_refused(served):
    """A page elsewhere that rebinds its DNS name to 127.0.0.1 gets nothing (DNS rebinding)."""
    _, _, client_for, db = served
    app = client_for().app
    before = stored(db)
    for host in ("attacker.example", "testserver", "127.0.0.1.attacker.example"):
        foreign = TestClient(app, base_url=f"http://{host}")
        for response in (foreign.post("/api/session", json={}), foreign.get("/")):
            assert response.status_code == 400 and "unknown Host" in response.json()["error"]
    assert stored(db) == before
    for host in ("localhost:8000", "127.0.0.1", "[::1]:8000"):
        assert client_for().get("/", headers={"Host": host}).status_code == 200


def test_a_busy_results_file_is_a_503_and_nothing_is_stored(served, monkeypatch):
    client, state, db = _ready_page(served)
    store = served[1]

    def locked(*args, **kwargs):
        raise sqlite3.OperationalError("database is locked")

    monkeypatch.setattr(store, "add_page", locked)
    response = client.post("/api/steps/0/answer", json=page_answer(state, [1.0, 2.0, 3.0]))
    assert response.status_code == 503 and "nothing was stored" in response.json()["error"]
    assert stored(db)["mushra_ratings"] == 0
