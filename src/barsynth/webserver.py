"""What barsynth's local web servers share: a bound socket, a quiet stop, Host checks,
bounded JSON bodies, the security headers and the limits that keep hostile clients from
holding the server (used by ``listen serve`` and ``studio``).

Limits on every connection (:func:`server_config`), whichever server:

- ``HEADER_TIMEOUT_S``: a request's line and headers must be complete this long after the
  connection opened (or after the previous answer); otherwise the connection is closed.
- ``BODY_TIMEOUT_S``: its body must be complete this long after its headers.
- ``KEEP_ALIVE_S``: an idle connection between requests is closed after this long.
- ``SEND_TIMEOUT_S``: a client that stops reading an answer (the server's send buffer full)
  for this long is cut off, so slow readers cannot hold connections the cap counts as busy.
- ``MAX_HEADER_BYTES``: a request line and headers larger than this get 431 and a close.
- ``MAX_CONNECTIONS`` (lowered to the open-file limit less ``FD_RESERVE``): one more connection
  closes the one that has waited longest without a complete request (idle or incomplete),
  so slow clients give way to new ones and busy requests are never cut.
- ``BACKLOG``: connections the kernel queues before the server takes them; the event loop
  takes up to this many at once before the cap can act, so ``FD_RESERVE`` leaves room for
  two such batches and the server's own files (worker pipes, the listening socket).
- ``LOG_EVERY_S``: a repeated log line (running out of file descriptors, bad requests) is
  written at most once this often, with a count of the ones left out, and no traceback for
  running out of file descriptors.

Kept free of FastAPI imports at module level except where a request is read, so the
command line stays quick to start.
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import re
import resource
import socket
import time
from collections.abc import Iterator
from typing import Any

import uvicorn

from .checks import show_text
from .errors import BarsynthError

LOCAL_HOSTS = ("127.0.0.1", "localhost", "[::1]")
HEADER_TIMEOUT_S = 10.0
BODY_TIMEOUT_S = 10.0
SEND_TIMEOUT_S = 30.0
KEEP_ALIVE_S = 5
MAX_HEADER_BYTES = 16 * 1024
MAX_CONNECTIONS = 1000
BACKLOG = 64
FD_RESERVE = 3 * BACKLOG
LOG_EVERY_S = 5.0
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


_HOST_HEADER = re.compile(r"(\[[0-9a-f:.]+\]|[a-z0-9.-]+)(?::[0-9]{1,5})?")


def host_name(header: str) -> str:
    """The host part of a Host header, lower case: 'localhost', '127.0.0.1', '[::1]'; '' unless
    the header is exactly a name or address with an optional ``:port`` (so ``[::1]evil.com``,
    ``127.0.0.1:80:80`` and ``localhost:`` name no host)."""
    found = _HOST_HEADER.fullmatch(header.strip().lower())
    return found.group(1) if found else ""


def hosts_for(host: str) -> tuple[str, ...] | None:
    """The Host names a server bound to ``host`` answers to (None: any, for a wildcard address)."""
    if host in WILDCARD_HOSTS:
        return None
    return (*LOCAL_HOSTS, f"[{host}]" if ":" in host else host)


def guard(app: Any, allowed: Any, limit: int, who: str, *, larger: dict[str, int] | None = None) -> None:
    """Add the middleware every barsynth server has: refuse a foreign Host (DNS rebinding)
    and a declared body over ``limit`` bytes, and add the security headers. ``allowed``:
    the Host names to answer to (None: any); ``who``: 'this test', 'the studio'; ``larger``:
    the paths that take a larger body, and their limit (bytes): the studio's uploads.

    A plain ASGI middleware, not ``@app.middleware("http")``: starlette's BaseHTTPMiddleware
    wraps ``receive`` so that ``request.is_disconnected()`` never sees a client that has gone,
    and the studio stops the work of such clients."""
    from fastapi.responses import JSONResponse
    from starlette.datastructures import Headers, MutableHeaders

    hosts = None if allowed is None else {h.lower() for h in allowed}
    limits = dict(larger or {})

    def headers(inner: Any) -> Any:
        async def middleware(scope: Any, receive: Any, send: Any) -> None:
            if scope["type"] != "http":
                await inner(scope, receive, send)
                return
            asked = Headers(scope=scope)
            if hosts is not None and host_name(asked.get("host", "")) not in hosts:
                refusal = JSONResponse({"error": f"unknown Host; {who} answers only at its own address"},
                                       status_code=400)
                await refusal(scope, receive, send)
                return
            length = asked.get("content-length", "0")
            most = limits.get(scope.get("path", ""), limit)
            if not length.isdigit() or int(length) > most:
                refusal = JSONResponse({"error": f"request body too large; allowed: up to {most} bytes"},
                                       status_code=413)
                await refusal(scope, receive, send)
                return

            async def secured(message: Any) -> None:
                if message["type"] == "http.response.start":
                    message = {**message, "headers": list(message.get("headers", []))}
                    MutableHeaders(scope=message).update(SECURITY_HEADERS)
                await send(message)

            await inner(scope, receive, secured)

        return middleware

    app.add_middleware(headers)


def no_constants(name: str) -> None:
    raise ValueError(f"{name} is not a number JSON allows")


async def read_body(request: Any, limit: int) -> bytes:
    """The request's body, at most ``limit`` bytes (a chunked body too, which has no length to
    check first); otherwise :class:`Refused` (413, or 400 for a client gone before the end)."""
    from starlette.requests import ClientDisconnect

    raw = bytearray()
    try:
        async for chunk in request.stream():
            raw += chunk
            if len(raw) > limit:
                raise Refused(413, f"request body too large; allowed: up to {limit} bytes")
    except ClientDisconnect:  # nobody to answer; not an error of the server's
        raise Refused(400, "the client went away before its request body was complete") from None
    return bytes(raw)


async def read_json(request: Any, limit: int) -> Any:
    """The request's JSON body (None when empty): application/json, at most ``limit`` bytes
    (a chunked body too), no NaN or Infinity; otherwise :class:`Refused`."""
    if request.headers.get("content-type", "").split(";")[0].strip() != "application/json":
        raise Refused(415, "send the request body as application/json")
    raw = await read_body(request, limit)
    try:
        return json.loads(raw or b"null", parse_constant=no_constants)
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


_FD_ERRNOS = (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM)


class RateLimitedLog(logging.Filter):
    """Lets one log record of a kind through every ``every_s`` seconds and counts the rest.

    A kind is the logger, the message's template and the exception's type. Running out of
    file descriptors (asyncio's ``socket.accept() out of system resource``, logged with a
    traceback every time the loop retries an accept) becomes one line without a traceback:
    under a flood of connections it would otherwise fill the log. The next record of a kind
    that gets through says how many were left out since the last one.
    """

    def __init__(self, every_s: float = LOG_EVERY_S, clock: Any = time.monotonic) -> None:
        super().__init__()
        self.every_s = every_s
        self.clock = clock
        self._seen: dict[tuple, list] = {}  # kind -> [time last shown, records left out since]

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        out_of_fds = isinstance(exc, OSError) and exc.errno in _FD_ERRNOS
        kind = ("fd",) if out_of_fds else (record.name, str(record.msg)[:200], type(exc).__name__)
        now = self.clock()
        seen = self._seen.get(kind)
        if seen is not None and now - seen[0] < self.every_s:
            seen[1] += 1
            return False
        if len(self._seen) > 1000:  # many kinds (messages made by hand): forget the old ones
            self._seen.clear()
        left_out = seen[1] if seen is not None else 0
        self._seen[kind] = [now, 0]
        more = f" ({left_out} more like this left out since)" if left_out else ""
        if out_of_fds:
            what = str(record.msg).split("\n")[0]
            record.msg, record.args = f"out of file descriptors: {what}: {exc.strerror}{more}", ()
            record.exc_info, record.exc_text = None, None
        elif more:
            record.msg, record.args = record.getMessage() + more, ()
        return True


def quiet_logs(every_s: float = LOG_EVERY_S) -> RateLimitedLog:
    """Put one :class:`RateLimitedLog` on the loggers a flood of clients can fill (asyncio's,
    uvicorn's error log and the studio's stream log); again is a no-op. Returns the filter."""
    loggers = [logging.getLogger(name) for name in ("asyncio", "uvicorn.error", "barsynth.studio")]
    found = next((f for f in loggers[0].filters if isinstance(f, RateLimitedLog)), None)
    rate = found or RateLimitedLog(every_s)
    for logger in loggers:
        if rate not in logger.filters:
            logger.addFilter(rate)
    return rate


def connection_cap(limit: int = MAX_CONNECTIONS) -> int:
    """``limit``, lowered so the open connections leave ``FD_RESERVE`` of the process's open-file
    limit for its own files, worker pipes and the listening socket."""
    soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    if soft == resource.RLIM_INFINITY:
        return limit
    return min(limit, max(8, soft - FD_RESERVE))  # (the floor of 8 is for the open-file limit only)


def guarded_protocol(*, header_timeout_s: float = HEADER_TIMEOUT_S, body_timeout_s: float = BODY_TIMEOUT_S,
                     send_timeout_s: float = SEND_TIMEOUT_S, max_connections: int | None = None,
                     max_header_bytes: int = MAX_HEADER_BYTES) -> type:
    """uvicorn's h11 HTTP protocol with a header timeout, a body timeout, a send timeout (a
    client that stops reading), a 431 for oversized headers and a cap on connections that
    closes the longest-waiting idle or incomplete one.

    Written here because uvicorn has none of these: its h11 protocol arms no timer on a new
    connection (one that sends nothing, or a header a byte a minute, is kept for ever), its
    keep-alive timer is cancelled by the first byte of the next request, it has no body
    timeout, and ``limit_concurrency`` answers 503 to every new request once slow clients
    fill it instead of dropping them. Oversized headers: h11 stops at
    ``h11_max_incomplete_event_size`` only while a head is incomplete (uvicorn then answers
    400; here 431), and a head that arrives in one piece is not measured at all: here it is.
    """
    import h11
    from uvicorn.protocols.http.h11_impl import H11Protocol

    cap = connection_cap(max_connections if max_connections is not None else MAX_CONNECTIONS)
    too_large = (b"HTTP/1.1 431 Request Header Fields Too Large\r\ncontent-type: application/json\r\n"
                 b"connection: close\r\ncontent-length: %d\r\n\r\n%s")
    message = json.dumps({"error": f"request headers too large; allowed: up to {max_header_bytes} bytes"}).encode()

    async def refuse_large(scope: Any, receive: Any, send: Any) -> None:
        await send({"type": "http.response.start", "status": 431,
                    "headers": [(b"content-type", b"application/json"), (b"connection", b"close")]})
        await send({"type": "http.response.body", "body": message})

    class GuardedH11Protocol(H11Protocol):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            inner = self.app

            async def app(scope: Any, receive: Any, send: Any) -> None:
                """A head that came in one piece is not measured by h11: it is measured here."""
                size = len(scope["raw_path"]) + len(scope["query_string"]) + sum(len(k) + len(v) + 4
                                                                                 for k, v in scope["headers"])
                await (refuse_large if size > max_header_bytes else inner)(scope, receive, send)

            self.app = app

        def connection_made(self, transport: Any) -> None:  # type: ignore[override]
            self._timer: Any = None
            self._send_timer: Any = None
            self._waiting = ""
            self._since = 0.0
            super().connection_made(transport)
            self._wait("head", header_timeout_s)
            self._make_room()

        def _wait(self, what: str, seconds: float) -> None:
            """Close the connection unless ``what`` ('head', 'body') is complete within ``seconds``."""
            self._stop_waiting()
            self._waiting, self._since = what, self.loop.time()
            self._timer = self.loop.call_later(seconds, self._drop)

        def _stop_waiting(self) -> None:
            if self._timer is not None:
                self._timer.cancel()
            self._timer, self._waiting = None, ""

        def _drop(self) -> None:
            self._stop_waiting()
            self.connections.discard(self)
            if not self.transport.is_closing():
                self.transport.close()

        def _make_room(self) -> None:
            """Over the cap: close the connections that have waited longest for a request
            (idle or incomplete); this new one too if every other is busy."""
            excess = len(self.connections) - cap
            if excess <= 0:
                return
            import heapq

            waiting = [c for c in self.connections if isinstance(c, GuardedH11Protocol) and c._waiting]
            for connection in heapq.nsmallest(excess, waiting, key=lambda c: (c is self, c._since)):
                connection._drop()

        def handle_events(self) -> None:  # after new data, and after an answer (pipelined requests)
            before = self.cycle
            super().handle_events()
            if self.transport.is_closing() or self._waiting == "":
                return
            if self.cycle is not before and self.cycle is not None:  # a request's head arrived
                if self.cycle.more_body:
                    self._wait("body", body_timeout_s)
                else:
                    self._stop_waiting()
            elif self._waiting == "body" and self.cycle is not None and not self.cycle.more_body:
                self._stop_waiting()

        def send_400_response(self, msg: str) -> None:
            if self.conn.their_state is h11.ERROR and len(self.conn.trailing_data[0]) > max_header_bytes:
                self._stop_waiting()
                self.transport.write(too_large % (len(message), message))
                self.transport.close()
                return
            super().send_400_response(msg)

        def on_response_complete(self) -> None:
            if not self.transport.is_closing():
                self._wait("head", header_timeout_s)  # for the next request (a pipelined one stops it)
            super().on_response_complete()

        def handle_websocket_upgrade(self, event: Any) -> None:
            self._stop_waiting()  # the WebSocket protocol takes the connection over
            super().handle_websocket_upgrade(event)

        def pause_writing(self) -> None:  # the client reads slower than we send: it has a while
            super().pause_writing()
            if self._send_timer is None:
                self._send_timer = self.loop.call_later(send_timeout_s, self._cut_off)

        def resume_writing(self) -> None:
            self._stop_send_timer()
            super().resume_writing()

        def _stop_send_timer(self) -> None:
            if self._send_timer is not None:
                self._send_timer.cancel()
                self._send_timer = None

        def _cut_off(self) -> None:
            """A client that read nothing for ``send_timeout_s``: dropped, its unsent answer too."""
            self._send_timer = None
            self.connections.discard(self)
            self.transport.abort()  # (close() would wait to send what is buffered, for ever)

        def connection_lost(self, exc: Exception | None) -> None:
            self._stop_waiting()
            self._stop_send_timer()
            super().connection_lost(exc)

    return GuardedH11Protocol


def server_config(app: Any, **options: Any) -> uvicorn.Config:
    """uvicorn's settings for a barsynth server: quiet (warnings only, no access log, rate-limited),
    no lifespan, and the limits above. ``options`` adds or overrides uvicorn's options; the
    limits of :func:`guarded_protocol` may be given as ``protocol={...}``."""
    limits = options.pop("protocol", {})
    settings = {"log_level": "warning", "access_log": False, "lifespan": "off", "timeout_keep_alive": KEEP_ALIVE_S,
                "backlog": BACKLOG,
                "h11_max_incomplete_event_size": limits.get("max_header_bytes", MAX_HEADER_BYTES), **options}
    config = uvicorn.Config(app, http=guarded_protocol(**limits), **settings)
    quiet_logs()  # after uvicorn has set its loggers up
    return config


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
        sock.listen(BACKLOG)  # connections wait in the backlog until uvicorn takes them
    except OSError as exc:
        sock.close()
        raise BarsynthError(f"cannot listen on {show_text(host)}:{port}: {exc.strerror or exc}") from None
    return sock


def shown_address(sock: socket.socket) -> str:
    """``http://host:port/`` of a bound socket."""
    bound_host, bound_port = sock.getsockname()[:2]
    shown = f"[{bound_host}]" if ":" in bound_host else bound_host
    return f"http://{shown}:{bound_port}/"
