"""What barsynth's local web servers share: a bound socket, a quiet stop, Host checks,
bounded JSON bodies and the security headers (used by ``listen serve`` and ``studio``).

Kept free of FastAPI imports at module level except where a request is read, so the
command line stays quick to start.
"""

from __future__ import annotations

import contextlib
import json
import socket
from collections.abc import Iterator
from typing import Any

import uvicorn

from .checks import show_text
from .errors import BarsynthError

LOCAL_HOSTS = ("127.0.0.1", "localhost", "[::1]")
WILDCARD_HOSTS = ("", "0.0.0.0", "::")
SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}


class Refused(BarsynthError):
    """A request the server will not carry out: an HTTP status and one line."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def host_name(header: str) -> str:
    """The host part of a Host header, lower case: 'localhost', '127.0.0.1', '[::1]'."""
    header = header.strip().lower()
    if header.startswith("["):
        return header[:header.find("]") + 1]
    return header.rsplit(":", 1)[0] if header.count(":") == 1 else header


def hosts_for(host: str) -> tuple[str, ...] | None:
    """The Host names a server bound to ``host`` answers to (None: any, for a wildcard address)."""
    if host in WILDCARD_HOSTS:
        return None
    return (*LOCAL_HOSTS, f"[{host}]" if ":" in host else host)


def guard(app: Any, allowed: Any, limit: int, who: str) -> None:
    """Add the middleware every barsynth server has: refuse a foreign Host (DNS rebinding)
    and a declared body over ``limit`` bytes, and add the security headers. ``allowed``:
    the Host names to answer to (None: any); ``who``: 'this test', 'the studio'."""
    from fastapi.responses import JSONResponse

    hosts = None if allowed is None else {h.lower() for h in allowed}

    @app.middleware("http")
    async def headers(request: Any, call_next: Any) -> Any:
        if hosts is not None and host_name(request.headers.get("host", "")) not in hosts:
            return JSONResponse({"error": f"unknown Host; {who} answers only at its own address"}, status_code=400)
        length = request.headers.get("content-length", "0")
        if not length.isdigit() or int(length) > limit:
            return JSONResponse({"error": f"request body too large; allowed: up to {limit} bytes"}, status_code=413)
        response = await call_next(request)
        response.headers.update(SECURITY_HEADERS)
        return response


def wav_bytes(samples: Any, sample_rate: float) -> bytes:
    """A mono 16-bit PCM WAV file of ``samples``, which every browser plays."""
    import io

    import soundfile

    buffer = io.BytesIO()
    soundfile.write(buffer, samples, int(round(sample_rate)), format="WAV", subtype="PCM_16")
    return buffer.getvalue()


def no_constants(name: str) -> None:
    raise ValueError(f"{name} is not a number JSON allows")


async def read_json(request: Any, limit: int) -> Any:
    """The request's JSON body (None when empty): application/json, at most ``limit`` bytes
    (a chunked body too), no NaN or Infinity; otherwise :class:`Refused`."""
    if request.headers.get("content-type", "").split(";")[0].strip() != "application/json":
        raise Refused(415, "send the request body as application/json")
    raw = bytearray()
    async for chunk in request.stream():  # a chunked body has no length to check first
        raw += chunk
        if len(raw) > limit:
            raise Refused(413, f"request body too large; allowed: up to {limit} bytes")
    try:
        return json.loads(bytes(raw) or b"null", parse_constant=no_constants)
    except (ValueError, RecursionError):
        raise Refused(400, "the request body is not valid JSON") from None


class QuietStop(uvicorn.Server):
    """Ctrl-C or SIGTERM ends the server normally (exit 0) once it has shut down,
    instead of uvicorn re-raising the signal after its graceful shutdown."""

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        with super().capture_signals():
            yield
            getattr(self, "_captured_signals", []).clear()


def listen_socket(host: str, port: int) -> socket.socket:
    """A bound TCP socket (port 0 picks a free one); one clear error if it cannot be had."""
    if not 0 <= port <= 65535:
        raise BarsynthError(f"parameter port = {port} is out of range; allowed: 0 to 65535")
    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
        sock = socket.socket(family, kind, proto)
    except (OSError, UnicodeError) as exc:
        raise BarsynthError(f"cannot listen on {show_text(host)}:{port}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(128)  # connections wait in the backlog until uvicorn takes them
    except OSError as exc:
        sock.close()
        raise BarsynthError(f"cannot listen on {show_text(host)}:{port}: {exc.strerror or exc}") from None
    return sock


def shown_address(sock: socket.socket) -> str:
    """``http://host:port/`` of a bound socket."""
    bound_host, bound_port = sock.getsockname()[:2]
    shown = f"[{bound_host}]" if ":" in bound_host else bound_host
    return f"http://{shown}:{bound_port}/"
