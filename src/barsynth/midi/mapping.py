"""Which model plays which MIDI channel: a TOML map of channels and programs to models and presets.

A map holds ``[[channel]]`` and ``[[program]]`` entries::

    [[channel]]
    channel = 2               # 1 to 16, as musicians count (10 is General MIDI's drums)
    model = "banded"
    preset = "marimba"        # optional: one of the model's presets
    parameters = { mallet_hardness = 0.4 }   # optional: overrides, checked against the model's table

    [[channel]]
    channel = 4
    ignore = true             # this channel plays nothing

    [[program]]
    program = 12              # General MIDI 1 to 128 (12 vibraphone, 13 marimba, 14 xylophone)
    model = "banded"
    preset = "vibraphone"

A note's player is found by, in turn: the ``[[channel]]`` entry of its channel; the ``[[program]]``
entry of the program in force on its channel (General MIDI program 1 before any program change);
the default (the ``--model`` and ``--preset`` given). The drum channel (10) plays only through a
``[[channel]]`` entry: programs there pick drum kits, not instruments, and a bar model is not a
drum kit, so without one it is ignored.

Every mistake is one :class:`~barsynth.errors.MidiMapError` line naming the file, the entry, the
key, its value and what is allowed.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..checks import check_input_file, show_text, show_value
from ..errors import BarsynthError, MidiMapError
from .events import DRUM_CHANNEL

__all__ = ["Assignment", "ChannelMap", "load_map", "parse_map"]

_ENTRY_KEYS = {"channel": {"channel", "model", "preset", "parameters", "ignore"},
               "program": {"program", "model", "preset", "parameters", "ignore"}}
_RANGES = {"channel": (1, 16), "program": (1, 128)}


@dataclass(frozen=True)
class Assignment:
    """A model, its preset (or None) and parameter overrides: what plays a channel.

    ``parameters`` is the model's resolved record (defaults, then the preset, then ``overrides``);
    ``source`` says where the assignment came from, for messages (``"[[channel]] #1"``, ``"default"``).
    Two assignments are equal when model, preset and overrides are.
    """

    model: str
    preset: str | None
    overrides: tuple[tuple[str, Any], ...]
    parameters: Any = field(compare=False, repr=False)
    source: str = field(default="default", compare=False)


@dataclass(frozen=True)
class ChannelMap:
    """The default assignment, and those of channels (keys 0 to 15) and programs (0 to 127).

    ``None`` as a channel's assignment means the channel is ignored.
    """

    default: Assignment
    channels: Mapping[int, Assignment | None]
    programs: Mapping[int, Assignment | None]

    def assignment(self, channel: int, program: int = 0) -> Assignment | None:
        """What plays a note on ``channel`` (0 to 15) while ``program`` (0 to 127) is in force;
        None if nothing does (an ignored channel, or the drum channel unmapped)."""
        if channel in self.channels:
            return self.channels[channel]
        if channel == DRUM_CHANNEL:
            return None
        if program in self.programs:
            return self.programs[program]
        return self.default


def _assignment(where: str, model: Any, preset: Any, overrides: Any) -> Assignment:
    """Check ``model``, ``preset`` and ``overrides`` against barsynth's registry; ``where`` prefixes messages."""
    from ..models import get_model, model_names
    from ..presets import preset_names, preset_parameters

    names = model_names()
    if not isinstance(model, str) or model not in names:
        raise MidiMapError(f"{where}: model = {show_value(model)} is not a known model; allowed: one of "
                           f"{', '.join(names)}")
    if preset is not None:
        presets = preset_names(model)
        if not isinstance(preset, str) or preset not in presets:
            raise MidiMapError(f"{where}: preset = {show_value(preset)} is not a preset of model {model}; allowed: "
                               f"{'one of ' + ', '.join(presets) if presets else 'none (it has no presets)'}")
    if overrides is None:
        overrides = {}
    if not isinstance(overrides, dict):
        raise MidiMapError(f"{where}: parameters = {show_value(overrides)} is not a table; allowed: a table of "
                           f"the model's parameters, e.g. parameters = {{ name = value }}")
    table = get_model(model).table
    try:
        checked = table.validate(overrides)
        record = table.resolve(preset_parameters(model, preset) if preset else None, overrides)
    except BarsynthError as exc:
        raise MidiMapError(f"{where}: {exc}") from None
    return Assignment(model, preset, tuple(sorted(checked.items())), record, where)


def _whole(where: str, key: str, value: Any) -> int:
    low, high = _RANGES[key]
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        extra = " (10 is General MIDI's drums)" if key == "channel" else " (General MIDI numbering)"
        raise MidiMapError(f"{where}: {key} = {show_value(value)} is not allowed; allowed: a whole number from "
                           f"{low} to {high}{extra}")
    return value


def parse_map(text: str, *, model: str, preset: str | None = None, name: str = "(text)") -> ChannelMap:
    """A :class:`ChannelMap` from TOML ``text`` (``name`` names it in messages), every other channel
    played by ``model`` with ``preset``."""
    default = _assignment("default", model, preset, None)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MidiMapError(f"map {show_text(name)}: is not valid TOML ({' '.join(str(exc).split())})") from None
    unknown = sorted(set(doc) - set(_ENTRY_KEYS))
    if unknown:
        raise MidiMapError(f"map {show_text(name)}: unknown key {show_text(repr(unknown[0]))}; allowed: "
                           "[[channel]] and [[program]] entries")
    found: dict[str, dict[int, Assignment | None]] = {"channel": {}, "program": {}}
    for kind, allowed in _ENTRY_KEYS.items():
        entries = doc.get(kind, [])
        if not isinstance(entries, list):
            raise MidiMapError(f"map {show_text(name)}: {kind} is not a list of [[{kind}]] entries; allowed: "
                               f"[[{kind}]] tables")
        for number, entry in enumerate(entries, start=1):
            where = f"map {show_text(name)}: [[{kind}]] #{number}"
            if not isinstance(entry, dict):
                raise MidiMapError(f"{where} is not a table; allowed: [[{kind}]] tables")
            strange = sorted(set(entry) - allowed)
            if strange:
                raise MidiMapError(f"{where}: unknown key {show_text(repr(strange[0]))}; allowed: "
                                   f"{', '.join(sorted(allowed))}")
            if kind not in entry:
                raise MidiMapError(f"{where}: {kind} is missing; allowed: a whole number from "
                                   f"{_RANGES[kind][0]} to {_RANGES[kind][1]}")
            number_given = _whole(where, kind, entry[kind])
            key = number_given - 1
            if key in found[kind]:
                raise MidiMapError(f"{where}: {kind} = {number_given} is mapped twice; allowed: one entry per {kind}")
            ignore = entry.get("ignore", False)
            if not isinstance(ignore, bool):
                raise MidiMapError(f"{where}: ignore = {show_value(ignore)} is not allowed; allowed: true or false")
            if ignore:
                others = sorted({"model", "preset", "parameters"} & set(entry))
                if others:
                    raise MidiMapError(f"{where}: ignore = true with {others[0]}; allowed: one or the other")
                found[kind][key] = None
                continue
            if "model" not in entry:
                raise MidiMapError(f"{where}: model is missing; allowed: a model name, or ignore = true")
            found[kind][key] = _assignment(f"{where} ({kind} = {number_given})", entry["model"],
                                           entry.get("preset"), entry.get("parameters"))
    return ChannelMap(default, found["channel"], found["program"])


def load_map(path: str | os.PathLike[str] | None, *, model: str, preset: str | None = None) -> ChannelMap:
    """The :class:`ChannelMap` in the TOML file ``path``, or with no file every channel but the
    drum channel played by ``model`` with ``preset``."""
    if path is None:
        return parse_map("", model=model, preset=preset)
    name = os.fspath(path)
    try:
        check_input_file(name, "map")  # a FIFO would hang the read, a device never end
        with open(name, encoding="utf-8") as handle:
            text = handle.read()
    except BarsynthError as exc:
        raise MidiMapError(str(exc)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise MidiMapError(f"map {show_text(name)}: cannot be read ({getattr(exc, 'strerror', None) or exc})") from None
    return parse_map(text, model=model, preset=preset, name=name)
