"""A MIDI song rendered offline: an :class:`~.instrument.Instrument` per channel and model the map
assigns, every event at its sample (spec 10.3; :mod:`barsynth.midi` reads the file and the map).

A note plays on its channel's instrument for the assignment in force when it starts (the
channel's, or its program's); its note off goes to the same instrument. Channels never share an
instrument, so one channel's pedal and note offs touch only its own notes. A control change goes
to every instrument its channel has played on, and an instrument's first note brings it the
channel's controls so far (a sustain pedal put down before the first note holds it). After the
song's end the tails ring until every instrument is ``TAIL_DB`` below the loudest block heard,
at most ``MAX_TAIL_S``.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..errors import ParameterError
from ..midi.events import ControlChange, NoteOff, NoteOn
from .instrument import Instrument

BLOCK = 4096
TAIL_DB = 90.0
MAX_TAIL_S = 30.0


def render_song(song: Any, channel_map: Any, *, sample_rate: float = 48000.0, voices: int = 16,
                watch: Callable[[float, float | None], None] | None = None,
                refused: list[tuple[Any, str]] | None = None) -> np.ndarray:
    """The song's samples (float64, the models' own levels). ``watch(done_s, total_s)`` is
    called after each block (a progress line; it may raise to stop). A note its model cannot
    reach (a key beyond a twang's table) is left out and, with ``refused``, appended there as
    (its NoteOn, the one-line reason); without it the first such note raises."""
    instruments: dict[Any, Instrument] = {}
    playing: dict[tuple[int, int], Instrument] = {}  # (channel, key) -> its instrument
    by_channel: dict[int, set[int]] = {}
    controls: dict[int, dict[int, int]] = {}  # channel -> control -> its last value
    events = list(song.events)
    indices = song.sample_indices(sample_rate)
    end = song.length_samples(sample_rate)
    limit = end + int(MAX_TAIL_S * sample_rate)
    out: list[np.ndarray] = []
    loudest = quiet_since = 0.0
    now, k = 0, 0
    block = np.empty(BLOCK)
    while now < limit:
        n = BLOCK
        while k < len(events) and indices[k] < now + n:
            try:
                _route(events[k], indices[k] - now, channel_map, instruments, playing, by_channel, controls, voices,
                       sample_rate)
            except ParameterError as error:
                if refused is None:
                    raise
                refused.append((events[k], str(error)))
            k += 1
        block.fill(0.0)
        for instrument in instruments.values():
            block += instrument.process(n)
        out.append(block.copy())
        peak = float(np.max(np.abs(block)))
        loudest = max(loudest, peak)
        now += n
        if now >= end and k >= len(events):
            quiet_since = quiet_since + n if peak <= loudest * 10 ** (-TAIL_DB / 20) else 0.0
            if quiet_since >= 0.1 * sample_rate or not instruments:
                break
        if watch is not None:
            watch(now / sample_rate, end / sample_rate)
    return np.concatenate(out) if out else np.zeros(0)


def _route(event: Any, at: int, channel_map: Any, instruments: dict, playing: dict, by_channel: dict,
           controls: dict, voices: int, sample_rate: float) -> None:
    if isinstance(event, NoteOn):
        assignment = channel_map.assignment(event.channel, event.program)
        if assignment is None:
            return
        key = (event.channel, assignment)  # an instrument per channel: one channel's pedal holds only its notes
        instrument = instruments.get(key)
        if instrument is None:
            from ..models import get_model

            model = get_model(assignment.model)
            instrument = instruments[key] = Instrument(
                model, voices, parameters=model.table.as_dict(assignment.parameters), sample_rate=sample_rate)
        on_channel = by_channel.setdefault(event.channel, set())
        if id(instrument) not in on_channel:  # the channel's controls so far (a pedal put down before any note)
            on_channel.add(id(instrument))
            for number, value in controls.get(event.channel, {}).items():
                instrument.control(number, value, at=at)
        instrument.note_on(event.key, event.velocity, at=at)  # (refused before it sounds: its note off finds nothing)
        playing[(event.channel, event.key)] = instrument
    elif isinstance(event, NoteOff):
        instrument = playing.pop((event.channel, event.key), None)
        if instrument is not None:
            instrument.note_off(event.key, at=at)
    elif isinstance(event, ControlChange):
        controls.setdefault(event.channel, {})[event.control] = event.value
        for instrument in instruments.values():
            if id(instrument) in by_channel.get(event.channel, ()):
                instrument.control(event.control, event.value, at=at)
