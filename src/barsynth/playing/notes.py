"""Notes on every model: what a pitch moves and what a velocity drives (spec 10.1).

A note's pitch is a MIDI note number (A4 = 69 = :data:`TUNING_HZ`; fractions allowed) or a
frequency in Hz; its velocity 0-127 (MIDI) or a fraction 0-1. Each model declares next to its
table (``Model.note_maps``, :mod:`barsynth.models.notemap`) which parameter the pitch moves and how:

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
import numbers
from types import SimpleNamespace
from typing import Any

from ..checks import check_number
from ..errors import ParameterError
from ..models.notemap import ControlCurve, NoteMap, VelocityCurve

TUNING_HZ = 440.0
"""A4, MIDI note 69 (Hz)."""
PITCH_CENTS = 0.01
"""How close a length-tuned note lands to its frequency (cents)."""
MAX_REFINEMENTS = 12


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
    if isinstance(velocity, numbers.Integral):  # (NumPy's integers too)
        return check_number("velocity", int(velocity), "", minimum=0, maximum=127) / 127.0
    return check_number("velocity", velocity, "", minimum=0.0, maximum=1.0)


def note_map(model: Any, params: Any) -> NoteMap:
    """The map of ``model`` that holds under ``params``."""
    for candidate in model.note_maps:
        if all(getattr(params, name) == value for name, value in candidate.when.items()):
            return candidate
    raise ParameterError(f"model {model.name} has no note map for these settings")


def pitch_of(model: Any, params: Any, group: str | None, sample_rate: float) -> float:
    """The model's pitch (Hz): the lowest mode of ``group`` that ``describe`` gives."""
    modes = [m for m in model.describe(params, sample_rate=sample_rate) if group is None or m.group == group]
    if not modes:
        raise ParameterError(f"model {model.name} describes no mode{' of ' + group if group else ''} here; "
                             "allowed: settings with a pitch")
    return min(m.frequency_hz for m in modes)


def note_settings(model: Any, params: Any, frequency_hz: float, velocity: float, *,
                  sample_rate: float = 48000.0, pitch_value: float | None = None) -> dict[str, Any]:
    """The parameter changes that play ``frequency_hz`` at ``velocity`` (a fraction 0-1) on
    ``model`` from the settings ``params``; one line if the table cannot reach the note.
    ``pitch_value``: the pitch's parameter as an earlier call found it for this frequency from
    the same settings (the search on ``describe`` is then skipped: a velocity costs nothing)."""
    if frequency_hz >= 0.5 * sample_rate:
        raise ParameterError(f"the note at {frequency_hz:.6g} Hz is above the Nyquist frequency ({0.5 * sample_rate:g} Hz "
                             f"at {sample_rate:g} Hz); allowed: notes below it")
    mapping = note_map(model, params)
    table = model.table
    curve = mapping.velocity.get(getattr(params, "excitation", None))

    def settings_for(pitch_value: float) -> dict[str, Any]:
        """The pitch's parameter and the velocity's, together: a velocity that scales with the
        pitch's parameter (a ruler's tip with its overhang) is checked with the new value."""
        changes = {mapping.pitch: pitch_value}
        if curve is not None:
            scale = None if curve.per is None else SimpleNamespace(
                **{curve.per: pitch_value if curve.per == mapping.pitch else getattr(params, curve.per)})
            changes[curve.parameter] = curve.value(velocity, scale)
        return changes

    row = table[mapping.pitch]
    if pitch_value is not None:
        changes = settings_for(pitch_value)
    elif mapping.law == "frequency":
        changes = settings_for(_in_range(row, frequency_hz, frequency_hz))
    else:
        length = getattr(params, mapping.pitch)
        current = params
        for _ in range(MAX_REFINEMENTS):
            found = pitch_of(model, current, mapping.group, sample_rate)
            if abs(1200.0 * math.log2(found / frequency_hz)) <= PITCH_CENTS:
                break
            length = _in_range(row, length * math.sqrt(found / frequency_hz), frequency_hz)
            current = table.changed(current, settings_for(length))
        changes = settings_for(length)
    table.changed(params, changes)  # every check of the table, on the note's settings together
    return changes


def _in_range(row: Any, value: float, frequency_hz: float) -> float:
    """``value`` for ``row``, or one line: the note needs a value outside its range."""
    if (row.minimum is not None and value < row.minimum) or (row.maximum is not None and value > row.maximum):
        raise ParameterError(f"the note at {frequency_hz:.6g} Hz needs {row.name} = {value:.6g}{' ' + row.unit if row.unit else ''}"
                             f"; allowed: {row.range_text()}")
    return float(value)


def control_settings(model: Any, params: Any, number: int, value: int) -> dict[str, Any]:
    """The parameter change MIDI control ``number`` at ``value`` (0-127) makes on ``model`` from
    the settings ``params``; empty for a control the model (or these settings) does not have."""
    curve: ControlCurve | None = note_map(model, params).controls.get(number)
    if curve is None or not all(getattr(params, name) in (v if isinstance(v, tuple) else (v,))
                                for name, v in curve.when.items()):
        return {}
    return {curve.parameter: curve.value(value)}



def note_maps_markdown(models: Any) -> str:
    """A Markdown table of ``models``' note maps (docs/playing.md is made with it)."""
    rows = ["| model | when | pitch moves | velocity drives (low to high, curve exponent) | controls |",
            "|---|---|---|---|---|"]
    for model in models:
        for index, mapping in enumerate(model.note_maps):
            when = ", ".join(f"`{k} = {v}`" for k, v in mapping.when.items()) or ("otherwise" if index else "always")
            law = "the pitch itself" if mapping.law == "frequency" else "f ~ 1/L², refined on `describe`"
            drives = "; ".join(
                f"{excitation + ': ' if excitation else ''}`{c.parameter}` {_shown(c.low)} to {_shown(c.high)}"
                f"{' x ' + c.per + (' x ' + _shown(c.factor) if c.factor != 1 else '') if c.per else ''}"
                f"{', ^' + _shown(c.gamma) if c.gamma != 1 else ''}"
                for excitation, c in mapping.velocity.items())
            controls = "; ".join(f"CC {n}: `{c.parameter}` {_shown(c.low)} to {_shown(c.high)}"
                                 + (" (when " + ", ".join(f"{k} = {v}" for k, v in c.when.items()) + ")"
                                    if c.when else "")
                                 for n, c in mapping.controls.items()) or "-"
            rows.append(f"| {model.name} | {when} | `{mapping.pitch}` ({law}) | {drives} | {controls} |")
    return "\n".join(rows) + "\n"


def _shown(value: float) -> str:
    return f"{value:g}"


__all__ = ["TUNING_HZ", "ControlCurve", "NoteMap", "VelocityCurve", "control_settings", "note_hz", "note_map",
           "note_maps_markdown", "note_settings", "velocity_fraction"]
