"""Finding a sound's partials (:func:`find_partials`) or measuring one (:func:`measure_partial`).

This is how a struck bar is measured (spec 3.4); the same code serves recordings
and barsynth's own tests, so it aims at precision first. Each partial is modelled
as a damped cosine that starts with the sound,
``A exp(-(t - t0) ln(1000) / T60) cos(2 pi f t + phi)``.

1. **Candidates** (:mod:`.candidates`): peaks of long spectra of the sound.
2. **Complex demodulation** (:mod:`.demodulation`): around each partial the
   sound's spectrum is cut out, shifted to 0 Hz and low-passed, the cutoff being
   at most half the distance to the nearest other partial; a short inverse FFT
   gives the partial's complex envelope.
3. **First estimate** (:mod:`.demodulation`): the best of a ladder of decay rates,
   each with its least-squares complex amplitude.
4. **Gauss-Newton on the residual** (:mod:`.refine`): each partial is corrected
   against the residual in its band, over all partials until none moves (a
   space-alternating, SAGE-like iteration); on a sum of exponentially decaying
   cosines the exact parameters are the fixed point.
5. **Order** (here): strong candidates are refined first and weaker ones added on
   what they leave; partials hidden under stronger ones (in their onset skirts)
   are then looked for twice more in the residual's spectra. Two models of one
   line (closer than the minimum separation or than their half-power widths)
   merge into the stronger.

References: J. O. Smith, *Spectral Audio Signal Processing*; J. A. Fessler and
A. O. Hero, "Space-alternating generalized expectation-maximization algorithm",
IEEE Trans. Signal Process. 42 (1994).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..checks import check_number, check_whole
from .candidates import spectral_candidates
from .demodulation import LN1000, Engine, Mode
from .inputs import as_signal, below_nyquist
from .partial import Partial
from .refine import neighbour_cutoff, refine

__all__ = ["find_partials", "measure_partial"]


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
    x, fs = as_signal(samples, sample_rate)
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


def _same_line(a: Mode, b: Mode, separation_cents: float) -> bool:
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
        self.engine = Engine(x, fs)

    def prune(self, ms: list[Mode], final: bool) -> list[Mode]:
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
        kept: list[Mode] = list(pinned)
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

    def run(self) -> list[Mode]:
        x, fs, engine, sep = self.x, self.fs, self.engine, self.sep
        if engine.peak == 0.0 or x.size < 32:
            return []
        cands, tops = spectral_candidates(
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
            neighbour_cutoff(freqs, i, fs, engine.duration, None) for i in range(len(freqs))
        ]
        engine.prepare([Mode(f, f, cutoff_hz=c) for f, c in zip(freqs, cutoffs)])
        spec = engine.spectrum(x)
        first = []
        for f, c in zip(freqs, cutoffs):
            m = engine.initial_fit(Mode(f, f, cutoff_hz=c), spec)
            first.append((f, m.level_db if m.ok else -math.inf))
        top_level = max(level for _, level in first)
        modes: list[Mode] = []
        for lo, hi in ((-30.0, math.inf), (-60.0, -30.0), (-math.inf, -60.0)):
            layer = [
                Mode(frequency_hz=f, centre_hz=f)
                for f, level in first
                if lo <= level - top_level < hi
                and not any(_same_line(Mode(f, f), m, sep) for m in modes)
            ]
            if layer:
                pending = tuple(f for f, level in first if level - top_level < lo)
                # (a few sweeps: the last refinement below finishes the job)
                modes = refine(
                    engine, modes + layer, prune=self.prune, pending=pending, max_sweeps=3
                )
        # Partials hidden under stronger ones (their onset skirts, mostly) show in
        # the residual once those are subtracted: look up to three more times.
        for _ in range(3):
            if not modes:
                break
            residual = x - engine.synthesise(modes)
            extra, _ = spectral_candidates(
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
                (f, h) for f, h in extra if not any(_same_line(Mode(f, f), m, sep) for m in modes)
            ]
            if not extra:
                break
            added = [Mode(frequency_hz=f, centre_hz=f) for f, _ in extra]
            modes = refine(engine, modes + added, prune=self.prune, max_sweeps=4)
        return refine(engine, modes, prune=self.prune)


def _to_partial(m: Mode) -> Partial:
    """A refined model as the partial reported (nan frequency and T60, -inf dB if it failed)."""
    if not m.ok or not m.fitted:
        return Partial(math.nan, -math.inf, math.nan)
    t60 = LN1000 / m.sigma if m.sigma > 0 else math.inf
    return Partial(float(m.frequency_hz), float(m.level_db), float(t60))


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
    against the residual until it settles (see this module's notes). Use it to measure
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
    x, fs = as_signal(samples, sample_rate)
    f0 = below_nyquist("frequency_hz", frequency_hz, fs)
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
        target = Mode(frequency_hz=f0, centre_hz=f0, pinned=True)
    if bandwidth_hz is not None:
        target.centre_hz, target.fixed_centre = f0, True
        target.cutoff_hz, target.fixed_cutoff = bandwidth_hz, True
    modes = refine(engine, others + [target], prune=search.prune)
    head = next(m for m in modes if m.pinned)
    # nothing there: the model explains less of its band than is left over
    if not (head.fitted and head.ok) or head.coherence < 0.3:
        return Partial(math.nan, -math.inf, math.nan)
    return _to_partial(head)
