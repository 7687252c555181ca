"""The attack of a note: the broadband strike that dies away in the first tens of ms.

**Where it ends** is judged from the energy *between* the partials, which their fits
cannot confuse: short spectra (Blackman-Harris, about 23 ms, hop an eighth of that)
centred from the start on, summed over the bins further than five bins from every candidate
partial. The attack ends where that energy falls (and stays, for three frames) below
both 30 dB under its peak and 6 dB over its late level (the median over the sound's
second half); it lasts at most :data:`MAX_ATTACK_S` or half the sound. There is no
attack when the peak is not 10 dB over the late level, or is more than 60 dB under the
loudest frame of the whole spectrum, or too few bins lie between the partials.

**What it is** (spec 7.1): the residual -- the sound less its resynthesised sustained
partials -- from the start to that end: its energy (dB re the whole sound's) and
spectral centroid (Hz). The strike's knock, which commuted synthesis restores. A residual
below -60 dB of the sound (the click of a sudden start) is no attack.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .peaks import blackman_harris
from .records import Attack

__all__ = ["MAX_ATTACK_S", "NO_ATTACK", "attack_end", "describe_attack"]

MAX_ATTACK_S = 0.15
WINDOW_S = 0.023
_HOP_DIVISOR = 8
_GUARD_BINS = 5
_BELOW_PEAK_DB = 30.0
_ABOVE_LATE_DB = 6.0
_PRESENT_DB = 10.0
_BELOW_SOUND_DB = 60.0
_STAY_FRAMES = 3
_MIN_FREE_SHARE = 0.1
_LATE_FRAMES = 64
NO_ATTACK = Attack(duration_s=0.0, energy_db=None, centroid_hz=None)


def _frames(x: np.ndarray, starts: np.ndarray, window: np.ndarray) -> np.ndarray:
    """Power spectra of windowed frames of ``x`` starting at ``starts`` (frames x bins)."""
    from scipy import fft as sfft

    index = starts[:, None] + np.arange(window.size)[None, :]
    spec = sfft.rfft(x[index] * window[None, :], axis=1)
    return spec.real**2 + spec.imag**2


def attack_end(x: np.ndarray, sample_rate: float, start: int, partials_hz: Sequence[float]) -> int | None:
    """Sample index where the attack ends (None when there is none); see the module.

    ``partials_hz`` are the frequencies of the (candidate) partials, Hz.
    """
    size = 1 << max(6, int(round(math.log2(WINDOW_S * sample_rate))))
    hop = max(1, size // _HOP_DIVISOR)
    after = x.size - start
    if after < 2 * size:
        return None
    window = blackman_harris(size)
    reach = min(int(MAX_ATTACK_S * sample_rate), after // 2)
    early = start + np.arange(0, max(1, reach), hop)
    early = early[early + size <= x.size + size // 2]
    late = np.linspace(start + after // 2, x.size - size, _LATE_FRAMES).astype(int)
    late = np.unique(late[late >= start])
    if early.size < _STAY_FRAMES + 1 or late.size == 0:
        return None
    freqs = np.arange(size // 2 + 1) * (sample_rate / size)
    free = freqs >= 20.0
    guard = _GUARD_BINS * sample_rate / size
    for f in partials_hz:
        free &= np.abs(freqs - f) > guard
    if np.count_nonzero(free) < _MIN_FREE_SHARE * freqs.size:
        return None
    # (frames centred from the start on: the sound padded with silence before it)
    half = size // 2
    padded = np.concatenate((np.zeros(half), x))
    power = _frames(padded, early, window)
    between = power[:, free].sum(axis=1)
    late_level = float(np.median(_frames(x, late, window)[:, free].sum(axis=1)))
    peak = int(np.argmax(between))
    top = float(between[peak])
    if not top > 0 or top < late_level * 10.0 ** (_PRESENT_DB / 10.0):
        return None
    if top < float(power.sum(axis=1).max()) * 10.0 ** (-_BELOW_SOUND_DB / 10.0):
        return None
    threshold = max(top * 10.0 ** (-_BELOW_PEAK_DB / 10.0), late_level * 10.0 ** (_ABOVE_LATE_DB / 10.0))
    quiet = between[peak:] < threshold
    for i in range(quiet.size):
        if quiet[i : i + _STAY_FRAMES].all() and i + _STAY_FRAMES <= quiet.size:
            # the frame centred here is quiet: the attack ended before its centre
            return int(min(early[peak + i], start + reach))
    return int(start + reach)


def describe_attack(x: np.ndarray, residual: np.ndarray, sample_rate: float, start: int, end: int | None) -> Attack:
    """The attack from ``start`` to ``end`` (sample indices): the residual's energy (dB re
    the whole sound's) and spectral centroid (Hz); :data:`NO_ATTACK` when ``end`` is None
    or the residual holds less than -60 dB of the sound's energy there."""
    if end is None or end <= start:
        return NO_ATTACK
    seg = residual[start:end]
    total = float(np.dot(x, x))
    energy = float(np.dot(seg, seg))
    energy_db = 10.0 * math.log10(energy / total) if energy > 0 and total > 0 else None
    if energy_db is None or energy_db < -_BELOW_SOUND_DB:  # (the click of a sudden start)
        return NO_ATTACK
    n = max(256, 1 << (seg.size - 1).bit_length())
    spectrum = np.fft.rfft(seg, n)
    power = spectrum.real**2 + spectrum.imag**2
    freqs = np.arange(power.size) * (sample_rate / n)
    centroid = float(np.dot(freqs, power) / power.sum()) if power.sum() > 0 else None
    return Attack(duration_s=(end - start) / sample_rate, energy_db=energy_db, centroid_hz=centroid)
