"""A polyphonic instrument: N voices of one model, notes allocated and stolen, a sustain pedal (spec 10.2).

Events (note on, note off, control change) take effect at a sample: ``at`` samples into the
next :meth:`Instrument.process` call, so a list of timed events gives the same samples
rendered in one block or in many. A note takes a silent voice, else the oldest released one,
else the quietest; a voice taken from a note that still sounds fades out over
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
from .notes import control_settings, note_hz, note_settings, velocity_fraction

STEAL_FADE_S = 0.005
SILENT = 1e-7
"""A released voice whose block peak falls below this (times its note's peak) is free again."""
SUSTAIN = 64
NOTES_KEPT = 1024
"""Notes whose settings are kept (a length-tuned note costs a few ``describe`` calls the first time)."""


@dataclass
class _Slot:
    voice: Any
    note: float | None = None
    started: int = -1
    released: int | None = None
    peak: float = 0.0
    loudest: float = 0.0
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
        self._notes: dict[tuple[float, float], dict[str, Any]] = {}  # (Hz, velocity fraction) -> its settings
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
        """A note ``at`` samples into the next process call. What it sets (the model's note map
        from the instrument's own settings) is worked out now, so a note the model cannot
        reach is refused here, in one line, and a note played again costs nothing more."""
        hz, fraction = note_hz(pitch, frequency_hz=frequency_hz), velocity_fraction(velocity)
        key = (hz, fraction)
        changes = self._notes.get(key)
        if changes is None:
            changes = note_settings(self.model, self._settings, hz, fraction, sample_rate=self.sample_rate)
            if len(self._notes) >= NOTES_KEPT:
                self._notes.clear()
            self._notes[key] = changes
        self._queue("on", at, hz, changes)

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
            if slot.note is not None and slot.peak > SILENT * max(slot.loudest, 1e-30):
                self._fading.append((copy.deepcopy(slot.voice), 0))
            slot.voice.reset()
            slot.voice.set_parameters(**changes)  # (Voice.note_on, its settings worked out when queued)
            slot.voice.trigger()
            slot.note, slot.started, slot.released, slot.held = hz, event.at, None, False
            slot.peak = slot.loudest = 0.0
        elif event.kind == "off":
            (hz,) = event.args
            for slot in self._slots:
                if slot.note == hz and slot.released is None and not slot.held:
                    if self._sustain:
                        slot.held = True
                    else:
                        slot.voice.note_off()
                        slot.released = event.at
                    break
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
        free = [s for s in self._slots if s.note is None or (s.released is not None
                                                             and s.peak <= SILENT * max(s.loudest, 1e-30))]
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
        for slot in self._slots:
            if slot.note is None:
                continue
            slot.voice.process(n, out=scratch)
            slot.peak = add_and_peak(out, scratch)  # out += scratch; np.max(np.abs(scratch))
            slot.loudest = max(slot.loudest, slot.peak)
        kept = []
        for voice, done in self._fading:
            voice.process(n, out=scratch)
            gains = np.clip(1.0 - (done + np.arange(1, n + 1)) / self._fade, 0.0, 1.0)
            out += scratch * gains
            if done + n < self._fade:
                kept.append((voice, done + n))
        self._fading = kept
