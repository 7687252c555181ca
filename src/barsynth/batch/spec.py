"""A batch spec (spec 11.1): which model and preset, how many items, the seed, and how each
varied parameter varies.

A spec is a TOML file::

    model = "twang"
    preset = "plastic-30cm"
    count = 1000
    seed = 7
    sample_rate = 48000        # Hz (default 48000)
    duration_s = "auto"        # or seconds (default "auto")
    format = "wav"             # "wav" or "flac" (default "wav")
    [vary.length_m]
    random = [0.15, 0.4]       # uniform on the table's scale (log for a log row), within these bounds
    [vary.q]
    grid = [60, 100, 200, 400] # the gridded parameters' product, in a fixed order
    [vary.gain_mapping]
    list = ["linear", "log"]  # item i takes value i mod 2
    [vary.shape]
    mutate = 0.2               # the preset's value +- 0.2 of the range (on its scale), clipped

Each ``[vary.NAME]`` holds exactly one of ``grid``, ``list``, ``random`` or ``mutate``. A
choice or bool parameter takes ``random = true`` (any of its values) or a list of the values
to draw from; ``mutate`` is for numbers only. Every value is checked against the model's
parameter table when the spec is read; a refusal is one line naming the file, the key, the
value and what is allowed (:class:`~barsynth.errors.BatchSpecError`).

Examples
--------
>>> spec = parse_spec('''
... model = "twang"
... preset = "plastic-30cm"
... count = 8
... seed = 7
... [vary.q]
... grid = [60, 100]
... [vary.length_m]
... random = [0.15, 0.4]
... ''', source="demo.toml")
>>> spec.count, spec.seed, [(v.name, v.kind) for v in spec.vary]
(8, 7, [('q', 'grid'), ('length_m', 'random')])
>>> spec.vary[0].values, spec.vary[1].bounds
((60.0, 100.0), (0.15, 0.4))
>>> parse_spec('model = "twang"\\ncount = 2\\nseed = 1\\n[vary.q]\\ngrid = [10]', source="bad.toml")
Traceback (most recent call last):
...
barsynth.errors.BatchSpecError: bad.toml: vary.q.grid value 1 = 10 is not allowed: parameter q = 10 is out of range; allowed: 50 to 800 dimensionless
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..checks import show_text, show_value
from ..errors import BarsynthError, BatchSpecError
from ..parameters import BOOL, CHOICE, FLOATS, Parameter
from ..studio.presets_file import toml_value

__all__ = ["KINDS", "MAX_COUNT", "BatchSpec", "Variation", "load_spec", "parse_spec", "spec_toml"]

KINDS = ("grid", "list", "random", "mutate")
FORMATS = ("wav", "flac")
MAX_COUNT = 1_000_000  # the manifest is held in memory and rewritten as items finish (docs/batch.md)
MAX_SEED = 2**63 - 1
_TOP_KEYS = ("model", "preset", "count", "seed", "sample_rate", "duration_s", "format", "vary")


@dataclass(frozen=True)
class Variation:
    """How one parameter varies across the items.

    ``kind`` is one of :data:`KINDS`. ``values``: the validated values of a ``grid`` or
    ``list`` (or, for a choice or bool drawn at random, the values drawn from); ``bounds``: a
    numeric ``random``'s (low, high) in the parameter's unit; ``spread``: a ``mutate``'s
    half-width as a fraction of the range on the parameter's scale.
    """

    name: str
    kind: str
    values: tuple[Any, ...] = ()
    bounds: tuple[float, float] | None = None
    spread: float = 0.0


@dataclass(frozen=True)
class BatchSpec:
    """A read and checked batch spec (see the module's docstring); ``source`` names its file."""

    model: str
    preset: str | None
    count: int
    seed: int
    sample_rate: float
    duration_s: float | str
    format: str
    vary: tuple[Variation, ...]
    source: str = "<spec>"

    @property
    def grid_size(self) -> int:
        """The number of combinations of the gridded parameters (1 without any)."""
        return math.prod(len(v.values) for v in self.vary if v.kind == "grid")


def load_spec(path: Any) -> BatchSpec:
    """Read and check the batch spec at ``path`` (see :func:`parse_spec`)."""
    shown = show_text(str(path))
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise BatchSpecError(f"cannot read batch spec {shown}: {getattr(exc, 'strerror', None) or exc}") from None
    return parse_spec(text, source=shown)


def parse_spec(text: str, *, source: str = "<spec>") -> BatchSpec:
    """A batch spec from TOML ``text``; ``source`` names it in every message."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise BatchSpecError(f"{source}: not valid TOML: {exc}") from None
    return _Reader(source).read(doc)


def spec_toml(spec: BatchSpec) -> str:
    """``spec`` as TOML text that :func:`parse_spec` reads back to the same spec (its source aside).

    >>> spec = parse_spec('model = "twang"\\ncount = 3\\nseed = 1\\n[vary.q]\\ngrid = [60, 100]\\n')
    >>> print(spec_toml(spec))
    model = "twang"
    count = 3
    seed = 1
    sample_rate = 48000.0
    duration_s = "auto"
    format = "wav"
    <BLANKLINE>
    [vary.q]
    grid = [60.0, 100.0]
    <BLANKLINE>
    >>> parse_spec(spec_toml(spec)) == spec
    True
    """
    lines = [f"model = {toml_value(spec.model)}"]
    if spec.preset is not None:
        lines.append(f"preset = {toml_value(spec.preset)}")
    lines += [f"{key} = {toml_value(getattr(spec, key))}" for key in ("count", "seed", "sample_rate", "duration_s", "format")]
    for v in spec.vary:
        value = {"grid": v.values, "list": v.values, "mutate": v.spread}[v.kind] if v.kind != "random" \
            else (v.values if v.bounds is None else v.bounds)
        lines += ["", f"[vary.{v.name}]", f"{v.kind} = {toml_value(value)}"]
    return "\n".join(lines) + "\n"


class _Reader:
    """One reading of a spec: every refusal names ``source``."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, value: Any, allowed: str) -> BatchSpecError:
        return BatchSpecError(f"{self.source}: {key} = {show_value(value)} is not allowed; allowed: {allowed}")

    def read(self, doc: dict[str, Any]) -> BatchSpec:
        from ..models import get_model, model_names

        for key in doc:
            if key not in _TOP_KEYS:
                raise BatchSpecError(f"{self.source}: unknown key {show_value(key)}; allowed: {', '.join(_TOP_KEYS)}")
        if "model" not in doc:
            raise BatchSpecError(f"{self.source}: no model; allowed: one of {', '.join(model_names())}")
        name = doc["model"]
        if not isinstance(name, str) or name not in model_names():
            raise self.fail("model", name, "one of " + ", ".join(model_names()))
        model = get_model(name)
        preset = doc.get("preset")
        if preset is not None and (not isinstance(preset, str) or preset not in model.presets):
            raise self.fail("preset", preset, f"one of {', '.join(model.presets)} (the {name} presets)")
        count = self.whole(doc, "count", 1, MAX_COUNT, required=True)
        seed = self.whole(doc, "seed", 0, MAX_SEED, required=True)
        sample_rate, duration_s = self.rendering(doc)
        fmt = doc.get("format", "wav")
        if fmt not in FORMATS:
            raise self.fail("format", fmt, " or ".join(FORMATS))
        vary = doc.get("vary", {})
        if not isinstance(vary, dict):
            raise self.fail("vary", vary, "a table of [vary.NAME] tables")
        variations = tuple(self.variation(model.table, pname, entry) for pname, entry in vary.items())
        self.no_clash(model.table, variations)
        return BatchSpec(model=name, preset=preset, count=count, seed=seed, sample_rate=sample_rate,
                         duration_s=duration_s, format=fmt, vary=variations, source=self.source)

    def whole(self, doc: dict[str, Any], key: str, low: int, high: int, *, required: bool) -> int:
        if key not in doc:
            if required:
                raise BatchSpecError(f"{self.source}: no {key}; allowed: a whole number from {low} to {high}")
            return low
        value = doc[key]
        if type(value) is not int or not low <= value <= high:
            raise self.fail(key, value, f"a whole number from {low} to {high}")
        return value

    def rendering(self, doc: dict[str, Any]) -> tuple[float, float | str]:
        from ..models.rendering import check_render_duration, check_sample_rate

        out = []
        for key, default, check in (("sample_rate", 48000, check_sample_rate),
                                    ("duration_s", "auto", check_render_duration)):
            value = doc.get(key, default)
            try:
                out.append(check(value))
            except BarsynthError as exc:
                raise self.fail(key, value, str(exc).partition("allowed: ")[2] or str(exc)) from None
        return out[0], out[1]

    def variation(self, table: Any, name: str, entry: Any) -> Variation:
        key = f"vary.{name}"
        if name not in table:
            raise BatchSpecError(f"{self.source}: {key}: unknown parameter {show_value(name)} for model "
                                 f"{table.model}; known: {', '.join(table.names)}")
        row: Parameter = table[name]
        if row.data:
            raise BatchSpecError(f"{self.source}: {key}: {name} holds data, not a control; allowed: "
                                 f"a control of {table.model}")
        if not isinstance(entry, dict) or len(entry) != 1 or next(iter(entry)) not in KINDS:
            shown = sorted(entry) if isinstance(entry, dict) else entry
            raise self.fail(key, shown, "a table with exactly one of " + ", ".join(KINDS))
        kind, value = next(iter(entry.items()))
        key = f"{key}.{kind}"
        if kind in ("grid", "list"):
            if not isinstance(value, list) or not value:
                raise self.fail(key, value, f"a non-empty list of values of {name} ({row.range_text()})")
            return Variation(name, kind, values=tuple(self.value(row, key, i, v) for i, v in enumerate(value, 1)))
        if row.kind == FLOATS:
            raise self.fail(key, value, f"grid or list for {name}, a list parameter (random and mutate "
                                        "take one number)")
        if kind == "random":
            if row.kind in (CHOICE, BOOL):
                every = row.choices if row.kind == CHOICE else (False, True)
                if value is True:
                    return Variation(name, kind, values=tuple(every))
                if not isinstance(value, list) or not value:
                    raise self.fail(key, value, f"true (any of {row.range_text()}) or a list of the values to draw from")
                return Variation(name, kind, values=tuple(self.value(row, key, i, v) for i, v in enumerate(value, 1)))
            if not (isinstance(value, list) and len(value) == 2):
                raise self.fail(key, value, f"[low, high] within {row.range_text()}")
            low, high = (self.value(row, key, i, v) for i, v in enumerate(value, 1))
            if low > high:
                raise self.fail(key, value, f"[low, high] with low <= high, within {row.range_text()}")
            return Variation(name, kind, bounds=(float(low), float(high)))
        # mutate
        if row.kind in (CHOICE, BOOL):
            raise self.fail(key, value, f"grid, list or random for {name} ({row.range_text()}); mutate is for numbers")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 < value <= 1.0:
            raise self.fail(key, value, "a fraction of the range, above 0 and at most 1")
        return Variation(name, kind, spread=float(value))

    def no_clash(self, table: Any, variations: tuple[Variation, ...]) -> None:
        """Refuse a choice that sets other parameters (a material: its modulus and density)
        varied together with one of them, where a value it can take sets it: every such item
        would be refused when it is made (mid-run, in a worker)."""
        varied = {v.name for v in variations}
        for v in variations:
            row = table[v.name]
            if row.sets is None:
                continue
            clash = sorted(set(row.sets.names) & varied)
            setting = [x for x in v.values if row.sets.values(x, row.default)]
            if clash and setting:
                raise BatchSpecError(f"{self.source}: vary.{v.name} and vary.{clash[0]}: {v.name} = "
                                     f"{show_value(setting[0])} sets {' and '.join(clash)}; allowed: vary one of "
                                     f"them (or {v.name} = {show_value(row.default)} only)")

    def value(self, row: Parameter, key: str, position: int, value: Any) -> Any:
        try:
            return row.validate(value)
        except BarsynthError as exc:
            raise BatchSpecError(f"{self.source}: {key} value {position} = {show_value(value)} is not allowed: "
                                 f"{exc}") from None
