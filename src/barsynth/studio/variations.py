"""Randomize and Mutate in the studio (issue 18): a seeded set of a model's settings that it accepts.

Both draw with :func:`barsynth.batch.sampler.valid_draw`, item 0 of the given seed, so the same
model, base settings, seed (and spread) give the same settings, on any machine and in any
worker: that is what lets a link name a draw by its seed. *Randomize* draws every drawable
row on its own scale over its whole range (the lists and a recorded attack come from the base
settings); *Mutate* moves each one from the base settings by up to ``spread`` of its range (a
choice or bool changes with probability ``spread``). A set the model refuses (its table's
ranges, its joint checks when its voice is designed, or non-finite samples in the first
``CHECK_S`` seconds) is drawn again, and counted.
"""

from __future__ import annotations

import collections
import json
from typing import Any

from ..checks import number_within, show_value
from ..jsonout import json_ready
from ..webserver import Refused

MODES = ("random", "mutate")
MAX_SEED = 2**32 - 1
"""Seeds are whole numbers from 0 to this (32 bits: short in a link)."""
DEFAULT_SPREAD = 0.1
CHECK_S = 0.05
"""Seconds of each drawn set rendered to check its samples are finite before it is kept."""
SHOWN_REASONS = 3


def mode_of(value: Any) -> str:
    """The draw's mode, ``random`` or ``mutate``; else a 422 naming it."""
    if value not in MODES:
        raise Refused(422, f"parameter mode = {show_value(value)} is not allowed; allowed: one of {', '.join(MODES)}")
    return value


def seed_of(value: Any) -> int:
    """A seed (a whole number from 0 to ``MAX_SEED``); else a 422 naming it."""
    if not number_within(value, 0, MAX_SEED, whole=True):
        raise Refused(422, f"parameter seed = {show_value(value)} is not a seed; allowed: whole numbers from 0 to "
                           f"{MAX_SEED}")
    return int(value)


def spread_of(value: Any, mode: str) -> float | None:
    """Mutate's spread (a fraction of each range, 0 to 1; ``DEFAULT_SPREAD`` when not given);
    None for Randomize, which takes none; else a 422 naming it."""
    if mode == "random":
        if value is not None:
            raise Refused(422, f"parameter spread = {show_value(value)} applies to mode mutate only; allowed: "
                               "no spread with mode random")
        return None
    if value is None:
        return DEFAULT_SPREAD
    if not number_within(value, 0.0, 1.0):
        raise Refused(422, f"parameter spread = {show_value(value)} is out of range; allowed: 0 to 1 (a fraction "
                           "of each parameter's range)")
    return float(value)


def draw(model_name: str, values: dict, mode: str, seed: int, spread: float | None,
         sample_rate: float) -> dict[str, Any]:
    """The settings drawn from ``values`` (the base: every parameter, checked) as the answer of
    ``/api/draw``: ``{"model", "mode", "seed", "spread", "parameters", "rejected", "reasons"}``
    (``reasons``: the commonest refusals, numbers blanked, with their counts)."""
    from ..batch.sampler import valid_draw
    from ..models import get_model

    model = get_model(model_name)
    settings, rejected, reasons = valid_draw(model, seed, 0, base=values, spread=spread, sample_rate=sample_rate,
                                             render_s=CHECK_S)
    common = collections.Counter(reasons).most_common(SHOWN_REASONS)
    return {"model": model.name, "mode": mode, "seed": seed, "spread": spread,
            "parameters": json_ready(settings), "rejected": rejected,
            "reasons": [{"reason": text, "count": count} for text, count in common]}


def draw_json(model_name: str, values: dict, mode: str, seed: int, spread: float | None, sample_rate: float) -> bytes:
    """:func:`draw` as JSON bytes (what a worker process gives back)."""
    found = draw(model_name, values, mode, seed, spread, sample_rate)
    return json.dumps(found, allow_nan=False, separators=(",", ":")).encode()
