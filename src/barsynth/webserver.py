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


def allowed_hosts(host: str) -> tuple[str, ...] | None:
    """The Host names a server bound to ``host`` answers to (None: any, for a wildcard address)."""
    if host in WILDCARD_HOSTS:
        return None
    return (*LOCAL_HOSTS, f"[{host}]" if ":" in host else host)


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
        raise BarsynthError(f"cannot listen on {host}:{port}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(128)  # connections wait in the backlog until uvicorn takes them
    except OSError as exc:
        sock.close()
        raise BarsynthError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    return sock


def shown_address(sock: socket.socket) -> str:
    """``http://host:port/`` of a bound socket."""
    bound_host, bound_port = sock.getsockname()[:2]
    shown = f"[{bound_host}]" if ":" in bound_host else bound_host
    return f"http://{shown}:{bound_port}/"
