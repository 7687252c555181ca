"""The studio's HTTP API (issue 6, part 1) over real HTTP semantics (FastAPI's TestClient)."""

from __future__ import annotations

import io
import json
import tomllib

import numpy as np
import pytest
import soundfile
from fastapi.testclient import TestClient

from barsynth.models import get_model, model_names
from barsynth.studio.server import MAX_BODY_BYTES, create_app


@pytest.fixture(scope="module")
def client():
    return TestClient(create_app(), base_url="http://127.0.0.1:8000")


def test_every_model_comes_with_its_table_and_presets(client):
    listed = client.get("/api/models").json()["models"]
    assert [m["name"] for m in listed] == list(model_names())
    for entry in listed:
        model = get_model(entry["name"])
        assert entry["parameters"] == json.loads(json.dumps(model.table.to_json()))
        assert entry["summary"] == model.summary
    banded = next(m for m in listed if m["name"] == "banded")
    assert {"marimba", "bowl"} <= set(banded["presets"])


def test_a_preset_comes_resolved(client):
    r = client.get("/api/models/banded/presets/marimba")
    assert r.status_code == 200
    body = r.json()
    assert body["parameters"]["mode_ratios"] == [1.0, 4.0, 10.0] and "marimba" in body["description"]
    assert set(body["parameters"]) == set(get_model("banded").table.names)


def test_a_render_is_a_wav_of_the_asked_sound(client):
    r = client.post("/api/render", json={"model": "banded", "parameters": {"tuning": "ratios", "frequency_hz": 330},
                                         "duration_s": 1.0, "sample_rate": 44100})
    assert r.status_code == 200 and r.headers["content-type"] == "audio/wav"
    x, rate = soundfile.read(io.BytesIO(r.content))
    assert rate == 44100 and x.size == 44100 and 0.85 < np.max(np.abs(x)) < 0.9
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    assert np.fft.rfftfreq(x.size, 1 / rate)[np.argmax(spectrum)] == pytest.approx(330.0, abs=1.0)


def test_the_longest_recorded_attack_fits_a_request_and_its_rows_are_data(client):
    """The studio sends every value it keeps, a data row's too: the longest attack (0.1 s at 192 kHz,
    each sample written as a browser writes a double) fits a request, and renders."""
    from barsynth.exciters.sample import MAX_ATTACK_SAMPLES

    rows = {row["name"]: row for row in next(m for m in client.get("/api/models").json()["models"]
                                             if m["name"] == "banded")["parameters"]}
    assert rows["attack_samples"]["data"] and rows["attack_rate_hz"]["data"] and not rows["level_db"]["data"]
    attack = (-0.12345678901234568 + 1e-20 * np.arange(MAX_ATTACK_SAMPLES)).tolist()
    body = {"model": "banded", "parameters": {"excitation": "sample", "attack_samples": attack,
                                              "attack_rate_hz": 192000}, "duration_s": 0.2, "sample_rate": 48000}
    assert MAX_BODY_BYTES > len(json.dumps(body)) > 400_000
    r = client.post("/api/render", json=body)
    assert r.status_code == 200, r.text
    assert soundfile.read(io.BytesIO(r.content))[0].size == 9600


def test_describe_gives_modes_and_a_reference_models_errors(client):
    r = client.post("/api/describe", json={"model": "fd", "parameters": {"points": 60}, "sample_rate": 48000})
    modes = r.json()["modes"]
    assert r.status_code == 200 and len(modes) > 4
    assert all(m["error_cents"] < 0 for m in modes)
    r = client.post("/api/describe", json={"model": "twang", "parameters": {}})
    assert r.status_code == 200 and "error_cents" not in r.json()["modes"][0]


def test_a_preset_file_reads_back_as_the_same_settings(client):
    settings = {"tuning": "ratios", "frequency_hz": 261.6, "mode_ratios": [1, 3.9, 9.2], "shape": "bar"}
    r = client.post("/api/preset-file", json={"model": "banded", "parameters": settings, "description": "my bar"})
    assert r.status_code == 200 and "attachment" in r.headers["content-disposition"]
    doc = tomllib.loads(r.text)
    assert doc["preset"]["description"] == "my bar"
    table = get_model("banded").table
    assert table.as_dict(table.resolve(doc["parameters"])) == table.as_dict(table.resolve(settings))


@pytest.mark.parametrize("path,body,status,needle", [
    ("/api/render", {"model": "banded", "parameters": {"q": 1e9}}, 422, "parameter q = 1000000000.0 is out of range"),
    ("/api/render", {"model": "nope"}, 404, "unknown model 'nope'"),
    ("/api/render", {"model": "banded", "duration_s": 3600}, 422, "duration_s = 3600 is out of range; allowed: 0.01 to 20 s"),
    ("/api/render", {"model": "banded", "sample_rate": 1e6}, 422, "sample_rate = 1000000.0 is not allowed"),
    ("/api/render", {"model": "banded", "volume": 11}, 422, "unknown field 'volume'"),
    ("/api/render", {"parameters": {}}, 422, "missing model"),
    ("/api/render", [1, 2], 422, "must be a JSON object"),
    ("/api/describe", {"model": "banded", "parameters": {"excitation": "kick"}}, 422, "parameter excitation = 'kick'"),
    ("/api/describe", {"model": "banded", "parameters": "loud"}, 422, "parameters must be a JSON object"),
    ("/api/preset-file", {"model": "fd", "parameters": {}, "description": ""}, 422, "description must be text"),
])
def test_bad_requests_get_one_line_and_the_server_keeps_serving(client, path, body, status, needle):
    r = client.post(path, json=body)
    assert r.status_code == status and needle in r.json()["error"], r.text
    assert "\n" not in r.json()["error"]
    assert client.get("/api/health").json() == {"ok": True}


def test_garbage_bodies_and_foreign_hosts_are_refused(client):
    assert client.post("/api/render", content=b"{not json", headers={"content-type": "application/json"}).status_code == 400
    assert client.post("/api/render", content=b"NaN", headers={"content-type": "application/json"}).status_code == 400
    assert client.post("/api/render", content=b"{}", headers={"content-type": "text/plain"}).status_code == 415
    big = b"[" + b"1," * MAX_BODY_BYTES + b"1]"
    assert client.post("/api/render", content=big, headers={"content-type": "application/json"}).status_code == 413
    assert client.get("/api/models/banded/presets/nothing").status_code == 404
    assert client.get("/api/health", headers={"host": "evil.example"}).status_code == 400
    assert client.get("/api/health").json() == {"ok": True}


def test_a_preset_file_names_its_model_and_the_cli_reads_it_back(client, tmp_path):
    from click.testing import CliRunner

    from barsynth.cli import main

    r = client.post("/api/preset-file", json={"model": "twang", "parameters": {"q": 321.0}, "description": "mine"})
    assert tomllib.loads(r.text)["preset"]["model"] == "twang"
    (tmp_path / "mine.toml").write_text(r.text)
    out = CliRunner().invoke(main, ["describe", "twang", "--preset", str(tmp_path / "mine.toml"), "--json"])
    assert out.exit_code == 0, out.output
    assert json.loads(out.output)["parameters"]["q"] == 321.0
    refused = CliRunner().invoke(main, ["describe", "banded", "--preset", str(tmp_path / "mine.toml")])
    assert refused.exit_code == 2 and "is for model 'twang', not 'banded'" in refused.output


def test_the_page_and_its_files_are_served_with_their_types(client):
    page = client.get("/")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert "default-src 'self'" in page.headers["content-security-policy"]
    scripts = ["app.js", "page.js", "controls.js", "live.js", "plots.js", "files.js", "fit.js", "worklet.js", "link.js"]
    for name, kind in [*((name, "text/javascript") for name in scripts), ("style.css", "text/css")]:
        r = client.get(f"/static/{name}")
        assert r.status_code == 200 and r.headers["content-type"].startswith(kind) and r.content
        assert r.headers["x-content-type-options"] == "nosniff"
    for name in ("server.py", "__init__.py", "..%2Fserver.py", "index.html", "app", "APP.JS"):
        assert client.get(f"/static/{name}").status_code == 404


def test_every_module_the_page_imports_is_served():
    """The page's ES modules import each other by relative name: each one imported must be among
    the files the server serves, and every .js file in web/ must be served (none forgotten)."""
    import re
    from importlib import resources

    from barsynth.studio.server import _STATIC

    web = resources.files("barsynth.studio") / "web"
    page = (web / "index.html").read_text()
    assert '<script type="module" src="/static/app.js"></script>' in page
    shipped = {f.name for f in web.iterdir() if f.name.endswith((".js", ".css"))}
    assert shipped == set(_STATIC)
    for name in shipped:
        for imported in re.findall(r'^import .* from "\./([\w.]+)";$', (web / name).read_text(), re.M):
            assert imported in _STATIC, f"{name} imports {imported}, which the server does not serve"


def test_a_picture_shows_the_sound_of_the_settings(client):
    r = client.post("/api/picture", json={"model": "banded", "parameters": {"tuning": "ratios", "frequency_hz": 1000.0},
                                          "duration_s": 1.0, "sample_rate": 48000, "width": 200})
    assert r.status_code == 200
    found = r.json()
    wave, spec = found["waveform"], found["spectrogram"]
    assert len(wave["min"]) == len(wave["max"]) == 200
    assert max(max(wave["max"]), -min(wave["min"])) == pytest.approx(10 ** (-1 / 20), rel=1e-3)
    levels = np.frombuffer(__import__("base64").b64decode(spec["levels"]), np.uint8)
    levels = levels.reshape(spec["bins"], len(spec["times_s"]))
    loudest_row = int(np.argmax(levels[:, :20].max(axis=1)))  # at the start, where every mode rings
    assert spec["scale"] == "log" and spec["min_frequency_hz"] == 20.0
    edges = np.geomspace(20.0, spec["max_frequency_hz"], spec["bins"] + 1)
    assert edges[loudest_row] - 12.0 <= 1000.0 <= edges[loudest_row + 1] + 12.0  # within a band (or a 12 Hz bin)
    assert [m["frequency_hz"] for m in found["modes"]] == pytest.approx([1000.0, 4000.0, 10000.0])  # ratios 1:4:10
    bad = client.post("/api/picture", json={"model": "banded", "width": 5})
    assert bad.status_code == 422 and "width = 5 is out of range" in bad.json()["error"]


def test_the_twangs_picture_lists_its_three_groups_of_modes(client):
    modes = client.post("/api/picture", json={"model": "twang", "width": 100}).json()["modes"]
    groups = [m["group"] for m in modes]
    assert {g: groups.count(g) for g in set(groups)} == {"full-cantilever": 6, "short-cantilever": 6, "free-bar": 6}
    assert all(m["t60_s"] > 0 and m["gain"] > 0 for m in modes)


def ws(client):
    return client.websocket_connect("/api/stream", headers={"host": "127.0.0.1:8000"})


def blocks(socket, count):
    out = []
    while len(out) < count:
        message = socket.receive()
        if message.get("bytes"):
            out.append(message["bytes"])
        elif message.get("text") and json.loads(message["text"])["type"] == "error":
            raise AssertionError(message["text"])
    return out


def test_a_stream_plays_the_model_and_follows_a_change(client):
    import struct

    with ws(client) as socket:
        socket.send_json({"type": "start", "model": "banded", "sample_rate": 48000,
                          "parameters": {"tuning": "ratios", "frequency_hz": 500.0}})
        assert socket.receive_json() == {"type": "started", "model": "banded", "sample_rate": 48000,
                                         "block": 256, "lead": 1536}
        socket.send_json({"type": "trigger"})
        got = blocks(socket, 6)
        assert [struct.unpack("<II", b[:8]) for b in got] == [(k, 0) for k in range(6)]
        socket.send_json({"type": "set", "id": 5, "parameters": {"frequency_hz": 800.0}})
        ids, played = [], 6
        while 5 not in ids and played < 100:  # the page keeps playing; the change lands in a few blocks
            socket.send_json({"type": "played", "samples": played * 256})
            ids.append(struct.unpack("<II", blocks(socket, 1)[0][:8])[1])
            played += 1
        assert ids[-1] == 5 and len(ids) <= 12
        socket.send_json({"type": "set", "parameters": {"colour": 1}})
        while (message := socket.receive()).get("text") is None:
            pass
        assert json.loads(message["text"]) == {
            "type": "error", "error": "unknown parameter 'colour' for model banded; known: " + ", ".join(
                get_model("banded").table.names)}


def test_a_stream_from_another_site_is_refused(client):
    from starlette.websockets import WebSocketDisconnect

    with pytest.raises(WebSocketDisconnect) as refused:
        with client.websocket_connect("/api/stream", headers={"host": "127.0.0.1:8000",
                                                              "origin": "http://evil.example"}):
            pass
    assert refused.value.code == 1008


def test_settings_too_slow_to_play_live_are_told_once(client):
    with ws(client) as socket:
        socket.send_json({"type": "start", "model": "fd", "sample_rate": 96000,
                          "parameters": {"points": 400, "oversampling": 8}})
        assert socket.receive_json()["type"] == "started"
        socket.send_json({"type": "trigger"})
        errors, count = [], 0
        while not errors and count < 200:
            message = socket.receive()
            if message.get("text"):
                errors.append(json.loads(message["text"])["error"])
            else:
                count += 1
                socket.send_json({"type": "played", "samples": count * 256})
        assert errors and "take longer to compute than to play" in errors[0]
        for more in range(count, count + 150):  # and only once
            message = socket.receive()
            assert not message.get("text"), message["text"]
            socket.send_json({"type": "played", "samples": more * 256})


def test_huge_numbers_unknown_paths_and_odd_descriptions_get_one_line(client):
    r = client.post("/api/picture", content=b'{"model": "twang", "width": 1e400}',
                    headers={"content-type": "application/json"})
    assert r.status_code == 422 and "width = inf is out of range" in r.json()["error"]
    assert client.get("/api/nothing").json()["error"].startswith("Not Found")
    assert client.get("/api/render").status_code == 405 and "error" in client.get("/api/render").json()
    r = client.post("/api/preset-file", json={"model": "twang", "parameters": {}, "description": "bad\u007fchar"})
    assert tomllib.loads(r.text)["preset"]["description"] == "bad\u007fchar"
    r = client.post("/api/preset-file", content='{"model": "twang", "parameters": {}, "description": "\\ud800"}',
                    headers={"content-type": "application/json"})
    assert r.status_code == 422 and "description must be text" in r.json()["error"]


def test_a_page_of_another_port_may_not_open_a_stream(client):
    from starlette.websockets import WebSocketDisconnect

    for origin in ("http://127.0.0.1:3000", "http://localhost:8000"):
        with pytest.raises(WebSocketDisconnect):
            with client.websocket_connect("/api/stream", headers={"host": "127.0.0.1:8000", "origin": origin}):
                pass
    with client.websocket_connect("/api/stream", headers={"host": "127.0.0.1:8000",
                                                          "origin": "http://127.0.0.1:8000"}) as socket:
        socket.send_json({"type": "start", "model": "twang"})
        assert socket.receive_json()["type"] == "started"


def test_a_dragged_slider_of_a_slow_model_is_merged_not_queued(client):
    """An allpass change needs a new design (about 0.1 to 0.3 s); 200 sets sent at once are merged
    into a few, the stream stays open and the last value is applied."""
    import struct

    with ws(client) as socket:
        socket.send_json({"type": "start", "model": "allpass", "sample_rate": 48000})
        assert socket.receive_json()["type"] == "started"
        socket.send_json({"type": "trigger"})
        for k in range(1, 201):
            socket.send_json({"type": "set", "id": k, "parameters": {"q": 100.0 + 2 * k}})
        seen, played = 0, 0
        while seen != 200 and played < 2000:
            played += 1
            socket.send_json({"type": "played", "samples": played * 256})
            seen = struct.unpack("<II", blocks(socket, 1)[0][:8])[1]
        assert seen == 200


def test_a_huge_id_gets_an_error_and_the_stream_goes_on(client):
    import struct

    with ws(client) as socket:
        socket.send_json({"type": "start", "model": "banded", "sample_rate": 48000})
        socket.receive_json()
        socket.send_text('{"type": "set", "id": 1e400, "parameters": {"level_db": -3}}')
        socket.send_text('{"type": "played", "samples": 1e400}')
        errors = []
        while len(errors) < 2:
            message = socket.receive()
            if message.get("text"):
                errors.append(json.loads(message["text"])["error"])
        assert all("= inf is out of range" in e for e in errors), errors
        socket.send_json({"type": "set", "id": 3, "parameters": {"level_db": -6}})
        socket.send_json({"type": "trigger"})
        seen, played = 0, 6
        while seen != 3 and played < 200:  # the page plays on; the change lands
            played += 1
            socket.send_json({"type": "played", "samples": played * 256})
            seen = struct.unpack("<II", blocks(socket, 1)[0][:8])[1]
        assert seen == 3
