"""How far a resynthesis sounds from a recording: barsynth's spectral distance (spec 7.3).

Both sounds are cut at their onsets and the first second (at most) is compared, cell by cell,
as power in 1/12-octave bands per STFT frame, in dB above a floor 60 dB below the recording's
loudest cell, after the resynthesis is scaled to the recording's total power. The score is
the mean absolute difference in dB: 0 for the same spectrogram, larger the further apart.

Steps, exactly as spec 7.3 gives them (so figures compare):

1. cut both from their onsets (:func:`onset_at`); keep ``T = min(1 s, recording's length)``;
2. STFT, Hann window of 2048 samples at 44.1 kHz (46.4 ms, the same duration at other
   rates), hop a quarter window;
3. power summed per frame in 1/12-octave bands from 50 Hz up to ``min(10 kHz, 0.45 fs)``;
4. the resynthesis scaled so its total power over all cells equals the recording's;
5. levels in dB, both floored at the recording's largest cell minus 60 dB;
6. the mean over all cells of ``|L_r - L_s|``.

Where spec 7.3 is silent: a band that holds no FFT bin (below about 370 Hz a 1/12-octave band
is narrower than the bins of a 46 ms window) is left out rather than counted as two floors;
a resynthesis shorter than ``T`` is padded with silence; both sounds must have the same rate.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ParameterError
from .inputs import as_signal

__all__ = ["ONSET_BELOW_PEAK_DB", "onset_at", "sine_baseline", "spectral_distance"]

ONSET_BELOW_PEAK_DB = 40.0  # the onset: the first sample within 40 dB of the peak ...
ONSET_LEAD_S = 0.003  # ... minus 3 ms
WINDOW_S = 2048 / 44100.0
LOWEST_BAND_HZ = 50.0
HIGHEST_BAND_HZ = 10_000.0
FLOOR_DB = 60.0
LONGEST_S = 1.0


def onset_at(samples: np.ndarray, sample_rate: float) -> int:
    """Index of the onset: the first sample within :data:`ONSET_BELOW_PEAK_DB` of the peak,
    minus :data:`ONSET_LEAD_S` (never before 0)."""
    magnitude = np.abs(samples)
    peak = magnitude.max() if magnitude.size else 0.0
    if peak <= 0.0:
        return 0
    first = int(np.argmax(magnitude >= peak * 10.0 ** (-ONSET_BELOW_PEAK_DB / 20.0)))
    return max(0, first - int(round(ONSET_LEAD_S * sample_rate)))



def _band_cells(samples: np.ndarray, sample_rate: float, length: int) -> np.ndarray:
    """Power per (frame, band) of ``samples[:length]`` (zero-padded), shape (frames, bands)."""
    window_len = max(16, int(round(WINDOW_S * sample_rate)))
    hop = max(1, window_len // 4)
    x = np.zeros(max(length, window_len))
    x[:min(length, samples.size)] = samples[:length]
    frames = 1 + (x.size - window_len) // hop
    index = np.arange(window_len)[None, :] + hop * np.arange(frames)[:, None]
    spectrum = np.fft.rfft(x[index] * np.hanning(window_len)[None, :], axis=1)
    power = spectrum.real ** 2 + spectrum.imag ** 2
    freqs = np.fft.rfftfreq(window_len, 1.0 / sample_rate)
    top = min(HIGHEST_BAND_HZ, 0.45 * sample_rate)
    n_bands = int(math.floor(12.0 * math.log2(top / LOWEST_BAND_HZ)))
    edges = LOWEST_BAND_HZ * 2.0 ** (np.arange(n_bands + 1) / 12.0)
    band = np.searchsorted(edges, freqs, side="right") - 1
    inside = (band >= 0) & (band < n_bands)
    cells = np.zeros((frames, n_bands))
    np.add.at(cells.T, band[inside], power[:, inside].T)
    occupied = np.bincount(band[inside], minlength=n_bands) > 0
    return cells[:, occupied]


def spectral_distance(recording: Any, resynthesis: Any, sample_rate: float) -> float:
    """The spectral distance (dB) between a recording and a resynthesis at ``sample_rate`` Hz
    (see the module docstring); mono 1-D arrays.

    >>> rate = 44100
    >>> t = np.arange(rate) / rate
    >>> a = np.sin(2 * np.pi * 440 * t) * np.exp(-3 * t)
    >>> spectral_distance(a, a, rate)
    0.0
    """
    r, rate = as_signal(recording, sample_rate)
    s, _ = as_signal(resynthesis, rate)
    r = r[onset_at(r, rate):]
    s = s[onset_at(s, rate):]
    length = min(int(round(LONGEST_S * rate)), r.size)
    if length < 16:
        raise ParameterError(f"parameter recording = {r.size} samples is not allowed; allowed: a sound of at "
                             "least 16 samples after its onset")
    cells_r = _band_cells(r, rate, length)
    cells_s = _band_cells(s, rate, length)
    total_r, total_s = cells_r.sum(), cells_s.sum()
    if total_r <= 0.0:
        raise ParameterError("parameter recording is silent: no power between 50 Hz and "
                             f"{min(HIGHEST_BAND_HZ, 0.45 * rate):g} Hz to compare")
    if total_s > 0.0:
        cells_s = cells_s * (total_r / total_s)
    floor = cells_r.max() * 10.0 ** (-FLOOR_DB / 10.0)
    level_r = 10.0 * np.log10(np.maximum(cells_r, floor))
    level_s = 10.0 * np.log10(np.maximum(cells_s, floor))
    return float(np.mean(np.abs(level_r - level_s)))


def sine_baseline(f0_hz: float, t60_s: float, sample_rate: float, num_samples: int) -> np.ndarray:
    """Spec 7.3's baseline: one sine at ``f0_hz`` decaying with ``t60_s`` (60 dB in that many
    seconds; ``inf`` for none), ``num_samples`` long, peak 1."""
    t = np.arange(num_samples) / sample_rate
    decay = 0.0 if not math.isfinite(t60_s) or t60_s <= 0.0 else math.log(1000.0) / t60_s
    return np.sin(2.0 * np.pi * f0_hz * t) * np.exp(-decay * t)
