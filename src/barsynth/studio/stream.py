"""One live stream of the studio: a model's voice, played at the page's pace.

The page (an AudioWorklet) plays what the server sends and reports how much it has
played; :class:`Stream` keeps at most ``lead`` samples beyond that in flight, so a
change is heard after at most the lead (about 32 ms), the report interval and the
browser's own output latency. Every change and re-trigger goes through a
:class:`~barsynth.models.crossfade.CrossfadingVoice`, so nothing clicks.

This module knows nothing of HTTP: the server feeds it the page's messages
(:meth:`Stream.handle`) and sends what :meth:`Stream.next_block` returns. The
messages are described in ``docs/studio.md``.

- Level: the gain is set when a voice starts, from an offline render of its settings
  (peak at ``HEADROOM_DBFS``); a limiter lowers it (ramped within a block) when a block
  would pass ``LIMIT`` and lets it back up by ``RECOVERY_DB_PER_S``, or faster after a deep cut:
  whatever its depth, the gain is back within ``RELEASE_S`` of the loud sound's end.
- Samples: every block of a voice passes :func:`~barsynth.models.rendering.check_samples`;
  non-finite or exploding output is never sent: the voice is silenced (until its next trigger
  or change) and the page gets the error line (``refused``). A ``start`` whose settings blow up
  is refused the same way, and the stream goes on as it was.
- A new ``start`` fades the old voice out over the cross-fade time while the new one
  begins; ``stop`` fades out, then silences the voice and stops sending.
- Sleep: a stream whose sound has stayed below ``SILENCE`` for ``SLEEP_AFTER_S`` and
  that has not been triggered for ``AWAKE_AFTER_TRIGGER_S`` sends nothing until the next
  trigger, note or change (a forgotten tab costs nothing).
- Notes (``note_on``, ``note_off``, ``control``): several at once, played by an Instrument of
  the stream's model beside its voice (:mod:`barsynth.studio.notes`: a ``set`` applies to the
  notes played after it), through the same gain, limiter, sample check, stop and sleep.
"""

from __future__ import annotations

import copy
import json
import math
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import BarsynthError, SamplesError
from ..checks import number_within, show_value
from ..models.crossfade import DEFAULT_FADE_S, CrossfadingVoice
from ..models.rendering import check_samples
from .notes import Notes, PlannedNote

BLOCK = 256  # samples per message
LEAD_S = 0.032  # how far the server may run ahead of what the page has played
HEADROOM_DBFS = -6.0
LIMIT = 0.98
RECOVERY_DB_PER_S = 6.0  # the limiter's release after a shallow cut
RELEASE_S = 0.5  # the longest release after any cut (a deep cut releases faster than RECOVERY_DB_PER_S)
SILENCE = 1e-5  # -100 dBFS
SLEEP_AFTER_S = 1.0
AWAKE_AFTER_TRIGGER_S = 3.0
MIN_STREAM_RATE = 8000
MAX_STREAM_RATE = 96000
MAX_ID = 2 ** 32 - 1
GAIN_PROBE_S = 1.0  # the offline render that sets a new voice's gain
MAX_LEAVING = 4  # voices fading out at once
MAX_ERRORS_WAITING = 4  # samples errors kept for the page until it is next told (more are dropped)
HEADER = struct.Struct("<II")

MESSAGES = {  # type -> (required fields, optional fields)
    "start": ({"model"}, {"parameters", "sample_rate"}),
    "trigger": (set(), set()),
    "release": (set(), set()),
    "set": ({"parameters"}, {"id"}),
    "played": ({"samples"}, set()),
    "stop": (set(), set()),
    "note_on": ({"pitch"}, {"velocity"}),
    "note_off": ({"pitch"}, set()),
    "control": ({"cc", "value"}, set()),
}
DEFAULT_VELOCITY = 100


class StreamError(BarsynthError):
    """A message the stream cannot act on; the stream goes on as it was."""


def _whole(name: str, value: Any, low: int, high: int, unit: str = "") -> int:
    if not number_within(value, low, high, whole=True):
        raise StreamError(f"parameter {name} = {show_value(value)} is out of range; allowed: whole numbers from "
                          f"{low} to {high}{' ' + unit if unit else ''}")
    return int(value)


def parse_message(text: str) -> dict[str, Any]:
    """A page's message as a dict with a known ``type`` and only its fields; else :class:`StreamError`."""
    try:
        message = json.loads(text, parse_constant=lambda name: (_ for _ in ()).throw(ValueError(name)))
    except (ValueError, RecursionError):
        raise StreamError("a stream message must be a JSON object; this is not valid JSON") from None
    if not isinstance(message, dict) or message.get("type") not in MESSAGES:
        kind = message.get("type") if isinstance(message, dict) else None
        raise StreamError(f"parameter type = {show_value(kind)} is not a stream message; allowed: one of "
                          f"{', '.join(MESSAGES)}")
    required, optional = MESSAGES[message["type"]]
    fields = set(message) - {"type"}
    if required - fields:
        raise StreamError(f"a {message['type']} message needs {', '.join(sorted(required - fields))}")
    if fields - required - optional:
        raise StreamError(f"unknown field {show_value(sorted(fields - required - optional)[0])} in a {message['type']} "
                          f"message; allowed: {', '.join(sorted(required | optional)) or 'none'}")
    return message


@dataclass
class _Playing:
    """A voice that sounds: its model, the cross-fading voice and its gain."""

    model: Any
    voice: CrossfadingVoice
    base_gain: float
    gain: float
    release_db_per_s: float = RECOVERY_DB_PER_S  # set by the last cut (see Stream._voice_block)
    total_samples: int = 0  # the voice's samples so far (the time named in a samples error)
    notes: Notes | None = None  # its notes (made with it)

    def __post_init__(self) -> None:
        if self.notes is None:
            self.notes = Notes(self.model, self.voice.sample_rate)

    def silence(self) -> None:
        """Nothing sounds: the voice reset, every note gone."""
        self.voice.reset()
        self.notes.silence()

    def copy(self) -> _Playing:
        """A copy that rings on beside this one (a stop's fade)."""
        return _Playing(self.model, copy.deepcopy(self.voice), self.base_gain, self.gain, notes=self.notes.copy())


class Stream:
    """One page's live stream (see the module docstring); not thread-safe: one caller at a time."""

    def __init__(self, *, lead_s: float = LEAD_S, block: int = BLOCK):
        self.block = block
        self.lead_s = lead_s
        self.sample_rate = 0
        self.blocks_sent = 0
        self.samples_sent = 0
        self.samples_played = 0
        self.applied_id = 0
        self._playing: _Playing | None = None
        self._leaving: list[tuple[_Playing, int]] = []  # voices fading out, with samples done
        self._running = False  # sending blocks
        self._stopping = -1  # samples of the stop fade done, or -1
        self._silent = 0  # samples in a row below SILENCE
        self._since_trigger = 0
        self._errors: list[str] = []  # samples errors to tell the page

    # -- state ------------------------------------------------------------------------
    @property
    def lead(self) -> int:
        """Samples the server may have in flight beyond what was played (whole blocks)."""
        return self.block * max(1, math.ceil(self.lead_s * self.sample_rate / self.block))

    @property
    def voice(self) -> CrossfadingVoice | None:
        """The voice that sounds now (None before the first start)."""
        return self._playing.voice if self._playing else None

    @property
    def model(self) -> Any:
        """The model that sounds now (None before the first start)."""
        return self._playing.model if self._playing else None

    @property
    def model_name(self) -> str | None:
        return self._playing.model.name if self._playing else None

    @property
    def running(self) -> bool:
        return self._running

    def wants_block(self) -> bool:
        """Whether a block should be sent now."""
        return self.blocks_wanted() > 0

    def blocks_wanted(self) -> int:
        """How many blocks the page has room for now (0 when the stream rests)."""
        if not self._running:
            return 0
        return max(0, math.ceil((self.lead - (self.samples_sent - self.samples_played)) / self.block))

    def _fade(self) -> int:
        return max(1, int(round(DEFAULT_FADE_S * self.sample_rate)))

    # -- messages -----------------------------------------------------------------------
    def prepare_start(self, message: dict[str, Any]) -> tuple[Any, Any, int]:
        """Check a ``start`` message: the model, its resolved parameters and the rate (cheap)."""
        from ..models import get_model

        name = message["model"]
        if not isinstance(name, str):
            raise StreamError(f"parameter model = {show_value(name)} is not a model name")
        model = get_model(name)
        parameters = message.get("parameters") or {}
        if not isinstance(parameters, dict):
            raise StreamError("parameters must be a JSON object of parameter names and values")
        resolved = model.table.resolve(parameters)
        rate = message.get("sample_rate", 48000)
        if self._playing is not None and rate != self.sample_rate:
            raise StreamError(f"parameter sample_rate = {show_value(rate)} differs from this stream's "
                              f"{self.sample_rate} Hz; allowed: {self.sample_rate} Hz (open a new stream)")
        return model, resolved, _whole("sample_rate", rate, MIN_STREAM_RATE, MAX_STREAM_RATE, "Hz")

    @staticmethod
    def build_voice(model: Any, resolved: Any, rate: int) -> tuple[CrossfadingVoice, float]:
        """A new cross-fading voice and its gain (the expensive part of a start: run it off the event loop)."""
        voice = model.voice(resolved, sample_rate=rate, seed=None)
        voice.warm_up()  # a later slider change never compiles in the stream (the twang's full kernel)
        try:
            probe = model.render(resolved, duration_s=GAIN_PROBE_S, sample_rate=rate, normalize=False,
                                 dtype=np.float64)
            peak = float(np.max(np.abs(probe)))
        except SamplesError:
            raise  # these settings blow up: the start is refused
        except BarsynthError:
            peak = 0.0  # e.g. a twang with no audible mode: silent now, a change may make it sound
        gain = 10.0 ** (HEADROOM_DBFS / 20.0) / peak if peak > 0.0 and math.isfinite(peak) else 1.0
        return CrossfadingVoice(voice, table=model.table), gain

    def start(self, model: Any, voice: CrossfadingVoice, gain: float, rate: int) -> dict[str, Any]:
        """Put a built voice in place (the old one fades out); returns the ``started`` message."""
        if self._playing is not None and self._running:
            self._leave(self._playing, max(0, self._stopping))
        elif not self._running:
            self._leaving = []  # nothing is sounding: nothing to fade
        self.sample_rate = rate
        self._playing = _Playing(model, voice, gain, gain)
        self._stopping = -1
        self._wake()
        return {"type": "started", "model": model.name, "sample_rate": rate, "block": self.block,
                "lead": self.lead}

    def handle(self, message: dict[str, Any]) -> None:
        """Carry out a parsed message other than ``start`` (raises :class:`StreamError` or a
        parameter error; then nothing has changed)."""
        kind = message["type"]
        if kind == "played":
            played = _whole("samples", message["samples"], 0, 2 ** 53)
            self.samples_played = max(self.samples_played, min(played, self.samples_sent))
            return
        playing = self._playing
        if playing is None:
            raise StreamError(f"a {kind} message needs a started stream; send start first")
        if kind == "set":
            values = message["parameters"]
            if not isinstance(values, dict):
                raise StreamError("parameters must be a JSON object of parameter names and values")
            change_id = _whole("id", message.get("id", self.applied_id), 0, MAX_ID)
            playing.voice.set_parameters(**values)
            self.applied_id = change_id
            self._wake()
        elif kind == "trigger":
            self._restart_after_stop(playing)
            playing.voice.trigger()
            playing.total_samples = 0
            self._since_trigger = 0
            self._wake()
        elif kind == "release":
            playing.voice.release()
        elif kind == "note_on":
            self.play_note(self.plan_note(message))
        elif kind == "note_off":
            playing.notes.note_off(message["pitch"])
        elif kind == "control":
            playing.notes.control(message["cc"], message["value"])
        elif kind == "stop":
            if self._running and self._stopping < 0:
                self._stopping = 0

    def plan_note(self, message: dict[str, Any]) -> PlannedNote:
        """Check a ``note_on`` message and build what the note needs (the slow part of a note:
        run it off the event loop); changes nothing. A note out of range or out of the model's
        reach raises the one line."""
        playing = self._playing
        if playing is None:
            raise StreamError("a note_on message needs a started stream; send start first")
        return playing.notes.plan(playing.voice.parameters, message["pitch"],
                                  message.get("velocity", DEFAULT_VELOCITY), base_gain=playing.base_gain)

    def play_note(self, note: PlannedNote) -> None:
        """Play a planned note from the next block (it wakes a sleeping stream)."""
        playing = self._playing
        self._restart_after_stop(playing)
        playing.notes.note_on(note)
        self._since_trigger = 0
        self._wake()

    def _restart_after_stop(self, playing: _Playing) -> None:
        """Struck or played while fading out for a stop: the fade goes on beside, and the new
        sound starts from what the stop would have left (silence)."""
        if self._stopping >= 0:
            self._leave(playing.copy(), self._stopping)
            playing.silence()
            self._stopping = -1

    def _leave(self, playing: _Playing, done: int) -> None:
        """Fade ``playing`` out beside the new sound, ``done`` samples of the fade already past;
        at most ``MAX_LEAVING`` at once (then the oldest, nearly faded, goes at once)."""
        self._leaving = [*self._leaving[-(MAX_LEAVING - 1):], (playing, done)]

    def _wake(self) -> None:
        self._running = True
        self._silent = 0

    def refused(self) -> list[str]:
        """Messages of changes the voice refused when they were applied after a fade, and of voices
        silenced because their samples blew up (then forgotten)."""
        messages, self._errors = self._errors, []
        if self._playing is not None and self._playing.voice.refused:
            messages, self._playing.voice.refused = messages + self._playing.voice.refused, []
        return messages

    # -- sound ------------------------------------------------------------------------
    def next_block(self) -> bytes:
        """The next message of audio: the header and ``block`` float32 samples."""
        n = self.block
        out = self._voice_block(self._playing, n) if self._playing else np.zeros(n)
        for k, (leaving, done) in enumerate(self._leaving):
            fall = 1.0 - (done + 1 + np.arange(n)) / (self._fade() + 1)
            out += self._voice_block(leaving, n) * np.clip(fall, 0.0, 1.0)
            self._leaving[k] = (leaving, done + n)
        self._leaving = [(p, d) for p, d in self._leaving if d < self._fade()]
        if self._stopping >= 0:
            out *= np.clip(1.0 - (self._stopping + 1 + np.arange(n)) / (self._fade() + 1), 0.0, 1.0)
            self._stopping += n
        np.clip(out, -1.0, 1.0, out=out)
        header = HEADER.pack(self.blocks_sent & MAX_ID, self.applied_id)
        self.blocks_sent += 1
        self.samples_sent += n
        self._since_trigger += n
        self._after_block(out)
        return header + out.astype("<f4").tobytes()

    def _voice_block(self, playing: _Playing, n: int) -> np.ndarray:
        x = playing.voice.process(n, dtype=np.float64)
        try:
            if playing.notes.playing:
                x = x + playing.notes.process(n)
            check_samples(x, playing.voice.parameters, self.sample_rate, start=playing.total_samples)
            playing.total_samples += n
        except BarsynthError as exc:  # never send a blow-up (or a note refused late): silence and say why
            playing.silence()
            playing.total_samples = 0
            if len(self._errors) < MAX_ERRORS_WAITING:
                self._errors.append(str(exc))
            x = np.zeros(n)
        magnitude = np.abs(x)
        peak = float(np.max(magnitude)) if n else 0.0
        rate = self.sample_rate
        wanted = playing.gain * 10.0 ** (playing.release_db_per_s * n / rate / 20.0)
        wanted = min(playing.base_gain, wanted)
        if peak * wanted > LIMIT:
            wanted = LIMIT / peak
            # the release that takes this cut back to the voice's gain within RELEASE_S (never slower
            # than RECOVERY_DB_PER_S): a single spike leaves no long silence behind
            depth_db = 20.0 * math.log10(playing.base_gain / wanted) if wanted > 0.0 else 0.0
            playing.release_db_per_s = max(RECOVERY_DB_PER_S, depth_db / RELEASE_S)
        ramp = min(n, 32) if wanted < playing.gain else n  # down fast (32 samples), up slowly
        gains = np.full(n, wanted)
        gains[:ramp] = playing.gain + (wanted - playing.gain) * (np.arange(1, ramp + 1) / ramp)
        with np.errstate(divide="ignore"):
            np.minimum(gains, LIMIT / magnitude, out=gains)  # and no sample of the ramp above the limit
        playing.gain = wanted
        return x * gains

    def _after_block(self, out: np.ndarray) -> None:
        if self._stopping >= self._fade():  # faded out: silence and rest
            self._stopping = -1
            self._running = False
            if self._playing is not None:
                self._playing.silence()
            self._leaving = []
            return
        loud = np.flatnonzero(np.abs(out) >= SILENCE)
        self._silent = self._silent + out.size if loud.size == 0 else out.size - 1 - int(loud[-1])
        if (self._silent >= SLEEP_AFTER_S * self.sample_rate and self._since_trigger >= AWAKE_AFTER_TRIGGER_S
                * self.sample_rate and not self._leaving and not (self._playing and self._playing.voice.fading)):
            self._running = False
