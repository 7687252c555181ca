"""The ruler twang: a physically derived model of a ruler twanged over a desk edge.

Source: L. Selfridge, J. Andreasson, E. Bengtsson, F. Kristjánsson, P. Lindborg,
E. Rydén, H. Tez and J. D. Reiss, "Twang! A physically derived synthesis model for
the sound of a vibrating bar", AES Convention Paper 10553, 152nd Convention, 2022.
(barsynth spec, part 2.)

Three groups of modes, all from Euler–Bernoulli physics (:mod:`barsynth.physics`):

1. the full-length cantilever (clamped at the finger, length ``length_m``): six
   phase-aligned decaying cosines;
2. the short cantilever at the desk edge (``short_length_ratio`` x the length):
   six more, at 0.75 x the gains of group 1 (``short_cantilever_gain``);
3. the free bar: white noise x (drive phasor at the full-length fundamental)²,
   a one-pole low-pass, and six 4th-order band-passes at the free–free modes,
   each with its gain and decay.

Gains follow a beta density (shape ``shape``, m = 4) over frequency, linear (the
paper) or logarithmic (the paper's suggested improvement). Every mode decays with
``alpha = pi f / q``; the damped-frequency shift (< 0.01 % for Q >= 50) is ignored.

Choices where the paper is silent (spec 2.8), all in the parameter table below or
the constants of :mod:`barsynth.models.twang_kernel`:

* one-pole cutoff ``noise_cutoff_hz`` = 4 kHz (Farnell's value); band-pass section
  Q ``free_band_q`` = 10, each band scaled to unit white-noise power gain;
* the free-bar bands carry their own decay (pi f / Q at their own frequency), not
  the cantilever's; the noise drive itself does not decay;
* vibrato moves every mode (and the drive phasor) by one common factor, so the bar
  keeps its ratios; the loudest mode swings by ``vibrato_depth_hz`` (18 Hz, the
  paper), capped at 6 %; the LFO restarts at each trigger;
* slide raises the short-cantilever modes by 35 % along a smoothstep (raised
  S-curve) over ``slide_time_s`` from the trigger, then holds;
* modes fade out over the top 5 % below Nyquist and are silent at or above it;
* controls are smoothed with a one-pole of ``SMOOTHING_TIME_S`` (5 ms) at the
  control rate (one frame every 2 ms), gains ramp linearly inside a frame;
* the level scale is ``level / max(1.75 x sum of the full-length beta gains, sum
  of the free-bar beta gains)``, recomputed with every design and ramped like the
  gains; the mix gains and ``mode_mask`` act on top of it as true gains. With the
  paper's mix, where the cantilever sum is the larger (every preset), a note's
  first sample (all cosines at phase 0, noise drive at 0) is exactly ``level_db``;
* vibrato depth fades in over rates from 0 to 0.5 Hz, so turning vibrato off
  glides back to pitch; free-bar bands fade out from 30 Hz to 20 Hz and are
  silent below (a band-pass that low and narrow only stores energy).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..dsp.noise import noise_state
from ..errors import ParameterError
from ..parameters import BOOL, CHOICE, Parameter, ParameterTable
from . import twang_kernel as K
from .base import Mode, resolve_parameters
from .shared import material_parameter
from .rendering import (
    check_block_size,
    check_dtype,
    check_sample_rate,
    check_seed,
    render_voice,
)

SMOOTHING_TIME_S = 0.005
CONTROL_FRAME_S = 0.002
GROUPS = ("full-cantilever", "short-cantilever", "free-bar")
AUDIBLE_MIN_HZ = 20.0  # an offline render needs one mode at least this high

TWANG_TABLE = ParameterTable(
    "twang",
    [
        Parameter("youngs_modulus_pa", "Pa", 1e8, 4e11, 3.2e9,
                  "Young's modulus E of the ruler (acrylic 3.2 GPa, steel 200 GPa)", scale="log"),
        Parameter("density_kg_m3", "kg/m^3", 100.0, 22000.0, 1180.0,
                  "density rho of the ruler material", scale="log"),
        material_parameter(),
        Parameter("length_m", "m", 0.05, 1.0, 0.30,
                  "clamped length L, from the finger to the tip (the paper's 'whole bar')"),
        Parameter("thickness_m", "m", 0.0003, 0.02, 0.003,
                  "thickness h of the ruler in the bending direction", scale="log"),
        Parameter("q", "", 50.0, 800.0, 100.0,
                  "decay quality factor Q of every mode: alpha = pi f / Q", scale="log"),
        Parameter("shape", "", 0.5, 10.0, 1.5,
                  "beta-density gain shape l (m = 4): small favours low modes"),
        Parameter("gain_mapping", "", None, None, "linear",
                  "frequency axis of the gain shape: linear 0..fs/2 (paper) or log 1 Hz..fs/2",
                  kind=CHOICE, choices=("linear", "log")),
        Parameter("vibrato_rate_hz", "Hz", 0.0, 8.0, 0.0,
                  "vibrato rate; 0 turns vibrato off"),
        Parameter("vibrato_depth_hz", "Hz", 0.0, 50.0, 18.0,
                  "vibrato swing of the loudest mode (paper: 18 Hz), at most 6 %"),
        Parameter("slide", "", None, None, False,
                  "slide: the short-cantilever modes rise 35 % (the ruler is shortened)",
                  kind=BOOL),
        Parameter("slide_time_s", "s", 0.05, 10.0, 1.0,
                  "duration of the slide's S-shaped rise, from the trigger", scale="log",
                  when={"slide": (True,)}),
        Parameter("short_length_ratio", "", 0.3, 0.95, 0.7,
                  "length of the short cantilever at the desk edge, as a fraction of L"),
        Parameter("full_cantilever_gain", "", 0.0, 1.0, 1.0,
                  "mix of the full-length cantilever modes"),
        Parameter("short_cantilever_gain", "", 0.0, 1.0, 0.75,
                  "mix of the short cantilever modes, relative to the full-length ones (paper: 0.75)"),
        Parameter("free_bar_gain", "", 0.0, 4.0, 1.0,
                  "mix of the noise-excited free-bar modes"),
        Parameter("noise_cutoff_hz", "Hz", 100.0, 20000.0, 4000.0,
                  "cutoff of the one-pole low-pass on the free-bar noise", scale="log"),
        Parameter("free_band_q", "", 1.0, 100.0, 10.0,
                  "Q of each 2nd-order section of the free-bar 4th-order band-passes", scale="log"),
        Parameter("level_db", "dB", -60.0, 0.0, -3.0,
                  "output level of a note's first peak, dB re full scale"),
    ],
)

_KERNEL_ORDER = (
    (K.P_YOUNGS, "youngs_modulus_pa"), (K.P_DENSITY, "density_kg_m3"), (K.P_LENGTH, "length_m"),
    (K.P_THICKNESS, "thickness_m"), (K.P_Q, "q"), (K.P_SHAPE, "shape"),
    (K.P_GAIN_MAPPING, "gain_mapping"), (K.P_VIB_RATE, "vibrato_rate_hz"),
    (K.P_VIB_DEPTH, "vibrato_depth_hz"), (K.P_SLIDE, "slide"), (K.P_SLIDE_TIME, "slide_time_s"),
    (K.P_SHORT_RATIO, "short_length_ratio"), (K.P_FULL_GAIN, "full_cantilever_gain"),
    (K.P_SHORT_GAIN, "short_cantilever_gain"), (K.P_FREE_GAIN, "free_bar_gain"),
    (K.P_NOISE_CUTOFF, "noise_cutoff_hz"), (K.P_BAND_Q, "free_band_q"), (K.P_LEVEL_DB, "level_db"),
)
assert tuple(name for _, name in sorted(_KERNEL_ORDER)) == tuple(n for n in TWANG_TABLE.names if n != "material")
assert len(TWANG_TABLE) - 1 == K.N_PARAMS

_LOG_MASK = np.array([TWANG_TABLE[name].scale == "log" for _, name in sorted(_KERNEL_ORDER)], dtype=np.bool_)


def _lambdas() -> np.ndarray:
    from ..physics import lambdas

    return np.concatenate(
        [lambdas("clamped-free", K.MODES_PER_GROUP), lambdas("free-free", K.MODES_PER_GROUP)]
    ).astype(np.float64)


def _vector(parameters: Any) -> np.ndarray:
    """The resolved parameters as the kernel's float64 vector."""
    vec = np.empty(K.N_PARAMS)
    for index, name in _KERNEL_ORDER:
        value = getattr(parameters, name)
        if name == "gain_mapping":
            value = 1.0 if value == "log" else 0.0
        vec[index] = float(value)
    return vec


def _mode_mask(mask: Any) -> np.ndarray:
    if mask is None:
        return np.ones(K.N_MODES)
    values = np.asarray(mask)
    if values.shape != (K.N_MODES,) or not np.isin(values, (0, 1)).all():
        raise ParameterError(
            f"parameter mode_mask = {mask!r} is not allowed; allowed: {K.N_MODES} values, "
            "each true/1 (sound) or false/0 (mute)"
        )
    return values.astype(np.float64)


def design_modes(parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
    """Every mode the twang will synthesise at the trigger (vibrato and slide at rest).

    Modes silenced by Nyquist or by a zero group gain are left out.
    """
    params = resolve_parameters(MODEL, parameters)
    freqs = np.empty(K.N_MODES)
    gains = np.empty(K.N_MODES)
    alphas = np.empty(K.N_MODES)
    K.design(_vector(params), _lambdas(), np.ones(K.N_MODES), check_sample_rate(sample_rate),
             0.0, 0.0, freqs, gains, alphas)
    modes = []
    for i in range(K.N_MODES):
        if gains[i] > 0.0:
            modes.append(
                Mode(
                    group=GROUPS[i // K.MODES_PER_GROUP],
                    frequency_hz=float(freqs[i]),
                    gain=float(gains[i]),
                    t60_s=float(math.log(1000.0) / alphas[i]),
                )
            )
    return modes


class TwangVoice:
    """A streaming twang voice: ``prepare`` / ``reset`` / ``trigger`` / ``process``.

    Parameters change at any time with :meth:`set_parameters`; the change is
    smoothed (5 ms) and never clicks. ``process(n)`` returns the next ``n``
    samples; the concatenation of blocks of any sizes equals one long block.

    ``mode_mask`` (18 booleans, in :func:`design_modes` order: 6 full-length
    cantilever, 6 short cantilever, 6 free-bar) solos or mutes single modes, to
    listen to or measure one component; by default every mode sounds.

    Examples
    --------
    >>> voice = TwangVoice({"length_m": 0.25}, sample_rate=48000, seed=1)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> voice.set_parameters(q=300)
    >>> more = voice.process(256)
    """

    restarts_on_trigger = True  # a trigger restarts the note (see models.crossfade)
    can_release = False
    uses_seed = True

    def __init__(self, parameters: Any = None, *, sample_rate: float = 48000.0, seed: int | None = 0,
                 mode_mask: Any = None):
        self._params = resolve_parameters(MODEL, parameters)
        self._mode_mask = _mode_mask(mode_mask)
        self._seed = check_seed(seed)
        self._lambdas = _lambdas()
        self.prepare(sample_rate)

    @property
    def parameters(self) -> Any:
        """The current (target) parameters, as the frozen dataclass."""
        return self._params

    def prepare(self, sample_rate: float, max_block: int | None = None) -> None:
        """Set the sample rate (Hz) and reset; ``max_block`` is accepted for symmetry."""
        self.sample_rate = check_sample_rate(sample_rate)
        self._frame_len = max(1, int(round(self.sample_rate * CONTROL_FRAME_S)))
        frames_per_tau = SMOOTHING_TIME_S * self.sample_rate / self._frame_len
        self._smooth_k = 1.0 - math.exp(-1.0 / frames_per_tau)
        self.reset()

    def reset(self) -> None:
        """Silence the voice and restart its noise from the seed (fresh noise if the seed is None)."""
        self._target = _vector(self._params)
        self._current = self._target.copy()
        self._scal = np.zeros(K.N_SCALARS)
        self._rng = noise_state(self._seed)
        frame = self._frame_len
        self._osc_z = np.zeros((2, K.N_OSC))
        self._osc_pow = np.zeros((2, K.N_OSC, frame + 1))
        self._osc_gain = np.zeros((3, K.N_OSC))
        self._band_state = np.zeros((4, K.N_BANDS))
        self._band_coef = np.zeros((4, K.N_BANDS))
        self._band_env = np.zeros(K.N_BANDS)
        self._band_pow = np.zeros((K.N_BANDS, frame + 1))
        self._band_gain = np.zeros((3, K.N_BANDS))
        self._excitation = np.zeros(frame)
        self._osc_active = np.zeros(K.N_OSC, dtype=np.int64)
        self._band_active = np.zeros(K.N_BANDS, dtype=np.int64)
        self._counts = np.zeros(2, dtype=np.int64)
        self._freqs = np.zeros(K.N_MODES)
        self._gains = np.zeros(K.N_MODES)
        self._alphas = np.zeros(K.N_MODES)

    def set_parameters(self, **values: Any) -> None:
        """Change parameters (validated); the sound follows within a few ms."""
        self._params = resolve_parameters(MODEL, {**TWANG_TABLE.as_dict(self._params), **values})
        self._target = _vector(self._params)

    def trigger(self) -> None:
        """Twang: restart every phasor at phase 0 with full amplitude. (A ringing note is cut:
        :class:`~barsynth.models.crossfade.CrossfadingVoice` fades it out instead.)"""
        self._current[:] = self._target
        self._scal[K.S_PHASE] = 0.0
        self._scal[K.S_TIME] = 0.0
        self._scal[K.S_FRAME_POS] = 0.0
        self._scal[K.S_LFO_PHASE] = 0.0
        self._scal[K.S_FORCE] = 1.0
        self._osc_z[0] = 1.0
        self._osc_z[1] = 0.0
        self._band_env[:] = 1.0
        # The new note's filters start empty: state left by the old note (with other
        # coefficients) would otherwise ring out through the new, maybe narrow, bands.
        self._band_state[:] = 0.0
        self._scal[K.S_LOWPASS] = 0.0
        self._scal[K.S_X1] = 0.0
        self._scal[K.S_X2] = 0.0

    def process(self, num_samples: int, *, dtype: Any = np.float32) -> np.ndarray:
        """The next ``num_samples`` samples (mono), float32 unless ``dtype`` says otherwise."""
        dtype = check_dtype(dtype)
        out = np.empty(check_block_size(num_samples))
        if out.size:
            K.process(out, self._current, self._target, _LOG_MASK, self._smooth_k, self._lambdas,
                      self._mode_mask, self.sample_rate, self._frame_len, self._scal, self._rng,
                      self._osc_z, self._osc_pow, self._osc_gain, self._band_state, self._band_coef,
                      self._band_env, self._band_pow, self._band_gain, self._freqs,
                      self._gains, self._alphas, self._excitation, self._osc_active,
                      self._band_active, self._counts)
        return out.astype(dtype, copy=False)


class TwangModel:
    """The ruler twang as a barsynth model (see the module docstring)."""

    reports_reference_errors = False
    name = "twang"
    summary = "ruler twanged over a desk edge (Selfridge et al., AES 2022)"
    table = TWANG_TABLE

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        return design_modes(parameters, sample_rate=sample_rate)

    def voice(self, parameters: Any = None, *, sample_rate: float = 48000.0,
              seed: int | None = 0, mode_mask: Any = None) -> TwangVoice:
        return TwangVoice(parameters, sample_rate=sample_rate, seed=seed, mode_mask=mode_mask)

    def render(self, parameters: Any = None, *, duration_s: float = 2.0,
               sample_rate: float = 48000.0, seed: int | None = 0,
               normalize: bool = True, dtype: Any = np.float32) -> np.ndarray:
        """Render one twang offline: ``duration_s`` seconds at ``sample_rate`` Hz.

        With ``normalize`` the peak is set to -1 dBFS; without it the samples are
        exactly those of a :class:`TwangVoice` triggered once. A bar none of whose
        modes lies below Nyquist would be silence: that is refused.

        Examples
        --------
        >>> from barsynth.models import get_model
        >>> samples = get_model("twang").render({"q": 200}, duration_s=1.0, seed=3)
        >>> samples.dtype, samples.shape
        (dtype('float32'), (48000,))
        """
        check_dtype(dtype)
        voice = self.voice(parameters, sample_rate=sample_rate, seed=seed)
        modes = design_modes(voice.parameters, sample_rate=voice.sample_rate)
        if not any(m.frequency_hz >= AUDIBLE_MIN_HZ for m in modes):
            raise ParameterError(
                f"parameters put every mode of this ruler below {AUDIBLE_MIN_HZ:g} Hz, at or above "
                f"Nyquist ({voice.sample_rate / 2:g} Hz) or at zero gain; allowed: settings with "
                "at least one audible mode (change length, thickness or material, or the sample_rate)"
            )
        return render_voice(voice, duration_s, normalize=normalize, dtype=dtype)


MODEL = TwangModel()
