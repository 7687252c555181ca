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
    def process(self, num_samples: int, *, dtype: Any = np.float32) -> np.ndarray:
        """The next ``num_samples`` samples, float32 unless ``dtype`` says otherwise."""
        dtype = check_dtype(dtype)
        n = check_block_size(num_samples)
        out = np.empty(n)
        start = 0
        while start < n:
            if self._old is None:
                out[start:] = self.voice.process(n - start, dtype=np.float64)
                break
            count = min(n - start, self._length - self._done)
            new = self.voice.process(count, dtype=np.float64)
            old = self._old.process(count, dtype=np.float64)
            rise = (self._done + 1 + np.arange(count)) / (self._length + 1)
            if self._restart:  # the new note with its own attack; the old one fades out
                out[start:start + count] = new + (1.0 - rise) * old
            else:  # the same sound before and after the change: gains that sum to one
                out[start:start + count] = old + rise * (new - old)
            self._done += count
            start += count
            if self._done >= self._length:
                self._old = None
                self._next_event()
        return out.astype(dtype, copy=False)
