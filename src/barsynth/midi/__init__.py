"""MIDI files for barsynth: timed events (:mod:`.events`) and the channel/program map (:mod:`.mapping`).

Nothing here synthesises: a player (``Instrument``) and ``barsynth midi`` consume what these read.
See docs/midi-notes.md.
"""

from .events import ControlChange, Event, Note, NoteOff, NoteOn, PitchBend, ProgramChange, Song, read_midi, sample_index
from .mapping import Assignment, ChannelMap, load_map, parse_map

__all__ = ["Assignment", "ChannelMap", "ControlChange", "Event", "Note", "NoteOff", "NoteOn", "PitchBend",
           "ProgramChange", "Song", "load_map", "parse_map", "read_midi", "sample_index"]
