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

    A note that holds still (no vibrato, no slide, no change) runs the static kernel, which a
    first render after an install compiles in half the time; the first change of a voice
    compiles the dynamic one (see :meth:`warm_up`, to have it ready).
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
        self._note.scalars[K.S.dynamic] = 1.0  # design again at the next frame; the gains ramp
        self._static = False

    def _prepare(self) -> None:
        frame_len = max(1, int(round(self.sample_rate * CONTROL_FRAME_S)))
        slots = len(TWANG_TABLE)
        self._setup = K.Setup(self.sample_rate, frame_len, ramp_steps(SMOOTHING_TIME_S, self.sample_rate / frame_len),
                              self._lambdas, self._mode_mask, ROWS)
        self._controls = K.Controls(np.zeros(slots), np.zeros(slots), np.zeros((slots, SMOOTHED_STATE)), RAMP_KINDS)
        self._note = K.Note(np.zeros(K.N_SCALARS), noise_state(self.seed), np.zeros(frame_len),
                            np.zeros(2, dtype=np.int64))
        self._modes = new_modes()
        self._osc = K.Oscillators(np.zeros((2, N_OSC)), np.zeros((2, N_OSC)), np.zeros((2, N_OSC, frame_len + 1)),
                                  np.zeros((3, N_OSC)), np.zeros(N_OSC, dtype=np.int64))
        self._bands = K.Bands(np.zeros((4, N_BANDS)), np.zeros((4, N_BANDS)), np.zeros(N_BANDS), np.zeros(N_BANDS),
                              np.zeros((N_BANDS, frame_len + 1)), np.zeros((3, N_BANDS)),
                              np.zeros(N_BANDS, dtype=np.int64))
        # process compiled for these records' types (jitstart.compiled_for; the same at every
        # rate, so kept across prepare), each resolved when first needed: the static kernel
        # (modes None) and the dynamic one
        if not hasattr(self, "_run_dynamic"):
            self._run_static = self._run_dynamic = None

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
        self._hold_still()
        self._design_due = False

    def _update(self, old: TwangParams) -> None:
        control_vector(self._params, self._controls.target)  # the kernel ramps there at its next frame
        self._static = False  # the ramps need the dynamic kernel

    def _hold_still(self) -> None:
        """Run the static kernel if the settled controls keep the trigger's design (no
        vibrato, no slide: what :func:`~.kernel._follow` checks) and this voice has not
        got the dynamic kernel yet (:meth:`warm_up`, an earlier change)."""
        values, rows = self._controls.target, ROWS
        vibrato = values[rows.vibrato_rate_hz] > 0.0 and values[rows.vibrato_depth_hz] > 0.0
        self._static = self._run_dynamic is None and not vibrato and not values[rows.slide] > 0.0

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the dynamic kernel now, and use it from now on:
        a parameter change then never waits for a compile, and a trigger designs in compiled
        code (the static kernel's Python design costs about 0.1 ms a trigger).

        Without it a note that holds still (no vibrato, no slide, no parameter change: a
        first render's usual case) runs the static kernel, which compiles in half the
        time, and the first parameter change of a voice compiles the dynamic one (about
        3.5 s on one core, once per install; loading it from numba's cache takes
        milliseconds). The samples are the same either way.
        """
        if self._run_dynamic is None:
            self._run_dynamic = compiled_for(K.process, self._scratch, self._setup, self._controls, self._note,
                                             self._modes, self._osc, self._bands)
        self._static = False  # exact at any point: see kernel.design_note

    def trigger(self) -> None:
        """Twang: restart every phasor at phase 0 with full amplitude. (A ringing note is cut:
        :class:`~barsynth.models.crossfade.CrossfadingVoice` fades it out instead.)"""
        K.settle(self._controls)
        scal = self._note.scalars
        scal[K.S.phase] = 0.0
        scal[K.S.time] = 0.0
        scal[K.S.frame_pos] = 0.0
        scal[K.S.lfo_phase] = 0.0
        scal[K.S.force] = 1.0
        self._osc.z[0] = 1.0
        self._osc.z[1] = 0.0
        self._bands.env[:] = 1.0
        # The new note's filters start empty: state left by the old note (with other
        # coefficients) would otherwise ring out through the new, maybe narrow, bands.
        self._bands.state[:] = 0.0
        scal[K.S.lowpass] = 0.0
        scal[K.S.x1] = 0.0
        scal[K.S.x2] = 0.0
        # A note that holds still is designed in Python at its first render (the static
        # kernel's only design); one that moves designs in the dynamic kernel (warm_up).
        self._hold_still()
        self._design_due = self._static

    def _render(self, out: np.ndarray) -> None:
        # compiled_for: process's dispatcher would type the records at every call (~6 us)
        if self._static:  # (a parameter change or a new mode mask ends it: _update, mode_mask)
            if self._design_due:
                self._design_due = False
                K.design_note(self._setup, self._controls, self._note, self._modes, self._osc, self._bands)
            run = self._run_static
            if run is None:
                run = self._run_static = compiled_for(K.process, out, self._setup, self._controls, self._note, None,
                                                      self._osc, self._bands)
            run(out, self._setup, self._controls, self._note, None, self._osc, self._bands)
            return
        run = self._run_dynamic
        if run is None:
            run = self._run_dynamic = compiled_for(K.process, out, self._setup, self._controls, self._note,
                                                   self._modes, self._osc, self._bands)
        run(out, self._setup, self._controls, self._note, self._modes, self._osc, self._bands)
