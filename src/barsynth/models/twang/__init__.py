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

Choices where the paper is silent (spec 2.8), all in the parameter table or the
constants of :mod:`.design` and :mod:`.voice`:

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
* every control ramps to a new value over ``SMOOTHING_TIME_S`` (5 ms) at the control
  rate (one frame every 2 ms), multiplicatively for the log-scaled ones and linearly
  for the others (:mod:`barsynth.dsp.smoothing`); gains ramp linearly inside a frame;
* the level scale is ``level / max(1.75 x sum of the full-length beta gains, sum
  of the free-bar beta gains)``, recomputed with every design and ramped like the
  gains; the mix gains and ``mode_mask`` act on top of it as true gains. With the
  paper's mix, where the cantilever sum is the larger (every preset), a note's
  first sample (all cosines at phase 0, noise drive at 0) is exactly ``level_db``;
* vibrato depth fades in over rates from 0 to 0.5 Hz, so turning vibrato off
  glides back to pitch; free-bar bands fade out from 30 Hz to 20 Hz and are
  silent below (a band-pass that low and narrow only stores energy).

The package: :mod:`.table` (parameters), :mod:`.design` (modes and band-passes),
:mod:`.kernel` (the samples), :mod:`.voice` (the streaming voice), :mod:`.model`
(:class:`TwangModel`, ``MODEL``).

Examples
--------
>>> from barsynth.models import get_model
>>> twang = get_model("twang")
>>> samples = twang.render({"q": 200}, duration_s=1.0, seed=3)
>>> samples.dtype, samples.shape
(dtype('float32'), (48000,))
>>> [round(m.frequency_hz, 2) for m in twang.describe()][:2]
[8.87, 55.57]
"""

from .design import GROUPS
from .model import MODEL, TwangModel
from .table import AUDIBLE_MIN_HZ, TWANG_TABLE, TwangParams
from .voice import CONTROL_FRAME_S, SMOOTHING_TIME_S, TwangVoice

__all__ = ["AUDIBLE_MIN_HZ", "CONTROL_FRAME_S", "GROUPS", "MODEL", "SMOOTHING_TIME_S", "TWANG_TABLE",
           "TwangModel", "TwangParams", "TwangVoice"]
