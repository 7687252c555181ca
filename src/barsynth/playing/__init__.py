"""Playing barsynth: notes and velocities (:mod:`.notes`); polyphony, MIDI and live audio follow."""

from .notes import (
    NOTE_MAPS,
    TUNING_HZ,
    NoteMap,
    note_hz,
    note_settings,
    velocity_fraction,
)

__all__ = ["NOTE_MAPS", "NoteMap", "TUNING_HZ", "note_hz", "note_settings", "velocity_fraction"]
