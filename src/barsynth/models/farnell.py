"""Farnell's ruler twang ("Boing") and the listening test's anchor.

Source: A. Farnell, *Designing Sound*, MIT Press 2010, chapter "Boing" (Pure Data
patch ``twang.pd``), as read in barsynth spec 5; the anchor is the twang paper's
(Selfridge et al., AES Convention Paper 10553, 2022): the same patch with its
``phasor~`` replaced by a cosine.

On a trigger the drive phasor restarts at 0 and runs *down* at ``f/4 + 6 E(t)``
(``E = 3 d^64``, ``d`` falling 1 -> 0 over 7 s: an 18 Hz glide of about 110 ms); the
clamped bank ``C = c^4 sum g_k cos(2 pi r_k p)`` (``c`` falling over 1.5 s, cantilever
ratios 1, 6.267, 17.55, 34.39, gains halving from 0.5) drives noise x p^2 x C through
a 4 kHz one-pole into six ``vcf~`` band-passes (Q 80) at the free-bar ratios of
``f (1 + 0.1 E)``; out = 4 x hip~90(free + 0.2 C). Vibrato: ``depth sin(2 pi 5 t)``
added to ``f``, free-running.

Where barsynth departs from the patch, for its own rules: band-passes fade out over
the top 5 % below Nyquist instead of aliasing; frequency and depth changes glide
over 5 ms; a ``level_db`` scales the patch's output (0 dB = the patch).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..dsp.noise import noise_state
from ..parameters import BOOL, Parameter, ParameterTable
from . import farnell_kernel as K
from .base import Mode, resolve_parameters
from .rendering import (
    check_block_size,
    check_dtype,
    check_sample_rate,
    check_seed,
    render_voice,
)

FARNELL_TABLE = ParameterTable(
    "farnell",
    [
        Parameter("frequency_hz", "Hz", 20.0, 800.0, 426.0,
                  "pitch f: the free bands sit at f x (1, 2.7565, ...), the drive at f/4", scale="log"),
        Parameter("vibrato_depth_hz", "Hz", 1.0, 6.0, 6.0,
                  "depth of the free-running 5 Hz vibrato added to f"),
        Parameter("anchor", "", None, None, False,
                  "the listening test's anchor: the drive phasor replaced by a cosine", kind=BOOL),
        Parameter("level_db", "dB", -60.0, 12.0, 0.0,
                  "output level re the patch's own (x4 after the 90 Hz high-pass)"),
    ],
)
_ORDER = (("frequency_hz", K.P_FREQUENCY), ("vibrato_depth_hz", K.P_DEPTH),
          ("anchor", K.P_ANCHOR), ("level_db", K.P_LEVEL_DB))
assert tuple(name for name, _ in _ORDER) == FARNELL_TABLE.names


def _vector(parameters: Any) -> np.ndarray:
    vec = np.empty(K.N_PARAMS)
    for name, index in _ORDER:
        vec[index] = float(getattr(parameters, name))
    return vec


class FarnellVoice:
    """Streaming voice of Farnell's twang: ``prepare`` / ``reset`` / ``trigger`` / ``process``.

    Examples
    --------
    >>> voice = FarnellVoice({"frequency_hz": 300}, sample_rate=48000, seed=2)
    >>> voice.trigger()
    >>> voice.process(256).shape
    (256,)
    """

    restarts_on_trigger = True  # a trigger restarts the note (see models.crossfade)
    can_release = False
    uses_seed = True

    def __init__(self, parameters: Any = None, *, sample_rate: float = 48000.0, seed: int | None = 0):
        self._params = resolve_parameters(MODEL, parameters)
        self._seed = check_seed(seed)
        self.prepare(sample_rate)

    @property
    def parameters(self) -> Any:
        return self._params

    def prepare(self, sample_rate: float, max_block: int | None = None) -> None:
        """Set the sample rate (Hz) and reset."""
        self.sample_rate = check_sample_rate(sample_rate)
        self.reset()

    def reset(self) -> None:
        """Silence; restart the noise from the seed and the vibrato LFO from 0."""
        self._vector = _vector(self._params)
        self._state = np.zeros(K.N_STATE)
        self._state[K.S_TIME] = -1.0
        self._state[K.S_FREQ] = self._vector[K.P_FREQUENCY]
        self._state[K.S_DEPTH] = self._vector[K.P_DEPTH]
        self._rng = noise_state(self._seed)
        self._bands = np.zeros((2, 6))

    def set_parameters(self, **values: Any) -> None:
        """Change parameters (validated); frequency and depth glide over 5 ms."""
        self._params = resolve_parameters(MODEL, {**FARNELL_TABLE.as_dict(self._params), **values})
        self._vector = _vector(self._params)

    def trigger(self) -> None:
        """Strike: the phasor restarts at 0, both envelopes jump to 1 and the filters start
        empty, so a new note is the same whether or not one was ringing. (A ringing note is
        cut: :class:`~barsynth.models.crossfade.CrossfadingVoice` fades it out instead.)"""
        self._state[K.S_TIME] = 0.0
        self._state[K.S_PHASE] = 0.0
        self._state[K.S_LOWPASS] = 0.0
        self._state[K.S_HP_LAST] = 0.0
        self._bands[:] = 0.0

    def process(self, num_samples: int, *, dtype: Any = np.float32, trace: bool = False) -> Any:
        """The next ``num_samples`` samples. With ``trace`` also a dict of the drive
        signal, the clamped bank C(t) and the free-bar sum (float64), for measuring."""
        dtype = check_dtype(dtype)
        n = check_block_size(num_samples)
        out = np.empty(n)
        lanes = np.empty((3, n)) if trace else np.empty((0, 0))
        K.process(out, lanes, self._vector, self.sample_rate, self._state, self._rng, self._bands)
        samples = out.astype(dtype, copy=False)
        if trace:
            return samples, {"drive": lanes[0], "clamped": lanes[1], "free": lanes[2]}
        return samples


class FarnellModel:
    """Farnell's twang as a barsynth model (see the module docstring)."""

    reports_reference_errors = False
    name = "farnell"
    summary = "Farnell's ruler twang, Designing Sound 2010 (and, with anchor=true, the paper's anchor)"
    table = FARNELL_TABLE

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The modes at rest (after the glide): the drive and clamped partials and the
        free bands. Gains are the patch's; T60 is that of the band-pass (free) or of
        the clamped envelope's c^4 fall (reported as the time to -60 dB)."""
        p = resolve_parameters(self, parameters)
        rate = check_sample_rate(sample_rate)
        drive = 0.25 * p.frequency_hz
        modes = []
        clamp_t60 = K.CLAMP_FALL_S * (1.0 - 10.0 ** (-60.0 / 80.0))  # c^4 = 1e-3
        for ratio, gain in zip(K.CLAMPED_RATIOS, K.CLAMPED_GAINS):
            f = drive * ratio
            if f < rate / 2:
                modes.append(Mode("clamped", f, gain * K.CLAMPED_MIX, clamp_t60))
        for ratio in K.FREE_RATIOS:
            fc = p.frequency_hz * ratio
            cf = 2.0 * math.pi * fc / rate
            edge = (rate / 2 - fc) / (K.NYQUIST_TAPER * rate / 2)
            if edge <= 0.0:
                continue
            r = max(1e-12, 1.0 - cf / K.BAND_Q)
            t60 = math.log(1000.0) / (-math.log(r) * rate) if r < 1.0 else math.inf
            modes.append(Mode("free-bar", fc, min(1.0, edge), t60))
        return modes

    def voice(self, parameters: Any = None, *, sample_rate: float = 48000.0,
              seed: int | None = 0) -> FarnellVoice:
        return FarnellVoice(parameters, sample_rate=sample_rate, seed=seed)

    def render(self, parameters: Any = None, *, duration_s: float = 2.0,
               sample_rate: float = 48000.0, seed: int | None = 0,
               normalize: bool = True, dtype: Any = np.float32) -> np.ndarray:
        """Render one strike offline (peak at -1 dBFS unless ``normalize`` is false,
        then exactly the voice's samples)."""
        return render_voice(self.voice(parameters, sample_rate=sample_rate, seed=seed), duration_s,
                            normalize=normalize, dtype=dtype)


MODEL = FarnellModel()
