"""A polyphonic instrument: N voices of one model, notes allocated and stolen, a sustain pedal (spec 10.2).

Events (note on, note off, control change) take effect at a sample: ``at`` samples into the
next :meth:`Instrument.process` call, so a list of timed events gives the same samples
rendered in one block or in many. A note takes a free voice (never used, or released and rung
out), else the oldest released one, else the quietest (by its last :data:`WINDOW`'s peak, so
these choices do not depend on the blocks either); a voice taken from a note that still sounds fades out over
``STEAL_FADE_S`` beside the new note (a copy of it, made at the event: no click). A released
note rings on (its tail); with the sustain pedal down (CC 64 >= 64) note offs wait until it
comes up.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import check_whole
from ..errors import ParameterError
from ..models import get_model
from ..models.base import check_out
from ..models.rendering import check_block_size
from .mixing import add_and_peak
from .notes import control_settings, note_hz, note_map, note_settings, velocity_fraction

STEAL_FADE_S = 0.005
SILENT = 1e-7
"""A released voice whose window peak falls below this (times its loudest window's) is free again
and no longer rendered (-140 dB)."""
SUSTAIN = 64
NOTES_KEPT = 1024
"""Notes whose pitch setting is kept (a length-tuned note costs a few ``describe`` calls the first
time: 0.1 ms on banded, 5 ms kalimba, about 50 ms fd, 110 ms allpass; then nothing, whatever its velocity)."""
WINDOW = 256
"""Voices' peaks are taken over windows of this many samples, aligned on the instrument's own
sample count: stealing and freeing then depend on the sound only, not on the caller's blocks."""


@dataclass
class _Slot:
    voice: Any
    note: float | None = None
    started: int = -1
    released: int | None = None
    peak: float = 0.0
    """The peak of the last whole :data:`WINDOW`."""
    loudest: float = 0.0
    """The loudest window's peak since the note began."""
    window_peak: float = 0.0
    """The peak so far of the window being rendered."""
    held: bool = False
    """Its note off came while the sustain pedal was down."""


@dataclass(order=True)
class _Event:
    at: int
    order: int
    kind: str = field(compare=False)
    args: tuple = field(compare=False)


class Instrument:
    """``voices`` voices of ``model`` (a name or a Model), from ``preset`` and ``parameters``.

    Examples
    --------
    >>> piano = Instrument("banded", voices=4, preset="marimba", sample_rate=48000)
    >>> piano.note_on(60, 100); piano.note_on(64, 90, at=100)
    >>> piano.process(512).shape
    (512,)
    """

    def __init__(self, model: Any, voices: int = 8, *, preset: str | None = None, parameters: dict | None = None,
                 sample_rate: float = 48000.0, seed: int | None = 0, max_block: int | None = None):
        self.model = get_model(model) if isinstance(model, str) else model
        count = check_whole("voices", voices, "voices", 1, 256)
        settings = dict(self.model.preset(preset).__dict__) if preset is not None else {}
        settings.update(parameters or {})
        self.sample_rate = sample_rate
        self._slots = [_Slot(self.model.voice(settings, sample_rate=sample_rate, seed=seed, max_block=max_block))
                       for _ in range(count)]
        self._settings = self._slots[0].voice.parameters  # every note's settings start from these
        self._pitch_parameter = note_map(self.model, self._settings).pitch
        self._pitches: dict[float, float] = {}  # a note's Hz -> the value its pitch's parameter takes
        self.max_block = self._slots[0].voice.max_block
        self._fading: list[tuple[Any, int]] = []  # (a stolen voice's copy, samples of its fade done)
        self._fade = max(1, int(round(STEAL_FADE_S * sample_rate)))
        self._events: list[_Event] = []
        self._order = 0
        self._now = 0  # samples rendered
        self._sustain = False
        self._scratch = np.empty(self.max_block)
        self._mix = np.empty(self.max_block)

    @property
    def rendered(self) -> int:
        """Samples rendered so far (events' ``at`` counts from here)."""
        return self._now

    # -- events ----------------------------------------------------------------------------
    def note_on(self, pitch: Any = None, velocity: Any = 100, *, frequency_hz: Any = None, at: int = 0) -> None:
        """A note ``at`` samples into the next process call. What it sets is worked out now
        (:meth:`note_settings`), so a note the model cannot reach is refused here, in one line."""
        self._queue("on", at, *self.note_settings(pitch, velocity, frequency_hz=frequency_hz))

    def note_settings(self, pitch: Any = None, velocity: Any = 100, *,
                      frequency_hz: Any = None) -> tuple[float, dict[str, Any]]:
        """A note's frequency (Hz) and the parameter changes it plays with (the model's note map
        from the instrument's own settings), or one line if the model cannot reach it. The pitch's
        setting is kept per frequency, so the note played again, at any velocity, costs no search
        (a caller may work it out ahead, off its audio thread: nothing else changes)."""
        hz, fraction = note_hz(pitch, frequency_hz=frequency_hz), velocity_fraction(velocity)
        changes = note_settings(self.model, self._settings, hz, fraction, sample_rate=self.sample_rate,
                                pitch_value=self._pitches.get(hz))
        if hz not in self._pitches:
            if len(self._pitches) >= NOTES_KEPT:
                self._pitches.clear()
            self._pitches[hz] = changes[self._pitch_parameter]
        return hz, changes

    def note_off(self, pitch: Any = None, *, frequency_hz: Any = None, at: int = 0) -> None:
        self._queue("off", at, note_hz(pitch, frequency_hz=frequency_hz))

    def control(self, number: int, value: int, *, at: int = 0) -> None:
        """A MIDI control change: 64 is the sustain pedal (a vibraphone's damper pedal: down, the
        bars ring on; up, a released note is damped, its preset's ``damper = release``); the
        others move what the model's note map says (CC 1 on a vibraphone: its motor's rate) and
        are ignored where it says nothing."""
        number = check_whole("number", number, "", 0, 127)
        value = check_whole("value", value, "", 0, 127)
        self._queue("cc", at, number, value)

    def _queue(self, kind: str, at: int, *args: Any) -> None:
        at = check_whole("at", at, "samples", 0, 10 ** 12)
        self._events.append(_Event(self._now + at, self._order, kind, args))
        self._order += 1
        self._events.sort()

    def _apply(self, event: _Event) -> None:
        if event.kind == "on":
            hz, changes = event.args
            slot = self._choose()
            if slot.note is not None:  # a sounding voice taken: its copy fades out beside the new note
                self._fading.append((copy.deepcopy(slot.voice), 0))
            # (Voice.note_on, its settings worked out when queued; set before the reset, which starts
            # a voice at its settings: set after it, Farnell's level and pitch would glide from the last note's)
            slot.voice.set_parameters(**changes)
            slot.voice.reset()
            slot.voice.trigger()
            slot.note, slot.started, slot.released, slot.held = hz, event.at, None, False
            slot.peak = slot.loudest = slot.window_peak = 0.0
        elif event.kind == "off":
            (hz,) = event.args
            sounding = [s for s in self._slots if s.note == hz and s.released is None and not s.held]
            if sounding:
                slot = min(sounding, key=lambda s: s.started)  # the oldest note of that pitch
                if self._sustain:
                    slot.held = True
                else:
                    slot.voice.note_off()
                    slot.released = event.at
        else:
            number, value = event.args
            changes = control_settings(self.model, self._slots[0].voice.parameters, number, value)
            if changes:
                for slot in self._slots:
                    slot.voice.set_parameters(**changes)
            if number == SUSTAIN:
                self._sustain = value >= 64
                if not self._sustain:
                    for slot in self._slots:
                        if slot.held:
                            slot.voice.note_off()
                            slot.released, slot.held = event.at, False

    def _choose(self) -> _Slot:
        free = [s for s in self._slots if s.note is None]
        if free:
            return free[0]
        released = [s for s in self._slots if s.released is not None]
        if released:
            return min(released, key=lambda s: s.released)
        return min(self._slots, key=lambda s: (s.peak, s.started))

    # -- sound -----------------------------------------------------------------------------
    def process(self, num_samples: int, *, out: np.ndarray | None = None) -> np.ndarray:
        """The next ``num_samples`` samples (float64), every event at its sample."""
        n = check_block_size(num_samples)
        if out is None:
            out = np.empty(n)
        else:
            check_out(out, n)
            if out.dtype != np.float64:
                raise ParameterError("parameter out must be float64 for an Instrument; allowed: a float64 buffer")
        done = 0
        while done < n:
            until = self._now + (n - done)
            if self._events and self._events[0].at < until:
                until = max(self._events[0].at, self._now)
            piece = min(until - self._now, self.max_block)
            if piece > 0:
                self._render(out[done:done + piece])
                done += piece
                self._now += piece
            while self._events and self._events[0].at <= self._now:
                self._apply(self._events.pop(0))
        return out

    def _render(self, out: np.ndarray) -> None:
        n = out.size
        out.fill(0.0)
        scratch = self._scratch[:n]
        first = (-self._now) % WINDOW or WINDOW  # samples to the end of the window this piece starts in
        for slot in self._slots:
            if slot.note is None:
                continue
            slot.voice.process(n, out=scratch)
            start, stop = 0, min(n, first)
            while start < n:
                # out += scratch; np.max(np.abs(scratch)), a window's piece at a time
                slot.window_peak = max(slot.window_peak, add_and_peak(out[start:stop], scratch[start:stop]))
                if (self._now + stop) % WINDOW == 0:  # a whole window: its peak is the voice's
                    slot.peak, slot.window_peak = slot.window_peak, 0.0
                    slot.loudest = max(slot.loudest, slot.peak)
                    if slot.released is not None and slot.peak <= SILENT * max(slot.loudest, 1e-30):
                        slot.note = None  # rung out: free, and no longer rendered
                        break
                start, stop = stop, min(n, stop + WINDOW)
        kept = []
        for voice, done in self._fading:
            voice.process(n, out=scratch)
            gains = np.clip(1.0 - (done + np.arange(1, n + 1)) / self._fade, 0.0, 1.0)
            out += scratch * gains
            if done + n < self._fade:
                kept.append((voice, done + n))
        self._fading = kept
