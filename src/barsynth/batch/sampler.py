"""Random and mutated settings of a model that it accepts (spec 11.4).

A draw is made on each row's own scale (log rows log-uniform, choices and bools uniformly),
from the row's range or a narrower one, or around a base preset with a spread per parameter.
A drawn set is kept only if the model accepts it: the table validates it, the model's voice is
made for the sample rate (where every joint constraint is checked today: a fundamental in the
band, a stable finite-difference grid, a tube on a mode that sounds) and, optionally, a short
render gives finite samples. A refused set is redrawn, a bounded number of times, and counted.

Item ``i`` of a batch draws from its own stream, ``SeedSequence(seed, spawn_key=(i,))`` (the
``i``-th of ``SeedSequence(seed).spawn``), so its settings do not depend on how many items are
asked for, nor on which worker draws it. See docs/batch-sampler-notes.md.
"""

from __future__ import annotations

import collections
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import show_value
from ..errors import ParameterError, SamplesError
from ..parameters import BOOL, CHOICE, FLOATS, INT, Parameter

MAX_ATTEMPTS = 1000
"""Draws tried for one item before giving up (a ruler drawn over its whole table is refused
about 30 times in 31, most by its cheap declared constraints)."""

LIST_LENGTHS = (2, 6)
"""How many values a list row gets when the drawn settings ask for one it has none of (inclusive)."""


def drawable(table: Any) -> tuple[Parameter, ...]:
    """The rows a draw sets: every control but a data row (a recorded attack) and lists."""
    return tuple(p for p in table if not p.data and p.kind != FLOATS)


def item_rng(seed: int, index: int) -> np.random.Generator:
    """The random stream of item ``index``'s draws in a batch seeded ``seed`` (both whole numbers
    >= 0): the same as ``default_rng(SeedSequence(seed).spawn(index + 1)[index])``."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(index),)))


def draw_settings(model: Any, rng: np.random.Generator, *, base: Any = None,
                  spread: float | Mapping[str, float] | None = None, names: Iterable[str] | None = None,
                  ranges: Mapping[str, tuple[float, float]] | None = None) -> dict[str, Any]:
    """One random set of ``model``'s parameters (every one, resolved, as a plain dict).

    Without ``spread``: each parameter of ``names`` (by default every drawable row) uniformly on
    its row's scale within its range, or within ``ranges[name]`` (low, high in the row's unit);
    the rest from ``base`` (a preset's record, a mapping, or None for the defaults). With
    ``spread`` (a fraction of the range, one for all or per name): each named parameter moves
    from ``base`` by up to that fraction of its range on its scale (uniformly, reflected at the
    ends), and a choice or bool changes with that probability. A list whose row the drawn
    choices ask for and which has no values by default (a profile of samples) gets 2 to 6 values.
    The draw is not checked against the model (see :func:`valid_draws`).
    """
    table = model.table
    start = model.resolve(base) if base is not None else table.resolve()
    rows = drawable(table)
    chosen = {p.name for p in rows} if names is None else {table[n].name for n in names}
    if spread is not None and not isinstance(spread, Mapping):
        spread = {name: float(spread) for name in chosen}
    changes: dict[str, Any] = {}
    for p in rows:
        u = rng.random()  # one number per row, always (a mutated choice or bool takes a second one)
        if p.name not in chosen:
            continue
        if spread is None:
            changes[p.name] = value_within(p, u, (ranges or {}).get(p.name))
        elif spread.get(p.name, 0.0) > 0.0:
            changes[p.name] = value_mutated(p, getattr(start, p.name), u, spread[p.name], rng)
    # a material drawn sets E and rho: they are left out then (as table.settings_at does)
    for p in table:
        if p.sets is not None and p.name in changes and changes[p.name] != p.default:
            for name in p.sets.names:
                changes.pop(name, None)
    resolved = table.changed(start, changes)
    lists = {}
    for p in table:
        if p.kind == FLOATS and not p.data and p.when and not p.default and p.acts_under(resolved) \
                and not getattr(resolved, p.name):
            count = int(rng.integers(LIST_LENGTHS[0], LIST_LENGTHS[1] + 1))
            lists[p.name] = tuple(float(value_within(p, x, None)) for x in rng.random(count))
    if lists:
        resolved = table.changed(resolved, lists)
    return table.as_dict(resolved)


def value_within(p: Parameter, u: float, span: tuple[float, float] | None) -> Any:
    """The value at ``u`` (0 to 1) along ``p``'s scale, over its range or ``span``; a whole-number
    row takes each whole number of the span with the same chance (rounding a uniform number
    would give its two ends half the chance of the others)."""
    if p.kind == INT:
        lo, hi = (p.minimum, p.maximum) if span is None else (p.validate(x) for x in span)
        if lo > hi:
            raise ParameterError(f"parameter {p.name}: random range {show_value(span)} runs backwards; allowed: "
                                 f"low <= high, each {p.range_text()}")
        return int(lo + min(hi - lo, math.floor(u * (hi - lo + 1))))
    if p.kind in (CHOICE, BOOL) or span is None:
        if p.kind == FLOATS:
            lo, hi = p.minimum, p.maximum
            return math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo))) if p.scale == "log" \
                else lo + u * (hi - lo)
        return p.from_unit_interval(u)
    lo, hi = (p.validate(x) for x in span)
    if lo > hi:
        raise ParameterError(f"parameter {p.name}: random range {show_value(span)} runs backwards; allowed: "
                             f"low <= high, each {p.range_text()}")
    a, b = p.to_unit_interval(lo), p.to_unit_interval(hi)
    value = p.from_unit_interval(a + u * (b - a))
    return min(hi, max(lo, value))


def value_mutated(p: Parameter, value: Any, u: float, spread: float, rng: np.random.Generator) -> Any:
    """``value`` moved by up to ``spread`` of ``p``'s range on its scale (reflected at the ends);
    a choice or bool redrawn among the others with probability ``spread``."""
    if p.kind in (CHOICE, BOOL):
        options = p.choices if p.kind == CHOICE else (False, True)
        if u >= spread or len(options) < 2:
            return value
        others = [o for o in options if o != value]
        return others[int(rng.integers(len(others)))]
    x = p.to_unit_interval(value) + spread * (2.0 * u - 1.0)
    x = abs(x) % 2.0  # reflected into [0, 1]
    x = 2.0 - x if x > 1.0 else x
    return p.from_unit_interval(x)


def check_draw(model: Any, settings: Mapping[str, Any], *, sample_rate: float = 48000.0,
               render_s: float | None = None, seed: int | None = 0) -> Any | None:
    """``model``'s voice for ``settings`` at ``sample_rate`` (seeded ``seed``), ready to render as
    :meth:`Model.render` would; :class:`ParameterError` (or :class:`SamplesError`) where the model
    refuses them: the table's ranges, the model's joint checks when its voice is designed (first
    the cheap ``constraints`` the model declares next to its table, then :meth:`Model.voice` and
    :meth:`Model.check_renderable`) and, with ``render_s``, that many seconds rendered with finite
    samples (then None is returned: the voice has played)."""
    resolved = model.resolve(settings)
    for constraint in model.constraints:  # cheap, declared next to the table: before any design
        constraint(resolved, sample_rate)
    voice = model.voice(resolved, sample_rate=sample_rate, seed=seed)
    model.check_renderable(voice)
    if render_s:
        from ..models.rendering import render_voice

        render_voice(voice, render_s, normalize=False)  # checks every block (check_samples)
        return None
    return voice


@dataclass
class Draws:
    """What :func:`draw_items` gives: the accepted ``settings`` (one dict per item), how many
    draws were ``rejected`` for each item, and the refusals by reason (numbers blanked)."""

    settings: list[dict[str, Any]]
    rejected: list[int]
    reasons: collections.Counter = field(default_factory=collections.Counter)

    @property
    def rejected_count(self) -> int:
        return sum(self.rejected)


def reason_of(exc: Exception) -> str:
    """A refusal's message with its numbers blanked (``#``): refusals grouped by kind."""
    return re.sub(r"-?\d[\d.]*(e[+-]?\d+)?", "#", str(exc))


def valid_draw(model: Any, seed: int, index: int, **options: Any) -> tuple[dict[str, Any], int, list[str]]:
    """Item ``index``'s accepted settings, how many draws were refused before them, and why
    (see :func:`valid_draws` for ``options``)."""
    sample_rate = options.pop("sample_rate", 48000.0)
    render_s = options.pop("render_s", None)
    max_attempts = options.pop("max_attempts", MAX_ATTEMPTS)
    fixed = options.pop("fixed", None) or {}
    rng = item_rng(seed, index)
    reasons: list[str] = []
    for _ in range(max_attempts):
        settings = draw_settings(model, rng, **options)
        if fixed:
            settings = model.table.as_dict(model.table.changed(model.resolve(settings), fixed))
        try:
            check_draw(model, settings, sample_rate=sample_rate, render_s=render_s)
        except (ParameterError, SamplesError) as exc:
            reasons.append(reason_of(exc))
            continue
        return settings, len(reasons), reasons
    common = collections.Counter(reasons).most_common(1)[0][0]
    raise ParameterError(f"model {model.name}: {max_attempts} random settings (item {index} of seed {seed}) were "
                         f"all refused, most often: {common}; allowed: narrower ranges or another base")


def draw_items(model: Any, seed: int, count: int, **options: Any) -> Draws:
    """Items 0 to ``count - 1`` of the batch seeded ``seed``: see :func:`valid_draws`."""
    out = Draws([], [])
    for index in range(int(count)):
        settings, rejected, reasons = valid_draw(model, seed, index, **dict(options))
        out.settings.append(settings)
        out.rejected.append(rejected)
        out.reasons.update(reasons)
    return out


def valid_draws(model: Any, seed: int, count: int, **options: Any) -> tuple[list[dict[str, Any]], int]:
    """``count`` settings ``model`` accepts, and how many draws it refused on the way.

    Item ``i`` draws from :func:`item_rng` ``(seed, i)`` until the model accepts a set (at most
    ``max_attempts``, :data:`MAX_ATTEMPTS` by default; then ParameterError), so it is the same
    whether 5 or 50 items are asked for. ``options``: those of :func:`draw_settings` (``base``,
    ``spread``, ``names``, ``ranges``), ``fixed`` (values set on every draw after it is drawn,
    e.g. a coarse grid), ``sample_rate`` (Hz, 48000 by default) and ``render_s`` (seconds
    rendered to check the samples are finite; none by default).
    """
    draws = draw_items(model, seed, count, **options)
    return draws.settings, draws.rejected_count
