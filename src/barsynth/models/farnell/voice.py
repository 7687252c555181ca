"""The streaming voice of Farnell's twang: it owns the kernel's records and follows changes."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ...dsp.noise import noise_state
from ...dsp.smoothing import SmoothedValue
from ...jitstart import compiled_for
from ..base import Voice
from ..rendering import check_block_size
from . import kernel as K
from .table import FarnellParams

SMOOTHING_TIME_S = 0.005  # frequency, depth and level glide to a new value over 5 ms
N_BANDS = len(K.FREE_RATIOS)


def level_gain(p: FarnellParams) -> float:
    """The output gain ``level_db`` sets (1 = the patch's own level)."""
    return 10.0 ** (p.level_db / 20.0)


class FarnellVoice(Voice):
    """Farnell's twang, streaming (Designing Sound, 2010, "Boing").

    A trigger restarts the note; ``frequency_hz``, ``vibrato_depth_hz`` and ``level_db``
    changed while it sounds glide over ``SMOOTHING_TIME_S`` (5 ms); ``anchor`` switches at
    once. :meth:`trace` also returns the patch's inner signals, for measuring.

    Examples
    --------
    >>> voice = FarnellVoice({"frequency_hz": 300}, sample_rate=48000, seed=2)
    >>> voice.trigger()
    >>> voice.process(256).shape
    (256,)
    >>> samples, lanes = voice.trace(256)
    >>> sorted(lanes)
    ['clamped', 'drive', 'free']
    """

    restarts_on_trigger: ClassVar[bool] = True
    uses_seed: ClassVar[bool] = True
    _params: FarnellParams
    _run: Any = None  # process compiled for the records' types (no rate or setting changes them)

    @property
    def parameters(self) -> FarnellParams:
        return self._params

    def _prepare(self) -> None:
        p = self._params
        ramp = {"ramp_s": SMOOTHING_TIME_S, "step_rate": self.sample_rate}  # one step a sample
        self._frequency = SmoothedValue(p.frequency_hz, kind="multiplicative", **ramp)
        self._depth = SmoothedValue(p.vibrato_depth_hz, kind="linear", **ramp)
        self._gain = SmoothedValue(level_gain(p), kind="linear", **ramp)
        self._controls = self._new_controls()
        self._patch = K.Patch(np.zeros(K.N_SCALARS), noise_state(self.seed), np.zeros((2, N_BANDS)))
        self._no_lanes = np.empty((0, 0))

    def _new_controls(self) -> K.Controls:
        return K.Controls(self._params.anchor, self._frequency.state, self._depth.state, self._gain.state)

    def _reset(self) -> None:
        """Silence; frequency, depth and level at their targets; the noise restarted from the
        seed and the vibrato LFO from 0."""
        p = self._params
        self._frequency.set_current_and_target(p.frequency_hz)
        self._depth.set_current_and_target(p.vibrato_depth_hz)
        self._gain.set_current_and_target(level_gain(p))
        self._controls = self._new_controls()
        self._patch.scalars[:] = 0.0
        self._patch.scalars[K.S.time] = -1.0
        self._patch.rng[:] = noise_state(self.seed)
        self._patch.bands[:] = 0.0

    def _update(self, old: FarnellParams) -> None:
        p = self._params
        self._frequency.set_target(p.frequency_hz)
        self._depth.set_target(p.vibrato_depth_hz)
        self._gain.set_target(level_gain(p))
        if p.anchor != old.anchor:
            self._controls = self._new_controls()

    def trigger(self) -> None:
        """Strike: the phasor restarts at 0, both envelopes jump to 1 and the filters start
        empty, so a new note is the same whether or not one was ringing. (A ringing note is
        cut: :class:`~barsynth.models.crossfade.CrossfadingVoice` fades it out instead.)"""
        scalars = self._patch.scalars
        scalars[K.S.time] = 0.0
        scalars[K.S.phase] = 0.0
        scalars[K.S.lowpass] = 0.0
        scalars[K.S.hp_last] = 0.0
        self._patch.bands[:] = 0.0

    def _render(self, out: np.ndarray) -> None:
        run = self._run
        if run is None:  # numba's dispatcher would type both records at every call
            run = self._run = compiled_for(K.process, out, self._no_lanes, self.sample_rate, self._controls,
                                           self._patch)
        run(out, self._no_lanes, self.sample_rate, self._controls, self._patch)

    def trace(self, num_samples: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The next ``num_samples`` samples (float64, as :meth:`process` would give them) and
        the patch's inner signals over them: ``{"drive": the drive (phasor or cosine),
        "clamped": the clamped bank C(t), "free": the free-bar sum}``."""
        n = check_block_size(num_samples)
        out = np.empty(n)
        lanes = np.empty((len(K.LANES), n))
        K.process(out, lanes, self.sample_rate, self._controls, self._patch)
        return out, dict(zip(K.LANES, lanes))
