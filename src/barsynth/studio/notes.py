"""The notes of a studio stream: several at once, from the page's keys or a MIDI device.

A stream's notes are played by a :class:`~barsynth.playing.instrument.Instrument` of
``VOICES`` voices of the stream's model, built from the settings the stream has when a note
comes (spec 10.2: voice allocation, stealing with a short fade, the sustain pedal, CC 64).
They sound beside the stream's own voice (``trigger``/``release``), through the same gain,
limiter, sample check and sleep (:mod:`barsynth.studio.stream`).

- A ``set`` applies to the notes played after it: the notes that sound ring on as they began.
  The next note builds a new Instrument from the new settings; the older one rings on until
  its notes are silent (at most ``MAX_RINGING`` of them; more fade out over ``FADE_S``), and
  a note off reaches the Instrument that holds its note. So a dragged slider never clicks a
  note and never redesigns eight voices at each step.
- Level: the notes' gain (relative to the stream's) is set at the first note of a voice from
  an offline render of one note at the settings' own pitch and full velocity, which peaks at
  ``NOTE_HEADROOM_DBFS``: 6 dB below a strike, room for a chord; the stream's limiter holds
  a louder chord under full scale.
- The work a note may take (building an Instrument, a length-tuned model's pitch search,
  the gain's render) is done by :meth:`Notes.plan`, which changes nothing, so the server runs
  it off the stream's lock; :meth:`Notes.note_on` only puts the planned note in place.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..checks import number_within, show_value
from ..errors import BarsynthError, ParameterError
from ..playing.instrument import Instrument
from ..playing.notes import note_map, pitch_of

VOICES = 8
NOTE_HEADROOM_DBFS = -12.0
GAIN_PROBE_S = 1.0
MAX_RINGING = 4  # older Instruments ringing on at once
FADE_S = 0.010
MAX_HELD = 256  # notes on remembered for their note offs (a page that never lets go forgets the oldest)
QUIET = 1e-6  # an older Instrument with no note held whose block falls this far below its loudest is dropped


def check_pitch(value: Any) -> float:
    """A MIDI note number 0 to 127 (fractions allowed), or a ParameterError naming it."""
    if not number_within(value, 0, 127):
        raise ParameterError(f"parameter pitch = {show_value(value)} is out of range; allowed: MIDI note numbers "
                            "from 0 to 127")
    return float(value)


def check_midi(name: str, value: Any, low: int) -> int:
    """A whole MIDI value ``low`` to 127, or a ParameterError naming it."""
    if not number_within(value, low, 127, whole=True):
        raise ParameterError(f"parameter {name} = {show_value(value)} is out of range; allowed: whole numbers from "
                            f"{low} to 127")
    return int(value)


@dataclass(frozen=True)
class PlannedNote:
    """A checked note and what :meth:`Notes.note_on` puts in place for it."""

    pitch: float
    velocity: int
    instrument: Instrument | None
    """A new Instrument of ``settings`` (None: the current one plays the note)."""
    settings: Any
    gain: float | None
    """The notes' gain relative to the stream's, when it was not set yet."""


@dataclass
class _Ringing:
    instrument: Instrument
    loudest: float = 0.0
    fade: int = -1  # samples of its fade done (-1: not fading)


class Notes:
    """The notes of one stream's voice: ``model`` at ``sample_rate`` (Hz); see the module docstring."""

    def __init__(self, model: Any, sample_rate: float):
        self.model = model
        self.sample_rate = sample_rate
        self.gain: float | None = None
        self.instrument: Instrument | None = None  # where new notes go
        self.settings: Any = None  # what it was built from
        self._ringing: list[_Ringing] = []  # older Instruments whose notes ring on
        self._held: list[tuple[float, Instrument]] = []  # notes on, in order, with their Instrument
        self._controls: dict[int, int] = {}  # the last value of each control change (a new Instrument gets them)

    @property
    def playing(self) -> bool:
        """Whether any note was played since the last silence (so :meth:`process` has work)."""
        return self.instrument is not None or bool(self._ringing)

    def plan(self, settings: Any, pitch: Any, velocity: Any, *, base_gain: float) -> PlannedNote:
        """Check a note (one line if it is out of range or the model cannot reach it) and build
        what it needs; changes nothing (safe beside :meth:`process` in another thread)."""
        midi = check_pitch(pitch)
        strength = check_midi("velocity", velocity, 1)
        built = None
        if self.instrument is None or self.settings is not settings:
            built = self._build(settings)
        # The note's settings worked out (and kept) by the Instrument that will play it: its
        # note_on then finds them, and does no pitch search under the stream's lock.
        (built or self.instrument).note_settings(midi, strength)
        gain = self._probe_gain(settings, base_gain) if self.gain is None else None
        return PlannedNote(midi, strength, built, settings, gain)

    def _build(self, settings: Any) -> Instrument:
        return Instrument(self.model, voices=VOICES, parameters=self.model.table.as_dict(settings),
                          sample_rate=self.sample_rate, seed=0)

    def _probe_gain(self, settings: Any, base_gain: float) -> float:
        """The gain (relative to ``base_gain``) at which one note at the settings' own pitch and
        full velocity peaks at NOTE_HEADROOM_DBFS."""
        try:
            mapping = note_map(self.model, settings)
            if mapping.law == "frequency":
                hz = float(getattr(settings, mapping.pitch))
            else:
                hz = pitch_of(self.model, settings, mapping.group, self.sample_rate)
            probe = Instrument(self.model, voices=1, parameters=self.model.table.as_dict(settings),
                               sample_rate=self.sample_rate, seed=0)
            probe.note_on(frequency_hz=hz, velocity=127)
            peak = float(np.max(np.abs(probe.process(int(GAIN_PROBE_S * self.sample_rate)))))
        except BarsynthError:
            peak = 0.0  # no note at these settings: the stream's own gain
        if not (peak > 0.0 and math.isfinite(peak)):
            return 1.0
        return 10.0 ** (NOTE_HEADROOM_DBFS / 20.0) / peak / base_gain

    def note_on(self, note: PlannedNote) -> None:
        """Play a planned note now (at the next block)."""
        if note.gain is not None and self.gain is None:
            self.gain = note.gain
        if note.instrument is None and self.instrument is None:  # silenced since it was planned
            note = replace(note, instrument=self._build(note.settings))
        if note.instrument is not None:
            if self.instrument is not None:
                self._ringing.append(_Ringing(self.instrument))
                for extra in self._ringing[:-MAX_RINGING]:
                    extra.fade = max(extra.fade, 0)
            self.instrument, self.settings = note.instrument, note.settings
            for number, value in self._controls.items():
                self.instrument.control(number, value)
        self.instrument.note_on(note.pitch, note.velocity)
        self._held = [*self._held[-(MAX_HELD - 1):], (note.pitch, self.instrument)]

    def note_off(self, pitch: Any) -> None:
        """Let a note go; a note that is not held (never played, or silenced since) is ignored."""
        midi = check_pitch(pitch)
        for k, (held, instrument) in enumerate(self._held):
            if held == midi:
                instrument.note_off(midi)
                del self._held[k]
                return

    def control(self, number: Any, value: Any) -> None:
        """A MIDI control change for every Instrument (64: the sustain pedal; the others as the
        model's note map says, e.g. CC 1), kept for the Instruments of later settings."""
        number, value = check_midi("cc", number, 0), check_midi("value", value, 0)
        self._controls[number] = value
        for instrument in self._instruments():
            instrument.control(number, value)

    def _instruments(self) -> list[Instrument]:
        return [r.instrument for r in self._ringing] + ([self.instrument] if self.instrument else [])

    def silence(self) -> None:
        """Every note gone at once (a stop's fade is over, or the sound blew up)."""
        self.instrument, self.settings, self._ringing, self._held = None, None, [], []

    def copy(self) -> Notes:
        """An independent copy (the model shared): it rings on as this would."""
        return copy.deepcopy(self, {id(self.model): self.model})

    def process(self, n: int) -> np.ndarray:
        """The next ``n`` samples of every note (float64), times the notes' gain; may raise a
        BarsynthError (a note the model refuses when it is played: then call :meth:`silence`)."""
        out = np.zeros(n)
        fade = max(1, int(round(FADE_S * self.sample_rate)))
        kept = []
        for ringing in self._ringing:
            x = ringing.instrument.process(n)
            if ringing.fade >= 0:
                x *= np.clip(1.0 - (ringing.fade + 1 + np.arange(n)) / (fade + 1), 0.0, 1.0)
                ringing.fade += n
            out += x
            peak = float(np.max(np.abs(x))) if n else 0.0
            ringing.loudest = max(ringing.loudest, peak)
            held = any(instrument is ringing.instrument for _, instrument in self._held)
            if ringing.fade >= fade or (not held and peak <= QUIET * ringing.loudest):
                self._held = [(p, i) for p, i in self._held if i is not ringing.instrument]
                continue
            kept.append(ringing)
        self._ringing = kept
        if self.instrument is not None:
            out += self.instrument.process(n)
        return out * (self.gain if self.gain is not None else 1.0)
