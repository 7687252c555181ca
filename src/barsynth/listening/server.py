"""The listening-test web server (spec 4): MUSHRA pages and A/B pairs in the browser.

``create_app`` builds the FastAPI app for a loaded test and a results store;
``serve`` binds the socket (127.0.0.1 unless told otherwise) and runs it with
uvicorn. A participant is a random id with a secret token in an HttpOnly cookie;
every answer is checked by :mod:`barsynth.listening.session` and committed to
SQLite before the browser hears back, so nothing answered is lost when a tab is
closed or the server is killed. No address, name or browser detail is stored.

HTTP API (JSON; errors are ``{"error": "one line"}`` with a 4xx status):

- ``POST /api/session``: start (or, with ``{"new": true}``, restart) a session
- ``GET /api/session``: the session's state (resume)
- ``GET /api/audio/{handle}``: a clip as 16-bit WAV, by its opaque handle
- ``POST /api/play``: ``{"handle": h}`` counts one play
- ``POST /api/steps/{k}/answer``: ``{"ratings": [{"handle", "rating", "comment"}]}``
  for a MUSHRA page, ``{"picked": "A"|"B", "difficulty": 1..5}`` for an A/B pair
"""

from __future__ import annotations

import json
import re
import sqlite3
import sys
from collections.abc import Callable, Iterable
from importlib import resources
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response

from ..audio_io import wav_bytes
from ..webserver import (LOCAL_HOSTS, QuietStop, Refused, guard, hosts_for, listen_socket, read_json,
                         server_config, shown_address)
from .config import ListeningTest, load_test
from .session import Session, fingerprint, make_plan
from .store import ResultsStore

COOKIE = "barsynth_session"
MAX_BODY_BYTES = 64 * 1024
_STATIC = {"app.js": "text/javascript; charset=utf-8", "style.css": "text/css; charset=utf-8"}


def create_app(test: ListeningTest, store: ResultsStore, *, rng: Any = None,
               allowed_hosts: Iterable[str] | None = LOCAL_HOSTS) -> FastAPI:
    """The FastAPI app for one test; ``store`` is tied to it (another test's file is refused).

    ``allowed_hosts``: the Host names the server answers to (so a web page elsewhere
    cannot reach it by DNS rebinding); None answers to any (``--host 0.0.0.0``).
    """
    audio = {clip_id: wav_bytes(clip.samples, clip.sample_rate) for clip_id, clip in test.clips.items()}
    store.bind_test(fingerprint(test, audio))
    web = resources.files("barsynth.listening") / "web"
    pages = {name: (web / name).read_bytes() for name in ("index.html", *_STATIC)}

    app = FastAPI(title="barsynth listening test", docs_url=None, redoc_url=None, openapi_url=None)

    @app.exception_handler(Refused)
    async def refused(_request: Request, exc: Refused) -> JSONResponse:
        return JSONResponse({"error": str(exc)}, status_code=exc.status, headers={"Cache-Control": "no-store"})

    @app.exception_handler(RequestValidationError)
    async def malformed(_request: Request, exc: RequestValidationError) -> JSONResponse:
        first = (exc.errors() or [{}])[0]
        where = ".".join(str(part) for part in first.get("loc", ("request",)))
        return JSONResponse({"error": f"{where}: {first.get('msg', 'malformed request')}"}, status_code=422,
                            headers={"Cache-Control": "no-store"})

    @app.exception_handler(sqlite3.OperationalError)
    async def busy(_request: Request, exc: sqlite3.OperationalError) -> JSONResponse:
        return JSONResponse({"error": f"the results file could not be written ({exc}); nothing was stored, "
                                      "try again"}, status_code=503, headers={"Cache-Control": "no-store"})

    guard(app, allowed_hosts, MAX_BODY_BYTES, "this test")

    def session_of(request: Request) -> Session:
        participant, _, token = request.cookies.get(COOKIE, "").partition(".")
        plan = store.session_plan(participant, token) if participant and token else None
        if plan is None:
            raise Refused(401, "no session; start the test from its first page")
        return Session(test, store, participant, json.loads(plan))

    async def body(request: Request) -> Any:
        return await read_json(request, MAX_BODY_BYTES)

    def state(session: Session, status: int = 200) -> JSONResponse:
        return JSONResponse(session.state(), status_code=status, headers={"Cache-Control": "no-store"})

    @app.get("/")
    async def index() -> Response:
        return Response(pages["index.html"], media_type="text/html; charset=utf-8",
                        headers={"Cache-Control": "no-store"})

    @app.get("/static/{name}")
    async def static(name: str) -> Response:
        if name not in _STATIC:
            raise Refused(404, f"no file {name[:40]!r}")
        return Response(pages[name], media_type=_STATIC[name], headers={"Cache-Control": "no-cache"})

    @app.get("/favicon.ico")
    async def favicon() -> Response:
        return Response(status_code=204)

    @app.get("/api/health")
    async def health() -> JSONResponse:
        return JSONResponse({"ok": True, "title": test.title})

    @app.get("/api/session")
    async def get_session(request: Request) -> JSONResponse:
        return state(session_of(request))

    @app.post("/api/session")
    async def post_session(request: Request) -> JSONResponse:
        wish = await body(request)
        if wish is None:
            wish = {}
        if not isinstance(wish, dict) or set(wish) - {"new"} or not isinstance(wish.get("new", False), bool):
            raise Refused(422, 'a new session takes {} or {"new": true}')
        if not wish.get("new", False):
            try:
                return state(session_of(request))
            except Refused:
                pass
        plan = make_plan(test, rng)
        participant, token = store.start_session(json.dumps(plan))
        response = state(Session(test, store, participant, plan), status=201)
        response.set_cookie(COOKIE, f"{participant}.{token}", httponly=True, samesite="strict", path="/",
                            max_age=180 * 24 * 3600)
        return response

    @app.get("/api/audio/{handle}")
    async def get_audio(handle: str, request: Request) -> Response:
        clip = session_of(request).clip_of(handle)
        return _ranged(audio[clip], request.headers.get("range"))

    @app.post("/api/play")
    async def post_play(request: Request) -> JSONResponse:
        session = session_of(request)
        wish = await body(request)
        if not isinstance(wish, dict) or set(wish) != {"handle"}:
            raise Refused(422, 'a play is {"handle": "..."}')
        return JSONResponse({"plays": session.play(wish["handle"])}, headers={"Cache-Control": "no-store"})

    @app.post("/api/steps/{step}/answer")
    async def post_answer(step: int, request: Request) -> JSONResponse:
        session = session_of(request)
        session.answer(step, await body(request))
        return state(session)

    return app


def _ranged(data: bytes, wanted: str | None) -> Response:
    """A WAV answer honouring one byte range (Safari asks for ranges before it plays media)."""
    headers = {"Accept-Ranges": "bytes", "Cache-Control": "private, max-age=86400"}
    match = re.fullmatch(r"bytes=(\d{0,15})-(\d{0,15})", (wanted or "").strip())
    if match is None or match.groups() == ("", ""):  # none, several or malformed: the whole file
        return Response(data, media_type="audio/wav", headers=headers)
    size = len(data)
    first, last = match.groups()
    if first == "":
        start, end = max(0, size - int(last)), size - 1
        if int(last) == 0:
            start = size
    else:
        start, end = int(first), min(int(last) if last else size - 1, size - 1)
    if start >= size or start > end:
        return Response(status_code=416, headers={**headers, "Content-Range": f"bytes */{size}"})
    return Response(data[start:end + 1], status_code=206, media_type="audio/wav",
                    headers={**headers, "Content-Range": f"bytes {start}-{end}/{size}"})


def serve(config: str | Path, results: str | Path, *, host: str = "127.0.0.1", port: int = 8000,
          echo: Callable[[str], None] = print) -> None:
    """Load the test (every clip checked and rendered first), then serve it until stopped."""
    test = load_test(config)
    sock = listen_socket(host, port)
    try:
        with ResultsStore(results) as store:
            app = create_app(test, store, allowed_hosts=hosts_for(host))
            echo(f"barsynth listen: {test.title!r} at {shown_address(sock)} ; answers go to {results} "
                 "(Ctrl-C stops)")
            if sock.getsockname()[0] not in ("127.0.0.1", "::1"):
                echo("barsynth listen: warning: listening beyond this machine; anyone who can reach it can "
                     "take the test")
            sys.stdout.flush()
            server = QuietStop(server_config(app))
            server.run(sockets=[sock])
    finally:
        sock.close()
    echo(f"barsynth listen: stopped; the answers are in {results}")
