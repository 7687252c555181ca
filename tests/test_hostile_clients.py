"""Both web servers against hostile clients, over real sockets on 127.0.0.1 (port 0).

The apps run under uvicorn in a thread of this process with the servers' own settings
(:func:`barsynth.webserver.server_config`), with short timeouts where a test waits for one.
The studio's worker pool is tested with real worker processes. Every wait is bounded.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import json
import logging
import os
import random
import resource
import socket
import threading
import time

import pytest
import uvicorn

from barsynth.listening.config import load_test
from barsynth.listening.server import create_app as listening_app
from barsynth.listening.store import ResultsStore
from barsynth.studio import server as studio_server
from barsynth.studio.work import Workers
from barsynth.webserver import (MAX_HEADER_BYTES, RateLimitedLog, Refused, host_name, listen_socket,
                                server_config)

WAIT_S = 10.0


@contextlib.contextmanager
def running(app, **limits):
    """``app`` served in a thread as the servers serve it; yields the port."""
    sock = listen_socket("127.0.0.1", 0)
    server = uvicorn.Server(server_config(app, protocol=limits))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    until = time.monotonic() + WAIT_S
    while not server.started and time.monotonic() < until:
        time.sleep(0.02)
    try:
        yield sock.getsockname()[1]
    finally:
        server.should_exit = True
        thread.join(WAIT_S)
        sock.close()


def exchange(port: int, raw: bytes, *, wait_s: float = WAIT_S) -> bytes:
    """Send ``raw``, read the answer until the server closes or has sent its body."""
    with socket.create_connection(("127.0.0.1", port), timeout=wait_s) as s:
        s.sendall(raw)
        answer = b""
        with contextlib.suppress(ConnectionResetError, TimeoutError):
            while chunk := s.recv(65536):
                answer += chunk
                head, _, body = answer.partition(b"\r\n\r\n")
                length = [int(line.split(b":")[1]) for line in head.split(b"\r\n")
                          if line.lower().startswith(b"content-length:")]
                if length and len(body) >= length[0]:
                    break
        return answer


def status(port: int, host: str | None, path: str = "/api/health") -> int:
    head = f"GET {path} HTTP/1.1\r\n" + ("" if host is None else f"Host: {host}\r\n") + "Connection: close\r\n\r\n"
    answer = exchange(port, head.encode("latin-1"))
    return int(answer.split(b" ", 2)[1]) if answer else 0


@pytest.fixture(scope="module")
def studio():
    workers = Workers()
    with running(studio_server.create_app(workers=workers), header_timeout_s=1.0, body_timeout_s=1.0) as port:
        yield port, workers
    workers.close()


@pytest.fixture
def listening(listening_config, tmp_path):
    store = ResultsStore(tmp_path / "results.db")
    with running(listening_app(load_test(listening_config), store, rng=random.Random(1))) as port:
        yield port
    store.close()


BAD_HOSTS = ["[::1]evil.com", "localhost.evil.com", "127.0.0.1:80:80", "", "localhost:", "evil.com",
             "127.0.0.1.evil.com:80", "[::1]:80evil", "127.0.0.1@evil.com", "localhost:8050/x"]
GOOD_HOSTS = ["127.0.0.1", "localhost:8050", "[::1]:80", "LOCALHOST", "127.0.0.1:65535"]


@pytest.mark.parametrize("header", BAD_HOSTS)
def test_host_name_takes_only_a_name_and_an_optional_port(header):
    assert host_name(header) not in {"127.0.0.1", "localhost", "[::1]"}


def test_foreign_hosts_get_400_and_local_ones_200_on_both_servers(studio, listening):
    for port in (studio[0], listening):
        for host in BAD_HOSTS:
            assert status(port, host) == 400, host
        assert status(port, None) == 400
        for host in GOOD_HOSTS:
            assert status(port, host) == 200, host


def test_oversized_headers_are_refused_on_both_servers(studio, listening):
    for port in (studio[0], listening):
        filler = "".join(f"X-Filler-{i}: {'a' * 100}\r\n" for i in range(MAX_HEADER_BYTES // 100 + 10))
        answer = exchange(port, f"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n{filler}\r\n".encode())
        assert answer.startswith(b"HTTP/1.1 431") and b"headers too large" in answer, answer[:80]
        unfinished = exchange(port, f"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n{filler}".encode())
        assert unfinished.startswith(b"HTTP/1.1 431"), unfinished[:80]  # not waiting for the end
        assert status(port, "127.0.0.1") == 200  # and the server goes on


def test_a_slow_header_and_a_silent_client_are_dropped_after_the_timeout(studio):
    port = studio[0]
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as silent, \
            socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as slow:
        slow.sendall(b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n")
        started = time.monotonic()
        for client in (silent, slow):
            assert client.recv(100) == b""  # closed by the server (header_timeout_s = 1 here)
        assert time.monotonic() - started < WAIT_S


@contextlib.contextmanager
def logged():
    """The records the servers' loggers write meanwhile (uvicorn's do not reach the root logger)."""
    records: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record):
            records.append(record)

    keep = Keep(logging.DEBUG)
    loggers = [logging.getLogger(name) for name in ("uvicorn", "uvicorn.error", "asyncio", "")]
    for logger in loggers:
        logger.addHandler(keep)
    try:
        yield records
    finally:
        for logger in loggers:
            logger.removeHandler(keep)


def test_a_slow_body_is_dropped_and_a_mid_body_disconnect_leaves_no_traceback(studio):
    port = studio[0]
    head = (b"POST /api/render HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            b"Content-Length: 200\r\n\r\n{\"model\": ")
    with logged() as records:
        with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as slow:
            slow.sendall(head)
            assert slow.recv(100) == b""  # body_timeout_s = 1 here
        for _ in range(3):
            with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as quitter:
                quitter.sendall(head)
        time.sleep(0.5)
        assert status(port, "127.0.0.1") == 200
    assert not [r for r in records if r.exc_info or r.levelno >= logging.WARNING], \
        [r.getMessage() for r in records]


def test_uploads_are_bounded_and_slow_or_abandoned_ones_free_their_turns(studio):
    """POST /api/fit: a declared body over the upload limit gets 413 at once, unread; uploads that
    stall (more of them than MAX_UPLOADS) are dropped after the body timeout, one over the cap gets
    503 meanwhile, and their turns come back: the next upload is read and answered."""
    from barsynth.studio.fitted import MAX_UPLOAD_BYTES

    port = studio[0]
    head = ("POST /api/fit?name=x.wav HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: audio/wav\r\n"
            "Content-Length: {}\r\n\r\n")
    answer = exchange(port, head.format(MAX_UPLOAD_BYTES + 1).encode())
    assert answer.startswith(b"HTTP/1.1 413") and f"up to {MAX_UPLOAD_BYTES} bytes".encode() in answer
    with logged() as records:
        stalled = []
        try:
            for _ in range(studio_server.MAX_UPLOADS):
                client = socket.create_connection(("127.0.0.1", port), timeout=WAIT_S)
                client.sendall(head.format(1_000_000).encode() + b"RIFF")
                stalled.append(client)
            until = time.monotonic() + WAIT_S
            while True:  # (415 until the server has taken every stalled upload in)
                answer = exchange(port, head.format(8).encode() + b"RIFFRIFF")
                if answer.startswith(b"HTTP/1.1 503") or time.monotonic() > until:
                    break
                time.sleep(0.05)
            assert answer.startswith(b"HTTP/1.1 503") and b"recordings at once" in answer
            for client in stalled:
                assert client.recv(100) == b""  # body_timeout_s = 1 here
        finally:
            for client in stalled:
                client.close()
        time.sleep(0.3)
        answer = exchange(port, head.format(8).encode() + b"RIFFRIFF")
        assert answer.startswith(b"HTTP/1.1 415") and b"cannot be read as WAV, FLAC or OGG" in answer
        assert status(port, "127.0.0.1") == 200
    assert not [r for r in records if r.exc_info or r.levelno >= logging.WARNING], \
        [r.getMessage() for r in records]


def _raise_nofile(wanted: int) -> None:
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != resource.RLIM_INFINITY and soft < wanted:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(wanted, hard), hard))


def test_health_answers_with_many_slow_connections_open(studio):
    port = studio[0]
    _raise_nofile(4096)
    soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    count = max(100, min(1500, (soft - 200) // 2))  # both ends of each connection are in this process
    clients = []
    try:
        for i in range(count):
            client = socket.socket()
            client.setblocking(False)
            with contextlib.suppress(BlockingIOError):
                client.connect(("127.0.0.1", port))
            clients.append(client)
            if i % 3 == 0:
                with contextlib.suppress(OSError):
                    client.send(b"GET / HTTP/1.1\r\nHo")
        started = time.monotonic()
        assert status(port, "127.0.0.1") == 200
        assert time.monotonic() - started < WAIT_S
    finally:
        for client in clients:
            client.close()


def test_a_cap_closes_the_longest_waiting_idle_connection_not_a_busy_one():
    from fastapi import FastAPI
    from fastapi.responses import JSONResponse

    app = FastAPI()

    @app.get("/slow")
    async def slow_answer():
        await asyncio.sleep(3.0)
        return JSONResponse({"ok": True})

    @app.get("/fast")
    async def fast():
        return JSONResponse({"ok": True})

    # The header timeout is far off: only the cap can close an idle connection here.
    with running(app, max_connections=4, header_timeout_s=120.0) as port:
        busy = socket.create_connection(("127.0.0.1", port), timeout=WAIT_S)
        busy.sendall(b"GET /slow HTTP/1.1\r\nHost: x\r\n\r\n")
        time.sleep(1.0)  # its request is being answered (a loaded machine takes its time)
        idle = []
        for _ in range(5):
            idle.append(socket.create_connection(("127.0.0.1", port), timeout=WAIT_S))
            time.sleep(0.1)  # accepted in this order
        time.sleep(0.5)
        assert b"200" in exchange(port, b"GET /fast HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        for client in idle[:3]:  # 4 allowed: busy + 5 idle + /fast -> the 3 oldest idle made room
            assert client.recv(10) == b""
        idle[-1].settimeout(0.5)
        with pytest.raises(TimeoutError):
            idle[-1].recv(10)  # the newest idle one is still open
        assert busy.recv(1000).startswith(b"HTTP/1.1 200")  # the busy one was kept
        for client in (busy, *idle):
            client.close()


def test_a_client_that_stops_reading_is_cut_off_after_the_send_timeout():
    from fastapi import FastAPI
    from fastapi.responses import Response

    app = FastAPI()
    size = 64 * 1024 * 1024  # far beyond what the two sockets' buffers hold

    @app.get("/big")
    async def big():
        return Response(b"x" * size, media_type="application/octet-stream")

    with running(app, send_timeout_s=1.0) as port:
        reader = socket.socket()
        reader.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        reader.settimeout(WAIT_S)
        reader.connect(("127.0.0.1", port))
        reader.sendall(b"GET /big HTTP/1.1\r\nHost: x\r\n\r\n")
        time.sleep(4.0)  # reads nothing: the server's buffer fills and its send timer runs out
        received = 0
        with contextlib.suppress(ConnectionResetError):
            while chunk := reader.recv(1 << 20):
                received += len(chunk)
        reader.close()
        assert 0 < received < size  # cut off, not waited for
        assert b"200" in exchange(port, b"GET /docs HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")


def test_running_out_of_file_descriptors_is_logged_once_in_a_while_without_a_traceback():
    now = [0.0]
    rate = RateLimitedLog(every_s=5.0, clock=lambda: now[0])
    logger = logging.getLogger("test.hostile.fds")
    seen: list[str] = []

    class Keep(logging.Handler):
        def emit(self, record):
            seen.append(self.format(record))

    logger.addHandler(Keep())
    logger.addFilter(rate)
    logger.propagate = False
    error = OSError(24, "Too many open files")
    for step in range(1000):
        now[0] = step * 0.01  # 1000 failed accepts in 10 s
        logger.error("socket.accept() out of system resource\nsocket: <fd=6>", exc_info=(OSError, error, None))
    logger.warning("Invalid HTTP request received.")
    logger.warning("Invalid HTTP request received.")
    assert len(seen) == 3  # at 0 s, at 5 s, and the first of the other kind
    assert all("Traceback" not in line and "\n" not in line for line in seen)
    assert "out of file descriptors" in seen[0] and "Too many open files" in seen[0]
    assert "499 more like this" in seen[1]


def _sleep(seconds):
    time.sleep(seconds)
    return os.getpid()


def test_a_job_over_its_time_limit_is_stopped_with_one_line_and_its_worker_replaced():
    # A fresh process takes a second to start, several on a loaded machine: the limit leaves room.
    workers = Workers(count=1, time_limit_s=12.0)

    async def main():
        with pytest.raises(Refused) as refused:
            await workers.run(_sleep, 60.0)
        assert refused.value.status == 503 and "time limit of 12 s" in str(refused.value)
        assert "\n" not in str(refused.value)
        return await workers.run(_sleep, 0.0)

    try:
        started = time.monotonic()
        pid = asyncio.run(asyncio.wait_for(main(), 90))
        assert pid in workers.processes_running() and time.monotonic() - started < 50  # not the 60 s sleep
    finally:
        workers.close()


def test_a_worker_that_cannot_start_gives_503_and_its_turn_comes_back(monkeypatch):
    workers = Workers(count=1)

    def out_of_files():
        raise OSError(errno.EMFILE, "Too many open files")

    async def main():
        with monkeypatch.context() as patch:
            patch.setattr(workers, "_new_process", out_of_files)
            for _ in range(3):  # one turn only: a lost turn would make the next wait, then 'busy'
                with pytest.raises(Refused) as refused:
                    await workers.run(_sleep, 0.0)
                assert refused.value.status == 503 and "cannot start a worker now (Too many open files)" \
                    in str(refused.value)
        return await workers.run(_sleep, 0.0)  # processes can be had again

    try:
        pid = asyncio.run(asyncio.wait_for(main(), 90))
        assert pid in workers.processes_running()
    finally:
        workers.close()


HEAVY = {"model": "fd", "parameters": {"points": 400, "oversampling": 8}, "duration_s": 20.0, "sample_rate": 96000}
SMALL = {"model": "banded", "duration_s": 0.2, "sample_rate": 22050}


SMALL_RENDER_S = 120.0  # how long a small render may take in a fresh worker at nice 10 on a machine busy elsewhere


def post(port: int, body: dict) -> socket.socket:
    data = json.dumps(body).encode()
    client = socket.create_connection(("127.0.0.1", port), timeout=SMALL_RENDER_S)
    client.sendall(b"POST /api/render HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                   b"Content-Length: %d\r\n\r\n%s" % (len(data), data))
    return client


def test_abandoned_heavy_renders_are_stopped_and_free_their_workers(studio):
    port, workers = studio
    warm = [post(port, SMALL) for _ in range(2)]  # two at once: both worker processes started
    for small in warm:
        assert small.recv(20).startswith(b"HTTP/1.1 200")
        small.close()
    before = set(workers.processes_running())
    heavy = [post(port, HEAVY) for _ in range(2)]
    time.sleep(1.0)
    for client in heavy:
        client.close()
    small = post(port, SMALL)
    # 200, not 503 after the studio's RENDER_WAIT_S (both workers would still be on the heavy
    # renders, 30 s or more each): no wall-clock bound, so a loaded machine cannot fail it.
    assert small.recv(20).startswith(b"HTTP/1.1 200")
    small.close()
    assert len(before - set(workers.processes_running())) >= 1  # the heavy renders' processes are gone
