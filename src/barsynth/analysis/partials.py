"""Partials of a sound: frequency, initial level and decay time (T60) of each.

This is how a struck bar is measured (spec 3.4); the same code serves recordings
and barsynth's own tests, so it aims at precision first. Each partial is modelled
as a damped cosine that starts with the sound,
``A exp(-(t - t0) ln(1000) / T60) cos(2 pi f t + phi)``.

1. **Candidates.** Peaks of long, zero-padded power spectra: of the whole sound
   under a symmetric Blackman-Harris window (weak partials beside strong,
   long-ringing ones) and, under a window that starts at full weight on the onset
   and tapers to zero, of the whole sound, its first eighth and its first
   sixty-fourth (partials that die within tens of milliseconds). Each spectrum is
   smoothed over half the minimum separation (a noise-excited resonance then shows
   as one peak, not dozens); a peak must be 10 dB prominent and 14 dB above the
   local floor, and is located on the unsmoothed spectrum. A peak seen in several
   spectra counts once.
2. **Complex demodulation.** Around each partial the sound's spectrum is cut out,
   shifted to 0 Hz and low-passed with the zero-phase response
   ``exp(-0.5 (f / f1)**4)`` (-6 dB at the cutoff, -96 dB at twice the cutoff),
   the cutoff being at most half the distance to the nearest other partial; a
   short inverse FFT gives the partial's complex envelope.
3. **First estimate.** For a ladder of decay rates, the complex amplitude that
   best fits the envelope follows by linear least squares; the best rate wins. Two
   nuisance columns (the low-pass's response to an impulse at the onset) take up
   the onset skirts of partials not yet modelled, which would otherwise pass for
   a fast decay.
4. **Gauss-Newton on the residual.** All models are subtracted from the sound,
   and each partial's frequency, decay and amplitude are corrected so that its
   model, sent through *the same* band extraction and low-pass (its DFT is a
   geometric series, in closed form), best matches the filtered residual plus its
   old model; the nearest partials on either side take part in the solve. This is
   repeated over all partials until none moves (a space-alternating, SAGE-like
   iteration). The low-pass therefore biases nothing: on a sum of exponentially
   decaying cosines the exact parameters are the fixed point, whatever the
   filters, the onsets or the neighbours.
5. **Order.** Strong candidates are refined first and weaker ones added on what
   they leave; partials hidden under stronger ones (in their onset skirts) are
   then looked for twice more in the residual's spectra. Two models of one line
   (closer than the minimum separation or than their half-power widths) merge into
   the stronger.

References: J. O. Smith, *Spectral Audio Signal Processing* (window choice, peak
interpolation); J. A. Fessler and A. O. Hero, "Space-alternating generalized
expectation-maximization algorithm", IEEE Trans. Signal Process. 42 (1994);
A. Lundeby et al., "Uncertainties of measurements in room acoustics", Acustica 81
(1995) (noise-floor aware decay fits, used by :func:`band_decay_t60`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..checks import check_array, check_number, check_whole
from ..errors import ParameterError
from ..jsonout import json_number

__all__ = [
    "Partial",
    "band_decay_t60",
    "find_partials",
    "measure_partial",
    "partial_ratios",
]

_LN1000 = math.log(1000.0)
_DB_PER_NEPER = 20.0 / math.log(10.0)
# exp(-0.5 (f/f1)^4) is 6 dB down at f = f1 * (2 ln 2)^(1/4).
_SG_6DB = (2.0 * math.log(2.0)) ** 0.25
# beyond 2.6 f1 the response is below 1e-10: the band kept around a partial
_SG_EXTENT = 2.6

_MAX_SWEEPS = 14
_FLOOR_MARGIN_DB = 10.0
_MIN_FIT_POINTS = 8


# ----------------------------------------------------------------------------------
# the result
# ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Partial:
    """One partial of a sound.

    Attributes
    ----------
    frequency_hz
        Frequency in Hz (``nan`` if the partial could not be measured).
    level_db
        Initial amplitude in dB re full scale, taken at the partial's onset: a
        cosine of amplitude 1.0 is 0 dB. ``-inf`` if nothing was found.
    t60_s
        Time in seconds for the partial to decay by 60 dB. ``math.inf`` for a
        partial that does not decay (or grows), ``nan`` if it could not be
        measured.

    :meth:`to_json` gives ``null`` for inf and nan, which JSON cannot hold.
    """

    frequency_hz: float
    level_db: float
    t60_s: float

    def to_json(self) -> dict[str, Any]:
        """``{"frequency_hz", "level_db", "t60_s"}``; inf and nan become ``None`` (null)."""
        return {
            "frequency_hz": json_number(self.frequency_hz),
            "level_db": json_number(self.level_db),
            "t60_s": json_number(self.t60_s),
        }


# ----------------------------------------------------------------------------------
# validation
# ----------------------------------------------------------------------------------
def _as_signal(samples: Any, sample_rate: Any) -> tuple[np.ndarray, float]:
    fs = _positive("sample_rate", sample_rate, "Hz")
    x = check_array("samples", samples, "")
    if x.ndim != 1:
        raise ParameterError(
            f"parameter samples has shape {x.shape}; allowed: a 1-D array "
            "(mono; average the channels first)"
        )
    if x.size == 0:
        raise ParameterError("parameter samples is empty; allowed: at least 1 sample")
    return x, fs


def _positive(name: str, value: Any, unit: str) -> float:
    """``value`` as a finite float > 0 (also used by :mod:`.plots`)."""
    return check_number(name, value, unit, minimum=0.0, minimum_exclusive=True)


def _below_nyquist(name: str, value: Any, sample_rate: float) -> float:
    """``value`` as a frequency strictly between 0 and half the sample rate, Hz."""
    return check_number(
        name, value, "Hz (below half the sample rate)", minimum=0.0, maximum=0.5 * sample_rate,
        minimum_exclusive=True, maximum_exclusive=True,
    )


# ----------------------------------------------------------------------------------
# small numerical helpers
# ----------------------------------------------------------------------------------
def _damped_phasor(start: float, count: int, s: complex) -> np.ndarray:
    """exp(s * (start + n)) for n = 0..count-1, by an outer product of two short tables.

    As exact as ``np.exp`` on every sample (no recursion, no drift) at a fraction of
    its cost.
    """
    if count <= 0:
        return np.zeros(0, dtype=np.complex128)
    block = 512
    nblocks = -(-count // block)
    inner = np.exp(s * np.arange(block))
    outer = np.exp(s * (start + block * np.arange(nblocks)))
    return np.multiply.outer(outer, inner).ravel()[:count]


def _wls_line(t: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[Any, Any, float]:
    """Weighted least-squares line y ~ a + b (t - tm); returns (a, b, tm). y may be complex."""
    sw = float(w.sum())
    tm = float((w * t).sum()) / sw
    tc = t - tm
    stt = float((w * tc * tc).sum())
    a = (w * y).sum() / sw
    b = (w * tc * (y - a)).sum() / stt if stt > 0 else 0.0 * a
    return a, b, tm


def _global_onset(x: np.ndarray, sample_rate: float) -> int:
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


# ----------------------------------------------------------------------------------
# candidate peaks
# ----------------------------------------------------------------------------------
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


def _spectral_candidates(
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


# ----------------------------------------------------------------------------------
# the refinement engine
# ----------------------------------------------------------------------------------
@dataclass
class _Mode:
    """A partial being refined.

    Its model, sampled like the sound, is 2 Re(amp exp((-sigma + 2j pi f)(t - t_on)))
    for t >= t_on and 0 before.
    """

    frequency_hz: float
    centre_hz: float  # where its demodulation band is centred
    cutoff_hz: float = 0.0
    fixed_cutoff: bool = False
    fixed_centre: bool = False
    sigma: float = 0.0  # decay rate, 1/s (amplitude ~ exp(-sigma t))
    amp: complex = 0j  # complex amplitude (half the cosine amplitude) at t_on
    t_on: float = 0.0
    fitted: bool = False
    ok: bool = True
    coherence: float = 1.0  # share of the band's energy the model explains
    settled: bool = False  # its last Gauss-Newton step changed nothing that matters
    pinned: bool = False  # measure_partial's partial: never dropped
    moved: bool = True  # it changed in the last sweep

    @property
    def level_db(self) -> float:
        a = 2.0 * abs(self.amp)
        return 20.0 * math.log10(a) if a > 0 else -math.inf

    def copy(self, **changes: Any) -> _Mode:
        return dataclasses.replace(self, **changes)


@dataclass
class _Band:
    """The demodulation band of one partial: FFT bins, low-pass weights, time grid."""

    k: np.ndarray  # FFT bins (k0 + m; may be negative or beyond Nyquist)
    m: np.ndarray  # offsets from k0
    mask: np.ndarray  # zero-phase low-pass response at each offset
    f_bin: float  # frequency of bin k0, Hz
    size: int  # length of the inverse FFT
    t: np.ndarray  # times of the envelope samples (within the sound), s


class _Engine:
    """One analysis: the signal, its zero padding and the demodulation machinery."""

    def __init__(self, x: np.ndarray, fs: float) -> None:
        self.x = x
        self.fs = fs
        self.n = x.size
        self.duration = x.size / fs
        self.n0 = _global_onset(x, fs)
        self.t0 = self.n0 / fs
        self.peak = float(np.max(np.abs(x))) if x.size else 0.0
        self.npad = 0

    def prepare(self, modes: list[_Mode]) -> None:
        """Choose the FFT length: room for the narrowest filter's smear on both sides."""
        from scipy import fft as sfft

        narrowest = min((m.cutoff_hz for m in modes), default=10.0)
        f1 = narrowest / _SG_6DB
        pad = int(math.ceil(2.0 * 2.3 / f1 * self.fs))
        pad = min(self.n, max(self.n // 4, pad, 64))
        self.npad = sfft.next_fast_len(self.n + pad, real=True)

    def spectrum(self, signal: np.ndarray) -> np.ndarray:
        from scipy import fft as sfft

        return sfft.rfft(signal, self.npad)

    # -- bands ---------------------------------------------------------------------
    def band(self, centre_hz: float, cutoff_hz: float) -> _Band:
        from scipy import fft as sfft

        npad, fs = self.npad, self.fs
        k0 = int(round(centre_hz * npad / fs))
        f1 = cutoff_hz / _SG_6DB
        half = int(math.ceil(_SG_EXTENT * f1 * npad / fs))
        half = max(1, min(half, npad // 2 - 1))
        m = np.arange(-half, half + 1)
        mask = np.exp(-0.5 * ((m * (fs / npad)) / f1) ** 4)
        size = sfft.next_fast_len(max(256, 2 * m.size))
        size = min(size, npad)
        dt = npad / (size * fs)
        count = min(size, int(math.ceil(self.duration / dt)))
        t = np.arange(count) * dt
        return _Band(k=k0 + m, m=m, mask=mask, f_bin=k0 * fs / npad, size=size, t=t)

    def band_values(self, spec: np.ndarray, band: _Band) -> np.ndarray:
        """A real signal's spectrum at the band's bins (negative ones mirrored)."""
        npad = self.npad
        k = band.k
        j = np.abs(k)
        beyond = j > npad // 2
        j = np.where(beyond, npad - j, j)
        vals = spec[np.clip(j, 0, spec.size - 1)]
        return np.where((k < 0) ^ beyond, np.conj(vals), vals)

    def envelope(self, band: _Band, values: np.ndarray) -> np.ndarray:
        """Low-passed complex envelope (on band.t) of spectrum values at the band's bins.

        A cosine A cos(2 pi f t + phi) in the band gives (A/2) exp(j(2 pi (f - f_bin) t + phi)).
        """
        from scipy import fft as sfft

        buf = np.zeros(band.size, dtype=np.complex128)
        np.add.at(buf, band.m % band.size, values * band.mask)
        z = sfft.ifft(buf) * (band.size / self.npad)
        return z[: band.t.size]

    def envelopes(self, band: _Band, values: np.ndarray) -> np.ndarray:
        """:meth:`envelope` of several rows of spectrum values at once."""
        from scipy import fft as sfft

        buf = np.zeros((values.shape[0], band.size), dtype=np.complex128)
        buf[:, band.m % band.size] = values * band.mask
        z = sfft.ifft(buf, axis=1) * (band.size / self.npad)
        return z[:, : band.t.size]

    # -- models ----------------------------------------------------------------------
    def span(self, m: _Mode) -> tuple[int, int]:
        """First sample of a model and how many samples it lasts (until 1e-14 of the peak)."""
        n_on = max(0, int(math.ceil(m.t_on * self.fs - 1e-9)))
        count = self.n - n_on
        floor = 1e-14 * max(self.peak, 1e-300)
        a2 = 2.0 * abs(m.amp)
        if m.sigma > 0 and a2 > floor:
            count = min(count, int(math.log(a2 / floor) / m.sigma * self.fs) + 1)
        return n_on, max(count, 0)

    def synthesise(
        self, modes: list[_Mode], out: np.ndarray | None = None, sign: float = 1.0
    ) -> np.ndarray:
        """Sum of the models, sampled like the input (added with ``sign`` to ``out``)."""
        if out is None:
            out = np.zeros(self.n)
        for m in modes:
            if not (m.fitted and m.ok) or m.amp == 0:
                continue
            n_on, count = self.span(m)
            if count <= 0:
                continue
            s = complex(-m.sigma, 2.0 * math.pi * m.frequency_hz) / self.fs
            ph = _damped_phasor(n_on - m.t_on * self.fs, count, s)
            out[n_on : n_on + count] += (2.0 * sign) * (m.amp * ph).real
        return out

    def residual(self, modes: list[_Mode], state: dict | None) -> tuple[np.ndarray, dict]:
        """The sound less all models, updated from ``state`` for the models that changed.

        ``state`` holds the last residual and the models in it (keyed by their
        parameters); pass None to start afresh.
        """
        wanted = {
            (m.frequency_hz, m.sigma, m.amp, m.t_on): m
            for m in modes
            if m.fitted and m.ok and m.amp != 0
        }
        if state is None:
            return self.x - self.synthesise(list(wanted.values())), {"models": wanted}
        held = state["models"]
        gone = [m for key, m in held.items() if key not in wanted]
        new = [m for key, m in wanted.items() if key not in held]
        out = state["residual"]
        self.synthesise(gone, out, +1.0)
        self.synthesise(new, out, -1.0)
        return out, {"models": wanted}

    def model_dft(
        self,
        m: _Mode,
        band: _Band,
        span: tuple[int, int],
        sigma: float,
        frequency_hz: float,
        amp: complex,
        derivative: bool = False,
    ):
        """DFT (length npad) at the band's bins of amp exp(s (n - t_on fs)), n in the span.

        Only the positive-frequency half of the (real) model: its mirror image is at
        least two cutoffs away and filtered out. With ``derivative``, also returns
        the derivative with respect to the complex rate -sigma + 2j pi f (1/s).
        """
        n_on, count = span
        if count <= 0:
            zero = np.zeros(band.k.size, dtype=np.complex128)
            return (zero, zero) if derivative else zero
        fs, npad = self.fs, self.npad
        s = complex(-sigma, 2.0 * math.pi * frequency_hz) / fs
        # u = s - 2j pi k / npad with the phase reduced near zero for precision;
        # the sum over the span is geometric: expm1(count u) / expm1(u)
        u = (-sigma / fs) + 2j * math.pi * (frequency_hz / fs - band.k / npad)
        den = np.expm1(u)
        num = np.expm1(count * u)
        tiny = np.abs(count * u) < 1e-4
        safe = np.where(tiny, 1.0, den)
        geo = np.where(tiny, count + 0.5 * count * (count - 1) * u, num / safe)
        phase0 = np.exp(-2j * math.pi * (np.mod(band.k * n_on, npad) / npad))
        offset = n_on - m.t_on * fs
        pre = amp * np.exp(s * offset) * phase0
        value = pre * geo
        if not derivative:
            return value
        # d geo / du = sum p exp(p u) = (count exp(count u) - geo exp(u)) / expm1(u)
        c = float(count)
        dgeo = np.where(
            tiny,
            0.5 * c * (c - 1.0) + c * (c - 1.0) * (2.0 * c - 1.0) / 6.0 * u,
            (c * (num + 1.0) - geo * (den + 1.0)) / safe,
        )
        return value, (value * offset + pre * dgeo) / fs

    def skip(self, cutoff_hz: float, t_on: float) -> float:
        """What the fits leave out after a partial's onset (the strike itself), s."""
        return min(0.5 / cutoff_hz, 0.005, 0.1 * (self.duration - t_on))

    # -- the first estimate: a ladder of decay rates ------------------------------------
    def initial_fit(self, m: _Mode, spec: np.ndarray) -> _Mode:
        """First estimate of a partial at its candidate frequency.

        The partial is taken to start with the sound; for each of a ladder of decay
        rates the complex amplitude that best fits the band's envelope follows by
        linear least squares, and the best decay rate wins. Gauss-Newton then
        refines frequency, decay and amplitude together.

        Every partial not yet modelled leaves, through the low-pass, a pulse at the
        onset in this band (the skirt of its sudden start); two nuisance columns,
        the low-pass's impulse response at the onset and its derivative, take that
        up, so that it does not pass for a fast decay.
        """
        band = self.band(m.centre_hz, m.cutoff_hz)
        t = band.t
        sel = t >= self.t0 + self.skip(m.cutoff_hz, self.t0)
        if np.count_nonzero(sel) < _MIN_FIT_POINTS + 2:
            return m.copy(ok=False)
        slowest = 0.3 / max(self.duration - self.t0, 1e-9)
        # from nearly steady to three cycles within the T60
        fastest = min(4.0 * math.pi * m.cutoff_hz, _LN1000 * m.centre_hz / 3.0)
        fastest = max(fastest, 2.0 * slowest)
        sigmas = np.concatenate(([0.0], np.geomspace(slowest, fastest, 16)))
        impulse = np.exp(-2j * math.pi * (np.mod(band.k * self.n0, self.npad) / self.npad))
        env = self.envelopes(
            band, np.stack([self.band_values(spec, band), impulse, impulse * band.m])
        )[:, sel]
        d, nuisance = env[0], env[1:].T
        # take the nuisance out of the data and of every column (orthogonal projection)
        q, _ = np.linalg.qr(nuisance)
        d = d - q @ (q.conj().T @ d)
        tt = t[sel]
        carrier = np.exp(2j * math.pi * (m.centre_hz - band.f_bin) * tt)
        cols = np.exp(-np.outer(tt - self.t0, sigmas)) * carrier[:, None]
        cols = cols - q @ (q.conj().T @ cols)
        power = np.sum(np.abs(cols) ** 2, axis=0)
        inner = cols.conj().T @ d
        score = np.abs(inner) ** 2 / np.maximum(power, 1e-300)
        k = int(np.argmax(score))
        if not (score[k] > 0 and power[k] > 0):
            return m.copy(ok=False)
        amp = complex(inner[k] / power[k]) * complex(np.exp(2j * math.pi * m.centre_hz * self.t0))
        return m.copy(
            frequency_hz=m.centre_hz,
            sigma=float(sigmas[k]),
            amp=amp,
            t_on=self.t0,
            fitted=True,
            ok=True,
        )

    # -- Gauss-Newton on the band-limited residual ----------------------------------------
    def newton_step(self, m: _Mode, spec: np.ndarray, neighbours: list[_Mode]) -> _Mode:
        """One Gauss-Newton step of a partial's model against the residual in its band.

        The model's own spectrum goes through the same band extraction and low-pass
        as the residual, so the filter biases nothing: this minimises
        sum |LPF(residual + model_old - model_new)|^2 over the partial's stretch.
        The nearest partials on either side take part in the least-squares solve
        (only this partial is updated), so that what is left of their errors in
        this band is not mistaken for this partial's.
        """
        band = self.band(m.centre_hz, m.cutoff_hz)
        t = band.t
        span = self.span(m)
        spectra = [self.band_values(spec, band)]
        for mode in [m, *neighbours]:
            sp = span if mode is m else self.span(mode)
            # d model / d log(amp) is the model itself; and d model / d(-sigma + 2j pi f)
            spectra += self.model_dft(
                mode, band, sp, mode.sigma, mode.frequency_hz, mode.amp, derivative=True
            )
        env = self.envelopes(band, np.stack(spectra))
        # the stretch: from just after the onset to 100 dB down (or the end)
        skip = self.skip(m.cutoff_hz, m.t_on)
        t_end = self.duration
        if m.sigma > 0:
            t_end = min(t_end, m.t_on + (100.0 / _DB_PER_NEPER) / m.sigma)
        sel = (t >= m.t_on + skip) & (t <= t_end)
        if np.count_nonzero(sel) < _MIN_FIT_POINTS:
            sel = t >= m.t_on
            if np.count_nonzero(sel) < _MIN_FIT_POINTS:
                return m.copy(ok=False)
        env = env[:, sel]
        ds, a1 = env[0], env[1]
        target = ds + a1
        energy = float(np.vdot(target, target).real)
        obj0 = float(np.vdot(ds, ds).real)
        if not energy > 0:
            return m.copy(ok=False)
        cols = env[1:].T
        # columns of neighbours that do not reach this band only spoil the conditioning
        norms = np.sqrt(np.sum(np.abs(cols) ** 2, axis=0))
        use = np.ones(cols.shape[1], dtype=bool)
        use[2:] = norms[2:] > 1e-9 * max(norms[0], 1e-300)
        try:
            sol, *_ = np.linalg.lstsq(cols[:, use], ds, rcond=1e-12)
        except np.linalg.LinAlgError:
            return m.copy(ok=False)
        da, dr = complex(sol[0]), complex(sol[1])
        if not (np.isfinite(da) and np.isfinite(dr)):
            return m.copy(ok=False)
        # keep a step within reason: the frequency within the band, the decay modest
        limit_f = 2.0 * math.pi * 0.5 * m.cutoff_hz
        limit_s = 5.0 / max(self.duration - m.t_on, 1e-9) + 0.5 * abs(m.sigma)
        scale = min(1.0, limit_f / max(abs(dr.imag), 1e-300), limit_s / max(abs(dr.real), 1e-300))
        scale = min(scale, 3.0 / max(abs(da), 1e-300))
        da, dr = da * scale, dr * scale
        best = None
        for _ in range(8):
            sigma = m.sigma - dr.real
            freq = m.frequency_hz + dr.imag / (2.0 * math.pi)
            amp = m.amp * complex(np.exp(da))
            trial = self.envelope(band, self.model_dft(m, band, span, sigma, freq, amp))[sel]
            resid = target - trial
            obj = float(np.vdot(resid, resid).real)
            if obj <= obj0 * (1.0 + 1e-9):
                best = (sigma, freq, amp, obj)
                break
            da, dr = 0.5 * da, 0.5 * dr
        if best is None:
            coherence = max(0.0, 1.0 - obj0 / energy)
            # a model that explains nothing and cannot be improved is not a partial
            return m.copy(coherence=coherence, ok=coherence > 0.01)
        sigma, freq, amp, obj = best
        return m.copy(
            frequency_hz=freq, sigma=sigma, amp=amp, coherence=max(0.0, 1.0 - obj / energy), ok=True
        )


def _neighbour_cutoff(
    freqs: list[float], i: int, fs: float, duration: float, sigma: float | None
) -> float:
    """Demodulation cutoff for partial i: at most half the distance to anything else."""
    f = freqs[i]
    # a DC offset, and the partial's own mirror images beyond 0 Hz and Nyquist
    d = min(f, 2.0 * (0.5 * fs - f))
    for j, g in enumerate(freqs):
        if j != i:
            d = min(d, abs(g - f))
    cap = 100.0 if sigma is None else max(5.0, 3.0 * max(sigma, 0.0) / math.pi)
    b = min(0.5 * d, cap)
    return max(b, 0.7 / duration, 1e-3)


def _same_line(a: _Mode, b: _Mode, separation_cents: float) -> bool:
    """Closer than the minimum separation, or within each other's half-power width.

    Only widths the partials' bands can show count (a model wider than its band
    is not a measurement of a line).
    """
    if abs(1200.0 * math.log2(a.frequency_hz / b.frequency_hz)) < separation_cents:
        return True
    widths = sum(
        min(max(m.sigma, 0.0) / (2.0 * math.pi), m.cutoff_hz) for m in (a, b) if m.fitted
    )
    return abs(a.frequency_hz - b.frequency_hz) < widths


def _refine(
    engine: _Engine,
    modes: list[_Mode],
    *,
    prune=None,
    max_sweeps: int = _MAX_SWEEPS,
    pending: tuple[float, ...] = (),
) -> list[_Mode]:
    """Fit every partial, then iterate Gauss-Newton steps against the common residual.

    A partial that has settled (its last step changed nothing that matters) rests
    until one of its neighbours moves or its band changes. ``pending`` are
    frequencies of candidates still to come: bands stay clear of them too.
    """
    fs = engine.fs
    full = False  # was the last sweep a step of every partial?
    state = None  # the residual, kept up to date
    for sweep in range(max_sweeps + 1):
        freqs = [m.frequency_hz for m in modes]
        others = freqs + [f for f in pending if all(abs(f - g) > 1e-9 * f for g in freqs)]
        for i, m in enumerate(modes):
            if not m.fixed_cutoff:
                sigma = m.sigma if m.fitted else None
                cutoff = _neighbour_cutoff(others, i, fs, engine.duration, sigma)
                if abs(cutoff - m.cutoff_hz) > 0.01 * cutoff:
                    m.settled = False
                m.cutoff_hz = cutoff
            if not m.fixed_centre:
                m.centre_hz = m.frequency_hz
        if sweep == 0 or engine.npad == 0:
            engine.prepare(modes)
        if all(m.settled for m in modes):
            if full:
                break
            # all resting: one step of every partial confirms (small changes of a
            # strong partial can matter to a weak neighbour)
            for m in modes:
                m.settled = False
        full = not any(m.settled for m in modes)
        residual, state = engine.residual(modes, state)
        state["residual"] = residual
        spec = engine.spectrum(residual)
        new: list[_Mode] = []
        fitted = sorted((m for m in modes if m.fitted), key=lambda m: m.frequency_hz)
        for m in modes:
            if m.fitted:
                below = [o for o in fitted if o.frequency_hz < m.frequency_hz]
                above = [o for o in fitted if o.frequency_hz > m.frequency_hz]
                neighbours = below[-1:] + above[:1]
                if m.settled and not any(o.moved for o in neighbours):
                    new.append(m.copy(moved=False))
                    continue
                upd = engine.newton_step(m, spec, neighbours)
                upd.settled = (
                    abs(upd.frequency_hz - m.frequency_hz) <= 2e-8 * upd.frequency_hz + 1e-7
                    and abs(upd.sigma - m.sigma) <= 2e-5 * abs(upd.sigma) + 1e-5 / engine.duration
                    and abs(abs(upd.amp) - abs(m.amp)) <= 1e-5 * abs(upd.amp)
                )
            else:
                upd = engine.initial_fit(m, spec)
                upd.settled = False
            upd.moved = not upd.settled
            # a partial that wandered out of its band belongs to something else
            if upd.ok and abs(upd.frequency_hz - m.centre_hz) > 1.5 * m.cutoff_hz:
                upd.ok = False
            if upd.ok and not (0.0 < upd.frequency_hz < 0.5 * fs):
                upd.ok = False
            if upd.pinned and not upd.ok and m.fitted:
                # measure_partial's partial: start afresh where it was asked for
                upd = _Mode(
                    frequency_hz=m.centre_hz,
                    centre_hz=m.centre_hz,
                    cutoff_hz=m.cutoff_hz,
                    fixed_cutoff=m.fixed_cutoff,
                    fixed_centre=m.fixed_centre,
                    pinned=True,
                )
            new.append(upd)
        before = len(new)
        modes = prune(new, final=False) if prune is not None else [m for m in new if m.ok]
        if len(modes) != before:
            # partials were dropped: their neighbours' bands and residual change
            for m in modes:
                m.moved = True
    return modes


# ----------------------------------------------------------------------------------
# public functions
# ----------------------------------------------------------------------------------
def find_partials(
    samples: Any,
    sample_rate: float,
    *,
    max_partials: int = 24,
    min_level_db: float = -80.0,
    min_separation_cents: float = 30.0,
    min_frequency_hz: float = 5.0,
) -> list[Partial]:
    """Find the partials of a sound and measure each one's frequency, level and T60.

    Parameters
    ----------
    samples
        Mono sound, a 1-D array of finite numbers (full scale is 1.0).
    sample_rate
        Samples per second, Hz.
    max_partials
        At most this many partials are returned, the strongest (by initial level).
    min_level_db
        Partials whose initial level is more than this many dB below the strongest
        partial's are ignored (a negative number, dB relative to the strongest).
    min_separation_cents
        Two partials closer than this are reported as one (the stronger).
    min_frequency_hz
        Nothing below this frequency is reported (keeps DC and rumble out).

    Returns
    -------
    list of Partial
        Sorted by frequency. ``t60_s`` is ``math.inf`` for a partial that does not
        decay (or grows).

    Notes
    -----
    See the module documentation for the method. On sums of exponentially
    decaying cosines the fit is exact up to rounding (frequencies within 1e-6
    cent, T60s and levels to 1e-6), provided each partial can be told from its
    neighbours: further from them than a couple of times 1/duration plus their
    half-power widths, and not buried more than about 60 dB under a neighbour's
    skirt. A resonance excited by noise is, locally, a crowd of decaying
    components: the strongest few are reported, the strongest near its centre;
    measure its decay with :func:`band_decay_t60`.

    Examples
    --------
    >>> import numpy as np
    >>> fs = 48000
    >>> t = np.arange(2 * fs) / fs
    >>> x = 0.5 * np.exp(-t * np.log(1000) / 1.5) * np.cos(2 * np.pi * 440 * t)
    >>> p = find_partials(x, fs)[0]
    >>> round(p.frequency_hz, 3), round(p.level_db, 2), round(p.t60_s, 3)
    (440.0, -6.02, 1.5)
    """
    x, fs = _as_signal(samples, sample_rate)
    max_partials = check_whole("max_partials", max_partials, "", 1)
    min_level_db = check_number(
        "min_level_db", min_level_db, "dB (relative to the strongest partial)",
        minimum=-300.0, maximum=0.0,
    )
    min_separation_cents = check_number(
        "min_separation_cents", min_separation_cents, "cents", minimum=0.0, maximum=2400.0
    )
    min_frequency_hz = check_number(
        "min_frequency_hz", min_frequency_hz, "Hz", minimum=0.0, maximum=0.5 * fs
    )
    min_frequency_hz = max(min_frequency_hz, 1e-6)
    sep = max(min_separation_cents, 1e-3)

    search = _Search(x, fs, max_partials, min_level_db, sep, min_frequency_hz)
    modes = search.run()
    return [_to_partial(m) for m in search.prune(modes, final=True)]


class _Search:
    """find_partials' search: candidates, layered refinement, residual rounds."""

    def __init__(
        self,
        x: np.ndarray,
        fs: float,
        max_partials: int,
        min_level_db: float,
        separation_cents: float,
        min_frequency_hz: float,
    ) -> None:
        self.x = x
        self.fs = fs
        self.max_partials = max_partials
        self.min_level_db = min_level_db
        self.sep = separation_cents
        self.min_frequency_hz = min_frequency_hz
        self.engine = _Engine(x, fs)

    def prune(self, ms: list[_Mode], final: bool) -> list[_Mode]:
        """Drop failed partials, duplicates and those too weak; sort by frequency.

        A pinned partial (the one measure_partial is after) always stays, and
        anything that would be a duplicate of it goes.
        """
        pinned = [m for m in ms if m.pinned]
        ms = [m for m in ms if not m.pinned and m.ok and m.frequency_hz >= self.min_frequency_hz]
        # a "partial" that decays within a cycle or so is a click, not a partial
        ms = [m for m in ms if not m.fitted or m.sigma < 2.0 * math.pi * m.frequency_hz]
        # the stronger of two partials closer than the minimum separation, or
        # whose lines overlap (two models of one broad line), wins
        ms.sort(key=lambda m: -abs(m.amp))
        kept: list[_Mode] = list(pinned)
        for m in ms:
            if not any(_same_line(m, k, self.sep) for k in kept):
                kept.append(m)
        kept = kept[len(pinned) :]
        if kept:
            top = kept[0].level_db
            margin = 0.0 if final else 20.0
            kept = [m for m in kept if m.level_db >= top + self.min_level_db - margin]
            kept = kept[: self.max_partials] if final else kept[: 2 * self.max_partials + 8]
        kept = pinned + kept
        kept.sort(key=lambda m: m.frequency_hz)
        return kept

    def run(self) -> list[_Mode]:
        x, fs, engine, sep = self.x, self.fs, self.engine, self.sep
        if engine.peak == 0.0 or x.size < 32:
            return []
        cands, tops = _spectral_candidates(
            x,
            fs,
            engine.n0,
            min_separation_cents=sep,
            min_level_db=self.min_level_db,
            min_frequency_hz=self.min_frequency_hz,
            max_candidates=3 * self.max_partials + 8,
            coarse=True,
        )
        if not cands:
            return []
        # Strong candidates first, then weaker ones on what the strong ones leave:
        # a weak partial's band is otherwise dominated by the onset skirts of strong
        # ones. Their strengths: a first estimate of each on the whole sound.
        freqs = [f for f, _ in cands]
        cutoffs = [
            _neighbour_cutoff(freqs, i, fs, engine.duration, None) for i in range(len(freqs))
        ]
        engine.prepare([_Mode(f, f, cutoff_hz=c) for f, c in zip(freqs, cutoffs)])
        spec = engine.spectrum(x)
        first = []
        for f, c in zip(freqs, cutoffs):
            m = engine.initial_fit(_Mode(f, f, cutoff_hz=c), spec)
            first.append((f, m.level_db if m.ok else -math.inf))
        top_level = max(level for _, level in first)
        modes: list[_Mode] = []
        for lo, hi in ((-30.0, math.inf), (-60.0, -30.0), (-math.inf, -60.0)):
            layer = [
                _Mode(frequency_hz=f, centre_hz=f)
                for f, level in first
                if lo <= level - top_level < hi
                and not any(_same_line(_Mode(f, f), m, sep) for m in modes)
            ]
            if layer:
                pending = tuple(f for f, level in first if level - top_level < lo)
                # (a few sweeps: the last refinement below finishes the job)
                modes = _refine(
                    engine, modes + layer, prune=self.prune, pending=pending, max_sweeps=3
                )
        # Partials hidden under stronger ones (their onset skirts, mostly) show in
        # the residual once those are subtracted: look up to three more times.
        for _ in range(3):
            if not modes:
                break
            residual = x - engine.synthesise(modes)
            extra, _ = _spectral_candidates(
                residual,
                fs,
                engine.n0,
                min_separation_cents=sep,
                min_level_db=self.min_level_db,
                min_frequency_hz=self.min_frequency_hz,
                max_candidates=self.max_partials,
                reference=tops,
                exclude=tuple(m.frequency_hz for m in modes),
                coarse=True,
            )
            extra = [
                (f, h) for f, h in extra if not any(_same_line(_Mode(f, f), m, sep) for m in modes)
            ]
            if not extra:
                break
            added = [_Mode(frequency_hz=f, centre_hz=f) for f, _ in extra]
            modes = _refine(engine, modes + added, prune=self.prune, max_sweeps=4)
        return _refine(engine, modes, prune=self.prune)


def _to_partial(m: _Mode) -> Partial:
    if not m.ok or not m.fitted:
        return Partial(math.nan, -math.inf, math.nan)
    t60 = _LN1000 / m.sigma if m.sigma > 0 else math.inf
    return Partial(float(m.frequency_hz), float(m.level_db), float(t60))


def partial_ratios(partials: Any) -> np.ndarray:
    """Frequencies divided by the lowest one (an array; empty for no partials).

    Accepts a sequence of :class:`Partial` or of frequencies in Hz.
    """
    freqs = []
    for p in partials:
        f = p.frequency_hz if isinstance(p, Partial) else p
        freqs.append(float(f))
    if not freqs:
        return np.zeros(0)
    arr = np.asarray(freqs, dtype=np.float64)
    finite = arr[np.isfinite(arr)]
    if finite.size == 0 or finite.min() <= 0:
        raise ParameterError(
            f"parameter partials has frequencies {freqs!r}; "
            "allowed: at least one finite frequency > 0 Hz"
        )
    return arr / finite.min()


def measure_partial(
    samples: Any,
    sample_rate: float,
    frequency_hz: float,
    *,
    bandwidth_hz: float | None = None,
) -> Partial:
    """Measure the one partial near ``frequency_hz`` precisely.

    The refinement of :func:`find_partials` aimed at one frequency: the sound's
    other partials are found and modelled first (so that neither they nor their
    skirts leak into the measurement), then the partial found nearest
    ``frequency_hz`` -- or, if none was found there, one started at
    ``frequency_hz`` -- is fitted by complex demodulation and Gauss-Newton steps
    against the residual until it settles (see the module notes). Use it to measure
    a known mode, especially one too close to a neighbour or too weak for
    :func:`find_partials` to report.

    Parameters
    ----------
    samples, sample_rate
        As for :func:`find_partials`.
    frequency_hz
        Where the partial is, Hz, to within ``bandwidth_hz`` (or 30 cents when no
        bandwidth is given).
    bandwidth_hz
        Cutoff of the demodulation low-pass, Hz, centred on ``frequency_hz``: a
        component ``bandwidth_hz`` away is attenuated by 6 dB, one twice as far by
        96 dB. At most half the distance to the nearest neighbour is a good choice.
        ``None``: half the distance to the nearest other partial found, at most
        about 100 Hz, and following the partial.

    Returns
    -------
    Partial
        ``frequency_hz`` and ``t60_s`` are ``nan`` and ``level_db`` is ``-inf``
        when there is no partial there (the best model explains less than 30 % of
        the band's energy).

    Examples
    --------
    >>> import numpy as np
    >>> fs = 48000
    >>> t = np.arange(2 * fs) / fs
    >>> decay = np.exp(-t * np.log(1000) / np.array([[1.2], [2.0]]))
    >>> x = (decay * np.cos(2 * np.pi * np.array([[1000.0], [1050.0]]) * t)).sum(axis=0)
    >>> p = measure_partial(x, fs, 1050.0, bandwidth_hz=20.0)
    >>> round(p.frequency_hz, 4), round(p.t60_s, 4)
    (1050.0, 2.0)
    """
    x, fs = _as_signal(samples, sample_rate)
    f0 = _below_nyquist("frequency_hz", frequency_hz, fs)
    if bandwidth_hz is not None:
        bandwidth_hz = check_number(
            "bandwidth_hz", bandwidth_hz, "Hz", minimum=1e-6, maximum=0.5 * fs
        )
    search = _Search(x, fs, 24, -80.0, 30.0, min(5.0, 0.5 * f0))
    engine = search.engine
    if engine.peak == 0.0:
        return Partial(math.nan, -math.inf, math.nan)
    modes = search.run()
    # the partial found nearest the requested frequency is the one asked for
    reach = bandwidth_hz or max(f0 * (2.0 ** (30.0 / 1200.0) - 1.0), 1.0 / engine.duration)
    near = min(modes, key=lambda m: abs(m.frequency_hz - f0), default=None)
    if near is not None and abs(near.frequency_hz - f0) <= reach:
        others = [m for m in modes if m is not near]
        target = near.copy(pinned=True, settled=False)
    else:
        others = modes
        target = _Mode(frequency_hz=f0, centre_hz=f0, pinned=True)
    if bandwidth_hz is not None:
        target.centre_hz, target.fixed_centre = f0, True
        target.cutoff_hz, target.fixed_cutoff = bandwidth_hz, True
    modes = _refine(engine, others + [target], prune=search.prune)
    head = next(m for m in modes if m.pinned)
    # nothing there: the model explains less of its band than is left over
    if not (head.fitted and head.ok) or head.coherence < 0.3:
        return Partial(math.nan, -math.inf, math.nan)
    return _to_partial(head)


def band_decay_t60(
    samples: Any,
    sample_rate: float,
    centre_hz: float,
    bandwidth_hz: float,
) -> float:
    """T60 (s) of the energy in a band, for noise-excited or otherwise rough decays.

    The sound is band-passed (zero phase, -3 dB at ``centre_hz +- bandwidth_hz/2``)
    and its squared magnitude taken (of the analytic band signal, so free of ripple
    at twice the frequency). A first line is fitted in dB to that energy smoothed
    over about 4/bandwidth_hz, from its maximum down to 10 dB above the noise
    floor (estimated from the last tenth, Lundeby-style) or 100 dB below the
    maximum. Returns ``math.inf`` if the energy does not decay and ``nan`` if there
    is too little to fit.
    """
    from scipy.ndimage import uniform_filter1d

    x, fs = _as_signal(samples, sample_rate)
    fc = _below_nyquist("centre_hz", centre_hz, fs)
    bw = check_number(
        "bandwidth_hz", bandwidth_hz, "Hz", minimum=0.0, maximum=fs, minimum_exclusive=True
    )
    engine = _Engine(x, fs)
    if engine.peak == 0.0:
        return math.nan
    # -3 dB at +-bw/2 for exp(-0.5 (f/f1)^4)
    half = 0.5 * bw
    f1 = half / (2.0 * math.log(math.sqrt(2.0))) ** 0.25
    cutoff = f1 * _SG_6DB
    engine.prepare([_Mode(frequency_hz=fc, centre_hz=fc, cutoff_hz=cutoff)])
    band = engine.band(fc, cutoff)
    t = band.t
    z = engine.envelope(band, engine.band_values(engine.spectrum(x), band))
    energy = z.real**2 + z.imag**2
    dt = t[1] - t[0] if t.size > 1 else 1.0 / fs
    width = max(1, int(round(min(4.0 / bw, 0.05 * engine.duration) / dt)))
    smooth = np.maximum(uniform_filter1d(energy, width, mode="nearest"), 1e-300)
    # leave out the filter's edge smear
    margin = min(2.0 / f1, 0.1 * engine.duration) + 0.5 * width * dt
    sel = (t >= engine.t0 + margin) & (t <= engine.duration - margin)
    if np.count_nonzero(sel) < _MIN_FIT_POINTS:
        return math.nan
    tt = t[sel]
    level = smooth[sel]
    top = float(level.max())
    if not top > 0:
        return math.nan
    db = 10.0 * np.log10(level / top + 1e-300)
    i0 = int(np.argmax(db >= -1.0))  # (a steady sound's maximum may be anywhere)
    below = np.flatnonzero(db[i0:] < -100.0)
    i1 = i0 + int(below[0]) if below.size else tt.size
    tail = max(_MIN_FIT_POINTS, tt.size // 10)
    floor_db = float(10.0 * np.log10(np.mean(level[-tail:]) / top + 1e-300))
    slope = 0.0
    for _ in range(5):
        if i1 - i0 < _MIN_FIT_POINTS:
            return math.nan
        a, slope, tm = _wls_line(tt[i0:i1], db[i0:i1], np.ones(i1 - i0))
        t_tail = float(np.mean(tt[-tail:]))
        if not (slope < 0 and floor_db > a + slope * (t_tail - tm) + 6.0):
            break
        t_cross = tm + (floor_db + _FLOOR_MARGIN_DB - a) / slope
        new_i1 = int(np.searchsorted(tt, t_cross))
        new_i1 = max(i0 + _MIN_FIT_POINTS, min(new_i1, i1))
        if new_i1 >= i1:
            break
        i1 = new_i1
    if slope >= 0:
        return math.inf
    return float(-60.0 / slope)
