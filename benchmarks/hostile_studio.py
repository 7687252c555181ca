"""``barsynth studio`` against hostile clients, on loopback (run by hand; bounded in count and time).

    python benchmarks/hostile_studio.py                 # the studio of the barsynth on PYTHONPATH
    python benchmarks/hostile_studio.py --slow 1500 --nofile 256

Starts ``python -m barsynth studio --port 0`` as a subprocess (with this process's PYTHONPATH,
so pointing PYTHONPATH at another checkout measures that one), three times, and measures:

1. ``/api/health`` latency (10 requests over ~5 s, each on a fresh connection) while
   ``--slow`` connections are open: a third send nothing, a third half a request line,
   a third headers one byte a second.
2. After two abandoned heavy renders (fd, 400 points, 8x oversampling, 20 s at 96 kHz; the
   clients close their sockets after 1 s): the time until a small render succeeds again
   (asked every 0.5 s, for at most 90 s), and the answers seen meanwhile.
3. With the server's open-file limit lowered to ``--nofile``: ``--slow`` silent connections
   for 5 s, then the lines the server wrote to stderr (fd exhaustion) and a health request.

Every socket is to 127.0.0.1; every loop stops by itself.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import resource
import socket
import statistics
import subprocess
import sys
import threading
import time


def start_studio(nofile: int | None = None) -> tuple[subprocess.Popen, int, list[str]]:
    def limit() -> None:
        if nofile is not None:
            hard = resource.getrlimit(resource.RLIMIT_NOFILE)[1]
            resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, hard))

    process = subprocess.Popen([sys.executable, "-m", "barsynth", "studio", "--port", "0"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, preexec_fn=limit)
    line = process.stdout.readline()
    found = re.search(r":(\d+)/", line)
    if not found:
        process.kill()
        raise SystemExit(f"the studio did not start: {line!r} {process.stderr.read()[:500]}")
    errors: list[str] = []
    threading.Thread(target=lambda: errors.extend(process.stderr), daemon=True).start()
    return process, int(found.group(1)), errors


def stop(process: subprocess.Popen) -> None:
    process.terminate()
    try:
        process.wait(10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(5)


def ask(port: int, method: str = "GET", path: str = "/api/health", body: dict | None = None,
        timeout: float = 30.0) -> tuple[int, float]:
    """(status or 0 for no answer, seconds) of one request on a new connection."""
    data = b"" if body is None else json.dumps(body).encode()
    head = (f"{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n"
            f"Content-Type: application/json\r\nContent-Length: {len(data)}\r\n\r\n").encode()
    started = time.monotonic()
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
            s.sendall(head + data)
            first = s.recv(16)
    except OSError:
        return 0, time.monotonic() - started
    took = time.monotonic() - started
    try:
        return int(first.split(b" ")[1]), took
    except (IndexError, ValueError):
        return 0, took


def open_slow(port: int, count: int, trickle: bool = True) -> list[socket.socket]:
    clients = []
    for i in range(count):
        client = socket.socket()
        client.setblocking(False)
        try:
            client.connect(("127.0.0.1", port))
        except BlockingIOError:
            pass
        except OSError:
            client.close()
            continue
        clients.append(client)
        if trickle and i % 3 == 1:
            time.sleep(0.0005)
            with contextlib.suppress(OSError):
                client.send(b"GET /api/he")
    return clients


def trickle(clients: list[socket.socket], step: int) -> None:
    for client in clients[2::3]:
        with contextlib.suppress(OSError):
            client.send(b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\nX: "[step:step + 1] or b"a")


def health_under_slow(count: int) -> dict:
    process, port, errors = start_studio()
    try:
        ask(port)
        clients = open_slow(port, count)
        latencies, statuses = [], []
        for step in range(10):
            trickle(clients, step)
            status, took = ask(port, timeout=20.0)
            statuses.append(status)
            latencies.append(took)
            time.sleep(0.5)
        for client in clients:
            client.close()
        return {"slow connections": len(clients), "health statuses": sorted(set(statuses)),
                "health latency median s": round(statistics.median(latencies), 3),
                "health latency max s": round(max(latencies), 3),
                "server stderr lines": len(errors)}
    finally:
        stop(process)


HEAVY = {"model": "fd", "parameters": {"points": 400, "oversampling": 8}, "duration_s": 20.0, "sample_rate": 96000}
SMALL = {"model": "banded", "duration_s": 0.2, "sample_rate": 22050}


def abandoned_renders() -> dict:
    process, port, errors = start_studio()
    try:
        for _ in range(2):  # both workers started and warm
            ask(port, "POST", "/api/render", SMALL, timeout=60.0)
        heavy = []
        for _ in range(2):
            data = json.dumps(HEAVY).encode()
            client = socket.create_connection(("127.0.0.1", port), timeout=10)
            client.sendall(b"POST /api/render HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                           b"Content-Length: %d\r\n\r\n%s" % (len(data), data))
            heavy.append(client)
        time.sleep(1.0)
        for client in heavy:
            client.close()
        started = time.monotonic()
        seen = []
        while time.monotonic() - started < 90.0:
            status, _ = ask(port, "POST", "/api/render", SMALL, timeout=30.0)
            seen.append(status)
            if status == 200:
                break
            time.sleep(0.5)
        return {"seconds until a render succeeds": round(time.monotonic() - started, 2),
                "answers meanwhile": seen, "server stderr lines": len(errors)}
    finally:
        stop(process)


def out_of_fds(count: int, nofile: int) -> dict:
    process, port, errors = start_studio(nofile)
    try:
        ask(port)
        clients = open_slow(port, count, trickle=False)
        time.sleep(5.0)
        status, took = ask(port, timeout=10.0)
        for client in clients:
            client.close()
        time.sleep(0.5)
        tracebacks = sum(1 for line in errors if line.startswith("Traceback"))
        return {"server open-file limit": nofile, "silent connections": len(clients),
                "server stderr lines in ~5 s": len(errors), "tracebacks": tracebacks,
                "health status": status, "health latency s": round(took, 3),
                "first stderr line": errors[0].strip()[:160] if errors else ""}
    finally:
        stop(process)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--slow", type=int, default=1500, help="slow connections (default 1500)")
    parser.add_argument("--nofile", type=int, default=256, help="the server's open-file limit in part 3")
    parser.add_argument("--skip", default="", help="parts to skip, e.g. '2' or '13'")
    options = parser.parse_args()
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft < 2 * options.slow + 200:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(hard, 2 * options.slow + 200), hard))
    import barsynth

    print(f"barsynth from {os.path.dirname(barsynth.__file__)}")
    for part, run in (("1", lambda: health_under_slow(options.slow)), ("2", abandoned_renders),
                      ("3", lambda: out_of_fds(options.slow, options.nofile))):
        if part in options.skip:
            continue
        print(f"part {part}: {json.dumps(run())}", flush=True)


if __name__ == "__main__":
    main()
