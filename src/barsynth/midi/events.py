"""Standard MIDI files (SMF type 0 and 1) read into one time-ordered list of events.

:func:`read_midi` parses a file with ``mido`` and returns a :class:`Song`: note-ons, note-offs,
control changes, program changes and pitch bends of every track merged into one list, each
stamped with its exact time in seconds through every tempo change. What the events mean for a
player (sustain pedal, voices, release tails) is the player's business; this module only makes
the list clean:

- **One sounding note per channel and key.** A note-on for a key that is already sounding first
  ends that note (an implicit :class:`NoteOff`, ``cause = "restrike"``); the key then sounds until
  as many note-offs have come as note-ons did (the extra note-offs are absorbed), so overlapping
  repeats never cut the later note short. A note-off for a key that is not sounding is dropped.
  Every :class:`NoteOn` is matched by exactly one later :class:`NoteOff` on its channel and key.
- A note-on with velocity 0 is a note-off (``cause = "note_on_0"``) with release velocity 64,
  the default MIDI 1.0 recommends for a sender without release velocity.
- CC 120 (all sound off), CC 123 (all notes off) and the mode messages CC 124-127 end every
  sounding note of their channel (``cause = "all_notes_off"``); the control change is kept too.
- Notes still sounding at the end of the song end there (``cause = "end"``).
- Events at the same tick keep the file's order: by track, then by position in the track.
- Tempo (``set_tempo``, in any track of a type 1 file) applies to every track; 500000 µs per beat
  (120 beats per minute) until the first one. SMPTE time division (24, 25, 29.97 or 30 frames per
  second) is read too, and then tempo changes do not move time.
- Kept: note on/off, control change (CC 64 sustain, CC 1 modulation and every other), program
  change, pitch bend. Dropped: aftertouch, system exclusive and meta events other than tempo.

Times are exact: each event's time is a :class:`~fractions.Fraction` of a second computed from
integer ticks and tempi, ``time_s`` its nearest float, and :meth:`Event.sample_index` the nearest
sample at a sample rate (a time exactly half-way between two samples goes to the later one).

Channels are numbered as on the wire, 0 to 15 (what musicians call channel 10, the General MIDI
drum channel, is 9 here); programs 0 to 127 (General MIDI's program 1 is 0 here).
"""

from __future__ import annotations

import io
import os
from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from ..checks import check_input_file, check_number, show_text
from ..errors import BarsynthError, MidiFileError

__all__ = [
    "ALL_NOTES_OFF_CC", "ALL_SOUND_OFF_CC", "DEFAULT_TEMPO_US", "DRUM_CHANNEL", "MAX_FILE_BYTES",
    "MODULATION_CC", "SUSTAIN_CC", "ControlChange", "Event", "Note", "NoteOff", "NoteOn", "PitchBend",
    "ProgramChange", "Song", "read_midi", "sample_index",
]

SUSTAIN_CC = 64  # damper pedal: value >= 64 is down
MODULATION_CC = 1
ALL_SOUND_OFF_CC = 120
ALL_NOTES_OFF_CC = 123
_ENDS_ALL_NOTES = frozenset({ALL_SOUND_OFF_CC, ALL_NOTES_OFF_CC, 124, 125, 126, 127})
DRUM_CHANNEL = 9  # General MIDI's channel 10, numbered from 0
DEFAULT_TEMPO_US = 500_000  # µs per beat before the first set_tempo (120 beats per minute)
RELEASE_VELOCITY = 64  # a note-off's velocity when the file gives none (note-on 0, implicit)
MAX_FILE_BYTES = 32 * 1024 * 1024  # larger "MIDI files" are refused before parsing
_SMPTE_FPS = {24: Fraction(24), 25: Fraction(25), 29: Fraction(30000, 1001), 30: Fraction(30)}
_ALLOWED = "allowed: a standard MIDI file of type 0 or 1"


def sample_index(time: Fraction, sample_rate: Any) -> int:
    """The nearest sample to ``time`` (s) at ``sample_rate`` (Hz); a tie goes to the later one.

    >>> sample_index(Fraction(1, 3), 48000), sample_index(Fraction(1, 96000), 48000)
    (16000, 1)
    """
    return _nearest(Fraction(time), _rate(sample_rate))


def _rate(sample_rate: Any) -> Fraction:
    from ..models.rendering import check_sample_rate

    return Fraction(check_sample_rate(sample_rate))


def _nearest(time: Fraction, rate: Fraction) -> int:
    """floor(time * rate + 1/2), in integers."""
    scale = 2 * time.denominator * rate.denominator
    return (2 * time.numerator * rate.numerator + time.denominator * rate.denominator) // scale


@dataclass(frozen=True, slots=True, kw_only=True)
class Event:
    """Something that happens on a channel at a time.

    Attributes
    ----------
    time : Fraction
        When, in seconds from the start of the song, exactly.
    channel : int
        The MIDI channel, 0 to 15 (9 is General MIDI's drum channel 10).
    """

    time: Fraction
    channel: int

    @property
    def time_s(self) -> float:
        """When, in seconds (the nearest float to :attr:`time`)."""
        return float(self.time)

    def sample_index(self, sample_rate: Any) -> int:
        """The nearest sample to this event at ``sample_rate`` (Hz); see :func:`sample_index`."""
        return sample_index(self.time, sample_rate)


@dataclass(frozen=True, slots=True, kw_only=True)
class NoteOn(Event):
    """A key pressed: ``key`` 0 to 127 (60 is middle C), ``velocity`` 1 to 127, and the
    ``program`` (0 to 127) in force on the channel then (0 before any program change)."""

    key: int
    velocity: int
    program: int


@dataclass(frozen=True, slots=True, kw_only=True)
class NoteOff(Event):
    """A key released: ``key`` 0 to 127, release ``velocity`` 0 to 127, and its ``cause``:
    "note_off", "note_on_0" (a note-on of velocity 0), "restrike" (the same key struck again),
    "all_notes_off" (CC 120, 123-127) or "end" (still sounding when the song ends)."""

    key: int
    velocity: int
    cause: str = "note_off"


@dataclass(frozen=True, slots=True, kw_only=True)
class ControlChange(Event):
    """A controller moved: ``control`` 0 to 127 (64 sustain, 1 modulation), ``value`` 0 to 127."""

    control: int
    value: int

    @property
    def pedal_down(self) -> bool:
        """Whether this is the sustain (damper) pedal going down (CC 64, value >= 64)."""
        return self.control == SUSTAIN_CC and self.value >= 64


@dataclass(frozen=True, slots=True, kw_only=True)
class ProgramChange(Event):
    """A new ``program`` (0 to 127; General MIDI's program 1 is 0) for the channel."""

    program: int


@dataclass(frozen=True, slots=True, kw_only=True)
class PitchBend(Event):
    """The pitch wheel: ``value`` -8192 to 8191 (0 is centred)."""

    value: int


@dataclass(frozen=True, slots=True)
class Note:
    """A note from its :class:`NoteOn` to the :class:`NoteOff` that ends it."""

    on: NoteOn
    off: NoteOff

    @property
    def duration_s(self) -> float:
        """How long the key is down, in seconds (a sustain pedal may hold it longer)."""
        return float(self.off.time - self.on.time)


@dataclass(frozen=True)
class Song:
    """A MIDI file's events, merged and timed.

    Attributes
    ----------
    path : str
        The file read.
    events : tuple of Event
        Every event kept, in time order (ties: the file's order, implicit note-offs before the
        note-on that causes them and after the control change that causes them).
    length : Fraction
        When the song ends, in seconds: the end of its longest track (its end-of-track event),
        so never before the last event. Release tails come after it.
    midi_type : int
        0 or 1.
    ticks_per_beat : int or None
        The time division, or None for SMPTE time (see ``ticks_per_second``).
    ticks_per_second : Fraction or None
        The SMPTE time division (frames per second times ticks per frame), or None.
    tempo_changes : tuple of (Fraction, int)
        Each tempo in force: (time in s, µs per beat), the first at time 0.
    dropped_note_offs : int
        Note-offs that ended nothing: for a key not sounding, or absorbed by a restruck key.
    """

    path: str
    events: tuple[Event, ...]
    length: Fraction
    midi_type: int
    ticks_per_beat: int | None
    ticks_per_second: Fraction | None
    tempo_changes: tuple[tuple[Fraction, int], ...]
    dropped_note_offs: int = 0

    @property
    def length_s(self) -> float:
        """When the song ends, in seconds (float)."""
        return float(self.length)

    def length_samples(self, sample_rate: Any) -> int:
        """The song's length in samples at ``sample_rate`` (Hz): the nearest sample to its end."""
        return sample_index(self.length, sample_rate)

    def sample_indices(self, sample_rate: Any) -> list[int]:
        """The nearest sample to each of :attr:`events` at ``sample_rate`` (Hz), in one pass
        (what :meth:`Event.sample_index` gives one by one)."""
        rate = _rate(sample_rate)
        return [_nearest(event.time, rate) for event in self.events]

    def notes(self) -> tuple[Note, ...]:
        """Every note (its note-on with the note-off that ends it), in the order they start."""
        sounding: dict[tuple[int, int], NoteOn] = {}
        notes: list[tuple[NoteOn, NoteOff]] = []
        for event in self.events:
            if isinstance(event, NoteOn):
                sounding[event.channel, event.key] = event
            elif isinstance(event, NoteOff):
                notes.append((sounding.pop((event.channel, event.key)), event))
        order = {id(on): number for number, on in enumerate(e for e in self.events if isinstance(e, NoteOn))}
        return tuple(Note(on, off) for on, off in sorted(notes, key=lambda pair: order[id(pair[0])]))

    def channels(self) -> tuple[int, ...]:
        """The channels (0 to 15) that play at least one note."""
        return tuple(sorted({e.channel for e in self.events if isinstance(e, NoteOn)}))

    def __iter__(self) -> Iterator[Event]:
        return iter(self.events)

    def __len__(self) -> int:
        return len(self.events)


def _fail(name: str, what: str) -> MidiFileError:
    return MidiFileError(f"MIDI file {show_text(name)}: {what}")


def _load(name: str) -> Any:
    """The file parsed by mido, or MidiFileError naming what is wrong."""
    import mido

    try:
        check_input_file(name, "MIDI file")  # a FIFO would hang the read, a device never end
    except BarsynthError as exc:
        raise MidiFileError(str(exc)) from None
    size = os.path.getsize(name)
    if size == 0:
        raise _fail(name, "is empty (0 bytes); " + _ALLOWED)
    if size > MAX_FILE_BYTES:
        raise _fail(name, f"is {size} bytes long; allowed: up to {MAX_FILE_BYTES} bytes")
    try:
        with open(name, "rb") as handle:
            data = handle.read()
    except OSError as exc:
        raise _fail(name, f"cannot be read ({exc.strerror or exc})") from None
    if data[:4] != b"MThd":
        raise _fail(name, "is not a MIDI file (it does not start with 'MThd'); " + _ALLOWED)
    try:
        return mido.MidiFile(file=io.BytesIO(data))
    except EOFError:
        raise _fail(name, "ends in the middle of a chunk or event (truncated); " + _ALLOWED) from None
    except Exception as exc:  # noqa: BLE001 - mido raises OSError, ValueError, IndexError, its KeySignatureError...
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise _fail(name, f"is corrupt ({reason}); " + _ALLOWED) from None


def _time_base(name: str, midi: Any) -> tuple[int | None, Fraction | None]:
    """(ticks per beat, None) or (None, SMPTE ticks per second) of the header's time division."""
    division = int(midi.ticks_per_beat)  # mido reads it as a signed 16-bit number
    if division > 0:
        return division, None
    if division == 0:
        raise _fail(name, "has a time division of 0 ticks per beat; allowed: 1 to 32767 ticks per beat, or SMPTE time")
    frames, ticks_per_frame = -(division >> 8), division & 0xFF
    if frames not in _SMPTE_FPS or ticks_per_frame == 0:
        raise _fail(name, f"has an SMPTE time division of {frames} frames per second and {ticks_per_frame} ticks "
                          "per frame; allowed: 24, 25, 29 (29.97) or 30 frames per second, 1 to 255 ticks per frame")
    return None, _SMPTE_FPS[frames] * ticks_per_frame


def read_midi(path: str | os.PathLike[str], *, max_length_s: float | None = None) -> Song:
    """Read a standard MIDI file (type 0 or 1) into a :class:`Song`.

    Parameters
    ----------
    path : str or path-like
        The ``.mid`` file.
    max_length_s : float, optional
        Refuse a song longer than this (s): a few bytes can ask for hours of sound.

    Raises
    ------
    MidiFileError
        One line naming the file and what is wrong: missing, not a regular file, empty, not MIDI,
        truncated, corrupt, type 2, a bad time division, no notes, or too long.
    ParameterError
        ``max_length_s`` not a positive number.
    """
    if max_length_s is not None:
        max_length_s = check_number("max_length_s", max_length_s, "s", minimum=0.0, minimum_exclusive=True)
    name = os.fspath(path)
    midi = _load(name)
    if midi.type not in (0, 1):
        what = "type 2 (independent sequences)" if midi.type == 2 else f"of unknown type {midi.type}"
        raise _fail(name, f"is {what}; {_ALLOWED}")
    if not midi.tracks:
        raise _fail(name, "has no tracks; " + _ALLOWED)
    ticks_per_beat, ticks_per_second = _time_base(name, midi)

    timeline = []  # (tick, track, position, message), sorted: the file's order at equal ticks
    end_tick = 0
    for number, track in enumerate(midi.tracks):
        tick = 0
        for position, message in enumerate(track):
            tick += message.time
            timeline.append((tick, number, position, message))
        end_tick = max(end_tick, tick)
    timeline.sort(key=lambda item: item[:3])

    # time = numerator / denominator seconds, both integers, so every time is exact
    if ticks_per_second is None:
        denominator, per_tick = ticks_per_beat * 1_000_000, DEFAULT_TEMPO_US
    else:
        denominator, per_tick = ticks_per_second.numerator, ticks_per_second.denominator
    numerator, last_tick = 0, 0
    tempo_changes: list[tuple[Fraction, int]] = [(Fraction(0), DEFAULT_TEMPO_US)]

    events: list[Event] = []
    sounding: dict[tuple[int, int], int] = {}  # (channel, key) -> note-ons not yet matched by note-offs
    programs = [0] * 16
    dropped = 0

    def end_notes(time: Fraction, channel: int | None, cause: str) -> None:
        for (ch, key) in [k for k in sounding if channel is None or k[0] == channel]:
            del sounding[ch, key]
            events.append(NoteOff(time=time, channel=ch, key=key, velocity=RELEASE_VELOCITY, cause=cause))

    for tick, _, _, message in timeline:
        numerator += (tick - last_tick) * per_tick
        last_tick = tick
        time = Fraction(numerator, denominator)
        kind = message.type
        if kind == "set_tempo":
            if ticks_per_second is None:
                per_tick = message.tempo
                if tempo_changes[-1][0] == time:
                    tempo_changes.pop()
                tempo_changes.append((time, message.tempo))
            continue
        if kind == "note_on" and message.velocity > 0:
            where = (message.channel, message.note)
            if where in sounding:
                events.append(NoteOff(time=time, channel=message.channel, key=message.note,
                                      velocity=RELEASE_VELOCITY, cause="restrike"))
            sounding[where] = sounding.get(where, 0) + 1
            events.append(NoteOn(time=time, channel=message.channel, key=message.note, velocity=message.velocity,
                                 program=programs[message.channel]))
        elif kind in ("note_on", "note_off"):
            where = (message.channel, message.note)
            held = sounding.get(where, 0)
            if held == 0:
                dropped += 1
            elif held > 1:
                sounding[where] = held - 1
                dropped += 1
            else:
                del sounding[where]
                velocity, cause = ((message.velocity, "note_off") if kind == "note_off"
                                   else (RELEASE_VELOCITY, "note_on_0"))
                events.append(NoteOff(time=time, channel=message.channel, key=message.note, velocity=velocity,
                                      cause=cause))
        elif kind == "control_change":
            events.append(ControlChange(time=time, channel=message.channel, control=message.control,
                                        value=message.value))
            if message.control in _ENDS_ALL_NOTES:
                end_notes(time, message.channel, "all_notes_off")
        elif kind == "program_change":
            programs[message.channel] = message.program
            events.append(ProgramChange(time=time, channel=message.channel, program=message.program))
        elif kind == "pitchwheel":
            events.append(PitchBend(time=time, channel=message.channel, value=message.pitch))

    numerator += (end_tick - last_tick) * per_tick
    length = Fraction(numerator, denominator)
    end_notes(length, None, "end")
    if not any(isinstance(e, NoteOn) for e in events):
        raise _fail(name, "contains no notes; allowed: a file with at least one note-on of velocity 1 to 127")
    if max_length_s is not None and length > Fraction(max_length_s):
        raise _fail(name, f"is {float(length):.6g} s long; allowed: up to {max_length_s:g} s")
    return Song(path=name, events=tuple(events), length=length, midi_type=int(midi.type),
                ticks_per_beat=ticks_per_beat, ticks_per_second=ticks_per_second,
                tempo_changes=tuple(tempo_changes), dropped_note_offs=dropped)
