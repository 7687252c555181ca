"""A voice whose every change is cross-faded: no parameter change or re-trigger clicks.

Each model's voice smooths what it can (the twang glides every control over 5 ms, every
model its output level), but some changes cannot glide: a new grid of the finite-difference
bar, a new set of banded loops, a rebuilt all-pass waveguide, or the twang's trigger, which
restarts every phasor of a note that is still ringing. :class:`CrossfadingVoice` wraps any
voice and, for each such event, keeps a copy of the voice as it was and fades from it to the
voice as it is now over ``fade_s`` (10 ms by default, linear: the two are the same sound up
to the change, so their gains sum to one). Both paths are continuous, so their mix is.

- ``set_parameters``: always cross-faded; a change that arrives during a fade waits
  for it to end (at most ``fade_s``), merged with any others that wait.
- ``trigger``: a voice whose trigger restarts the sound (``restarts_on_trigger``: the
  twang and Farnell's twang, whose voices declare ``restarts_on_trigger``) rings
  on in a copy that fades out while the new note starts at once, at full level, with its
  own attack (more triggers during that fade make one more restart after it); a voice
  whose strikes add to what rings (banded, all-pass, finite-difference) is struck as it
  is, with no copy.
- ``release`` goes straight to the voice.

With no event pending the output is the voice's own, sample for sample.

``process(n, out=buf)`` keeps the voice contract (:meth:`barsynth.models.base.Voice.process`):
the samples go into the caller's float32 or float64 buffer and nothing is allocated, during a
fade too (the fade's work space is allocated when the wrapper is made and by :meth:`prepare`;
the copy a fade starts from is made by the event that starts it, not by ``process``).

Examples
--------
>>> from barsynth.models import get_model
>>> voice = CrossfadingVoice(get_model("twang").voice(sample_rate=48000))
>>> voice.trigger()
>>> first = voice.process(4800)
>>> voice.trigger()            # the ringing note fades out over 10 ms; no click
>>> voice.set_parameters(length_m=0.2)
>>> voice.process(4800).shape
(4800,)
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from ..checks import check_number
from .base import check_out
from .rendering import check_block_size, check_dtype

DEFAULT_FADE_S = 0.010


class CrossfadingVoice:
    """``voice`` with its parameter changes and restarting triggers cross-faded over ``fade_s`` seconds.

    ``table``: the model's parameter table, to refuse a bad value at once even when the
    change has to wait for a fade (by default the voice's ``model.table`` where it has one).
    A change that the voice refuses only when it is applied after a fade (a combination
    of values, each in range, that the model cannot run) is dropped, and its message is
    kept in :attr:`refused`.
    """

    def __init__(self, voice: Any, *, fade_s: float = DEFAULT_FADE_S, table: Any = None):
        self.voice = voice
        self.fade_s = check_number("fade_s", fade_s, "s", minimum=0.0005, maximum=1.0)
        self._table = table if table is not None else voice.model.table
        self._old: Any = None  # the voice as it was, fading out
        self._done = 0  # samples of the fade done
        self._restart = False  # the fade is a restart: the new note sounds at once, the old fades out
        self._waiting: list[tuple[str, dict[str, Any]]] = []  # events that arrived during a fade
        self.refused: list[str] = []
        self._allocate(voice.max_block)

    def _allocate(self, max_block: int) -> None:
        """The work space of a fade, for pieces of up to ``max_block`` samples."""
        self.max_block = max_block
        self._old_block = np.empty(max_block)  # the old voice's samples
        self._gains = np.empty(max_block)  # the fade's gains
        self._counts = np.arange(1.0, max_block + 1.0)  # 1, 2, ...: samples into the piece
        self._mix = np.empty(max_block)  # the mix, in float64, for a float32 buffer

    def prepare(self, sample_rate: float, max_block: int | None = None) -> None:
        """Prepare the voice for ``sample_rate`` (Hz) and blocks of up to ``max_block`` samples
        (:meth:`barsynth.models.base.Voice.prepare`: it is reset, so silent) and allocate the
        fade's work space. A fade under way ends; changes waiting for it are made now (one the
        voice refuses goes to :attr:`refused`), a trigger waiting for it is dropped. A refused
        rate changes nothing."""
        from ..errors import BarsynthError

        self.voice.prepare(sample_rate, max_block)  # may raise: then nothing has changed
        self._allocate(self.voice.max_block)
        waiting, self._old, self._done, self._waiting = self._waiting, None, 0, []
        for kind, values in waiting:
            if kind == "set":
                try:
                    self.voice.set_parameters(**values)
                except BarsynthError as exc:
                    self.refused.append(str(exc))

    # -- what the wrapped voice has ------------------------------------------------------
    @property
    def sample_rate(self) -> float:
        return self.voice.sample_rate

    @property
    def parameters(self) -> Any:
        """The parameters the voice has (changes still waiting for a fade to end not included)."""
        return self.voice.parameters

    @property
    def fading(self) -> bool:
        """Whether a cross-fade is under way."""
        return self._old is not None

    @property
    def _length(self) -> int:
        return max(1, int(round(self.fade_s * self.voice.sample_rate)))

    def reset(self) -> None:
        """Silence: the voice reset, any fade and waiting event dropped."""
        self.voice.reset()
        self._old, self._done, self._waiting = None, 0, []

    # -- events ----------------------------------------------------------------------
    def set_parameters(self, **values: Any) -> None:
        """Change parameters (each value validated now); the change is cross-faded."""
        if self._table is not None:
            self._table.validate(values)
        if self._old is not None:
            if self._waiting and self._waiting[-1][0] == "set":
                self._waiting[-1][1].update(values)
            else:
                self._waiting.append(("set", dict(values)))
            return
        self._change(values)

    def _change(self, values: dict[str, Any]) -> None:
        old = copy.deepcopy(self.voice)
        self.voice.set_parameters(**values)  # may raise: then nothing has changed
        self._old, self._done, self._restart = old, 0, False

    def trigger(self) -> None:
        """Strike (twang, bow, pluck) now; a restarting note's old sound fades out."""
        if not type(self.voice).restarts_on_trigger:
            self.voice.trigger()  # strikes add to what rings: strike both sides of a fade alike
            if self._old is not None:
                self._old.trigger()
        elif self._old is not None:  # the mix of a fade cannot be copied: after it (once, however often asked)
            if not any(kind == "trigger" for kind, _ in self._waiting):
                self._waiting.append(("trigger", {}))
        else:
            self._old, self._done, self._restart = copy.deepcopy(self.voice), 0, True
            self.voice.trigger()

    def release(self) -> None:
        """End a bow stroke (voices that have no bow ignore it)."""
        for voice in (self.voice, self._old):
            if voice is not None and type(voice).can_release:
                voice.release()

    def _next_event(self) -> None:
        """After a fade: carry out what waited, up to the next event that fades."""
        from ..errors import BarsynthError

        while self._waiting and self._old is None:
            kind, values = self._waiting.pop(0)
            if kind == "trigger":
                self.trigger()
                continue
            try:
                self._change(values)
            except BarsynthError as exc:
                self.refused.append(str(exc))

    # -- sound -----------------------------------------------------------------------
    def process(self, num_samples: int, *, out: np.ndarray | None = None, dtype: Any = np.float32) -> np.ndarray:
        """The next ``num_samples`` samples (mono), as :meth:`barsynth.models.base.Voice.process`.

        Without ``out``: a new array, float32 unless ``dtype`` says float64. With ``out`` (a 1-D
        float32 or float64 array of exactly ``num_samples``, which the caller owns): the samples
        are written there and ``out`` is returned; nothing is allocated.
        """
        n = check_block_size(num_samples)
        if out is None:
            kind = check_dtype(dtype)
            samples = np.empty(n)
            self._render(samples)
            return samples.astype(kind, copy=False)
        check_out(out, n)
        if out.dtype == np.float64:
            self._render(out)
            return out
        for start in range(0, n, self.max_block):  # float32: mixed in float64, then cast
            stop = min(n, start + self.max_block)
            piece = self._mix[:stop - start]
            self._render(piece)
            out[start:stop] = piece
        return out

    def _render(self, out: np.ndarray) -> None:
        """Write ``out.size`` samples into the float64 array ``out``: the voice's own, or during
        a fade the mix, in place (the new voice's samples are rendered into ``out``)."""
        n, start = out.size, 0
        while start < n:
            if self._old is None:
                self.voice.process(n - start, out=out[start:])
                return
            count = min(n - start, self._length - self._done, self.max_block)
            new = self.voice.process(count, out=out[start:start + count])
            old = self._old.process(count, out=self._old_block[:count])
            rise = np.add(self._counts[:count], self._done, out=self._gains[:count])  # done + 1, done + 2, ...
            rise /= self._length + 1
            if self._restart:  # the new note with its own attack; the old one fades out: new + (1 - rise) old
                np.subtract(1.0, rise, out=rise)
                rise *= old
                new += rise
            else:  # the same sound before and after the change, gains that sum to one: old + rise (new - old)
                new -= old
                new *= rise
                new += old
            self._done += count
            start += count
            if self._done >= self._length:
                self._old = None
                self._next_event()
