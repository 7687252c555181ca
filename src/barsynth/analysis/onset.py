"""Where a recorded note starts: its onset (spec 7.1) and its strike.

The **onset** is :data:`ONSET_LEAD_S` before the first sample within
:data:`ONSET_BELOW_PEAK_DB` of the peak magnitude (never before the first sample); the
spectral distance (spec 7.3) cuts sounds there. Noise before the note at more than
-40 dB moves it, though: the **strike** (:func:`strike_at`) is found from 1 ms frames
against the lead-in's own level, and a note's partials are extrapolated back to it.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["ONSET_BELOW_PEAK_DB", "ONSET_LEAD_S", "onset_at", "start_at", "strike_at"]

ONSET_BELOW_PEAK_DB = 40.0  # the start: the first sample within 40 dB of the peak ...
ONSET_LEAD_S = 0.003  # ... and the onset 3 ms before it


def start_at(samples: np.ndarray) -> int:
    """Index of the first sample whose magnitude is within :data:`ONSET_BELOW_PEAK_DB` of the
    peak (0 for silence)."""
    magnitude = np.abs(samples)
    peak = magnitude.max() if magnitude.size else 0.0
    if peak <= 0.0:
        return 0
    return int(np.argmax(magnitude >= peak * 10.0 ** (-ONSET_BELOW_PEAK_DB / 20.0)))


def onset_at(samples: np.ndarray, sample_rate: float) -> int:
    """Index of the onset: :func:`start_at` minus :data:`ONSET_LEAD_S` (never before 0)."""
    return max(0, start_at(samples) - int(round(ONSET_LEAD_S * sample_rate)))


_FRAME_S = 0.001
_QUIET_DB = 30.0  # a lead-in this far below the loudest frame is quiet ...
_RISE_DB = 20.0  # ... and the strike is the first frame this far above its median
_SILENT_DB = 80.0  # without a quiet lead-in: the first sample above -80 dB of the peak
_NOISE_PEAKS = 4.0  # within the strike's frame, the first sample above 4 RMS of the lead-in


def strike_at(samples: np.ndarray, sample_rate: float) -> int:
    """Index of the sample where the note is struck (0 for silence).

    The sound is cut into 1 ms frames (at least 8 samples). When the frames before the
    loudest one have a median energy at least 30 dB below it (a quiet lead-in of noise or
    silence, at least 5 frames), the strike is in the first frame 20 dB above that median:
    at its first sample four times the lead-in's RMS, looking from the frame before.
    Otherwise (a sound that starts at once) it is the first sample above -80 dB of the
    peak.
    """
    x = np.asarray(samples, dtype=np.float64)
    magnitude = np.abs(x)
    peak = float(magnitude.max()) if magnitude.size else 0.0
    if peak <= 0.0:
        return 0
    first = int(np.argmax(magnitude >= peak * 10.0 ** (-_SILENT_DB / 20.0)))
    frame = max(8, int(round(_FRAME_S * sample_rate)))
    count = x.size // frame
    if count < 6:
        return first
    energy = np.mean(x[: count * frame].reshape(count, frame) ** 2, axis=1)
    loudest = int(np.argmax(energy))
    if loudest < 5:
        return first
    floor = float(np.median(energy[:loudest]))
    if not floor < energy[loudest] * 10.0 ** (-_QUIET_DB / 10.0):
        return first
    rising = np.flatnonzero(energy[: loudest + 1] >= max(floor, 1e-300) * 10.0 ** (_RISE_DB / 10.0))
    index = int(rising[0]) if rising.size else loudest
    lo = max(0, (index - 1) * frame)
    above = np.flatnonzero(magnitude[lo : (index + 1) * frame] >= _NOISE_PEAKS * math.sqrt(floor))
    return max(first, lo + int(above[0])) if above.size else max(first, index * frame)
