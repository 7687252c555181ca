"""Where a note's partials may be: prominent peaks of long spectra from its start.

Four power spectra of the sound from its start, zero-padded to at least twice their
length: under a Blackman-Harris window that starts at full weight and tapers to zero
(partials that die within tens of ms show) over the whole sound, its first quarter and
its first sixteenth, and under a symmetric one over the whole sound (weak long partials
beside strong short ones). Each is smoothed over +-15 cents (at least +-2 resolution
bins: a noise-excited resonance or a close doublet shows as one peak, which the band
fits then take apart). A peak is kept when it is at least 10 dB prominent (within
+-256 resolution bins) and 14 dB above the local floor (the 20th percentile within
+-40 % or +-24 resolution bins), and within the level asked for of the spectrum's
maximum; it is then located on the unsmoothed spectrum (parabolic interpolation in dB).
A peak seen in several spectra counts once: within half the coarser spectrum's main
lobe, or closer than the minimum separation.

NumPy only (no :mod:`scipy.signal`, whose import costs half a second on the command
line). Reference: J. O. Smith, *Spectral Audio Signal Processing* (windows, peak
interpolation); the prominence is SciPy's ``peak_prominences``' definition.
"""

from __future__ import annotations

import functools
import math

import numpy as np

__all__ = ["blackman_harris", "note_peaks"]

_BH = (0.35875, 0.48829, 0.14128, 0.01168)
_PROMINENCE_DB = 10.0
_ABOVE_FLOOR_DB = 14.0
_SMOOTH_CENTS = 15.0
_PROMINENCE_BINS = 256
_FLOOR_BINS = 24
_MIN_SPECTRUM_S = 0.01


@functools.lru_cache(maxsize=16)
def blackman_harris(n: int, half: bool = False) -> np.ndarray:
    """The 4-term Blackman-Harris window (periodic) of ``n`` samples; with ``half``, its
    falling half stretched over ``n`` samples (full weight first, tapering to zero)."""
    length = 2 * n if half else n
    phase = 2.0 * math.pi * np.arange(length) / length
    a0, a1, a2, a3 = _BH
    w = a0 - a1 * np.cos(phase) + a2 * np.cos(2 * phase) - a3 * np.cos(3 * phase)
    w = w[n:] if half else w
    w.setflags(write=False)
    return w


def _prominences(db: np.ndarray, peaks: np.ndarray, wlen: int) -> np.ndarray:
    """Prominence of each peak within +-``wlen`` bins (SciPy's definition)."""
    out = np.empty(peaks.size)
    for i, p in enumerate(peaks):
        lo, hi = max(0, p - wlen), min(db.size, p + wlen + 1)
        height = db[p]
        left = db[lo:p][::-1]
        higher = np.flatnonzero(left > height)
        left_min = left[: higher[0]].min() if higher.size and higher[0] > 0 else (
            left.min() if left.size and not higher.size else height)
        right = db[p + 1 : hi]
        higher = np.flatnonzero(right > height)
        right_min = right[: higher[0]].min() if higher.size and higher[0] > 0 else (
            right.min() if right.size and not higher.size else height)
        out[i] = height - max(left_min, right_min)
    return out


def note_peaks(
    x: np.ndarray,
    sample_rate: float,
    start: int,
    *,
    min_level_db: float,
    min_frequency_hz: float,
    max_count: int,
    min_separation_cents: float = 30.0,
) -> list[tuple[float, float]]:
    """Candidate partials as (frequency in Hz, height in dB below the spectrum's maximum),
    strongest first; see the module docstring. ``start`` is the sample where the sound
    starts; ``min_level_db`` (negative) how far below the maximum a peak may be."""
    seg = x[start:]
    length = seg.size
    specs = [(length, True), (length, False)]
    for div in (4, 16):
        if length // div >= max(64, int(_MIN_SPECTRUM_S * sample_rate)):
            specs.append((length // div, True))
    found: list[tuple[float, float, float]] = []  # (frequency, height, half main lobe in Hz)
    widen = 2.0 ** (_SMOOTH_CENTS / 1200.0) - 1.0
    for n, half in specs:
        if n < 16:
            continue
        w = blackman_harris(n, half)
        nfft = 1 << max(13, int(math.ceil(math.log2(2 * n))))
        spec = np.fft.rfft(seg[:n] * w, nfft)
        power = (spec.real**2 + spec.imag**2) * (2.0 / w.sum()) ** 2
        pad = nfft / n  # FFT bins per resolution bin
        fine = 10.0 * np.log10(power + 1e-300)
        # smoothed over +-15 cents (at least +-2 resolution bins)
        k = np.arange(power.size)
        reach = np.maximum(np.floor(k * widen), 2.0 * pad).astype(np.int64)
        first = np.clip(k - reach, 0, power.size - 1)
        last = np.clip(k + reach, 0, power.size - 1)
        csum = np.concatenate(([0.0], np.cumsum(power)))
        coarse = 10.0 * np.log10(np.maximum((csum[last + 1] - csum[first]) / (last - first + 1), 0.0) + 1e-300)
        top = float(coarse.max())
        if top <= -290.0:
            continue
        inner = coarse[1:-1]
        peaks = 1 + np.flatnonzero((inner > coarse[:-2]) & (inner >= coarse[2:]) & (inner >= top + min_level_db))
        freqs = peaks * (sample_rate / nfft)
        peaks = peaks[(freqs >= min_frequency_hz) & (freqs < 0.4995 * sample_rate)]
        if peaks.size > 4 * max_count:  # the costly tests: only for the highest
            peaks = np.sort(peaks[np.argsort(coarse[peaks])[::-1][: 4 * max_count]])
        if peaks.size == 0:
            continue
        keep = _prominences(coarse, peaks, int(_PROMINENCE_BINS * pad)) >= _PROMINENCE_DB
        for i, p in enumerate(peaks):
            if not keep[i]:
                continue
            span = int(max(0.4 * p, _FLOOR_BINS * pad))
            lo, hi = max(0, p - span), min(coarse.size, p + span + 1)
            stride = max(1, (hi - lo) // 4096)
            keep[i] = coarse[p] >= np.percentile(coarse[lo:hi:stride], 20.0) + _ABOVE_FLOOR_DB
        lobe = (2.0 if half else 4.0) * sample_rate / n
        for p in peaks[keep]:
            # the highest fine bin under the coarse peak, interpolated
            r = int(reach[p])
            q = max(1, min(fine.size - 2, p - r + int(np.argmax(fine[max(0, p - r) : p + r + 1]))))
            a, b, c = fine[q - 1], fine[q], fine[q + 1]
            den = a - 2.0 * b + c
            delta = max(-0.5, min(0.5, 0.5 * (a - c) / den)) if den < 0 else 0.0
            found.append(((q + delta) * sample_rate / nfft, float(coarse[p] - top), lobe))
    chosen: list[tuple[float, float, float]] = []
    for f, h, lobe in sorted(found, key=lambda item: item[2]):  # the finest spectra first
        if any(abs(1200.0 * math.log2(f / g)) < min_separation_cents or abs(f - g) < 0.5 * max(lobe, gl)
               for g, _, gl in chosen):
            continue
        chosen.append((f, h, lobe))
    chosen.sort(key=lambda item: -item[1])
    return [(f, h) for f, h, _ in chosen[:max_count]]
