"""Parameter tables: the single description of a model's controls.

One :class:`ParameterTable` per model drives validation, the CLI's ``--set``
options and ``params`` listing, preset checks, (later) web sliders and the docs.
Nothing else in barsynth keeps a second copy of a range, default or unit.

A table also builds the model's frozen parameter dataclass, so resolved
parameters read as attributes (``p.length_m``) and cannot be changed in place.
"""

from __future__ import annotations

import dataclasses
import math
import operator
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from .checks import show_value
from .errors import ParameterError

FLOAT = "float"
INT = "int"
BOOL = "bool"
CHOICE = "choice"
FLOATS = "floats"  # a list of numbers, each within [minimum, maximum]

_COMPARISONS = {"<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge}
_COUNT_WORDS = {"<": ("fewer values than", "fewer than"), "<=": ("at most as many values as", "at most"),
                ">": ("more values than", "more than"), ">=": ("at least as many values as", "at least")}


@dataclass(frozen=True)
class Compare:
    """A condition of a row's ``when`` on a number: the parameter it is keyed by, ``op`` (one of
    ``<``, ``<=``, ``>``, ``>=``) ``than``, a number or the name of another parameter of the table.

    With ``count`` the parameter is a list and its number of values is compared; a list named by
    ``than`` counts its values too. ``{"vibrato_rate_hz": Compare(">", 0.0)}``: acts only while
    the vibrato runs; ``{"mode_t60s_s": Compare("<", "mode_count", count=True)}``: only while
    some mode has no T60 of its own.
    """

    op: str
    than: float | str
    count: bool = False

    def __post_init__(self) -> None:
        if self.op not in _COMPARISONS:
            raise ValueError(f"unknown comparison {self.op!r}; allowed: one of {', '.join(_COMPARISONS)}")
        if not isinstance(self.than, str) and (isinstance(self.than, bool) or not (
                isinstance(self.than, (int, float)) and math.isfinite(self.than))):
            raise ValueError(f"a comparison is with a finite number or a parameter's name, not {self.than!r}")

    def holds(self, value: Any, resolved: Any) -> bool:
        """Whether ``value`` (the keyed parameter's, under ``resolved``) passes the comparison."""
        other = getattr(resolved, self.than) if isinstance(self.than, str) else self.than
        left = len(value) if self.count else value
        right = len(other) if isinstance(other, tuple) else other
        return _COMPARISONS[self.op](left, right)

    def text(self, name: str) -> str:
        """``vibrato_rate_hz > 0``, ``mode_t60s_s has fewer values than mode_count``: in words."""
        than = self.than if isinstance(self.than, str) else _fmt(self.than)
        if not self.count:
            return f"{name} {self.op} {than}"
        with_name, with_number = _COUNT_WORDS[self.op]
        return f"{name} has {with_name} {than}" if isinstance(self.than, str) else \
            f"{name} has {with_number} {than} values"

    def to_json(self) -> dict[str, Any]:
        return {"op": self.op, "than": self.than, "count": self.count}


@dataclass(frozen=True)
class Sets:
    """What choosing a value of a choice parameter sets: the parameters ``names``, to the values
    ``lookup(choice)`` gives in that order (nothing for the parameter's default)."""

    names: tuple[str, ...]
    lookup: Any  # Callable[[str], tuple[Any, ...]]

    def values(self, choice: str, default: str) -> dict[str, Any]:
        return {} if choice == default else dict(zip(self.names, self.lookup(choice)))


_TRUE_WORDS = {"1", "true", "yes", "on"}
_FALSE_WORDS = {"0", "false", "no", "off"}


@dataclass(frozen=True)
class Parameter:
    """One control of a model.

    ``scale`` is ``"linear"`` or ``"log"``: how a slider (or a random draw)
    spreads over the range. ``kind`` is ``float``, ``int``, ``bool``,
    ``choice`` or ``floats``; a choice parameter lists its ``choices`` and keeps
    ``minimum`` and ``maximum`` as ``None``; a floats parameter is a tuple of at
    most ``max_items`` numbers, each within ``[minimum, maximum]`` (written
    ``1,4,10`` on the command line, a list in TOML or JSON).

    ``when`` says under which settings the parameter acts at all: elsewhere it has no effect (the
    CLI warns, the studio greys it out). It maps names of other parameters to a condition each,
    all of which must hold: a tuple of values of a choice or bool (``{"excitation": ("bow",)}``:
    the parameter holds one of them), or a :class:`Compare` of a number or of a list's length
    (``{"vibrato_rate_hz": Compare(">", 0.0)}``). A list of such mappings says the parameter acts
    when any one of them holds. Kept as :attr:`when`: a tuple of those clauses, each a tuple of
    ``(name, condition)`` pairs in the order given (empty: the parameter always acts).
    ``sets``, for a choice, maps a chosen value to the other parameters it sets (a
    ``material`` sets Young's modulus and density); see :meth:`ParameterTable.resolve`.
    ``data`` marks a row that holds data rather than a control (a recorded attack's thousands
    of samples, the rate they were recorded at): presets, ``--set``, validation and the docs
    take it as any row, but the studio draws no control for it (it keeps and sends its value)
    and listings show it briefly (:meth:`shown`: ``(4800 values)``).
    """

    name: str
    unit: str
    minimum: float | None
    maximum: float | None
    default: Any
    doc: str
    scale: str = "linear"
    kind: str = FLOAT
    choices: tuple[str, ...] = ()
    max_items: int = 0
    when: Any = ()
    sets: Any = None
    data: bool = False

    def __post_init__(self) -> None:
        # ``when``: kept as a tuple of clauses of pairs, so the record stays hashable.
        clauses = [self.when] if isinstance(self.when, Mapping) else list(self.when)
        if not all(isinstance(clause, Mapping) for clause in clauses):
            raise ValueError(f"{self.name}: when must be a mapping or a list of mappings")
        object.__setattr__(self, "when", tuple(
            tuple((name, c if isinstance(c, Compare) else tuple(c)) for name, c in clause.items())
            for clause in clauses if clause))
        if self.kind not in (FLOAT, INT, BOOL, CHOICE, FLOATS):
            raise ValueError(f"{self.name}: unknown kind {self.kind!r}")
        if self.scale not in ("linear", "log"):
            raise ValueError(f"{self.name}: unknown scale {self.scale!r}")
        if self.kind == CHOICE:
            if self.default not in self.choices:
                raise ValueError(f"{self.name}: default not among choices")
        elif self.kind == BOOL:
            if not isinstance(self.default, bool):
                raise ValueError(f"{self.name}: bool parameter needs a bool default")
        elif self.kind == FLOATS:
            if not (isinstance(self.default, tuple) and self.max_items >= len(self.default)
                    and all(self.minimum <= x <= self.maximum for x in self.default)):
                raise ValueError(f"{self.name}: floats default must be a tuple within the range")
        else:
            assert self.minimum is not None and self.maximum is not None
            if not self.minimum <= self.default <= self.maximum:
                raise ValueError(f"{self.name}: default outside its range")
            if self.scale == "log" and self.minimum <= 0:
                raise ValueError(f"{self.name}: a log scale needs a positive minimum")

    # -- describing ---------------------------------------------------------------
    @property
    def unit_label(self) -> str:
        """The unit as shown to people (``dimensionless`` when there is none)."""
        return self.unit or "dimensionless"

    def range_text(self) -> str:
        """The allowed values in words, with the unit."""
        if self.kind == CHOICE:
            return "one of " + ", ".join(self.choices)
        if self.kind == BOOL:
            return "true or false"
        if self.kind == FLOATS:
            return (f"a list of up to {self.max_items} values, each {_fmt(self.minimum)} to "
                    f"{_fmt(self.maximum)} {self.unit_label}")
        return f"{_fmt(self.minimum)} to {_fmt(self.maximum)} {self.unit_label}"

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready description (``name, unit, min, max, default, doc`` and more)."""
        return {
            "name": self.name,
            "unit": self.unit,
            "min": self.minimum,
            "max": self.maximum,
            "default": list(self.default) if self.kind == FLOATS else self.default,
            "doc": self.doc,
            "scale": self.scale,
            "kind": self.kind,
            "choices": list(self.choices) if self.kind == CHOICE else None,
            "max_items": self.max_items if self.kind == FLOATS else None,
            "when": self._when_json(),
            "when_text": self.when_text() or None,
            "sets": None if self.sets is None else {
                "names": list(self.sets.names),
                "values": {c: list(self.sets.values(c, self.default).values()) for c in self.choices
                           if c != self.default}},
            "data": self.data,
        }

    def shown(self, value: Any) -> str:
        """A value as listings show it: ``0.3``, ``6.9e+10``, ``1,4,10`` (a list), ``-`` (an empty
        one); a data row's list by its count, ``(4800 values)``."""
        if isinstance(value, tuple):
            if self.data:
                return f"({len(value)} values)"
            return ",".join(f"{x:g}" for x in value) or "-"
        return f"{value:g}" if isinstance(value, float) else str(value)

    def _when_json(self) -> Any:
        """``when`` for the studio: None, one clause (``{"excitation": ["bow"]}``, a comparison
        as ``{"op", "than", "count"}``) or a list of clauses (any one of which must hold)."""
        clauses = [{name: c.to_json() if isinstance(c, Compare) else list(c) for name, c in clause}
                   for clause in self.when]
        return None if not clauses else clauses[0] if len(clauses) == 1 else clauses

    @property
    def reads(self) -> tuple[str, ...]:
        """The other parameters ``when`` reads (sorted): a change of one may turn this one on or off."""
        return tuple(sorted({name for clause in self.when for name, _ in clause}
                            | {c.than for clause in self.when for _, c in clause
                               if isinstance(c, Compare) and isinstance(c.than, str)}))

    def acts_under(self, resolved: Any) -> bool:
        """Whether this parameter has any effect with the other parameters at ``resolved``."""
        return not self.when or any(all(_holds(getattr(resolved, name), c, resolved) for name, c in clause)
                                    for clause in self.when)

    def when_text(self) -> str:
        """``excitation = bow``, ``vibrato_rate_hz > 0``, ``tuning = physics and ..., or ...``: the
        settings under which the parameter acts, in words."""
        return ", or ".join(" and ".join(c.text(name) if isinstance(c, Compare)
                                         else f"{name} = {' or '.join(_word(v) for v in c)}" for name, c in clause)
                            for clause in self.when)

    # -- validating -----------------------------------------------------------------
    def validate(self, value: Any) -> Any:
        """Return ``value`` converted to this parameter's type, or raise ParameterError.

        Strings (from the CLI, a URL or a form) are parsed; numbers must be finite
        and inside ``[minimum, maximum]``.
        """
        if self.kind == CHOICE:
            text = str(value).strip().lower()
            if text not in self.choices:
                raise self._error(value)
            return text
        if self.kind == BOOL:
            if isinstance(value, bool):
                return value
            if isinstance(value, (int, float)) and value in (0, 1):
                return bool(value)
            text = str(value).strip().lower()
            if text in _TRUE_WORDS:
                return True
            if text in _FALSE_WORDS:
                return False
            raise self._error(value)
        if self.kind == FLOATS:
            return self._validate_floats(value)
        number = self._to_number(value)
        assert self.minimum is not None and self.maximum is not None
        if not self.minimum <= number <= self.maximum:
            raise self._error(value)
        if self.kind == INT:
            if number != int(number):
                raise ParameterError(
                    f"parameter {self.name} = {show_value(value)} must be a whole number "
                    f"from {self.range_text()}"
                )
            return int(number)
        return float(number)

    def _validate_floats(self, value: Any) -> tuple[float, ...]:
        if isinstance(value, tuple) and len(value) <= self.max_items and all(type(x) is float for x in value):
            # a record's own list (every change re-validates the whole record): checked at once,
            # item by item below only for the message when it is refused
            import numpy as np

            numbers = np.array(value, dtype=np.float64)
            if np.all(np.isfinite(numbers) & (numbers >= self.minimum) & (numbers <= self.maximum)):
                return value
        if isinstance(value, str):
            items: list[Any] = [part for part in value.replace(" ", "").split(",") if part] \
                if value.strip() else []
        elif isinstance(value, (list, tuple)):
            items = list(value)
        else:
            raise ParameterError(f"parameter {self.name} = {show_value(value)} is not a list; allowed: "
                                 f"{self.range_text()}")
        if len(items) > self.max_items:
            raise ParameterError(f"parameter {self.name} has {len(items)} values; allowed: "
                                 f"{self.range_text()}")
        out = []
        for position, item in enumerate(items, start=1):
            number = self._to_number(item, position)
            assert self.minimum is not None and self.maximum is not None
            if not self.minimum <= number <= self.maximum:
                raise ParameterError(f"parameter {self.name}: value {position} = {show_value(item)} is out of range; "
                                     f"allowed: {self.range_text()}")
            out.append(number)
        return tuple(out)

    def _to_number(self, value: Any, position: int | None = None) -> float:
        """``value`` (a number, or text holding one) as a finite float, or ParameterError;
        ``position``: which item of a list it is (for the message)."""
        which = self.name if position is None else f"{self.name}: value {position}"
        if isinstance(value, bool):
            raise self._error(value)
        try:
            number = float(value) if isinstance(value, (int, float)) else float(str(value).strip())
        except OverflowError:  # an int beyond float range: out of every range
            return math.inf
        except ValueError:
            raise ParameterError(
                f"parameter {which} = {show_value(value)} is not a number; allowed: {self.range_text()}"
            ) from None
        if not math.isfinite(number):
            raise ParameterError(
                f"parameter {which} = {show_value(value)} is not a finite number; allowed: {self.range_text()}"
            )
        return number

    def _error(self, value: Any) -> ParameterError:
        return ParameterError(
            f"parameter {self.name} = {show_value(value)} is out of range; "
            f"allowed: {self.range_text()}"
        )

    # -- sliders and random draws --------------------------------------------------
    def to_unit_interval(self, value: float) -> float:
        """Map a value to [0, 1] along the parameter's scale (for sliders)."""
        assert self.kind != FLOATS, "a list has no slider"
        assert self.minimum is not None and self.maximum is not None
        if self.scale == "log":
            lo, hi = math.log(self.minimum), math.log(self.maximum)
            return (math.log(value) - lo) / (hi - lo)
        return (value - self.minimum) / (self.maximum - self.minimum)

    def from_unit_interval(self, u: float) -> Any:
        """Inverse of :meth:`to_unit_interval`, clipped into the range."""
        u = min(1.0, max(0.0, float(u)))
        if self.kind == CHOICE:
            return self.choices[min(len(self.choices) - 1, int(u * len(self.choices)))]
        if self.kind == BOOL:
            return u >= 0.5
        if self.kind == FLOATS:
            return self.default  # a list has no slider; a random draw keeps it
        assert self.minimum is not None and self.maximum is not None
        if self.scale == "log":
            lo, hi = math.log(self.minimum), math.log(self.maximum)
            value = math.exp(lo + u * (hi - lo))
        else:
            value = self.minimum + u * (self.maximum - self.minimum)
        value = min(self.maximum, max(self.minimum, value))
        return int(round(value)) if self.kind == INT else value


def _fmt(x: float | None) -> str:
    if x is None:
        return "?"
    return f"{x:g}"


_FIELD_TYPES = {FLOAT: "float", INT: "int", BOOL: "bool", CHOICE: "str", FLOATS: "tuple[float, ...]"}


class ParameterTable:
    """An ordered collection of :class:`Parameter` for one model.

    ``record``: the model's typed, frozen, keyword-only dataclass of resolved parameters
    (``p.length_m`` reads as a float in an editor), checked here against the table: the same
    names in the same order, each annotated with its kind's type (``float``, ``int``,
    ``bool``, ``str`` for a choice, ``tuple[float, ...]`` for a list), and a field with a
    default has its row's. Without one, a dataclass of untyped fields is made from the table.
    :func:`table_of` finds the table of a record.
    """

    def __init__(self, model: str, parameters: Iterable[Parameter], *, record: type | None = None):
        self.model = model
        self.parameters: tuple[Parameter, ...] = tuple(parameters)
        self._by_name = {p.name: p for p in self.parameters}
        if len(self._by_name) != len(self.parameters):
            raise ValueError(f"{model}: duplicate parameter names")
        if record is None:
            fields = [(p.name, Any, dataclasses.field(default=p.default)) for p in self.parameters]
            cls_name = "".join(part.capitalize() for part in model.replace("-", "_").split("_"))
            record = dataclasses.make_dataclass(cls_name + "Parameters", fields, frozen=True, kw_only=True)
            record.__doc__ = f"Resolved parameters of the {model} model (see its table)."
        else:
            self._check_record(record)
        self.dataclass = record
        _TABLES[record] = self
        for p in self.parameters:
            for name, condition in (pair for clause in p.when for pair in clause):
                if not self._can_take(name, condition):
                    raise ValueError(f"{model}: {p.name} acts when {name} is {condition}, not a value it takes")

    def _can_take(self, name: str, condition: Any) -> bool:
        """Whether parameter ``name`` can meet ``condition`` of a ``when``: a choice's or bool's
        values, or a comparison of a number (of a list's length with ``count``) with a number or
        with another number or list of the table."""
        row = self._by_name.get(name)
        if row is None:
            return False
        if not isinstance(condition, Compare):
            return row.kind in (CHOICE, BOOL) and all(v in (row.choices or (True, False)) for v in condition)
        compared = row.kind == FLOATS if condition.count else row.kind in (FLOAT, INT)
        if not isinstance(condition.than, str):
            return compared
        other = self._by_name.get(condition.than)
        return compared and other is not None and other.kind in (FLOAT, INT, FLOATS)

    def _check_record(self, record: type) -> None:
        params = getattr(record, "__dataclass_params__", None)
        if params is None or not params.frozen:
            raise TypeError(f"{self.model}: {record.__name__} must be a frozen dataclass")
        fields = dataclasses.fields(record)
        names = tuple(f.name for f in fields)
        if names != self.names:
            raise TypeError(f"{self.model}: {record.__name__} has fields {names}, the table {self.names}")
        for f, p in zip(fields, self.parameters):
            if not f.kw_only:
                raise TypeError(f"{self.model}: {record.__name__}.{f.name} must be keyword-only")
            typed = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type))
            if typed != _FIELD_TYPES[p.kind]:
                raise TypeError(f"{self.model}: {record.__name__}.{f.name} is annotated {typed!r}; "
                                f"its table row ({p.kind}) needs {_FIELD_TYPES[p.kind]!r}")
            if f.default_factory is not dataclasses.MISSING or (
                    f.default is not dataclasses.MISSING and f.default != p.default):
                shown = "a default factory" if f.default is dataclasses.MISSING else f"default {f.default!r}"
                raise TypeError(f"{self.model}: {record.__name__}.{f.name} has {shown}; its table row's default "
                                f"is {p.default!r} (give none, or the row's)")

    def __iter__(self):
        return iter(self.parameters)

    def __len__(self) -> int:
        return len(self.parameters)

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def index(self, name: str) -> int:
        """The row of parameter ``name`` (for a kernel's parameter vector: indices come from here)."""
        return self.names.index(self[name].name)

    def __getitem__(self, name: str) -> Parameter:
        try:
            return self._by_name[name]
        except KeyError:
            raise ParameterError(
                f"unknown parameter {show_value(name)} for model {self.model}; "
                f"known: {', '.join(self.names)}"
            ) from None

    def defaults(self) -> dict[str, Any]:
        return {p.name: p.default for p in self.parameters}

    def validate(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """Validate a partial mapping; return it converted (unknown names raise)."""
        return {name: self[name].validate(value) for name, value in values.items()}

    def resolve(self, *layers: Mapping[str, Any] | None) -> Any:
        """Defaults, overridden by each mapping in turn, validated, as the frozen dataclass.

        A choice with ``sets`` (a ``material``) sets its parameters when chosen; giving one of
        them other values in the same mapping is refused, and giving one in a later mapping (a
        ``--set`` on top of a preset) turns the choice back to its default (``custom``).
        """
        merged = self.defaults()
        for layer in layers:
            if not layer:
                continue
            values = self.validate(layer)
            for p in self.parameters:
                if p.sets is None:
                    continue
                implied = p.sets.values(values[p.name], p.default) if p.name in values else {}
                clash = sorted(name for name in set(implied) & set(values) if values[name] != implied[name])
                if clash:
                    raise ParameterError(
                        f"parameter {p.name} = {values[p.name]} sets {' and '.join(clash)}; allowed: "
                        f"either {p.name} or {' and '.join(clash)}, not both")
                if p.name not in values:  # one of its parameters given by hand, other than it sets: custom
                    chosen = p.sets.values(merged[p.name], p.default)
                    if any(values[n] != chosen.get(n) for n in set(p.sets.names) & set(values)):
                        values[p.name] = p.default
                values.update(implied)
            merged.update(values)
        return self.dataclass(**merged)

    def settings_at(self, units: Mapping[str, float]) -> dict[str, Any]:
        """The settings at a point of the unit cube (``{name: u}``, u in [0, 1], each along its
        parameter's scale): for sliders and random draws. A parameter that a chosen ``sets``
        value (a material) already sets is left out."""
        values = {name: self[name].from_unit_interval(u) for name, u in units.items()}
        for p in self.parameters:
            if p.sets is not None and values.get(p.name, p.default) != p.default:
                for name in p.sets.names:
                    values.pop(name, None)
        return values

    def inactive(self, resolved: Any, names: Iterable[str] | None = None) -> list[tuple[str, str]]:
        """``(name, when)`` for each parameter (of ``names``, by default all) that has no effect
        under ``resolved``: e.g. ``("bow_force_n", "excitation = bow")``."""
        chosen = self.names if names is None else names
        return [(name, self[name].when_text()) for name in chosen
                if not self[name].acts_under(resolved)]

    def changed(self, resolved: Any, values: Mapping[str, Any]) -> Any:
        """``resolved`` with ``values`` changed on top (a material chosen now sets E and rho; an E
        given now turns the material back to custom), as a new record."""
        return self.resolve(self.as_dict(resolved), values)

    def as_dict(self, resolved: Any) -> dict[str, Any]:
        """The resolved dataclass as a plain ordered dict."""
        return {p.name: getattr(resolved, p.name) for p in self.parameters}

    def to_json(self) -> list[dict[str, Any]]:
        return [p.to_json() for p in self.parameters]

    def to_markdown(self) -> str:
        """The table as Markdown, for the docs (generated, never edited by hand)."""
        lines = [
            "| name | unit | range | default | scale | what it does |",
            "|---|---|---|---|---|---|",
        ]
        for p in self.parameters:
            if p.kind == CHOICE:
                span = " / ".join(p.choices)
            elif p.kind == BOOL:
                span = "true / false"
            elif p.kind == FLOATS:
                span = f"up to {p.max_items} values, each {_fmt(p.minimum)} to {_fmt(p.maximum)}"
            else:
                span = f"{_fmt(p.minimum)} to {_fmt(p.maximum)}"
            if p.kind == FLOATS:
                default = p.shown(p.default) if p.data else ", ".join(_fmt(x) for x in p.default) or "(none)"
            else:
                default = str(p.default).lower() if p.kind == BOOL else (
                    _fmt(p.default) if isinstance(p.default, float) else str(p.default))
            acts = f" (acts only when {p.when_text()})" if p.when else ""
            lines.append(f"| `{p.name}` | {p.unit or '-'} | {span} | {default} | {p.scale} | {p.doc}{acts} |")
        return "\n".join(lines) + "\n"


_TABLES: dict[type, ParameterTable] = {}
"""Each record class (:attr:`ParameterTable.dataclass`) and its table."""


def table_of(record: Any) -> ParameterTable | None:
    """The table whose resolved record ``record`` is (None for anything else: no record)."""
    return _TABLES.get(type(record))


def parse_assignments(items: Iterable[str]) -> dict[str, str]:
    """Parse ``NAME=VALUE`` strings (the CLI's ``--set``) into a dict of strings."""
    out: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ParameterError(f"--set {show_value(item)} must have the form NAME=VALUE")
        out[name] = value.strip()
    return out


def _holds(value: Any, condition: Any, resolved: Any) -> bool:
    """Whether a parameter's ``value`` meets one ``condition`` of a ``when`` (see :class:`Parameter`)."""
    return condition.holds(value, resolved) if isinstance(condition, Compare) else value in condition


def _word(value: Any) -> str:
    """A value as written on the command line (``true``, not ``True``)."""
    return str(value).lower() if isinstance(value, bool) else str(value)
