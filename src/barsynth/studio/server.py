"""The studio's HTTP API (issue 6, part 1): models, presets, bounded renders, mode tables.

Every model's parameter table drives what the page shows (names, units, ranges,
scales, choices); everything sent back is validated by the same table, so a bad value
gets one line naming the parameter, the value, the allowed range and the unit, with a
4xx status, and the server keeps serving. Renders are bounded in length
(``MAX_DURATION_S``) and in number at once (``MAX_RENDERS``; the rest wait up to
``RENDER_WAIT_S``, then get 503), and run off the event loop.

HTTP API (JSON in and out; errors are ``{"error": "one line"}``):

- ``GET /api/health``
- ``GET /api/models``: every model's name, summary, parameter table and presets
- ``GET /api/models/{model}/presets/{preset}``: a preset's resolved parameters
- ``POST /api/render`` ``{"model", "parameters", "duration_s", "sample_rate"}``: a WAV file
  (16-bit, peak at -1 dBFS)
- ``POST /api/describe`` ``{"model", "parameters", "sample_rate"}``: the modes (and, for the
  reference models, each mode's error in cents)
- ``POST /api/preset-file`` ``{"model", "parameters", "description"}``: a preset file (TOML)
"""

from __future__ import annotations

import asyncio
import io
import math
from collections.abc import Iterable
from typing import Any

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse, Response

from ..errors import BarsynthError, ModelError
from ..webserver import LOCAL_HOSTS, Refused, guard, read_json
from .presets_file import preset_toml

MAX_BODY_BYTES = 16 * 1024
MAX_DURATION_S = 20.0
MAX_RENDERS = 2
RENDER_WAIT_S = 10.0
SAMPLE_RATES = (22050, 44100, 48000, 96000)
_NO_STORE = {"Cache-Control": "no-store"}


def _model(name: Any) -> Any:
    from ..models import get_model

    if not isinstance(name, str):
        raise Refused(422, f"parameter model = {name!r} is not a model name")
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
        raise Refused(422, f"unknown field {sorted(unknown)[0]!r}; allowed: {', '.join(sorted(required | optional))}")
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
        raise Refused(422, f"parameter sample_rate = {value!r} is not allowed; allowed: one of "
                           f"{', '.join(str(r) for r in SAMPLE_RATES)} Hz")
    return float(value)


def _duration(value: Any) -> float:
    if value is None:
        return 2.0
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.01 <= value <= MAX_DURATION_S:
        raise Refused(422, f"parameter duration_s = {value!r} is out of range; allowed: 0.01 to "
                           f"{MAX_DURATION_S:g} s")
    return float(value)


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, tuple):
        return list(value)
    return value


def wav_bytes(samples: Any, sample_rate: float) -> bytes:
    import soundfile

    buffer = io.BytesIO()
    soundfile.write(buffer, samples, int(sample_rate), format="WAV", subtype="PCM_16")
    return buffer.getvalue()


def create_app(*, allowed_hosts: Iterable[str] | None = LOCAL_HOSTS) -> FastAPI:
    """The studio's FastAPI app; ``allowed_hosts`` as for the listening server (None: any)."""
    renders = asyncio.Semaphore(MAX_RENDERS)
    app = FastAPI(title="barsynth studio", docs_url=None, redoc_url=None, openapi_url=None)

    @app.exception_handler(Refused)
    async def refused(_request: Request, exc: Refused) -> JSONResponse:
        return JSONResponse({"error": str(exc)}, status_code=exc.status, headers=_NO_STORE)

    @app.exception_handler(BarsynthError)
    async def bad_value(_request: Request, exc: BarsynthError) -> JSONResponse:
        return JSONResponse({"error": str(exc)}, status_code=422, headers=_NO_STORE)

    guard(app, allowed_hosts, MAX_BODY_BYTES, "the studio")

    @app.get("/api/health")
    async def health() -> JSONResponse:
        return JSONResponse({"ok": True})

    @app.get("/api/models")
    async def models() -> JSONResponse:
        from ..models import get_model, model_names
        from ..presets import preset_names

        listed = []
        for name in model_names():
            model = get_model(name)
            listed.append({"name": name, "summary": model.summary, "parameters": model.table.to_json(),
                           "presets": list(preset_names(name))})
        return JSONResponse({"models": listed})

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
        values = {k: _json_safe(v) for k, v in model.table.as_dict(resolved).items()}
        return JSONResponse({"model": model.name, "preset": preset, "description": info.get("description", ""),
                             "parameters": values})

    @app.post("/api/render")
    async def render(request: Request) -> Response:
        wish = _fields(await read_json(request, MAX_BODY_BYTES), {"model"}, {"parameters", "duration_s",
                                                                               "sample_rate"})
        model = _model(wish["model"])
        resolved = _resolved(model, wish.get("parameters"))
        rate, seconds = _rate(wish.get("sample_rate")), _duration(wish.get("duration_s"))
        try:
            await asyncio.wait_for(renders.acquire(), RENDER_WAIT_S)
        except TimeoutError:
            raise Refused(503, f"the studio is busy ({MAX_RENDERS} renders at once); try again") from None
        try:
            samples = await asyncio.to_thread(model.render, resolved, duration_s=seconds, sample_rate=rate)
        finally:
            renders.release()
        return Response(wav_bytes(samples, rate), media_type="audio/wav",
                        headers={**_NO_STORE, "Content-Disposition": f'attachment; filename="{model.name}.wav"'})

    @app.post("/api/describe")
    async def describe(request: Request) -> JSONResponse:
        wish = _fields(await read_json(request, MAX_BODY_BYTES), {"model"}, {"parameters", "sample_rate"})
        model = _model(wish["model"])
        resolved = _resolved(model, wish.get("parameters"))
        rate = _rate(wish.get("sample_rate"))
        modes = await asyncio.to_thread(model.describe, resolved, sample_rate=rate)
        errors = model.errors_cents(resolved, sample_rate=rate) if hasattr(model, "errors_cents") else None
        rows = [{k: _json_safe(v) for k, v in m.to_json().items()} for m in modes]
        for k, row in enumerate(rows):
            if errors is not None and k < len(errors):
                row["error_cents"] = _json_safe(errors[k])
        return JSONResponse({"model": model.name, "sample_rate": rate, "modes": rows}, headers=_NO_STORE)

    @app.post("/api/preset-file")
    async def preset_file(request: Request) -> Response:
        wish = _fields(await read_json(request, MAX_BODY_BYTES), {"model", "parameters"}, {"description"})
        model = _model(wish["model"])
        resolved = _resolved(model, wish["parameters"])
        description = wish.get("description", f"{model.name} settings")
        if not isinstance(description, str) or not 0 < len(description) <= 200:
            raise Refused(422, "description must be text of 1 to 200 characters")
        text = preset_toml(model.table.as_dict(resolved), description=description)
        return Response(text, media_type="application/toml; charset=utf-8",
                        headers={**_NO_STORE, "Content-Disposition": f'attachment; filename="{model.name}.toml"'})

    return app
