"""The studio under load and under abuse, over real HTTP and WebSockets on loopback.

Most tests talk to one ``python -m barsynth studio --port 0`` subprocess (module-scoped,
stopped with SIGTERM): the load test of ``benchmarks/load_studio.py`` with 50 clients for
3 s, bad requests, bad stream messages, the stream limit and foreign origins. The render
bound is tested in-process (``create_app`` under uvicorn in a thread, over real HTTP)
because the studio's queue waits ``RENDER_WAIT_S`` = 10 s before a 503, and only a
patched module constant makes that quick.

Every network wait here has a timeout; the whole file takes about 15 s.
"""

from __future__ import annotations

import asyncio
import importlib.util
import io
import json
import socket
import struct
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile
import uvicorn
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidStatus

from barsynth.models import get_model
from barsynth.studio import live as studio_live
from barsynth.studio import server as studio_server
from barsynth.studio import work as studio_work
from barsynth.studio.work import Workers

try:
    import httpx2 as httpx
except ImportError:  # pragma: no cover
    import httpx


def _load_benchmark():
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "load_studio.py"
    spec = importlib.util.spec_from_file_location("load_studio", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


load = _load_benchmark()
HEADER = struct.Struct("<II")
JSON = {"content-type": "application/json"}
WAIT_S = 10.0  # the longest any single network wait here may take


class Studio:
    def __init__(self, url: str, stderr):
        self.url = url
        self.stderr = stderr
        self.origin = url.rstrip("/")
        self.ws = url.replace("http://", "ws://") + "api/stream"

    def client(self):
        return httpx.Client(base_url=self.url, timeout=WAIT_S * 3, trust_env=False)


@pytest.fixture(scope="module")
def studio():
    with load.studio_process() as (url, stderr):
        yield Studio(url, stderr)


def _run(coroutine, timeout: float = 60.0):
    async def bounded():
        return await asyncio.wait_for(coroutine, timeout)
    return asyncio.run(bounded())


# -- load ---------------------------------------------------------------------------------------
def test_fifty_clients_for_three_seconds_without_a_failure(studio):
    results = _run(load.run_load(studio.url, clients=50, seconds=3.0), timeout=90.0)
    lines: list[str] = []
    load.report(results, studio.url, echo=lines.append)
    text = "\n".join(lines)
    print(text)
    # The benchmark counts a documented 503 "busy" as a failure too; on a machine loaded by
    # other work, renders can queue past RENDER_WAIT_S, so here only the rest must be none.
    other = {where: n for where, n in results.failures.items() if "the studio is busy" not in where[1]}
    assert not other, text
    for endpoint in load.ENDPOINTS:
        assert results.requests(endpoint) > 0, f"{endpoint} was not exercised\n{text}"
    assert len(results.streams) == 4
    for stream in results.streams:  # about 560 blocks in 3 s on an idle machine; flowing on any
        assert stream.blocks > 20 and stream.set_to_block, text
    assert sum(results.requests(e) for e in load.ENDPOINTS) > 100, text


# -- bad requests over HTTP -----------------------------------------------------------------------
TOO_BIG = b"[" + b"1," * studio_server.MAX_BODY_BYTES + b"1]"

BAD_REQUESTS = [  # path, body (JSON, or bytes with its content type), status, words the one line must have
    ("/api/render", {"model": "banded", "parameters": {"q": 1e9}}, 422, ["parameter q = 1000000000.0", "out of range"]),
    ("/api/render", {"model": "twang", "parameters": {"length_m": -1}}, 422,
     ["parameter length_m = -1", "0.05 to 1 m"]),
    ("/api/describe", {"model": "fd", "parameters": {"points": 4}}, 422, ["parameter points = 4", "8 to 400"]),
    ("/api/picture", {"model": "banded", "parameters": {"excitation": "kick"}}, 422, ["parameter excitation = 'kick'"]),
    ("/api/render", {"model": "nope"}, 404, ["unknown model 'nope'"]),
    ("/api/picture", {"model": 7}, 422, ["parameter model = 7"]),
    ("/api/render", (b"{not json", "application/json"), 400, ["not valid JSON"]),
    ("/api/render", (b'{"model": "twang"}', "text/plain"), 415, ["application/json"]),
    ("/api/render", (b'{"model": "twang"}', None), 415, ["application/json"]),
    ("/api/render", {"model": "twang", "duration_s": 1e9}, 422,
     ["parameter duration_s = 1000000000.0", "0.01 to 20 s"]),
    ("/api/render", {"model": "twang", "duration_s": -1}, 422, ["parameter duration_s = -1", "0.01 to 20 s"]),
    ("/api/picture", {"model": "twang", "duration_s": "NaN"}, 422, ["parameter duration_s = 'NaN'", "0.01 to 20 s"]),
    ("/api/render", (b'{"model": "twang", "duration_s": 1e400}', "application/json"), 422,
     ["parameter duration_s = inf", "0.01 to 20 s"]),
    # NaN and Infinity are not JSON (RFC 8259): the body is refused as such, before any field is read
    ("/api/render", (b'{"model": "twang", "duration_s": NaN}', "application/json"), 400, ["not valid JSON"]),
    ("/api/picture", (b'{"model": "twang", "duration_s": -Infinity}', "application/json"), 400, ["not valid JSON"]),
    ("/api/render", (TOO_BIG, "application/json"), 413, ["too large", str(studio_server.MAX_BODY_BYTES)]),
    ("/api/render", {"model": "twang", "volume": 11}, 422, ["unknown field 'volume'"]),
    ("/api/render", {"model": "twang", "sample_rate": 12345}, 422, ["parameter sample_rate = 12345"]),
    ("/api/picture", {"model": "twang", "width": 3}, 422, ["parameter width = 3"]),
    ("/api/picture", (b'{"model": "twang", "width": 1' + b'0' * 400 + b'}', "application/json"), 422,
     ["parameter width = <int>", "out of range"]),  # beyond float range: no overflow
    ("/api/describe", {"model": "banded", "parameters": [1, 2]}, 422, ["parameters must be a JSON object"]),
    ("/api/preset-file", {"model": "fd", "parameters": {}, "description": "x" * 201}, 422, ["description"]),
    ("/api/render", (b'{"model": "twang", "parameters": {"q": ' + b"[" * 5000 + b"]" * 5000 + b"}}",
                     "application/json"), 400, ["not valid JSON"]),
]


@pytest.mark.parametrize("path,body,status,words", BAD_REQUESTS,
                         ids=[f"{p.rsplit('/', 1)[1]}-{s}-{w[0][:28]}" for p, _, s, w in BAD_REQUESTS])
def test_a_bad_request_gets_one_clear_line(studio, path, body, status, words):
    with studio.client() as client:
        if isinstance(body, tuple):
            content, kind = body
            r = client.post(path, content=content, headers={"content-type": kind} if kind else {})
        else:
            r = client.post(path, json=body)
    assert r.status_code == status, r.text
    error = r.json()["error"]
    assert set(r.json()) == {"error"} and "\n" not in error and len(error) < 600
    for word in words:
        assert word in error, error


def test_a_huge_body_without_a_length_and_a_missing_preset_are_refused(studio):
    def chunks():  # sent chunked: the server cannot check a Content-Length first
        for _ in range(studio_server.MAX_BODY_BYTES // 4096 + 2):
            yield b" " * 4096

    with studio.client() as client:
        r = client.post("/api/render", content=chunks(), headers=JSON)
        assert r.status_code == 413 and "too large" in r.json()["error"]
        r = client.get("/api/models/banded/presets/nothing")
        assert r.status_code == 404 and "nothing" in r.json()["error"]
        r = client.get("/api/models/nope/presets/marimba")
        assert r.status_code == 404 and "unknown model 'nope'" in r.json()["error"]


def test_after_the_bad_requests_the_studio_still_serves(studio):
    with studio.client() as client:
        for path, body, _status, _words in BAD_REQUESTS[:6]:
            client.post(path, json=body)
        assert client.get("/api/health").json() == {"ok": True}
        r = client.post("/api/render", json={"model": "twang", "duration_s": 0.5, "sample_rate": 44100})
    assert r.status_code == 200 and r.headers["content-type"] == "audio/wav"
    x, rate = soundfile.read(io.BytesIO(r.content))
    assert rate == 44100 and x.size == 22050 and 0.85 < np.max(np.abs(x)) < 0.9


# -- the live stream ----------------------------------------------------------------------------
class Page:
    """A stream client that reports its blocks played at real time (as the page's worklet)."""

    def __init__(self, ws, rate: int = 48000):
        self.ws, self.rate = ws, rate
        self.blocks: list[tuple[int, int]] = []  # headers (number, set id)
        self.texts: list[dict] = []
        self.since = time.monotonic()
        self.reported = 0

    async def send(self, message) -> None:
        await self.ws.send(message if isinstance(message, (str, bytes)) else json.dumps(message))

    async def until(self, wanted, timeout: float = 5.0):
        """Read until ``wanted(page)`` is true (a text message or block arrived), reporting played."""
        deadline = time.monotonic() + timeout
        while not wanted(self):
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"timed out; last texts {self.texts[-3:]}, blocks {len(self.blocks)}")
            try:
                message = await asyncio.wait_for(self.ws.recv(), min(left, 0.005))
            except TimeoutError:
                message = None
            if isinstance(message, bytes):
                assert len(message) == HEADER.size + 4 * 256
                self.blocks.append(HEADER.unpack_from(message))
            elif message is not None:
                self.texts.append(json.loads(message))
            played = min(len(self.blocks) * 256, int((time.monotonic() - self.since) * self.rate))
            if played > self.reported:
                self.reported = played
                await self.send({"type": "played", "samples": played})

    async def text(self, timeout: float = 5.0) -> dict:
        count = len(self.texts)
        await self.until(lambda page: len(page.texts) > count, timeout)
        return self.texts[count]

    async def start(self, model: str = "twang", **parameters) -> dict:
        await self.send({"type": "start", "model": model, "parameters": parameters, "sample_rate": self.rate})
        started = await self.text(WAIT_S)
        assert started["type"] == "started" and started["model"] == model, started
        self.since = time.monotonic()
        return started


def _connect(studio: Studio, origin: str | None = "own"):
    return connect(studio.ws, origin=studio.origin if origin == "own" else origin, proxy=None,
                   open_timeout=WAIT_S, close_timeout=2)


BAD_MESSAGES = [  # message, words of the error line
    ("garbage", ["not valid JSON"]),
    ('{"type": "boom"}', ["parameter type = 'boom'", "start, trigger"]),
    ('{"type": "set", "id": 1, "parameters": {"length_m": 99}}', ["parameter length_m = 99", "0.05 to 1 m"]),
    (b"\x00\x01binary", ["binary frames"]),
    ('{"type": "set", "id": 2, "parameters": {"wobble": 1}}', ["unknown parameter 'wobble'"]),
    ('{"type": "set", "id": -3, "parameters": {}}', ["parameter id = -3"]),
    ('{"type": "played", "samples": "many"}', ["parameter samples = 'many'"]),
    ('{"type": "played", "samples": 1' + '0' * 400 + '}', ["parameter samples = <int>", "out of range"]),
    ('{"type": "start", "model": "nope"}', ["unknown model 'nope'"]),
    ('{"type": "start", "model": "twang", "sample_rate": 44100}', ["sample_rate = 44100", "48000"]),
    ('{"type": "set", "id": 4, "parameters": {"q": NaN}}', ["not valid JSON"]),
    ('{"type": "trigger", "hard": true}', ["unknown field 'hard'"]),
]


def test_bad_stream_messages_get_an_error_and_the_sound_goes_on(studio):
    async def scenario():
        async with _connect(studio) as ws:
            page = Page(ws)
            await page.start("twang")
            await page.send({"type": "trigger"})
            await page.until(lambda p: len(p.blocks) >= 5)
            for message, words in BAD_MESSAGES:
                await page.send(message)
                answer = await page.text()
                assert answer["type"] == "error" and set(answer) == {"type", "error"}, (message, answer)
                assert "\n" not in answer["error"] and all(w in answer["error"] for w in words), (message, answer)
                before = len(page.blocks)
                await page.until(lambda p: len(p.blocks) >= before + 3)  # the sound goes on
            numbers = [n for n, _ in page.blocks]
            assert numbers == list(range(len(numbers)))
            assert all(i == 0 for _, i in page.blocks)  # no bad set was applied
            await page.send({"type": "set", "id": 7, "parameters": {"length_m": 0.25}})
            await page.until(lambda p: p.blocks[-1][1] == 7)
            await page.send({"type": "trigger"})
            before = len(page.blocks)
            await page.until(lambda p: len(p.blocks) >= before + 20)

    _run(scenario())
    with studio.client() as client:
        assert client.get("/api/health").json() == {"ok": True}


def test_an_oversized_stream_message_is_refused_and_a_huge_one_closes_only_that_stream(studio):
    async def scenario():
        async with _connect(studio) as ws:
            most = studio_live.MAX_MESSAGE_BYTES
            await ws.send(json.dumps({"type": "start", "model": "twang", "parameters": {"x": "a" * (most + 100)}}))
            answer = json.loads(await asyncio.wait_for(ws.recv(), WAIT_S))
            assert answer == {"type": "error", "error": f"a stream message is too large; allowed: up to {most} bytes"}
            await Page(ws).start("banded")
        async with _connect(studio) as ws:
            await ws.send(json.dumps({"type": "start", "model": "twang", "parameters": {"x": "a" * (5 * most)}}))
            with pytest.raises(ConnectionClosed) as closed:
                await asyncio.wait_for(ws.recv(), WAIT_S)
            assert closed.value.rcvd is not None and closed.value.rcvd.code == 1009  # message too big
        async with _connect(studio) as ws:
            await Page(ws).start("banded")

    _run(scenario())


async def _open_started(studio: Studio, model: str, attempts: int = 20):
    """A started stream; a stream the test before closed may take a moment to free its place."""
    for _ in range(attempts):
        ws = await _connect(studio)
        try:
            await Page(ws).start(model)
            return ws
        except ConnectionClosed as exc:
            if exc.rcvd is None or exc.rcvd.code != 1013:
                raise
            await asyncio.sleep(0.1)
    raise AssertionError("four streams could not be opened")


def test_a_fifth_stream_is_refused_with_1013_while_four_play(studio):
    async def scenario():
        four = []
        try:
            for k in range(4):
                four.append(await _open_started(studio, ("twang", "banded")[k % 2]))
            async with _connect(studio) as fifth:
                with pytest.raises(ConnectionClosed) as closed:
                    await fifth.send(json.dumps({"type": "start", "model": "twang"}))
                    await asyncio.wait_for(fifth.recv(), WAIT_S)
                assert closed.value.rcvd.code == 1013
                reason = closed.value.rcvd.reason
                assert "4 streams at once" in reason and "try again" in reason
            for ws in four:  # the four still play
                page = Page(ws)
                await page.send({"type": "trigger"})
                await page.until(lambda p: len(p.blocks) >= 3)
            await four.pop().close()
            four.append(await _open_started(studio, "farnell"))  # its place is free again
        finally:
            for ws in four:
                await ws.close()

    _run(scenario())


def test_a_foreign_origin_is_refused_and_no_origin_is_not(studio):
    async def scenario():
        for origin in ("http://evil.example", "http://127.0.0.1.evil.example:1234", "null"):
            with pytest.raises(InvalidStatus) as refused:
                async with _connect(studio, origin=origin):
                    pass
            assert refused.value.response.status_code == 403
        async with _connect(studio, origin=None) as ws:  # not a browser: no Origin
            await Page(ws).start("twang")

    _run(scenario())


def test_the_studio_logged_no_error(studio):
    """Everything above was refused cleanly: nothing in the server's log."""
    with studio.client() as client:
        assert client.get("/api/health").json() == {"ok": True}
    logged = studio.stderr()
    assert not load.server_errors(logged), logged[-4000:]


# -- the render bound (in-process: RENDER_WAIT_S patched) -------------------------------------------
HEAVY = {"model": "fd", "parameters": {"oversampling": 8, "points": 200}, "sample_rate": 96000}  # ~0.7 s a second


@pytest.fixture
def in_process(monkeypatch):
    """The studio app under uvicorn in a thread, its fd renders counted; yields (url, counter)."""
    counter = {"now": 0, "most": 0, "spans": []}
    lock = threading.Lock()
    fd = get_model("fd")
    render = fd.render

    def counted(*args, **kwargs):
        with lock:
            counter["now"] += 1
            counter["most"] = max(counter["most"], counter["now"])
            began = time.monotonic()
        try:
            return render(*args, **kwargs)
        finally:
            with lock:
                counter["now"] -= 1
                counter["spans"].append((began, time.monotonic()))

    monkeypatch.setattr(fd, "render", counted)
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(64)
    app = studio_server.create_app(workers=Workers(processes=False))  # threads: the counted render is seen
    config = uvicorn.Config(app, log_level="warning", lifespan="off")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    deadline = time.monotonic() + WAIT_S
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.01)
    assert server.started
    try:
        yield f"http://127.0.0.1:{sock.getsockname()[1]}/", counter
    finally:
        server.should_exit = True
        thread.join(WAIT_S)
        sock.close()


async def _wait_for(condition, timeout: float = WAIT_S) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        await asyncio.sleep(0.01)


def test_at_most_two_renders_run_and_a_third_waits_then_gets_503(in_process, monkeypatch):
    url, counter = in_process
    assert studio_server.MAX_RENDERS == 2

    async def scenario():
        async with httpx.AsyncClient(base_url=url, timeout=60, trust_env=False) as client:
            # 1. a third render waits for a place, then runs
            monkeypatch.setattr(studio_work, "RENDER_WAIT_S", 30.0)
            heavy = [asyncio.create_task(client.post("/api/render", json={**HEAVY, "duration_s": 1.0}))
                     for _ in range(2)]
            await _wait_for(lambda: counter["now"] == 2)
            third = asyncio.create_task(client.post("/api/render", json={**HEAVY, "duration_s": 0.1}))
            assert (await client.get("/api/health")).json() == {"ok": True}  # the event loop is free:
            assert counter["spans"] == []  # answered while both renders still ran (on any load)
            answers = await asyncio.gather(*heavy, third)
            assert [r.status_code for r in answers] == [200, 200, 200]
            assert counter["most"] == 2
            *first, last = sorted(counter["spans"])  # by start: the two heavy ones, then the third
            assert last[0] >= min(end for _, end in first) - 0.01, counter["spans"]  # it began when one ended
            # 2. when the wait would be too long: 503 and one line
            monkeypatch.setattr(studio_work, "RENDER_WAIT_S", 0.3)
            spans = len(counter["spans"])
            heavy = [asyncio.create_task(client.post("/api/render", json={**HEAVY, "duration_s": 2.0}))
                     for _ in range(2)]
            await _wait_for(lambda: counter["now"] == 2)
            began = time.monotonic()
            busy = await client.post("/api/picture", json={**HEAVY, "duration_s": 0.1})
            waited = time.monotonic() - began
            assert busy.status_code == 503, busy.text
            assert busy.json() == {"error": "the studio is busy (2 renders at once); try again"}
            assert waited > 0.25 and len(counter["spans"]) == spans  # refused while both still ran
            answers = await asyncio.gather(*heavy)
            assert [r.status_code for r in answers] == [200, 200] and counter["most"] == 2
            # 3. and then it renders again
            r = await client.post("/api/render", json={"model": "twang", "duration_s": 0.2})
            assert r.status_code == 200 and soundfile.read(io.BytesIO(r.content))[0].size == 9600

    _run(scenario(), timeout=60)


# -- stopping: no render holds the server up, no worker outlives it ------------------------------
def _studio_with_workers():
    import subprocess

    process = subprocess.Popen([sys.executable, "-m", "barsynth", "studio", "--port", "0"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = process.stdout.readline()
    url = line.split(" at ")[1].split()[0]
    with httpx.Client(base_url=url, timeout=60, trust_env=False) as client:  # starts both workers
        for _ in range(2):
            assert client.post("/api/render", json={"model": "twang", "duration_s": 0.1}).status_code == 200
    return process, url


def _children(pid: int) -> list[int]:
    found = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(p) for p in found.read_text().split()] if found.exists() else []


def _gone(pids: list[int], within_s: float) -> bool:
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        if not any(Path(f"/proc/{p}").exists() and "Z" not in Path(f"/proc/{p}/stat").read_text().split()[2]
                   for p in pids):
            return True
        time.sleep(0.1)
    return False


def test_sigterm_during_a_long_render_stops_the_studio_and_its_workers_quickly():
    import signal

    process, url = _studio_with_workers()
    workers = _children(process.pid)
    assert workers, "the render workers should be child processes"

    def long_render():
        with httpx.Client(base_url=url, timeout=60, trust_env=False) as client:
            try:
                client.post("/api/render", json={"model": "fd", "parameters": {"points": 300, "oversampling": 8},
                                                 "duration_s": 20.0, "sample_rate": 96000})
            except httpx.HTTPError:
                pass  # cut off by the stop: expected

    thread = threading.Thread(target=long_render, daemon=True)
    thread.start()
    time.sleep(1.0)
    began = time.monotonic()
    process.send_signal(signal.SIGTERM)
    process.wait(timeout=20)
    assert time.monotonic() - began < 15.0  # not waiting for the render (30 s or more); 2 s on an idle machine
    assert _gone(workers, 5.0)
    process.stdout.close()
    process.stderr.close()


def test_workers_end_when_the_studio_is_killed():
    import signal

    process, _ = _studio_with_workers()
    workers = _children(process.pid)
    process.send_signal(signal.SIGKILL)
    process.wait(timeout=10)
    assert _gone(workers, 5.0)
    process.stdout.close()
    process.stderr.close()
