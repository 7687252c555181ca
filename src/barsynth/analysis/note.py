"""Analysis of a recorded note (spec 7.1): :func:`analyze_note`.

1. **Onset** (spec 7.1) and **start**: where the strike is, robust to noise before it
   (:mod:`.onset`); partials are extrapolated to the start and the attack measured from
   it. The **noise floor** by frequency from the
   recording's tail (:mod:`.noise`).
2. **Candidates**: peaks of long spectra from the start (:mod:`.peaks`); each gets a
   band of its own, at most :data:`MAX_CUTOFF_HZ` wide and clear of its neighbours.
3. **Each band** (:mod:`.bandfit`): a decay fitted in dB over a stated range (from where
   the envelope is clean to 10 dB above the noise floor, with a knee where two slopes fit
   clearly better, :mod:`.slopes`), and one or two damped exponentials fitted to the
   complex envelope (matrix pencil and Gauss-Newton, :mod:`.poles`): frequency, level,
   phase, a resolved doublet or a beating pair.
4. **Sustained** partials are kept: coherent over their range (a damped exponential
   explains most of it), decaying no faster than :data:`MIN_T60_S`, fitted over at least
   :data:`MIN_SPAN_S`, and well described by their decay fit (:data:`MAX_RMS_DB`,
   :data:`MIN_R2`): a transient or noise is not a partial.
5. **Attack** (:mod:`.attack`): where it ends is judged from the energy between the
   candidates, before any fit, and the fits start there; what it is, from the sound less
   the resynthesised partials.
6. **f0** (:mod:`.pitch`): the partial that best explains the sustained spectrum.
7. **Looped**: the partials at and above f0 that do not decay within the file hold
   more than half of their energy.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..checks import check_number, check_whole
from .attack import NO_ATTACK, attack_end, describe_attack
from .bandfit import Component, measure_band
from .bands import BandEnvelope, Bands
from .demodulation import _damped_phasor
from .inputs import as_signal
from .noise import NoiseFloor, noise_floor
from .onset import onset_at, strike_at
from .peaks import note_peaks
from .pitch import choose_f0
from .records import Attack, Damped, Decay, NoteAnalysis, NotePartial

__all__ = ["MAX_CUTOFF_HZ", "MIN_SPAN_S", "MIN_T60_S", "analyze_note"]

MAX_CUTOFF_HZ = 100.0  # the widest band's cutoff (-6 dB), Hz
MIN_T60_S = 0.03  # a partial decays no faster than this
MIN_SPAN_S = 0.02  # and is fitted over at least this long
MIN_COHERENCE = 0.5  # a damped exponential explains at least this share of its band
MAX_RMS_DB = 6.0  # the decay fit misses the envelope by at most this (RMS, dB) ...
MIN_R2 = 0.5  # ... and explains at least this share of its variance
DOUBLET_COHERENCE = 0.99  # a doublet whose two exponentials explain this share of its band is
# sustained whatever its dB envelope's fit says (deep beats make that fit meaningless)
MAX_LEVEL_ABOVE_PEAK = 2.0  # no partial starts more than twice the sound's peak
MAX_EXTRAPOLATION_DB = 40.0  # nor has fallen by more than this where its fit begins
MIN_DURATION_S = 0.01  # shorter sounds (after the start) are not analysed
WIDEN = 4.0  # a band too narrow for its partial's decay is tried this much wider
SHADOW_DB, SHADOW_WIDTHS, SHADOW_HZ = 30.0, 3.0, 10.0  # a peak this much weaker within this many narrowest cutoffs (at most SHADOW_HZ)
_CANDIDATE_SEPARATION_CENTS = 30.0
_MIN_FREQUENCY_HZ = 5.0
_LN1000 = math.log(1000.0)


def analyze_note(
    samples: Any,
    sample_rate: float,
    *,
    nominal_hz: float | None = None,
    max_partials: int = 24,
    min_level_db: float = -60.0,
    partials_hz: Any = None,
    attack_s: float | None = None,
) -> NoteAnalysis:
    """Analyse a recorded note: f0, sustained partials with their decays, attack, loop.

    Parameters
    ----------
    samples
        Mono sound, a 1-D array of finite numbers (full scale 1.0).
    sample_rate
        Samples per second, Hz.
    nominal_hz
        The pitch the note is meant to have (a soundfont's root key), Hz: f0 is sought
        near it (see :mod:`.pitch`). None: no prior.
    max_partials
        At most this many sustained partials (the strongest), f0 and below included.
    min_level_db
        Partials more than this far below the strongest (initial level) are left out,
        dB (negative).
    partials_hz
        Where to look for partials (Hz), instead of the sound's spectral peaks: a
        resynthesis measured where its recording's partials were (a fit's comparison).
    attack_s
        How long the attack lasts from the start (s), instead of judging it: the same
        span as the recording's when a resynthesis is compared with it.

    Returns
    -------
    NoteAnalysis
        See :class:`~barsynth.analysis.records.NoteAnalysis`. Silence, noise or a sound
        too short to measure give an analysis without partials (``f0_hz`` None) and a
        line in ``notes`` saying why.

    Examples
    --------
    >>> import numpy as np
    >>> fs = 44100
    >>> t = np.arange(2 * fs) / fs
    >>> x = sum(a * np.exp(-t * np.log(1000) / T) * np.cos(2 * np.pi * f * t)
    ...         for f, a, T in [(440.0, 0.5, 1.5), (1760.0, 0.2, 0.5)])
    >>> note = analyze_note(x, fs)
    >>> round(note.f0_hz, 3), [round(p.ratio, 4) for p in note.partials]
    (440.0, [1.0, 4.0])
    """
    x, fs = as_signal(samples, sample_rate)
    if nominal_hz is not None:
        nominal_hz = check_number(
            "nominal_hz", nominal_hz, "Hz (below half the sample rate)", minimum=0.0,
            maximum=0.5 * fs, minimum_exclusive=True, maximum_exclusive=True,
        )
    max_partials = check_whole("max_partials", max_partials, "", 1, 1000)
    min_level_db = check_number(
        "min_level_db", min_level_db, "dB (relative to the strongest partial)", minimum=-300.0, maximum=0.0
    )
    if partials_hz is not None:
        partials_hz = sorted(check_number("partials_hz", f, "Hz (below half the sample rate)", minimum=0.0,
                                          maximum=0.5 * fs, minimum_exclusive=True, maximum_exclusive=True)
                             for f in partials_hz)
    if attack_s is not None:
        attack_s = check_number("attack_s", attack_s, "s", minimum=0.0, maximum=x.size / fs)
    analysis = _Analysis(x, fs, nominal_hz, max_partials, min_level_db)
    analysis.partials_hz, analysis.attack_s = partials_hz, attack_s
    return analysis.run()


class _Analysis:
    """One run of :func:`analyze_note`."""

    def __init__(self, x: np.ndarray, fs: float, nominal_hz: float | None, max_partials: int,
                 min_level_db: float) -> None:
        self.x, self.fs = x, fs
        self.nominal_hz = nominal_hz
        self.max_partials = max_partials
        self.min_level_db = min_level_db
        self.duration = x.size / fs
        self.start = strike_at(x, fs)
        self.onset = onset_at(x, fs)
        self.start_s = self.start / fs
        self.onset_s = self.onset / fs
        self.peak = float(np.max(np.abs(x))) if x.size else 0.0
        self.band_maker: Bands | None = None
        self.partials_hz: list[float] | None = None
        self.attack_s: float | None = None
        self.envelopes: dict[tuple[float, float], BandEnvelope] = {}

    def empty(self, note: str, noise: NoiseFloor | None = None) -> NoteAnalysis:
        floor = noise.rms_db if noise is not None else -math.inf
        return NoteAnalysis(
            sample_rate=self.fs, duration_s=self.duration, onset_s=self.onset_s, start_s=self.start_s,
            f0_hz=None, f0_family=None, f0_explained=None, partials=(), below_f0=(), attack=NO_ATTACK,
            looped=False, noise_floor_db=floor if math.isfinite(floor) else None, notes=(note,),
        )

    # -- the steps ---------------------------------------------------------------------
    def bands(self) -> list[tuple[float, float, float]]:
        """(centre, cutoff, widest cutoff its neighbours allow) of each candidate's band, Hz."""
        x, fs = self.x, self.fs
        cands = [(f, 0.0) for f in self.partials_hz] if self.partials_hz is not None else note_peaks(
            x, fs, self.start,
            min_level_db=max(-300.0, self.min_level_db - 20.0),
            min_frequency_hz=_MIN_FREQUENCY_HZ,
            max_count=2 * self.max_partials + 8,
            min_separation_cents=_CANDIDATE_SEPARATION_CENTS,
        )
        span = self.duration - self.start_s
        lowest = max(4.0 / span, 1.0)
        # a peak far weaker than a close neighbour is its sideband (a loop's or a tremolo's
        # ripple, a window's leakage), not a partial: it would only narrow the neighbour's band
        reach = min(SHADOW_WIDTHS * lowest, SHADOW_HZ)
        freqs = sorted(f for f, h in cands
                       if not any(abs(f - g) < reach and k - h >= SHADOW_DB for g, k in cands))
        # candidates closer than two of the narrowest cutoffs share a band (a doublet:
        # the band's two-exponential fit tells them apart)
        merged: list[float] = []
        for f in freqs:
            if merged and f - merged[-1] < 2.2 * lowest:
                continue
            merged.append(f)
        out = []
        for i, f in enumerate(merged):
            gap = min(f, 2.0 * (0.5 * fs - f))
            if i > 0:
                gap = min(gap, f - merged[i - 1])
            if i + 1 < len(merged):
                gap = min(gap, merged[i + 1] - f)
            widest = max(0.45 * gap, lowest)
            out.append((f, min(MAX_CUTOFF_HZ, widest), widest))
        return out

    def fit(self, plan: list[tuple[float, float, float]], noise: NoiseFloor, clean_s: float) -> list[Component]:
        """The sustained components of every band, fitted from ``clean_s`` (plus each band's
        settling). A band whose partial decays too fast for it (or that finds none) is
        tried again up to four times wider, where its neighbours allow."""
        found: list[Component] = []
        for centre, cutoff, widest in plan:
            comps = self.measure(self.envelope(centre, cutoff), noise, clean_s)
            wide = min(widest, WIDEN * cutoff)
            if wide > 1.5 * cutoff and not any(_holds(c, cutoff) for c in comps):
                wider = self.measure(self.envelope(centre, wide), noise, clean_s)
                if _range_db(wider) > _range_db(comps):
                    comps = wider
            found.extend(comps)
        return self.sustained(found)

    def envelope(self, centre: float, cutoff: float) -> BandEnvelope:
        """The band's envelope (computed once)."""
        key = (centre, cutoff)
        if key not in self.envelopes:
            self.envelopes[key] = self.band_maker.envelope(centre, cutoff)
        return self.envelopes[key]

    def measure(self, env: BandEnvelope, noise: NoiseFloor, clean_s: float) -> list[Component]:
        """The components of one band that lie inside it."""
        noise_power = noise.at(env.centre_hz) * env.enbw_hz / self.fs
        comps = measure_band(
            env, noise_power=noise_power, start_s=self.start_s,
            t_clean=clean_s + env.settle_s, t_last=self.duration - env.settle_s,
        )
        return [c for c in comps if c.doublet or abs(c.frequency_hz - env.centre_hz) <= env.cutoff_hz]

    def sustained(self, comps: list[Component]) -> list[Component]:
        """The components that are sustained partials, strongest first, duplicates merged."""
        keep = []
        for c in comps:
            if not (c.frequency_hz > 0 and c.frequency_hz < 0.5 * self.fs and math.isfinite(c.amplitude)):
                continue
            if c.amplitude <= 0 or c.coherence < MIN_COHERENCE:
                continue
            if c.amplitude > MAX_LEVEL_ABOVE_PEAK * self.peak:  # extrapolated from a fit of something else
                continue
            explained = c.doublet and c.coherence >= DOUBLET_COHERENCE  # beats leave notches in dB
            if not explained and (c.rms_db > MAX_RMS_DB or (not c.sustains and c.r2 < MIN_R2)):
                continue
            if c.t_end - c.t_start < MIN_SPAN_S:
                continue
            if c.t60_s is not None and c.t60_s < MIN_T60_S:
                continue
            if c.start_db < -MAX_EXTRAPOLATION_DB:  # its start is a guess from far later
                continue
            keep.append(c)
        keep.sort(key=lambda c: -c.amplitude)
        out: list[Component] = []
        for c in keep:
            span = c.t_end - c.t_start
            tol = max(1.0 / span, c.frequency_hz * (2.0 ** (5.0 / 1200.0) - 1.0))
            if any(abs(c.frequency_hz - o.frequency_hz) < tol and not (c.doublet and o.doublet) for o in out):
                continue
            out.append(c)
        if out:
            top = 20.0 * math.log10(out[0].amplitude)
            out = [c for c in out if 20.0 * math.log10(c.amplitude) >= top + self.min_level_db]
        return out[: self.max_partials]

    def resynthesis(self, comps: list[Component]) -> np.ndarray:
        """The components as cosines from the start (:class:`.bandfit.Component`'s parts)."""
        fs, n = self.fs, self.x.size
        out = np.zeros(n)
        count = n - self.start
        if count <= 0:
            return out
        for c in comps:
            for p in c.parts:
                rate = complex(-p.sigma, 2.0 * math.pi * p.frequency_hz) / fs
                wave = _damped_phasor(0.0, count, rate) * p.phasor
                if c.piecewise and c.knee_s is not None and c.second_sigma is not None:
                    k = int(round((c.knee_s - self.start_s) * fs))
                    if 0 < k < count:
                        after = complex(-c.second_sigma, 2.0 * math.pi * p.frequency_hz) / fs
                        wave[k:] = wave[k] * _damped_phasor(0.0, count - k, after)
                out[self.start:] += wave.real
        return out

    def run(self) -> NoteAnalysis:
        x, fs = self.x, self.fs
        if self.peak == 0.0:
            return self.empty("silent: every sample is zero")
        if (x.size - self.start) < max(64, int(MIN_DURATION_S * fs)):
            return self.empty(f"too short to analyse: {(x.size - self.start) / fs * 1000:.1f} ms after the "
                              f"start (at least {MIN_DURATION_S * 1000:g} ms and 64 samples)")
        noise = noise_floor(x, fs, self.start)
        plan = self.bands()
        if not plan:
            return self.empty("no partials: no spectral peak stands out", noise)
        self.band_maker = Bands(x, fs, min(c for _, c, _ in plan))
        if self.attack_s is not None:
            end = self.start + int(round(self.attack_s * fs)) if self.attack_s > 0 else None
        else:
            end = attack_end(x, fs, self.start, [f for f, _, _ in plan])
        comps = self.fit(plan, noise, (end if end is not None else self.start) / fs)
        attack = describe_attack(x, x - self.resynthesis(comps), fs, self.start, end)
        if not comps:
            return dataclasses.replace(self.empty("no sustained partials", noise), attack=attack)
        return self.result(comps, attack, noise)

    def result(self, comps: list[Component], attack: Attack, noise: NoiseFloor) -> NoteAnalysis:
        comps = sorted(comps, key=lambda c: c.frequency_hz)
        length = self.duration - self.start_s
        energies = [sum(p.energy(length) for p in c.parts) for c in comps]
        levels = [20.0 * math.log10(c.amplitude) for c in comps]
        choice = choose_f0([c.frequency_hz for c in comps], levels, energies, nominal_hz=self.nominal_hz)
        f0 = comps[choice.index].frequency_hz
        # the two halves of a resolved doublet name each other (when both are kept)
        kept = [c.frequency_hz for c in comps]
        partner = {
            i: c.partner_hz for i, c in enumerate(comps)
            if c.partner_hz is not None and any(abs(f - c.partner_hz) <= 1e-9 * f for f in kept)
        }
        records = [self.partial(c, f0, levels[i], partner.get(i)) for i, c in enumerate(comps)]
        above = [i for i in range(len(comps)) if i >= choice.index]
        held = sum(energies[i] for i in above if records[i].t60_s is None)
        looped = held > 0.5 * sum(energies[i] for i in above)
        floor = noise.rms_db
        return NoteAnalysis(
            sample_rate=self.fs, duration_s=self.duration, onset_s=self.onset_s, start_s=self.start_s,
            f0_hz=f0, f0_family=choice.family or None, f0_explained=choice.explained,
            partials=tuple(records[choice.index:]), below_f0=tuple(records[: choice.index]),
            attack=attack, looped=looped, noise_floor_db=floor if math.isfinite(floor) else None,
        )

    def partial(self, c: Component, f0: float, level_db: float, doublet_hz: float | None) -> NotePartial:
        decay = Decay(
            method=c.method, t60_s=c.t60_s, range_start_s=c.t_start, range_end_s=c.t_end,
            range_start_db=c.start_db, range_end_db=c.end_db, floor_db=c.floor_db, rms_db=c.rms_db,
            r2=c.r2, points=c.points, knee_s=c.knee_s, second_t60_s=c.second_t60_s,
            line_rms_db=c.line_rms_db, sustains=c.sustains,
        )
        components = tuple(
            Damped(
                frequency_hz=p.frequency_hz, level_db=20.0 * math.log10(max(p.amplitude, 1e-300)),
                t60_s=_LN1000 / p.sigma if p.sigma > 0 else None,
                phase_rad=math.atan2(p.phasor.imag, p.phasor.real),
            )
            for p in c.parts
        )
        return NotePartial(
            frequency_hz=c.frequency_hz, ratio=c.frequency_hz / f0, level_db=level_db,
            t60_s=None if c.sustains else c.t60_s, phase_rad=math.atan2(c.phasor.imag, c.phasor.real),
            decay=decay, beats=c.beats, doublet_hz=doublet_hz, components=components,
        )


def _holds(c: Component, cutoff_hz: float) -> bool:
    """Is the band (cutoff in Hz) narrow enough for the component's decay: a T60 of at
    least 13 / cutoff leaves three settling times within its first 30 dB?"""
    return c.coherence >= MIN_COHERENCE and (c.t60_s is None or c.t60_s * cutoff_hz >= 13.0)


def _range_db(comps: list[Component]) -> float:
    """How many dB the best component's fit covers (0 for none)."""
    return max((c.start_db - c.end_db for c in comps), default=0.0)
