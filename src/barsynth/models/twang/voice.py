"""The twang's voice: it owns the kernel's records, follows changes, restarts on a trigger."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ...dsp.noise import noise_state
from ...dsp.smoothing import CURRENT, LEFT, LINEAR, MULTIPLICATIVE, SMOOTHED_STATE, TARGET, ramp_steps
from ...errors import ParameterError
from ...jitstart import compiled_for
from ..base import Voice
from . import kernel as K
from .design import N_BANDS, N_MODES, N_OSC, mode_lambdas, new_modes
from .table import ROWS, TWANG_TABLE, TwangParams, control_vector

SMOOTHING_TIME_S = 0.005  # every control ramps to a new value over 5 ms
CONTROL_FRAME_S = 0.002  # control work (ramps, vibrato, slide, design) every 2 ms
RAMP_KINDS = np.array([MULTIPLICATIVE if p.scale == "log" else LINEAR for p in TWANG_TABLE], dtype=np.int64)
"""Each control's ramp: multiplicative for the log-scaled rows, linear for the others."""


def check_mode_mask(mask: Any) -> np.ndarray:
    """``mask`` (None: every mode sounds) as 18 values, 1 (sound) or 0 (mute)."""
    if mask is None:
        return np.ones(N_MODES)
    values = np.asarray(mask)
    if values.shape != (N_MODES,) or not np.isin(values, (0, 1)).all():
        raise ParameterError(
            f"parameter mode_mask = {mask!r} is not allowed; allowed: {N_MODES} values, "
            "each true/1 (sound) or false/0 (mute)"
        )
    return values.astype(np.float64)


class TwangVoice(Voice):
    """A streaming ruler twang (Selfridge et al., AES 2022).

    A parameter change glides over ``SMOOTHING_TIME_S`` (5 ms) and never clicks; a trigger
    restarts every phasor at phase 0 with full amplitude (the paper's phase-aligned
    release). ``mode_mask`` (18 booleans, in ``describe`` order: 6 full-length cantilever,
    6 short cantilever, 6 free-bar) solos or mutes single modes, to listen to or measure
    one component; by default every mode sounds. It can also be set on a voice made by
    ``model.voice()`` (``voice.mode_mask = mask``); the change ramps like a gain.

    Examples
    --------
    >>> voice = TwangVoice({"length_m": 0.25}, sample_rate=48000, seed=1)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> voice.set_parameters(q=300)
    >>> more = voice.process(256)
    """

    restarts_on_trigger: ClassVar[bool] = True
    uses_seed: ClassVar[bool] = True
    _params: TwangParams

    def __init__(self, parameters: Any = None, *, sample_rate: float = 48000.0, seed: int | None = 0,
                 max_block: int | None = None, mode_mask: Any = None):
        self._mode_mask = check_mode_mask(mode_mask)
        self._lambdas = mode_lambdas()
        super().__init__(parameters, sample_rate=sample_rate, seed=seed, max_block=max_block)

    @property
    def parameters(self) -> TwangParams:
        return self._params

    @property
    def mode_mask(self) -> np.ndarray:
        """The 18 mode gates (1 sounds, 0 mutes); a copy."""
        return self._mode_mask.copy()

    @mode_mask.setter
    def mode_mask(self, mask: Any) -> None:
        self._mode_mask[:] = check_mode_mask(mask)
        self._note.scalars[K.S_DYNAMIC] = 1.0  # design again at the next frame; the gains ramp

    def _prepare(self) -> None:
        frame_len = max(1, int(round(self.sample_rate * CONTROL_FRAME_S)))
        slots = len(TWANG_TABLE)
        self._setup = K.Setup(self.sample_rate, frame_len, ramp_steps(SMOOTHING_TIME_S, self.sample_rate / frame_len),
                              self._lambdas, self._mode_mask, ROWS)
        self._controls = K.Controls(np.zeros(slots), np.zeros(slots), np.zeros((slots, SMOOTHED_STATE)), RAMP_KINDS)
        self._note = K.Note(np.zeros(K.N_SCALARS), noise_state(self.seed), np.zeros(frame_len),
                            np.zeros(2, dtype=np.int64))
        self._modes = new_modes()
        self._osc = K.Oscillators(np.zeros((2, N_OSC)), np.zeros((2, N_OSC, frame_len + 1)), np.zeros((3, N_OSC)),
                                  np.zeros(N_OSC, dtype=np.int64))
        self._run = None  # process compiled for these records, resolved at the first render (jitstart.compiled_for)
        self._bands = K.Bands(np.zeros((4, N_BANDS)), np.zeros((4, N_BANDS)), np.zeros(N_BANDS),
                              np.zeros((N_BANDS, frame_len + 1)), np.zeros((3, N_BANDS)),
                              np.zeros(N_BANDS, dtype=np.int64))

    def _reset(self) -> None:
        """Silence, every control at its target, and the noise restarted from the seed (fresh
        noise if the seed is None)."""
        control_vector(self._params, self._controls.target)
        ramps = self._controls.ramps
        ramps[:, CURRENT] = ramps[:, TARGET] = self._controls.target
        ramps[:, LEFT] = 0.0
        self._controls.values[:] = self._controls.target
        self._note.rng[:] = noise_state(self.seed)
        for record in (self._note, self._osc, self._bands):
            for array in record:
                if array is not self._note.rng:
                    array[...] = 0

    def _update(self, old: TwangParams) -> None:
        control_vector(self._params, self._controls.target)  # the kernel ramps there at its next frame

    def trigger(self) -> None:
        """Twang: restart every phasor at phase 0 with full amplitude. (A ringing note is cut:
        :class:`~barsynth.models.crossfade.CrossfadingVoice` fades it out instead.)"""
        K.settle(self._controls)
        scal = self._note.scalars
        scal[K.S_PHASE] = 0.0
        scal[K.S_TIME] = 0.0
        scal[K.S_FRAME_POS] = 0.0
        scal[K.S_LFO_PHASE] = 0.0
        scal[K.S_FORCE] = 1.0
        self._osc.z[0] = 1.0
        self._osc.z[1] = 0.0
        self._bands.env[:] = 1.0
        # The new note's filters start empty: state left by the old note (with other
        # coefficients) would otherwise ring out through the new, maybe narrow, bands.
        self._bands.state[:] = 0.0
        scal[K.S_LOWPASS] = 0.0
        scal[K.S_X1] = 0.0
        scal[K.S_X2] = 0.0

    def _render(self, out: np.ndarray) -> None:
        run = self._run
        if run is None:  # process's dispatcher would type the five records at every call (~6 us)
            run = self._run = compiled_for(K.process, out, self._setup, self._controls, self._note, self._modes,
                                           self._osc, self._bands)
        run(out, self._setup, self._controls, self._note, self._modes, self._osc, self._bands)
