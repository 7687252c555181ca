"""The noise floor of a recording, as a function of frequency, from its last part.

The last quarter of the sound (at least 46 ms, at most what follows the start) is
windowed (Blackman-Harris, whose -92 dB sidelobes keep partials' leakage out) and its
periodogram taken. Around each frequency the **median** over a neighbourhood of
+-10 % (at least +-16 bins) ignores the few bins that partials occupy; a periodogram
of noise is exponentially distributed, so the median is ``ln 2`` times the mean.

The result is the noise's *white-equivalent variance* ``v(f)``: the variance white
noise would need to have the same density at ``f``. A band of equivalent noise
bandwidth ``B`` then holds noise power ``v(f) B / sample_rate`` in its complex envelope
(:mod:`.bands`), which decay fits use as their floor (Lundeby et al., below).

Reference: A. Lundeby, T. E. Vigran, H. Bietz and M. Vorlaender, "Uncertainties of
measurements in room acoustics", Acustica 81 (1995) (decay fits aware of the noise floor).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .peaks import blackman_harris
__all__ = ["NoiseFloor", "noise_floor"]

_TAIL_FRACTION = 0.25
_MIN_TAIL_S = 0.046
_NEIGHBOURHOOD = 0.10  # +-10 % of the frequency
_MIN_BINS = 16
_TINY = 1e-300


@dataclass(frozen=True)
class NoiseFloor:
    """White-equivalent noise variance per frequency (see the module docstring).

    Attributes
    ----------
    freqs_hz
        Frequencies, Hz (0 to half the sample rate).
    variance
        White-equivalent variance at each frequency (full scale 1.0).
    """

    freqs_hz: np.ndarray
    variance: np.ndarray

    def at(self, frequency_hz: float) -> float:
        """White-equivalent variance at ``frequency_hz`` (interpolated)."""
        if self.freqs_hz.size == 0:
            return 0.0
        return float(np.interp(frequency_hz, self.freqs_hz, self.variance))

    @property
    def rms_db(self) -> float:
        """The noise's RMS level over the whole band, dB re full scale (``-inf`` for none)."""
        if self.variance.size == 0:
            return -math.inf
        v = float(np.mean(self.variance))
        return 10.0 * math.log10(v) if v > 0 else -math.inf


def noise_floor(x: np.ndarray, sample_rate: float, start: int) -> NoiseFloor:
    """The noise floor of ``x`` (see the module docstring); ``start`` is the sound's start
    (sample index): the tail is taken after it when the sound is long enough."""
    from scipy import fft as sfft
    after = x.size - start
    length = max(int(_TAIL_FRACTION * after), int(_MIN_TAIL_S * sample_rate))
    length = min(length, after if after >= 64 else x.size)
    if length < 16:
        return NoiseFloor(np.zeros(0), np.zeros(0))
    seg = x[x.size - length:]
    w = blackman_harris(length)
    nfft = sfft.next_fast_len(length, real=True)
    spec = sfft.rfft(seg * w, nfft)
    power = (spec.real**2 + spec.imag**2) / float(np.sum(w * w))
    freqs = np.arange(power.size) * (sample_rate / nfft)
    # the median over +-10 % (at least +-16 bins), on a grid of about 200 frequencies
    centres = np.unique(np.round(np.concatenate((
        np.arange(0, min(power.size, 10 * _MIN_BINS), _MIN_BINS // 2),
        np.geomspace(10 * _MIN_BINS, max(10 * _MIN_BINS, power.size - 1), 160),
    ))).astype(int))
    centres = centres[centres < power.size]
    median = np.empty(centres.size)
    for i, c in enumerate(centres):
        half = int(max(_MIN_BINS, _NEIGHBOURHOOD * c))
        median[i] = np.median(power[max(0, c - half): c + half + 1])
    freqs = freqs[centres]
    variance = np.maximum(median / math.log(2.0), _TINY)
    return NoiseFloor(freqs, variance)
