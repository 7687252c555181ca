"""Playing barsynth: notes and velocities (:mod:`.notes`), polyphony (:mod:`.instrument`), songs
from MIDI files (:mod:`.song`) and live audio (:mod:`.player`, over :mod:`.live`'s ring buffer)."""

from .instrument import Instrument
from .notes import TUNING_HZ, NoteMap, control_settings, note_hz, note_settings, velocity_fraction

__all__ = ["TUNING_HZ", "Instrument", "NoteMap", "control_settings", "note_hz", "note_settings", "velocity_fraction"]
