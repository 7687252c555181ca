"""Load test of ``barsynth studio``: many pages at once, on loopback (run by hand).

    python benchmarks/load_studio.py                       # 50 clients for 10 s, own studio
    python benchmarks/load_studio.py --clients 20 --seconds 30
    python benchmarks/load_studio.py --url http://127.0.0.1:8050/   # a studio already running

Without ``--url`` it starts ``python -m barsynth studio --port 0`` as a subprocess, reads the
address from its first line of output and stops it with SIGTERM at the end (what the server
wrote to stderr is shown if it logged an error). Then it warms the server up (one request of
every kind, so numba's cached kernels and scipy are loaded before the clock starts) and runs
``--clients`` clients for ``--seconds`` seconds:

- ``--streams`` of them (default: 4, the studio's stream limit) are live pages: each opens the
  WebSocket ``/api/stream``, starts a voice (twang and banded in turn), strikes it, and then
  plays it like the page's AudioWorklet would: the samples received go into a simulated
  buffer that drains at real time, and how much has been played is reported every 256
  samples (``played``), as the worklet does. Every ~100 ms it moves a slider (``set`` of
  ``length_m`` with the next id) and every ~1.5 s it strikes again. These clients run in a
  thread with an event loop of their own, so the HTTP clients' work (parsing WAV files and
  pictures) does not delay their clock; the lateness of their ticks is reported as
  "client lag", so a stall of the load test itself can be told from one of the server.
- The others loop over what the page asks of the HTTP API: the model list, a preset,
  ``describe`` (the mode table), a ``picture`` (0.5 to 1.5 s; twang, Farnell and banded mostly,
  now and then fd with 40 grid points), a WAV ``render`` (twang or banded, 0.5 to 2 s) and a
  preset file, with the parameters of a shipped preset and one slider moved.

Think time: each HTTP client waits a random 50 to 300 ms between its requests (uniformly),
about what a page does while a slider is dragged (it asks for a new picture 150 ms after the
last move, one at a time) and much busier than a person reading a picture. So 50 clients are
50 people dragging sliders without a pause: a stress test of one studio (the studio is a local
tool, normally one page). Each client waits for its answer before it thinks again (a closed
loop), as a page does, so at most ``--clients`` requests are in flight.

What counts as a failure (the exit status is 1 if there is any): a 5xx answer, including the
documented 503 "busy" (with a closed loop of 50 clients and the render queue's 10 s patience it
should not happen, so it is counted as a failure and also shown on its own), any other
unexpected status, a connection error or timeout, an answer of the wrong content (a WAV file
that soundfile cannot read or of the wrong rate or length, JSON without the expected keys), a
stream that is refused, sends an ``error``, sends a malformed block or closes before the client
does, and, when the studio was started here, an exception in its log.

Printed: per endpoint the number of requests and the latency percentiles (p50, p90, p99, max in
ms); per stream the blocks received, the sound received against the wall-clock time, the gaps
between blocks (a block is 256 samples, 5.3 ms at 48 kHz) and the underruns (times the simulated
buffer ran dry while the sound should have been playing); the latency from a ``set`` to the
first block whose header carries its id, and to the moment the simulated playback reaches that
block (what a listener hears); and the failures.
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import contextlib
import io
import json
import os
import random
import re
import select
import signal
import ssl
import struct
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

import numpy as np
import soundfile
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidStatus

try:
    import httpx2 as httpx  # the venv's client (pip install httpx2)
except ImportError:  # pragma: no cover
    import httpx

from barsynth.models import model_names
from barsynth.studio.server import MAX_STREAMS

CLIENTS = 50
SECONDS = 10.0
THINK_S = (0.05, 0.3)  # random wait between one client's requests
REQUEST_TIMEOUT_S = 30.0  # > the studio's render queue wait (10 s) plus a render
DRAIN_S = 30.0  # after the run, requests in flight may take this long before they are failures
STREAM_RATE = 48000
BLOCK = 256
TICK_S = 128 / 48000  # the simulated worklet's clock: one render quantum
SET_EVERY_S = 0.1
TRIGGER_EVERY_S = 1.5
HEADER = struct.Struct("<II")
PAGE_RATE = 48000  # the page's pictures and WAV files

MODELS = "GET /api/models"
PRESET = "GET /api/models/{model}/presets/{preset}"
DESCRIBE = "POST /api/describe"
PICTURE = "POST /api/picture"
RENDER = "POST /api/render"
PRESET_FILE = "POST /api/preset-file"
ENDPOINTS = (MODELS, PRESET, DESCRIBE, PICTURE, RENDER, PRESET_FILE)
STREAM = "WS /api/stream"
MODEL_NAMES = ("twang", "farnell", "banded", "allpass", "fd")
"""The models the load mixes its requests over (the ruler and the kalimba, whose contacts are solved
each sample, are listed by /api/models and checked there, not loaded)."""


# -- results ----------------------------------------------------------------------------------
@dataclass
class StreamStats:
    """What one live stream measured."""

    model: str
    start_s: float = float("nan")  # start sent -> started received
    blocks: int = 0
    wall_s: float = 0.0  # first block -> end of the run
    gaps: list[float] = field(default_factory=list)  # seconds between consecutive blocks
    underruns: int = 0
    dry_s: float = 0.0
    set_to_block: list[float] = field(default_factory=list)
    set_to_heard: list[float] = field(default_factory=list)
    sets: int = 0
    triggers: int = 0
    lag_max_s: float = 0.0  # how late the client's own ticks ran (its event loop's stalls)

    @property
    def sound_s(self) -> float:
        return self.blocks * BLOCK / STREAM_RATE


@dataclass
class Results:
    latencies: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))
    failures: Counter = field(default_factory=Counter)  # (where, what) -> count
    busy: Counter = field(default_factory=Counter)  # endpoint -> 503 answers
    streams: list[StreamStats] = field(default_factory=list)
    clients: int = 0
    seconds: float = 0.0
    wall_s: float = 0.0
    http_lag_max_s: float = 0.0  # the HTTP clients' event loop's longest stall
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def fail(self, where: str, what: str) -> None:
        with self.lock:
            self.failures[(where, what[:300])] += 1

    @property
    def failure_count(self) -> int:
        return sum(self.failures.values())

    def requests(self, endpoint: str) -> int:
        return len(self.latencies.get(endpoint, ()))


# -- the studio as a subprocess -----------------------------------------------------------------
@contextlib.contextmanager
def studio_process(*, start_timeout_s: float = 60.0) -> Iterator[tuple[str, Callable[[], str]]]:
    """Run ``python -m barsynth studio --port 0``; yields its address and a function that
    returns what it has written to stderr so far. Stopped with SIGTERM (then killed if it lingers)."""
    log = tempfile.TemporaryFile(mode="w+b")
    process = subprocess.Popen([sys.executable, "-m", "barsynth", "studio", "--port", "0"],
                               stdout=subprocess.PIPE, stderr=log, stdin=subprocess.DEVNULL,
                               env={**os.environ, "PYTHONUNBUFFERED": "1"})

    def stderr_text() -> str:
        log.flush()
        log.seek(0)
        return log.read().decode(errors="replace")

    try:
        deadline = time.monotonic() + start_timeout_s
        line = b""
        while not line.endswith(b"\n"):
            left = deadline - time.monotonic()
            if left <= 0 or process.poll() is not None:
                raise RuntimeError(f"the studio did not start (output {line!r}); stderr: {stderr_text()[-2000:]}")
            ready, _, _ = select.select([process.stdout], [], [], min(left, 0.5))
            if ready:
                chunk = os.read(process.stdout.fileno(), 1)
                if not chunk:
                    continue
                line += chunk
        found = re.search(rb"http://127\.0\.0\.1:(\d+)/", line)
        if not found:
            raise RuntimeError(f"no address in the studio's first line: {line!r}")
        yield f"http://127.0.0.1:{int(found.group(1))}/", stderr_text
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(timeout=5)
        process.stdout.close()
        log.close()


def server_errors(stderr: str) -> list[str]:
    """The exceptions and errors a studio logged (uvicorn logs at level warning and above)."""
    lines = stderr.splitlines()
    return [line for line in lines if "Traceback" in line or line.startswith(("ERROR", "CRITICAL"))
            or "Exception in ASGI application" in line]


# -- what the page asks for ------------------------------------------------------------------------
class Catalogue:
    """The models and presets (from /api/models and the presets), to build realistic requests."""

    def __init__(self, models: list[dict], presets: dict[tuple[str, str], dict]):
        self.models = {m["name"]: m for m in models}
        self.presets = presets  # (model, preset) -> resolved parameters

    def settings(self, rng: random.Random, model: str) -> dict:
        """A preset's parameters (or the defaults) with one slider moved, as the page sends them."""
        names = self.models[model]["presets"]
        chosen = rng.choice([None, *names])
        parameters = dict(self.presets[(model, chosen)]) if chosen else {}
        if model == "farnell":
            parameters["frequency_hz"] = round(rng.uniform(200.0, 700.0), 1)
        elif model == "banded" and parameters.get("tuning") == "ratios":
            parameters["frequency_hz"] = round(rng.uniform(150.0, 900.0), 1)
        else:
            parameters["length_m"] = round(rng.uniform(0.2, 0.45), 3)
        if model == "fd":
            parameters["points"] = 40
        return {k: v for k, v in parameters.items() if v is not None}


def check_models(r: Any) -> str | None:
    listed = r.json()["models"]
    names = [m["name"] for m in listed]
    if tuple(names) != model_names():
        return f"models {names}"
    for m in listed:
        if not {"name", "summary", "parameters", "presets"} <= set(m) or not m["parameters"]:
            return f"model entry {m['name']} lacks keys"
    return None


def check_preset(model: str, preset: str) -> Callable[[Any], str | None]:
    def check(r: Any) -> str | None:
        body = r.json()
        if body.get("model") != model or body.get("preset") != preset or not isinstance(body.get("parameters"), dict) \
                or "description" not in body:
            return f"preset answer {sorted(body)}"
        return None
    return check


def check_modes(modes: Any) -> str | None:
    if not isinstance(modes, list) or not modes:
        return "no modes"
    for mode in modes:
        if not {"group", "frequency_hz", "gain", "t60_s"} <= set(mode):
            return f"mode row keys {sorted(mode)}"
    return None


def check_describe(model: str) -> Callable[[Any], str | None]:
    def check(r: Any) -> str | None:
        body = r.json()
        if body.get("model") != model or body.get("sample_rate") != PAGE_RATE:
            return f"describe answer model={body.get('model')} rate={body.get('sample_rate')}"
        return check_modes(body.get("modes"))
    return check


def check_picture(model: str, width: int) -> Callable[[Any], str | None]:
    def check(r: Any) -> str | None:
        body = r.json()
        if not {"model", "sample_rate", "duration_s", "waveform", "spectrogram", "modes"} <= set(body):
            return f"picture keys {sorted(body)}"
        if body["model"] != model:
            return f"picture of {body['model']}"
        wave = body["waveform"]
        if len(wave["min"]) != width or len(wave["max"]) != width:
            return f"waveform of {len(wave['min'])} columns, asked {width}"
        if not all(-1.0 <= lo <= hi <= 1.0 for lo, hi in zip(wave["min"], wave["max"])):
            return "waveform outside -1..1"
        spec = body["spectrogram"]
        levels = base64.b64decode(spec["levels"], validate=True)
        if len(levels) != spec["bins"] * len(spec["times_s"]):
            return f"spectrogram of {len(levels)} bytes for {spec['bins']} x {len(spec['times_s'])}"
        return check_modes(body["modes"])
    return check


def check_wav(rate: int, seconds: float) -> Callable[[Any], str | None]:
    def check(r: Any) -> str | None:
        if r.headers.get("content-type") != "audio/wav":
            return f"content type {r.headers.get('content-type')}"
        x, got = soundfile.read(io.BytesIO(r.content), dtype="float64")
        if got != rate or abs(x.shape[0] - round(seconds * rate)) > 1:
            return f"WAV of {x.shape[0]} samples at {got} Hz, asked {seconds} s at {rate} Hz"
        peak = float(np.max(np.abs(x))) if x.size else 0.0
        if not 0.85 <= peak <= 0.9:  # normalised to -1 dBFS (0.891)
            return f"WAV peak {peak:.3f}, not -1 dBFS"
        return None
    return check


def check_preset_file(description: str) -> Callable[[Any], str | None]:
    def check(r: Any) -> str | None:
        doc = tomllib.loads(r.text)
        if doc.get("preset", {}).get("description") != description or not doc.get("parameters"):
            return "preset file without its description or parameters"
        return None
    return check


async def call(client: Any, results: Results, key: str, method: str, path: str, payload: Any = None,
               check: Callable[[Any], str | None] | None = None) -> Any:
    """One request, timed and checked; returns the answer if it is right, else None."""
    start = time.perf_counter()
    try:
        r = await client.request(method, path, json=payload)
    except Exception as exc:  # connection refused or reset, timeout...
        results.fail(key, f"{type(exc).__name__}: {exc}")
        return None
    with results.lock:
        results.latencies[key].append(time.perf_counter() - start)
    if r.status_code != 200:
        try:
            text = r.json().get("error", r.text)
        except Exception:
            text = r.text
        if r.status_code == 503:
            with results.lock:
                results.busy[key] += 1
        results.fail(key, f"HTTP {r.status_code}: {text[:200]}")
        return None
    if check is not None:
        try:
            problem = check(r)
        except Exception as exc:
            problem = f"unreadable answer ({type(exc).__name__}: {exc})"
        if problem:
            results.fail(key, problem)
            return None
    return r


def choose(rng: random.Random, weights: dict[str, float]) -> str:
    return rng.choices(list(weights), list(weights.values()))[0]


PICTURE_MODELS = {"twang": 0.3, "farnell": 0.3, "banded": 0.32, "fd": 0.05, "allpass": 0.03}
DESCRIBE_MODELS = {"twang": 0.3, "farnell": 0.2, "banded": 0.3, "fd": 0.1, "allpass": 0.1}
ACTIONS = {"models": 0.05, "preset": 0.15, "describe": 0.25, "picture": 0.3, "render": 0.15, "preset-file": 0.1}


async def act(client: Any, results: Results, catalogue: Catalogue, rng: random.Random, action: str) -> None:
    if action == "models":
        await call(client, results, MODELS, "GET", "/api/models", check=check_models)
    elif action == "preset":
        model = rng.choice(MODEL_NAMES)
        preset = rng.choice(catalogue.models[model]["presets"])
        await call(client, results, PRESET, "GET", f"/api/models/{model}/presets/{preset}",
                   check=check_preset(model, preset))
    elif action == "describe":
        model = choose(rng, DESCRIBE_MODELS)
        await call(client, results, DESCRIBE, "POST", "/api/describe",
                   {"model": model, "parameters": catalogue.settings(rng, model), "sample_rate": PAGE_RATE},
                   check_describe(model))
    elif action == "picture":
        model = choose(rng, PICTURE_MODELS)
        width = rng.choice((300, 600, 900))
        await call(client, results, PICTURE, "POST", "/api/picture",
                   {"model": model, "parameters": catalogue.settings(rng, model),
                    "duration_s": round(rng.uniform(0.5, 1.5), 2), "sample_rate": PAGE_RATE, "width": width},
                   check_picture(model, width))
    elif action == "render":
        model = rng.choice(("twang", "banded"))
        seconds, rate = round(rng.uniform(0.5, 2.0), 2), rng.choice((48000, 48000, 44100))
        await call(client, results, RENDER, "POST", "/api/render",
                   {"model": model, "parameters": catalogue.settings(rng, model), "duration_s": seconds,
                    "sample_rate": rate}, check_wav(rate, seconds))
    elif action == "preset-file":
        model = rng.choice(MODEL_NAMES)
        description = f"load test {rng.randrange(10 ** 6)}"
        await call(client, results, PRESET_FILE, "POST", "/api/preset-file",
                   {"model": model, "parameters": catalogue.settings(rng, model), "description": description},
                   check_preset_file(description))


_TLS: list[ssl.SSLContext] = []


def http_client(base: str) -> Any:
    """A client of its own for each page (as a browser has), sharing one TLS context: making
    one per client costs ~20 ms of the load test's own time, which would be counted as latency."""
    if not _TLS:
        _TLS.append(ssl.create_default_context())
    return httpx.AsyncClient(base_url=base, timeout=REQUEST_TIMEOUT_S, trust_env=False, verify=_TLS[0],
                             limits=httpx.Limits(max_connections=6, max_keepalive_connections=6))


async def page(client: Any, results: Results, catalogue: Catalogue, rng: random.Random, deadline: float) -> None:
    """One HTTP client: the page loads the model list, then the user keeps asking."""
    async with client:
        await call(client, results, MODELS, "GET", "/api/models", check=check_models)
        while time.monotonic() < deadline:
            await asyncio.sleep(rng.uniform(*THINK_S))
            if time.monotonic() >= deadline:
                break
            await act(client, results, catalogue, rng, choose(rng, ACTIONS))


async def warm_up(base: str, results: Results) -> Catalogue:
    """One request of every kind (not timed), and the catalogue of models and presets."""
    rng = random.Random(1)
    async with http_client(base) as client:
        r = await call(client, results, "warm-up " + MODELS, "GET", "/api/models", check=check_models)
        if r is None:
            raise RuntimeError(f"the studio at {base} does not answer /api/models: {dict(results.failures)}")
        models = r.json()["models"]
        presets = {}
        for m in models:
            for name in m["presets"]:
                r = await call(client, results, "warm-up " + PRESET, "GET", f"/api/models/{m['name']}/presets/{name}",
                               check=check_preset(m["name"], name))
                if r is not None:
                    presets[(m["name"], name)] = r.json()["parameters"]
        catalogue = Catalogue(models, presets)
        for model in MODEL_NAMES:
            settings = catalogue.settings(rng, model)
            await call(client, results, "warm-up " + DESCRIBE, "POST", "/api/describe",
                       {"model": model, "parameters": settings}, check_describe(model))
            await call(client, results, "warm-up " + PICTURE, "POST", "/api/picture",
                       {"model": model, "parameters": settings, "duration_s": 0.5, "width": 300},
                       check_picture(model, 300))
        for model in ("twang", "banded"):
            await call(client, results, "warm-up " + RENDER, "POST", "/api/render",
                       {"model": model, "duration_s": 0.5, "sample_rate": 48000}, check_wav(48000, 0.5))
    return catalogue


# -- a live page ------------------------------------------------------------------------------
class Player:
    """The page's AudioWorklet, simulated: a buffer filled by the blocks and drained at real time
    from the first block on; it counts the times it runs dry while sound is due."""

    def __init__(self, stats: StreamStats, rate: int):
        self.stats, self.rate = stats, rate
        self.written = 0  # samples received
        self.read = 0.0  # samples played
        self.clock: float | None = None  # when `read` was last brought up to date
        self.first_block_at: float | None = None
        self.dry_since: float | None = None
        self.marks: list[tuple[int, int, float]] = []  # (first sample of a block, set id, set sent at)

    def receive(self, now: float, n: int) -> None:
        if self.clock is None:
            self.clock = self.first_block_at = now
        else:
            self.advance(now)  # what was due before these samples came (it may have run dry)
        self.written += n

    def advance(self, now: float) -> None:
        """Play what is due up to ``now`` (the sound is always due: the client keeps it awake)."""
        if self.clock is None:
            return
        due = max(0.0, now - self.clock) * self.rate
        start_read, start_clock = self.read, self.clock
        take = min(due, self.written - self.read)
        self.read += take
        self.clock = now
        if take < due - 1e-6:  # ran dry: the buffer is empty before the time is up
            if self.dry_since is None:
                self.stats.underruns += 1
                self.dry_since = start_clock + take / self.rate
        elif self.dry_since is not None:
            self.stats.dry_s += start_clock - self.dry_since
            self.dry_since = None
        while self.marks and self.marks[0][0] < self.read:  # a changed block reaches the ear
            first, _id, sent = self.marks.pop(0)
            heard = start_clock + max(0.0, first - start_read) / self.rate
            self.stats.set_to_heard.append(heard - sent)


async def live_page(k: int, ws_url: str, origin: str, results: Results, stats: StreamStats,
                    deadline: float) -> None:
    """One live stream, played at real time until ``deadline``; its problems are failures."""
    rng = random.Random(1000 + k)
    where = f"{STREAM} #{k + 1} ({stats.model})"
    closing = False
    pending: dict[int, float] = {}  # set id -> sent at
    player = Player(stats, STREAM_RATE)
    last_block: list[float] = []
    started = asyncio.Event()

    def on_block(data: bytes, now: float) -> None:
        if len(data) != HEADER.size + 4 * BLOCK:
            results.fail(where, f"a binary frame of {len(data)} bytes, not {HEADER.size + 4 * BLOCK}")
            return
        number, applied = HEADER.unpack_from(data)
        if number != stats.blocks:
            results.fail(where, f"block {number} after {stats.blocks} blocks")
        samples = np.frombuffer(data, "<f4", offset=HEADER.size)
        if not np.all(np.isfinite(samples)) or np.max(np.abs(samples)) > 1.0:
            results.fail(where, "a block with samples outside -1..1")
        if last_block:
            stats.gaps.append(now - last_block[0])
            last_block[0] = now
        else:
            last_block.append(now)
        for change in sorted(i for i in pending if i <= applied):
            sent = pending.pop(change)
            stats.set_to_block.append(now - sent)
            player.marks.append((player.written, change, sent))
        player.receive(now, BLOCK)
        stats.blocks += 1

    async def receive(ws: Any) -> None:
        async for message in ws:
            now = time.perf_counter()
            if isinstance(message, bytes):
                if started.is_set():
                    on_block(message, now)
                else:
                    results.fail(where, "a block before started")
                continue
            answer = json.loads(message)
            if answer.get("type") == "started" and not started.is_set():
                started.set()
            else:
                results.fail(where, f"message {message[:200]}")

    try:
        async with connect(ws_url, origin=origin, proxy=None, open_timeout=10, close_timeout=5,
                           max_size=2 ** 20) as ws:
            receiver = asyncio.create_task(receive(ws))
            try:
                sent_at = time.perf_counter()
                await ws.send(json.dumps({"type": "start", "model": stats.model, "parameters": {},
                                          "sample_rate": STREAM_RATE}))
                try:
                    await asyncio.wait_for(asyncio.shield(started.wait()), 10.0)
                except TimeoutError:
                    results.fail(where, "no started answer within 10 s")
                    return
                stats.start_s = time.perf_counter() - sent_at
                await ws.send('{"type": "trigger"}')
                stats.triggers += 1
                next_set = next_trigger = tick = time.perf_counter()
                next_set += SET_EVERY_S
                next_trigger += TRIGGER_EVERY_S
                reported = 0
                set_id = 0
                while time.monotonic() < deadline and not receiver.done():
                    tick += TICK_S
                    await asyncio.sleep(max(0.0, tick - time.perf_counter()))
                    now = time.perf_counter()
                    stats.lag_max_s = max(stats.lag_max_s, now - tick)
                    if now - tick > 0.1:
                        tick = now  # do not try to catch up after a long stall
                    player.advance(now)
                    played = int(player.read)
                    if played - reported >= BLOCK:
                        reported = played
                        await ws.send(json.dumps({"type": "played", "samples": played}))
                    if now >= next_set:
                        next_set += SET_EVERY_S * rng.uniform(0.8, 1.2)
                        set_id += 1
                        pending[set_id] = time.perf_counter()
                        await ws.send(json.dumps({"type": "set", "id": set_id,
                                                  "parameters": {"length_m": round(rng.uniform(0.25, 0.35), 4)}}))
                        stats.sets += 1
                    if now >= next_trigger:
                        next_trigger += TRIGGER_EVERY_S
                        await ws.send('{"type": "trigger"}')
                        stats.triggers += 1
                if player.first_block_at is not None:
                    stats.wall_s = time.perf_counter() - player.first_block_at
                if receiver.done():
                    error = receiver.exception()
                    results.fail(where, f"the stream ended early: {describe_close(error)}")
                    return
                closing = True
                await ws.send('{"type": "stop"}')
                await asyncio.sleep(0.05)
            finally:
                closing = True
                receiver.cancel()
                with contextlib.suppress(asyncio.CancelledError, ConnectionClosed):
                    await receiver
    except InvalidStatus as exc:
        results.fail(where, f"handshake refused: HTTP {exc.response.status_code}")
    except (ConnectionClosed, InvalidHandshake, OSError, TimeoutError) as exc:
        if not closing:
            results.fail(where, f"{describe_close(exc)}")
    for change in pending:  # sets that never showed up in a block header
        if pending[change] < deadline_perf(deadline) - 1.0:
            results.fail(where, f"set {change} never reached a block")


def deadline_perf(deadline: float) -> float:
    """A ``time.monotonic`` deadline on the ``time.perf_counter`` clock."""
    return time.perf_counter() + (deadline - time.monotonic())


def describe_close(error: BaseException | None) -> str:
    if error is None:
        return "closed by the server"
    if isinstance(error, ConnectionClosed):
        rcvd = error.rcvd
        return f"closed: code {rcvd.code if rcvd else None}, reason {rcvd.reason if rcvd else ''!r}"
    return f"{type(error).__name__}: {error}"


def run_streams(ws_url: str, origin: str, results: Results, count: int, deadline: float) -> threading.Thread:
    """The live pages, in a thread with their own event loop (so HTTP clients do not delay them)."""
    stats = [StreamStats(model=("twang", "banded")[k % 2]) for k in range(count)]
    results.streams.extend(stats)

    async def main() -> None:
        await asyncio.gather(*(live_page(k, ws_url, origin, results, s, deadline) for k, s in enumerate(stats)))

    thread = threading.Thread(target=asyncio.run, args=(main(),), name="live pages", daemon=True)
    thread.start()
    return thread


# -- the run ----------------------------------------------------------------------------------
async def run_load(url: str, *, clients: int = CLIENTS, seconds: float = SECONDS, streams: int | None = None,
                   seed: int = 0) -> Results:
    """Run the load test against the studio at ``url``; returns what it measured."""
    streams = min(MAX_STREAMS, clients) if streams is None else streams
    if not 0 <= streams <= min(MAX_STREAMS, clients):
        raise ValueError(f"streams = {streams}; allowed: 0 to {min(MAX_STREAMS, clients)}")
    base = url if url.endswith("/") else url + "/"
    parts = urlsplit(base)
    origin = f"{parts.scheme}://{parts.netloc}"
    ws_url = f"{'wss' if parts.scheme == 'https' else 'ws'}://{parts.netloc}/api/stream"
    results = Results(clients=clients, seconds=seconds)
    catalogue = await warm_up(base, results)
    if results.failures:
        return results
    pages = [http_client(base) for _ in range(clients - streams)]
    started = time.monotonic()
    deadline = started + seconds
    thread = run_streams(ws_url, origin, results, streams, deadline) if streams else None
    rng = random.Random(seed)
    tasks = [asyncio.create_task(page(client, results, catalogue, random.Random(rng.random()), deadline))
             for client in pages]
    watch = asyncio.create_task(watch_lag(results, deadline))
    done, late = await asyncio.wait(tasks, timeout=seconds + DRAIN_S) if tasks else (set(), set())
    for task in late:
        task.cancel()
        results.fail("client", f"still busy {DRAIN_S:g} s after the end")
    for task in done:
        if task.exception() is not None:
            results.fail("client", f"crashed: {type(task.exception()).__name__}: {task.exception()}")
    if thread is not None:
        await asyncio.to_thread(thread.join, max(1.0, deadline + DRAIN_S - time.monotonic()))
        if thread.is_alive():
            results.fail(STREAM, "the live pages did not finish")
    results.wall_s = time.monotonic() - started
    watch.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await watch
    return results


async def watch_lag(results: Results, deadline: float) -> None:
    """How late a 10 ms sleep of the HTTP clients' event loop wakes: the load test's own stalls,
    which add to every latency it measures."""
    while time.monotonic() < deadline:
        began = time.perf_counter()
        await asyncio.sleep(0.01)
        results.http_lag_max_s = max(results.http_lag_max_s, time.perf_counter() - began - 0.01)


# -- the report ----------------------------------------------------------------------------------
def ms(values: Any, q: float) -> str:
    return f"{1000.0 * float(np.percentile(values, q)):.1f}" if len(values) else "-"


def report(results: Results, url: str, *, echo: Callable[[str], None] = print) -> None:
    echo(f"barsynth studio load test: {results.clients} clients ({len(results.streams)} live streams) for "
         f"{results.seconds:g} s at {url} (nproc {os.cpu_count()}; run took {results.wall_s:.1f} s)")
    echo(f"think time {THINK_S[0] * 1000:.0f}-{THINK_S[1] * 1000:.0f} ms between one client's requests")
    echo("")
    echo(f"{'endpoint':42} {'count':>6} {'p50 ms':>8} {'p90 ms':>8} {'p99 ms':>8} {'max ms':>8} {'503':>5}")
    total = 0
    for key in ENDPOINTS:
        values = results.latencies.get(key, [])
        total += len(values)
        echo(f"{key:42} {len(values):>6} {ms(values, 50):>8} {ms(values, 90):>8} {ms(values, 99):>8} "
             f"{ms(values, 100):>8} {results.busy.get(key, 0):>5}")
    rate = total / results.seconds if results.seconds else 0.0
    echo(f"{'all':42} {total:>6}   ({rate:.0f} requests/s; the load test's own loop stalled up to "
         f"{1000 * results.http_lag_max_s:.0f} ms)")
    if results.streams:
        block_ms = 1000.0 * BLOCK / STREAM_RATE
        echo("")
        echo(f"live streams (a block is {BLOCK} samples = {block_ms:.1f} ms at {STREAM_RATE} Hz; "
             f"played reported every {BLOCK} samples, set every ~{SET_EVERY_S * 1000:.0f} ms):")
        for k, s in enumerate(results.streams):
            gaps = s.gaps
            echo(f"  #{k + 1} {s.model:7} start {1000 * s.start_s:.0f} ms; {s.blocks} blocks = {s.sound_s:.2f} s of "
                 f"sound in {s.wall_s:.2f} s; gaps p50 {ms(gaps, 50)} p99 {ms(gaps, 99)} max {ms(gaps, 100)} ms; "
                 f"underruns {s.underruns} (dry {1000 * s.dry_s:.0f} ms); {s.sets} sets, {s.triggers} triggers; "
                 f"client lag max {1000 * s.lag_max_s:.1f} ms")
        to_block = [x for s in results.streams for x in s.set_to_block]
        heard = [x for s in results.streams for x in s.set_to_heard]
        gaps = [x for s in results.streams for x in s.gaps]
        echo(f"  block gaps, all streams: p50 {ms(gaps, 50)}  p90 {ms(gaps, 90)}  p99 {ms(gaps, 99)}  "
             f"max {ms(gaps, 100)} ms; underruns {sum(s.underruns for s in results.streams)}")
        echo(f"  set -> first block carrying its id ({len(to_block)}): p50 {ms(to_block, 50)}  p90 {ms(to_block, 90)}"
             f"  p99 {ms(to_block, 99)}  max {ms(to_block, 100)} ms")
        echo(f"  set -> simulated playback reaches it ({len(heard)}): p50 {ms(heard, 50)}  p90 {ms(heard, 90)}  "
             f"p99 {ms(heard, 99)}  max {ms(heard, 100)} ms")
    echo("")
    echo(f"failures: {results.failure_count} (of which 503 busy: {sum(results.busy.values())})")
    for (where, what), count in sorted(results.failures.items(), key=lambda kv: -kv[1])[:20]:
        echo(f"  {count:5} x {where}: {what}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clients", type=int, default=CLIENTS, help="clients at once (default %(default)s)")
    parser.add_argument("--seconds", type=float, default=SECONDS, help="how long (default %(default)s)")
    parser.add_argument("--url", help="a running studio (default: start one on a free port)")
    parser.add_argument("--streams", type=int, default=None,
                        help=f"how many of the clients hold a live stream (default {MAX_STREAMS}, the limit)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.clients < 1 or not 0 < args.seconds <= 3600:
        parser.error("--clients must be at least 1 and --seconds from 0 to 3600")
    if args.streams is not None and not 0 <= args.streams <= min(MAX_STREAMS, args.clients):
        parser.error(f"--streams must be from 0 to {min(MAX_STREAMS, args.clients)}")
    if args.url:
        try:
            results = asyncio.run(run_load(args.url, clients=args.clients, seconds=args.seconds,
                                           streams=args.streams, seed=args.seed))
        except RuntimeError as exc:
            print(f"load_studio: {exc}", file=sys.stderr)
            return 1
        report(results, args.url)
        return 1 if results.failure_count else 0
    with studio_process() as (url, stderr):
        results = asyncio.run(run_load(url, clients=args.clients, seconds=args.seconds, streams=args.streams,
                                       seed=args.seed))
        logged = stderr()
    for line in server_errors(logged):
        results.fail("server log", line)
    report(results, url)
    if server_errors(logged):
        print("\nthe studio's stderr:\n" + logged[-4000:])
    return 1 if results.failure_count else 0


if __name__ == "__main__":
    sys.exit(main())
