"""Where partials may be: peaks of long spectra of a sound, and where the sound starts.

Peaks of long, zero-padded power spectra: of the whole sound under a symmetric
Blackman-Harris window (weak partials beside strong, long-ringing ones) and, under
a window that starts at full weight on the onset and tapers to zero, of the whole
sound, its first eighth and its first sixty-fourth (partials that die within tens
of milliseconds). Each spectrum is smoothed over half the minimum separation (a
noise-excited resonance then shows as one peak, not dozens); a peak must be 10 dB
prominent and 14 dB above the local floor, and is located on the unsmoothed
spectrum. A peak seen in several spectra counts once.

Reference: J. O. Smith, *Spectral Audio Signal Processing* (window choice, peak
interpolation).
"""

from __future__ import annotations

import functools
import math

import numpy as np


def global_onset(x: np.ndarray, sample_rate: float) -> int:
    """The sample where the sound starts.

    When the sound opens with at least 5 ms of silence or noise 30 dB or more below
    its loudest 0.5 ms, the start of the first 0.5 ms that rises 20 dB above that;
    otherwise (a sound that starts at once, however gently) the first sample above
    -80 dB of the peak.
    """
    peak = float(np.max(np.abs(x)))
    if peak == 0.0:
        return 0
    first = int(np.argmax(np.abs(x) >= 1e-4 * peak))
    size = max(1, int(round(0.0005 * sample_rate)))
    count = x.size // size
    if count < 3:
        return first
    energy = np.mean(x[: count * size].reshape(count, size) ** 2, axis=1)
    loudest = int(np.argmax(energy))
    if loudest == 0:
        return first
    before = energy[:loudest]
    floor = float(before.min())
    if not floor < 1e-3 * energy[loudest]:
        return first
    loud = np.flatnonzero(before >= min(100.0 * floor, 0.1 * energy[loudest]))
    start = int(loud[0]) if loud.size else loudest
    if start < 10:  # no 5 ms of quiet at the start
        return first
    return max(first, start * size)



def _extent(side: np.ndarray) -> int:
    """Bins from a peak (side[0]) until 6 dB down or the first dip, whichever is nearer."""
    down = np.flatnonzero(side < side[0] - 6.0)
    rising = np.flatnonzero(np.diff(side) > 0.0)
    ends = [int(down[0])] if down.size else [side.size]
    if rising.size:
        ends.append(int(rising[0]))
    return min(ends)


@functools.lru_cache(maxsize=16)
def _window(n: int, kind: str) -> np.ndarray:
    """Blackman-Harris window: symmetric, or its falling half (full weight at the onset)."""
    from scipy.signal.windows import blackmanharris

    if kind == "sym":
        w = blackmanharris(n, sym=False)
    else:  # starts at full weight on the onset, tapers smoothly to zero
        w = blackmanharris(2 * n, sym=False)[n:]
    w.setflags(write=False)
    return w


def spectral_candidates(
    x: np.ndarray,
    fs: float,
    n0: int,
    *,
    min_separation_cents: float,
    min_level_db: float,
    min_frequency_hz: float,
    max_candidates: int,
    reference: list[float] | None = None,
    exclude: tuple[float, ...] = (),
    coarse: bool = False,
) -> tuple[list[tuple[float, float]], list[float]]:
    """Peaks as (frequency_hz, height in dB relative to the spectrum's maximum), strongest first.

    Also returns the maximum of each spectrum. For a residual, ``reference`` gives
    the maxima of the original sound's spectra (heights are then relative to
    those) and ``exclude`` the partials already known: nothing closer to them than
    the minimum separation is returned.
    """
    from scipy import fft as sfft
    from scipy.ndimage import uniform_filter1d
    from scipy.signal import find_peaks, peak_prominences

    seg = x[n0:]
    length = seg.size
    specs: list[tuple[int, str]] = [(length, "sym"), (length, "half")]
    shortest = max(64, int(0.01 * fs))
    for div in (8, 64):
        n = length // div
        if n >= shortest:
            specs.append((n, "half"))
    # (frequency, relative height, spectrum index, extent low, extent high)
    found: list[tuple[float, float, int, float, float]] = []
    tops: list[float] = []
    for index, (n, kind) in enumerate(specs):
        tops.append(-math.inf)
        if n < 16:
            continue
        w = _window(n, kind)
        nfft = sfft.next_fast_len(max(2 * n, 8192), real=True)
        spec = sfft.rfft(seg[:n] * w, nfft)
        power = (spec.real**2 + spec.imag**2) * (2.0 / w.sum()) ** 2
        freqs = np.arange(power.size) * (fs / nfft)
        # Smooth over +-2/duration (half the window's main lobe; a peak loses about
        # 1 dB), or when coarse, over +-half the minimum separation where that is
        # wider: a resonance excited by noise then shows one peak, not dozens.
        light = int(round(2.0 * nfft / n))
        if light > 0:
            power = np.maximum(uniform_filter1d(power, 2 * light + 1, mode="nearest"), 0.0)
        fine_db = 10.0 * np.log10(power + 1e-300)
        half = None
        if coarse:
            widen = 2.0 ** (0.5 * min_separation_cents / 1200.0) - 1.0
            half = np.maximum(np.floor(freqs * widen * (nfft / fs)).astype(np.int64), light)
            k = np.arange(power.size)
            first = np.clip(k - half, 0, power.size - 1)
            last = np.clip(k + half, 0, power.size - 1)
            csum = np.concatenate(([0.0], np.cumsum(power)))
            power = np.maximum((csum[last + 1] - csum[first]) / (last - first + 1), 0.0)
            db = 10.0 * np.log10(power + 1e-300)
        else:
            db = fine_db
        top = float(db.max())
        tops[-1] = top
        if reference is not None:
            top = reference[index] if index < len(reference) else -math.inf
        if not math.isfinite(top) or top <= -290.0:
            continue
        peaks, _ = find_peaks(db, height=top + min_level_db - 20.0)
        pf = freqs[peaks]
        peaks = peaks[(pf >= min_frequency_hz) & (pf < 0.5 * fs * 0.999)]
        if peaks.size == 0:
            continue
        # prominent within +-256 resolution bins (+-256/duration Hz)
        pad = nfft / n
        prom = peak_prominences(db, peaks, wlen=2 * int(256 * pad) + 1)[0]
        peaks = peaks[prom >= 10.0]
        # and well above the local floor: the 20th percentile of the spectrum within
        # +-40 % or +-24 resolution bins, whichever is wider (low enough to ignore the
        # main lobes of dense low partials)
        if peaks.size > 4 * max_candidates:  # the floor is costly: only for the highest
            peaks = np.sort(peaks[np.argsort(db[peaks])[::-1][: 4 * max_candidates]])
        keep = []
        for p in peaks:
            width = int(max(0.4 * p, 24.0 * pad))
            lo, hi = max(0, p - width), min(db.size, p + width + 1)
            stride = max(1, (hi - lo) // 4096)
            floor = float(np.percentile(db[lo:hi:stride], 20.0))
            keep.append(db[p] >= floor + 14.0)
        peaks = peaks[np.asarray(keep, dtype=bool)]
        reach = int(256 * pad)
        db = fine_db
        for p in peaks:
            if half is not None:
                # a peak of the coarse spectrum: locate it on the fine one
                lo = max(0, p - int(half[p]))
                p = lo + int(np.argmax(db[lo : p + int(half[p]) + 1]))
            if 0 < p < db.size - 1:
                a, b, c = db[p - 1], db[p], db[p + 1]
                den = a - 2.0 * b + c
                delta = 0.5 * (a - c) / den if den < 0 else 0.0
                delta = max(-0.5, min(0.5, delta))
                height = b - 0.25 * (a - c) * delta
            else:
                delta, height = 0.0, db[p]
            # the peak's extent, 6 dB down or to the dip before the next peak, for
            # telling duplicates across spectra
            lo = _extent(db[max(0, p - reach) : p + 1][::-1])
            hi = _extent(db[p : p + reach + 1])
            freq = (p + delta) * fs / nfft
            extent = ((p - lo) * fs / nfft, (p + hi) * fs / nfft)
            found.append((freq, float(height - top), index, *extent))
    # the finest spectra first (they come in order of resolution), each by height
    found.sort(key=lambda item: (item[2], -item[1]))
    # half-width of each window's main lobe, Hz
    resolution = [(4.0 if kind == "sym" else 2.0) * fs / n for n, kind in specs]
    chosen: list[tuple[float, float, int, float, float]] = []
    sep = min_separation_cents
    known = [g for g in exclude if g > 0]

    def cents(f: float, g: float) -> float:
        return abs(1200.0 * math.log2(f / g))

    for item in found:
        f, h, index, lo, hi = item
        if any(cents(f, g) < sep for g in known):
            continue
        # one peak seen in two spectra: closer than half the coarser one's main
        # lobe, or each within the other's 6 dB extent; a coarse peak spanning two
        # finer ones is several partials seen as one
        if any(
            cents(f, c[0]) < sep
            or (
                c[2] != index
                and (
                    abs(f - c[0]) < 0.5 * max(resolution[index], resolution[c[2]])
                    or (c[3] < f < c[4] and lo < c[0] < hi)
                )
            )
            for c in chosen
        ):
            continue
        if sum(1 for c in chosen if c[2] < index and lo < c[0] < hi) >= 2:
            continue
        chosen.append(item)
    chosen.sort(key=lambda item: -item[1])
    return [(c[0], c[1]) for c in chosen[:max_candidates]], tops
