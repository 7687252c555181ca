"""Notes on every model: what a pitch moves and what a velocity drives (spec 10.1).

A note's pitch is a MIDI note number (A4 = 69 = :data:`TUNING_HZ`; fractions allowed) or a
frequency in Hz; its velocity 0-127 (MIDI) or a fraction 0-1. Each model's :class:`NoteMap`
says which parameter the pitch moves and how:

- ``frequency``: the parameter is the pitch itself (a ratio-tuned bar, Farnell's patch);
- ``length``: a length of a bar built from physics, scaled by ``sqrt(f_now / f_target)``
  (``f ~ 1 / L^2``, material kept) and refined on the model's own ``describe`` until its
  pitch mode lies within :data:`PITCH_CENTS` of the target (a bar whose pitch is not exactly
  ``1 / L^2``: a thick bar, a tine behind its bridge, a twang's two lengths);

and which parameter each excitation's velocity drives, through the curve
``low + (high - low) * v^gamma``. A note the table cannot reach is refused in one line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..checks import check_number
from ..errors import ParameterError

TUNING_HZ = 440.0
"""A4, MIDI note 69 (Hz)."""
PITCH_CENTS = 0.01
"""How close a length-tuned note lands to its frequency (cents)."""
MAX_REFINEMENTS = 12


@dataclass(frozen=True)
class VelocityCurve:
    """``parameter = low + (high - low) * v^gamma`` for a velocity fraction ``v`` (0 to 1);
    with ``per`` that times the (new) value of the parameter ``per`` times ``factor`` (a twang's
    tip is bent by a fraction of its overhang, in mm)."""

    parameter: str
    low: float
    high: float
    gamma: float = 1.0
    per: str | None = None
    factor: float = 1.0

    def value(self, fraction: float, settings: Any = None) -> float:
        base = self.low + (self.high - self.low) * fraction ** self.gamma
        return base if self.per is None else base * getattr(settings, self.per) * self.factor


@dataclass(frozen=True)
class NoteMap:
    """What a note does to a model (see the module docstring)."""

    pitch: str
    """The parameter the pitch moves."""
    law: str
    """``frequency`` or ``length``."""
    group: str | None = None
    """The ``describe`` group whose lowest mode is the pitch (None: the lowest mode described)."""
    velocity: dict[str | None, VelocityCurve] = field(default_factory=dict)
    """Per ``excitation`` (None for a model that has none), the velocity's curve."""
    when: dict[str, str] = field(default_factory=dict)
    """Settings under which this map holds (a banded bar tuned by ratios moves its frequency)."""


def _mallets(level_low: float = 0.2, level_high: float = 4.0) -> dict[str | None, VelocityCurve]:
    return {"strike": VelocityCurve("mallet_velocity_m_s", level_low, level_high, 1.0),
            "pluck": VelocityCurve("pluck_displacement_mm", 0.05, 3.0, 1.0),
            "bow": VelocityCurve("bow_force_n", 0.5, 8.0, 1.0)}


NOTE_MAPS: dict[str, tuple[NoteMap, ...]] = {
    "twang": (NoteMap("length_m", "length", "short-cantilever", {None: VelocityCurve("level_db", -40.0, 0.0, 0.5)}),),
    "farnell": (NoteMap("frequency_hz", "frequency", "free-bar", {None: VelocityCurve("level_db", -40.0, 0.0, 0.5)}),),
    "banded": (NoteMap("frequency_hz", "frequency", None, _mallets(), when={"tuning": "ratios"}),
               NoteMap("length_m", "length", None, _mallets())),
    "allpass": (NoteMap("length_m", "length", "fitted", {k: v for k, v in _mallets().items() if k != "bow"}),),
    "fd": (NoteMap("length_m", "length", None, _mallets()),),
    "ruler": (NoteMap("overhang_m", "length", "short cantilever",
                      {None: VelocityCurve("tip_displacement_mm", 0.02, 0.25, 1.0, per="overhang_m", factor=1000.0)}),),
    "kalimba": (NoteMap("vibrating_length_m", "length", "tine on bridge",
                        {None: VelocityCurve("pluck_displacement_mm", 0.2, 3.0, 1.0)}),),
}
"""Each model's note maps, the first whose ``when`` holds is used."""


def note_hz(pitch: Any = None, *, frequency_hz: Any = None, tuning_hz: float = TUNING_HZ) -> float:
    """The frequency (Hz) of MIDI note ``pitch`` (69 = ``tuning_hz``), or ``frequency_hz`` as given."""
    if (pitch is None) == (frequency_hz is None):
        raise ParameterError("a note needs one of pitch (a MIDI note number) or frequency_hz; allowed: exactly one")
    if frequency_hz is not None:
        return check_number("frequency_hz", frequency_hz, "Hz", minimum=0.0, minimum_exclusive=True, maximum=1e5)
    note = check_number("pitch", pitch, "", minimum=-60.0, maximum=187.0)
    tuning = check_number("tuning_hz", tuning_hz, "Hz", minimum=100.0, maximum=1000.0)
    return tuning * 2.0 ** ((note - 69.0) / 12.0)


def velocity_fraction(velocity: Any) -> float:
    """A MIDI velocity (a whole number 0-127) or a fraction (a float 0-1) as a fraction 0-1."""
    if isinstance(velocity, bool):
        raise ParameterError(f"parameter velocity = {velocity} is not allowed; allowed: 0 to 127 or 0.0 to 1.0")
    if isinstance(velocity, int):
        return check_number("velocity", velocity, "", minimum=0, maximum=127) / 127.0
    return check_number("velocity", velocity, "", minimum=0.0, maximum=1.0)


def note_map(model: Any, params: Any) -> NoteMap:
    """The map of ``model`` that holds under ``params``."""
    for candidate in NOTE_MAPS[model.name]:
        if all(getattr(params, name) == value for name, value in candidate.when.items()):
            return candidate
    raise ParameterError(f"model {model.name} has no note map for these settings")


def pitch_of(model: Any, params: Any, group: str | None, sample_rate: float) -> float:
    """The model's pitch (Hz): the lowest mode of ``group`` that ``describe`` gives."""
    modes = [m for m in model.describe(params, sample_rate=sample_rate) if group is None or m.group == group]
    if not modes:
        raise ParameterError(f"model {model.name} describes no mode {'of ' + group if group else ''} here; "
                             "allowed: settings with a pitch")
    return min(m.frequency_hz for m in modes)


def note_settings(model: Any, params: Any, frequency_hz: float, velocity: float, *,
                  sample_rate: float = 48000.0) -> dict[str, Any]:
    """The parameter changes that play ``frequency_hz`` at ``velocity`` (a fraction 0-1) on
    ``model`` from the settings ``params``; one line if the table cannot reach the note."""
    mapping = note_map(model, params)
    table = model.table
    changes: dict[str, Any] = {}
    row = table[mapping.pitch]
    if mapping.law == "frequency":
        changes[mapping.pitch] = _in_range(row, frequency_hz, frequency_hz)
    else:
        length = getattr(params, mapping.pitch)
        current = params
        for _ in range(MAX_REFINEMENTS):
            found = pitch_of(model, current, mapping.group, sample_rate)
            if abs(1200.0 * math.log2(found / frequency_hz)) <= PITCH_CENTS:
                break
            length = _in_range(row, length * math.sqrt(found / frequency_hz), frequency_hz)
            current = table.changed(current, {mapping.pitch: length})
        changes[mapping.pitch] = length
    excitation = getattr(params, "excitation", None)
    curve = mapping.velocity.get(excitation)
    if curve is not None:
        changes[curve.parameter] = curve.value(velocity, table.changed(params, changes))
    return changes


def _in_range(row: Any, value: float, frequency_hz: float) -> float:
    """``value`` for ``row``, or one line: the note needs a value outside its range."""
    if (row.minimum is not None and value < row.minimum) or (row.maximum is not None and value > row.maximum):
        raise ParameterError(f"the note at {frequency_hz:.6g} Hz needs {row.name} = {value:.6g}{' ' + row.unit if row.unit else ''}"
                             f"; allowed: {row.range_text()}")
    return float(value)
