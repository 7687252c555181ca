"""The studio's web server: the page, its HTTP API and the live stream (issue 6).

Every model's parameter table drives what the page shows (names, units, ranges,
scales, choices); everything sent back is validated by the same table, so a bad value
gets one line naming the parameter, the value, the allowed range and the unit, with a
4xx status, and the server keeps serving. Renders are bounded in length
(``MAX_DURATION_S``), in number at once (``MAX_RENDERS``; the rest wait up to
``RENDER_WAIT_S``, then get 503) and in time (``JOB_TIME_LIMIT_S``, then 503), are stopped
when their client disconnects, and run in worker processes (:mod:`barsynth.studio.work`),
so they never hold up a live stream. Slow or idle connections are dropped and their number
capped (:func:`barsynth.webserver.server_config`). Live streams are
bounded too (``MAX_STREAMS``; one more is closed with code 1013 and a reason).

HTTP API (JSON in and out; errors are ``{"error": "one line"}``):

- ``GET /api/health``
- ``GET /api/models``: every model's name, summary, parameter table and presets; the models a
  recording can be fitted to and the upload's limits
- ``GET /api/models/{model}/presets/{preset}``: a preset's resolved parameters
- ``POST /api/render`` ``{"model", "parameters", "duration_s", "sample_rate"}``: a WAV file
  (16-bit, peak at -1 dBFS)
- ``POST /api/describe`` ``{"model", "parameters", "sample_rate"}``: the modes (and, for the
  reference models, each mode's error in cents)
- ``POST /api/picture`` ``{"model", "parameters", "duration_s", "sample_rate", "width"}``:
  waveform, spectrogram and modes of one strike (:mod:`barsynth.studio.pictures`)
- ``POST /api/preset-file`` ``{"model", "parameters", "description"}``: a preset file (TOML)
- ``POST /api/draw`` ``{"model", "mode", "seed", "parameters", "spread", "sample_rate"}``: Randomize
  (``mode`` ``random``) or Mutate (``mutate``, by ``spread`` of each range) seeded, the settings the
  model accepts (:mod:`barsynth.studio.variations`)
- ``POST /api/fit?model=banded|twang|fd&max_modes=N&nominal_hz=HZ&name=FILE&width=W``, the body a
  WAV, FLAC or OGG file's bytes (at most ``MAX_UPLOAD_BYTES``, ``MAX_UPLOAD_S`` long): the
  recording fitted, its settings, the comparison, both sounds and spectrograms
  (:mod:`barsynth.studio.fitted`); at most ``MAX_UPLOADS`` uploads are read or fitted at once
- ``WebSocket /api/stream``: the live stream (:mod:`barsynth.studio.live`, :mod:`barsynth.studio.stream`)

``docs/studio.md`` describes every field.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable
from importlib import resources
from typing import Any
from urllib.parse import urlsplit

from fastapi import FastAPI, Request, WebSocket
from fastapi.responses import JSONResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException

from ..errors import AudioFormatError, BarsynthError, ModelError
from ..checks import number_within, show_value
from ..jsonout import json_ready
from ..webserver import (LOCAL_HOSTS, QuietStop, Refused, guard, host_name, hosts_for, listen_socket, read_body,
                         read_json, server_config, shown_address)
from .fitted import MAX_UPLOAD_BYTES, MAX_UPLOAD_S
from .live import DATA_BYTES, MAX_MESSAGE_BYTES, play
from .pictures import MAX_COLUMNS
from .presets_file import preset_toml
from .stream import Stream
from .variations import draw_json, mode_of, seed_of, spread_of
from .work import MAX_RENDERS, Workers, fit_json, modes_json, picture_json, render_wav

__all__ = ["MAX_BODY_BYTES", "MAX_RENDERS", "MAX_STREAMS", "MAX_UPLOADS", "MAX_UPLOAD_BYTES", "create_app", "serve"]

MAX_BODY_BYTES = 16 * 1024 + DATA_BYTES  # settings with a recorded attack's samples fit
MAX_DURATION_S = 20.0
SAMPLE_RATES = (22050, 44100, 48000, 96000)
MAX_STREAMS = 4
MAX_UPLOADS = 4  # uploads read, waiting for a worker or fitted at once (each held in memory); more get 503
FIT_OPTIONS = ("model", "max_modes", "nominal_hz", "name", "width")
DEFAULT_PORT = 8050
_NO_STORE = {"Cache-Control": "no-store"}
_JS = "text/javascript; charset=utf-8"
# The page's files (only these are served): app.js and the ES modules it imports, the worklet,
# the stream's worker and the style sheet.
_STATIC = {**{name: _JS for name in ("app.js", "page.js", "controls.js", "live.js", "plots.js", "files.js",
                                    "fit.js", "worklet.js", "link.js", "keys.js", "history.js",
                                    "variations.js")},
           "style.css": "text/css; charset=utf-8"}


def _model(name: Any) -> Any:
    from ..models import get_model

    if not isinstance(name, str):
        raise Refused(422, f"parameter model = {show_value(name)} is not a model name")
    try:
        return get_model(name)
    except ModelError as exc:
        raise Refused(404, str(exc)) from None


def _fields(wish: Any, required: set[str], optional: set[str]) -> dict:
    if not isinstance(wish, dict):
        raise Refused(422, f"the request body must be a JSON object with {', '.join(sorted(required))}")
    missing, unknown = required - set(wish), set(wish) - required - optional
    if missing:
        raise Refused(422, f"missing {', '.join(sorted(missing))}")
    if unknown:
        raise Refused(422, f"unknown field {show_value(sorted(unknown)[0])}; allowed: {', '.join(sorted(required | optional))}")
    return wish


def _resolved(model: Any, parameters: Any) -> Any:
    if parameters is None:
        parameters = {}
    if not isinstance(parameters, dict):
        raise Refused(422, "parameters must be a JSON object of parameter names and values")
    return model.table.resolve(parameters)


def _rate(value: Any) -> float:
    if value is None:
        return 48000.0
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value not in SAMPLE_RATES:
        raise Refused(422, f"parameter sample_rate = {show_value(value)} is not allowed; allowed: one of "
                           f"{', '.join(str(r) for r in SAMPLE_RATES)} Hz")
    return float(value)


def _duration(value: Any, default: float = 2.0) -> float:
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.01 <= value <= MAX_DURATION_S:
        raise Refused(422, f"parameter duration_s = {show_value(value)} is out of range; allowed: 0.01 to "
                           f"{MAX_DURATION_S:g} s")
    return float(value)


def _width(value: Any) -> int:
    if value is None:
        return 600
    if not number_within(value, 16, MAX_COLUMNS, whole=True):
        raise Refused(422, f"parameter width = {show_value(value)} is out of range; allowed: whole numbers from 16 to "
                           f"{MAX_COLUMNS} pixels")
    return int(value)


def _fit_options(query: Any) -> dict:
    """The options of ``/api/fit`` from its query: the model to fit, the most modes, the note's
    nominal frequency, the file's name (for messages) and the spectrograms' width. Their ranges
    are the fit's own (:func:`barsynth.fitting.fit_recording` checks them, in the worker)."""
    from ..fitting import FIT_MODELS

    unknown = sorted(set(query.keys()) - set(FIT_OPTIONS))
    if unknown:
        raise Refused(422, f"unknown option {show_value(unknown[0])}; allowed: {', '.join(FIT_OPTIONS)}")
    model = query.get("model", "banded")
    if model not in FIT_MODELS:
        raise Refused(422, f"parameter model = {show_value(model)} cannot be fitted; allowed: one of "
                           f"{', '.join(FIT_MODELS)}")
    max_modes = query.get("max_modes", "12")
    if not (max_modes.isascii() and max_modes.isdigit() and len(max_modes) <= 6):
        raise Refused(422, f"parameter max_modes = {show_value(max_modes)} is not a whole number of modes")
    nominal_hz = query.get("nominal_hz")
    if nominal_hz is not None:
        try:
            nominal_hz = float(nominal_hz)
        except ValueError:
            raise Refused(422, f"parameter nominal_hz = {show_value(nominal_hz)} is not a number of Hz") from None
    width = query.get("width")
    if width is not None:
        width = int(width) if width.isascii() and width.isdigit() and len(width) <= 6 else width
    name = query.get("name", "upload")
    if not 0 < len(name) <= 200 or any(0xD800 <= ord(c) <= 0xDFFF for c in name):
        raise Refused(422, "parameter name (the file's name) must be text of 1 to 200 characters")
    return {"model": model, "max_modes": int(max_modes), "nominal_hz": nominal_hz, "name": name,
            "width": _width(width)}


def create_app(*, allowed_hosts: Iterable[str] | None = LOCAL_HOSTS, workers: Workers | None = None) -> FastAPI:
    """The studio's FastAPI app; ``allowed_hosts`` as for the listening server (None: any);
    ``workers`` run the renders (by default a pool of ``MAX_RENDERS`` worker processes)."""
    workers = workers if workers is not None else Workers()
    streams: set[Stream] = set()
    uploads = [0]  # uploads being read, waiting or fitted now
    hosts = None if allowed_hosts is None else {h.lower() for h in allowed_hosts}
    web = resources.files("barsynth.studio") / "web"
    app = FastAPI(title="barsynth studio", docs_url=None, redoc_url=None, openapi_url=None)

    @app.exception_handler(Refused)
    async def refused(_request: Request, exc: Refused) -> JSONResponse:
        return JSONResponse({"error": str(exc)}, status_code=exc.status, headers=_NO_STORE)

    @app.exception_handler(StarletteHTTPException)
    async def no_such(_request: Request, exc: StarletteHTTPException) -> JSONResponse:
        return JSONResponse({"error": f"{exc.detail} (see docs/studio.md for the API)"}, status_code=exc.status_code,
                            headers=_NO_STORE)

    @app.exception_handler(BarsynthError)
    async def bad_value(_request: Request, exc: BarsynthError) -> JSONResponse:
        return JSONResponse({"error": str(exc)}, status_code=422, headers=_NO_STORE)

    guard(app, allowed_hosts, MAX_BODY_BYTES, "the studio", larger={"/api/fit": MAX_UPLOAD_BYTES})

    @app.get("/")
    async def index() -> Response:
        return Response((web / "index.html").read_bytes(), media_type="text/html; charset=utf-8",
                        headers={"Cache-Control": "no-cache"})

    @app.get("/static/{name}")
    async def static(name: str) -> Response:
        if name not in _STATIC:
            raise Refused(404, f"no file {name[:40]!r}")
        return Response((web / name).read_bytes(), media_type=_STATIC[name], headers={"Cache-Control": "no-cache"})

    @app.get("/favicon.ico")
    async def favicon() -> Response:
        return Response(status_code=204)

    @app.get("/api/health")
    async def health() -> JSONResponse:
        return JSONResponse({"ok": True})

    @app.get("/api/models")
    async def models() -> JSONResponse:
        from ..models import get_model, model_names
        from ..presets import preset_names

        from ..fitting import FIT_MODELS

        listed = []
        for name in model_names():
            model = get_model(name)
            listed.append({"name": name, "summary": model.summary, "parameters": model.table.to_json(),
                           "presets": list(preset_names(name))})
        return JSONResponse({"models": listed, "fit": {"models": list(FIT_MODELS), "max_upload_bytes": MAX_UPLOAD_BYTES,
                                                       "max_upload_s": MAX_UPLOAD_S}})

    @app.get("/api/models/{name}/presets/{preset}")
    async def preset(name: str, preset: str) -> JSONResponse:
        from ..errors import PresetError
        from ..presets import load_preset, preset_parameters

        model = _model(name)
        try:
            info = load_preset(model.name, preset)["preset"]
            resolved = model.table.resolve(preset_parameters(model.name, preset))
        except PresetError as exc:
            raise Refused(404, str(exc)) from None
        values = json_ready(model.table.as_dict(resolved))
        return JSONResponse({"model": model.name, "preset": preset, "description": info.get("description", ""),
                             "parameters": values})

    @app.post("/api/render")
    async def render(request: Request) -> Response:
        wish = _fields(await read_json(request, MAX_BODY_BYTES), {"model"}, {"parameters", "duration_s",
                                                                               "sample_rate"})
        model = _model(wish["model"])
        resolved = _resolved(model, wish.get("parameters"))
        rate, seconds = _rate(wish.get("sample_rate")), _duration(wish.get("duration_s"))
        wav = await workers.run(render_wav, model.name, model.table.as_dict(resolved), seconds, rate,
                                gone=request.is_disconnected)
        return Response(wav, media_type="audio/wav",
                        headers={**_NO_STORE, "Content-Disposition": f'attachment; filename="{model.name}.wav"'})

    @app.post("/api/describe")
    async def describe(request: Request) -> JSONResponse:
        wish = _fields(await read_json(request, MAX_BODY_BYTES), {"model"}, {"parameters", "sample_rate"})
        model = _model(wish["model"])
        resolved = _resolved(model, wish.get("parameters"))
        rate = _rate(wish.get("sample_rate"))
        found = await workers.run(modes_json, model.name, model.table.as_dict(resolved), rate,
                                  gone=request.is_disconnected)
        return Response(found, media_type="application/json", headers=_NO_STORE)

    @app.post("/api/picture")
    async def picture_of(request: Request) -> JSONResponse:
        wish = _fields(await read_json(request, MAX_BODY_BYTES), {"model"},
                       {"parameters", "duration_s", "sample_rate", "width"})
        model = _model(wish["model"])
        resolved = _resolved(model, wish.get("parameters"))
        rate, seconds = _rate(wish.get("sample_rate")), _duration(wish.get("duration_s"), 1.5)
        found = await workers.run(picture_json, model.name, model.table.as_dict(resolved), rate, seconds,
                                  _width(wish.get("width")), gone=request.is_disconnected)
        return Response(found, media_type="application/json", headers=_NO_STORE)

    @app.post("/api/preset-file")
    async def preset_file(request: Request) -> Response:
        wish = _fields(await read_json(request, MAX_BODY_BYTES), {"model", "parameters"}, {"description"})
        model = _model(wish["model"])
        resolved = _resolved(model, wish["parameters"])
        description = wish.get("description", f"{model.name} settings")
        if not isinstance(description, str) or not 0 < len(description) <= 200 \
                or any(0xD800 <= ord(c) <= 0xDFFF for c in description):
            raise Refused(422, "description must be text of 1 to 200 characters")
        text = preset_toml(model.table.as_dict(resolved), description=description, model=model.name)
        return Response(text, media_type="application/toml; charset=utf-8",
                        headers={**_NO_STORE, "Content-Disposition": f'attachment; filename="{model.name}.toml"'})

    @app.post("/api/draw")
    async def draw(request: Request) -> Response:
        wish = _fields(await read_json(request, MAX_BODY_BYTES), {"model", "mode", "seed"},
                       {"parameters", "spread", "sample_rate"})
        model = _model(wish["model"])
        mode = mode_of(wish["mode"])
        seed, spread = seed_of(wish["seed"]), spread_of(wish.get("spread"), mode)
        resolved = _resolved(model, wish.get("parameters"))
        rate = _rate(wish.get("sample_rate"))
        found = await workers.run(draw_json, model.name, model.table.as_dict(resolved), mode, seed, spread, rate,
                                  gone=request.is_disconnected)
        return Response(found, media_type="application/json", headers=_NO_STORE)

    @app.post("/api/fit")
    async def fit(request: Request) -> Response:
        options = _fit_options(request.query_params)
        if uploads[0] >= MAX_UPLOADS:
            raise Refused(503, f"the studio is fitting {MAX_UPLOADS} recordings at once; try again")
        uploads[0] += 1
        try:
            data = await read_body(request, MAX_UPLOAD_BYTES)
            if not data:
                raise Refused(422, f"the upload is empty (0 bytes); allowed: a WAV, FLAC or OGG file of up to "
                                   f"{MAX_UPLOAD_S:g} s and {MAX_UPLOAD_BYTES} bytes")
            try:
                found = await workers.run(fit_json, data, options["name"], options["model"], options["max_modes"],
                                          options["nominal_hz"], options["width"], gone=request.is_disconnected)
            except AudioFormatError as exc:  # not a sound file: the one line, as unsupported media
                raise Refused(415, str(exc)) from None
        finally:
            uploads[0] -= 1
        return Response(found, media_type="application/json", headers=_NO_STORE)

    def foreign(socket: WebSocket) -> bool:
        """A page of another origin (another site, or another port of this machine) or a rebound
        name (its Host) may not open a stream. A client that sends no Origin is no browser page."""
        host = socket.headers.get("host", "").strip().lower()
        origin = socket.headers.get("origin")
        if origin is not None and urlsplit(origin.strip().lower()).netloc != host:
            return True
        return hosts is not None and host_name(host) not in hosts

    @app.websocket("/api/stream")
    async def stream(socket: WebSocket) -> None:
        if foreign(socket):
            await socket.close(code=1008)  # before accepting: the handshake is refused (403)
            return
        await socket.accept()
        if len(streams) >= MAX_STREAMS:
            await socket.close(code=1013, reason=f"the studio is playing {MAX_STREAMS} streams at once; "
                                                 "try again later")
            return
        session = Stream()
        streams.add(session)
        try:
            await play(socket, session)
        finally:
            streams.discard(session)

    return app


def serve(*, host: str = "127.0.0.1", port: int = DEFAULT_PORT, echo: Callable[[str], None] = print) -> None:
    """Serve the studio until stopped (Ctrl-C or SIGTERM)."""
    sock = listen_socket(host, port)
    workers = Workers()
    try:
        app = create_app(allowed_hosts=hosts_for(host), workers=workers)
        echo(f"barsynth studio at {shown_address(sock)} (Ctrl-C stops)")
        if sock.getsockname()[0] not in ("127.0.0.1", "::1"):
            echo("barsynth studio: warning: listening beyond this machine; anyone who can reach it can use it")
        sys.stdout.flush()
        config = server_config(app, timeout_graceful_shutdown=2, ws_max_size=4 * MAX_MESSAGE_BYTES,
                               ws_ping_interval=20.0, ws_ping_timeout=20.0)
        QuietStop(config).run(sockets=[sock])
    finally:
        sock.close()
        workers.close()
    echo("barsynth studio: stopped")
