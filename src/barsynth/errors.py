"""The one exception family of barsynth.

Every message names what was wrong, the value given, what is allowed and the unit,
so the CLI (and the web layer) can show it as a single line.
"""

from __future__ import annotations


class BarsynthError(Exception):
    """Base class of every error barsynth raises on purpose."""


class ParameterError(BarsynthError, ValueError):
    """A parameter is unknown, of the wrong type, or outside its range."""


class PresetError(BarsynthError, ValueError):
    """A preset is unknown or its file is malformed."""


class ModelError(BarsynthError, ValueError):
    """An unknown model name."""


class AudioFileError(BarsynthError, OSError):
    """An audio file is missing, unreadable or of an unsupported kind."""


class AudioFormatError(AudioFileError):
    """An audio file's bytes are not a sound libsndfile reads (not WAV, FLAC or OGG, or broken)."""


class MidiFileError(BarsynthError, ValueError):
    """A MIDI file is missing, unreadable, malformed or of a kind barsynth does not play."""


class MidiMapError(BarsynthError, ValueError):
    """A channel/program map (TOML) is unreadable or names an unknown model, preset or parameter."""


class SamplesError(BarsynthError, ValueError):
    """Settings for which a model gives non-finite or exploding samples (never played or written)."""


class BatchSpecError(BarsynthError, ValueError):
    """A batch spec (TOML) is unreadable, or names an unknown key, model, preset or parameter, or a
    variation outside what the parameter's table allows."""
