"""A batch spec -> its items (spec 11.1): each item's index, resolved parameters and seed.

Item ``i`` depends only on the spec and ``i``: never on ``count``, on which items are made,
or on the worker that makes it. Its randomness comes from
``numpy.random.SeedSequence(seed, spawn_key=(i,))``, the sequence that
``SeedSequence(seed).spawn(n)[i]`` is for any ``n > i``: its first word seeds the render
(:attr:`Item.seed`), a child of it (spawn key ``(i, 0)``) drives the item's draws. Grid
parameters take combination ``i mod N`` of their product (the last gridded parameter
changes fastest), a list takes value ``i mod len``, and random and mutated parameters are
drawn in the order the spec names them.

Random draws go through :func:`draw_value`, the one place that draws a value: the sampler of
valid sets (spec 11.4) takes over there.

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
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import BarsynthError, BatchSpecError
from ..parameters import BOOL, CHOICE, INT, Parameter
from .spec import BatchSpec, Variation

__all__ = ["Item", "base_parameters", "draw_value", "item_rng", "item_seed", "make_item", "make_items"]


@dataclass(frozen=True)
class Item:
    """One item of a batch.

    ``index``: its place (0 first); ``seed``: the seed its render takes; ``values``: the
    varied parameters' values (name -> value, in the spec's order); ``parameters``: every
    parameter resolved through the model's table (name -> value, in the table's order).
    """

    index: int
    seed: int
    values: dict[str, Any]
    parameters: dict[str, Any]


def item_seed(seed: int, index: int) -> int:
    """The render seed of item ``index`` of a batch seeded ``seed``: a whole number below 2**32."""
    return int(np.random.SeedSequence(seed, spawn_key=(index,)).generate_state(1)[0])


def item_rng(seed: int, index: int) -> np.random.Generator:
    """The generator of item ``index``'s draws (independent of its render seed)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index, 0)))


def draw_value(row: Parameter, variation: Variation, base_value: Any, rng: np.random.Generator) -> Any:
    """One draw of ``row``'s value for a ``random`` or ``mutate`` variation.

    ``random``: a choice or bool picks one of ``variation.values``; a number is uniform on
    the row's scale (log for a log row) between ``variation.bounds``. ``mutate``: the
    ``base_value`` (the preset's) moved uniformly by up to ``variation.spread`` of the range
    on the row's scale, clipped into the range. A whole-number row is rounded.
    """
    if variation.kind == "random" and row.kind in (CHOICE, BOOL):
        return variation.values[int(rng.integers(len(variation.values)))]
    if variation.kind == "random":
        low, high = (row.to_unit_interval(b) for b in variation.bounds)
        u = low + (high - low) * rng.random()
    elif variation.kind == "mutate":
        u = row.to_unit_interval(base_value) + variation.spread * (2.0 * rng.random() - 1.0)
    else:
        raise ValueError(f"{variation.kind} is not drawn")
    value = row.from_unit_interval(u)
    if variation.kind == "random" and row.kind != INT:  # (no rounding drift outside the bounds)
        value = min(variation.bounds[1], max(variation.bounds[0], value))
    return value


def base_parameters(spec: BatchSpec) -> Any:
    """The record every item starts from: the spec's preset (or the model's defaults)."""
    from ..models import get_model

    model = get_model(spec.model)
    return model.preset(spec.preset) if spec.preset else model.resolve()


def make_item(spec: BatchSpec, index: int, *, base: Any = None) -> Item:
    """Item ``index`` of ``spec`` (``base``: :func:`base_parameters`, when already known)."""
    from ..models import get_model

    table = get_model(spec.model).table
    base = base_parameters(spec) if base is None else base
    grid = [v for v in spec.vary if v.kind == "grid"]
    combination = _combination(grid, index)
    rng = item_rng(spec.seed, index)
    values: dict[str, Any] = {}
    for variation in spec.vary:
        if variation.kind == "grid":
            values[variation.name] = combination[variation.name]
        elif variation.kind == "list":
            values[variation.name] = variation.values[index % len(variation.values)]
        else:
            values[variation.name] = draw_value(table[variation.name], variation,
                                                getattr(base, variation.name), rng)
    try:
        record = table.resolve(table.as_dict(base), values)
    except BarsynthError as exc:  # e.g. a material and its Young's modulus both varied
        raise BatchSpecError(f"{spec.source}: item {index}: {exc}") from None
    return Item(index=index, seed=item_seed(spec.seed, index), values=values, parameters=table.as_dict(record))


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
