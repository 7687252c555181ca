"""A batch spec -> its items (spec 11.1): each item's index, resolved parameters and seed.

Item ``i`` depends only on the spec and ``i``: never on ``count``, on which items are made,
or on the worker that makes it. Its randomness comes from ``SeedSequence(seed).spawn(n)[i]``
for any ``n > i`` (``SeedSequence(seed, spawn_key=(i,))``): that sequence drives the item's
draws (:func:`~barsynth.batch.sampler.item_rng`), and the first word of its first child
(spawn key ``(i, 0)``) seeds the render (:attr:`Item.seed`). Grid parameters take
combination ``i mod N`` of their product (the last gridded parameter changes fastest), a list
takes value ``i mod len``, and random and mutated parameters are drawn in the order the spec
names them.

Drawn items are valid (spec 11.4): a set the model refuses (a declared joint constraint, or
its own checks when the voice is designed) is drawn again from the item's stream, at most
:data:`~barsynth.batch.sampler.MAX_ATTEMPTS` times, and :attr:`Item.rejected` counts the
refusals.

Examples
--------
>>> from barsynth.batch.spec import parse_spec
>>> spec = parse_spec('model = "twang"\\npreset = "plastic-30cm"\\ncount = 4\\nseed = 7\\n'
...                   '[vary.q]\\ngrid = [60, 100]\\n[vary.length_m]\\nrandom = [0.15, 0.4]')
>>> items = make_items(spec)
>>> [item.values["q"] for item in items]
[60.0, 100.0, 60.0, 100.0]
>>> all(0.15 <= item.values["length_m"] <= 0.4 for item in items)
True
>>> make_items(spec, start=3)[0] == items[3]
True
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import BarsynthError, BatchSpecError, ParameterError, SamplesError
from ..parameters import BOOL, CHOICE, Parameter
from .sampler import MAX_ATTEMPTS, check_draw, item_rng, value_mutated, value_within
from .spec import BatchSpec, Variation

__all__ = ["Item", "base_parameters", "designed_item", "draw_value", "item_rng", "item_seed", "make_item",
           "make_items"]


@dataclass(frozen=True)
class Item:
    """One item of a batch.

    ``index``: its place (0 first); ``seed``: the seed its render takes; ``values``: the
    varied parameters' values (name -> value, in the spec's order); ``parameters``: every
    parameter resolved through the model's table (name -> value, in the table's order);
    ``rejected``: the drawn sets the model refused before this one; ``error``: why the model
    refused every draw (empty when it accepted one).
    """

    index: int
    seed: int
    values: dict[str, Any]
    parameters: dict[str, Any]
    rejected: int = 0
    error: str = ""


def item_seed(seed: int, index: int) -> int:
    """The render seed of item ``index`` of a batch seeded ``seed``: a whole number below 2**32."""
    return int(np.random.SeedSequence(seed, spawn_key=(index, 0)).generate_state(1)[0])


def draw_value(row: Parameter, variation: Variation, base_value: Any, rng: np.random.Generator) -> Any:
    """One draw of ``row``'s value for a ``random`` or ``mutate`` variation.

    ``random``: a choice or bool picks one of ``variation.values``; a number is uniform on the
    row's scale (log for a log row) between ``variation.bounds``. ``mutate``: the ``base_value``
    (the preset's) moved uniformly by up to ``variation.spread`` of the range on the row's
    scale, reflected at the ends of the range. A whole-number row is rounded. (The sampler's
    own draws: :mod:`barsynth.batch.sampler`.)
    """
    if variation.kind == "random" and row.kind in (CHOICE, BOOL):
        return variation.values[int(rng.integers(len(variation.values)))]
    if variation.kind == "random":
        return value_within(row, rng.random(), variation.bounds)
    if variation.kind == "mutate":
        return value_mutated(row, base_value, rng.random(), variation.spread, rng)
    raise ValueError(f"{variation.kind} is not drawn")


def base_parameters(spec: BatchSpec) -> Any:
    """The record every item starts from: the spec's preset (or the model's defaults)."""
    from ..models import get_model

    model = get_model(spec.model)
    return model.preset(spec.preset) if spec.preset else model.resolve()


def make_item(spec: BatchSpec, index: int, *, base: Any = None) -> Item:
    """Item ``index`` of ``spec`` (``base``: :func:`base_parameters`, when already known)."""
    return designed_item(spec, index, base=base)[0]


def designed_item(spec: BatchSpec, index: int, *, base: Any = None) -> tuple[Item, Any]:
    """Item ``index`` of ``spec`` and, where its settings were drawn, the voice designed while
    checking them (ready to render, seeded :attr:`Item.seed`; else None: the render designs it).

    Without random or mutated parameters the item is its grid and list values over ``base``,
    unchecked (a setting the model refuses is reported when it is rendered). With them, sets are
    drawn from the item's stream until the model accepts one (:func:`~.sampler.check_draw` at the
    spec's sample rate); after :data:`~.sampler.MAX_ATTEMPTS` refusals the item carries the last
    refusal in ``error``.
    """
    from ..models import get_model

    model = get_model(spec.model)
    base = base_parameters(spec) if base is None else base
    fixed: dict[str, Any] = dict(_combination([v for v in spec.vary if v.kind == "grid"], index))
    for variation in spec.vary:
        if variation.kind == "list":
            fixed[variation.name] = variation.values[index % len(variation.values)]
    drawn = [v for v in spec.vary if v.kind in ("random", "mutate")]
    seed = item_seed(spec.seed, index)
    rng = item_rng(spec.seed, index)
    rejected = 0
    while True:
        values = {v.name: fixed[v.name] if v.name in fixed
                  else draw_value(model.table[v.name], v, getattr(base, v.name), rng) for v in spec.vary}
        item = Item(index=index, seed=seed, values=values, parameters=_resolved(spec, model.table, base, values, index),
                    rejected=rejected)
        if not drawn:
            return item, None
        try:
            return item, check_draw(model, item.parameters, sample_rate=spec.sample_rate, seed=seed)
        except (ParameterError, SamplesError) as exc:
            rejected += 1
            if rejected == MAX_ATTEMPTS:
                return replace(item, rejected=rejected, error=f"{MAX_ATTEMPTS} drawn settings were all refused, "
                                                              f"the last: {exc}"), None


def _resolved(spec: BatchSpec, table: Any, base: Any, values: dict[str, Any], index: int) -> dict[str, Any]:
    """Every parameter of ``base`` with ``values`` set, checked by the table, as a plain dict."""
    try:
        return table.as_dict(table.resolve(table.as_dict(base), values))
    except BarsynthError as exc:  # e.g. a material and its Young's modulus both varied
        raise BatchSpecError(f"{spec.source}: item {index}: {exc}") from None


def make_items(spec: BatchSpec, *, start: int = 0, stop: int | None = None) -> list[Item]:
    """Items ``start`` to ``stop`` (default: to ``spec.count``) of ``spec``, in order."""
    stop = spec.count if stop is None else min(stop, spec.count)
    base = base_parameters(spec)
    return [make_item(spec, i, base=base) for i in range(start, stop)]


def _combination(grid: list[Variation], index: int) -> dict[str, Any]:
    """The gridded values of item ``index``: combination ``index mod N`` of the product."""
    if not grid:
        return {}
    size = 1
    for v in grid:
        size *= len(v.values)
    k = index % size
    out: dict[str, Any] = {}
    for v in reversed(grid):  # the last changes fastest, as itertools.product
        k, j = divmod(k, len(v.values))
        out[v.name] = v.values[j]
    return out


def _product_order(grid: list[Variation]) -> list[dict[str, Any]]:
    """Every combination in order (the reference :func:`_combination` agrees with; for tests)."""
    return [dict(zip([v.name for v in grid], combo)) for combo in itertools.product(*(v.values for v in grid))]
