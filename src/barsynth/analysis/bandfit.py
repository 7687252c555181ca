"""What one band holds: a partial (one or two decay stages), a resolved doublet, or a
beating pair seen as one.

Given a band's complex envelope (:mod:`.bands`) and its noise power (:mod:`.noise`):

1. The decay is fitted in dB over a stated range (:mod:`.slopes`): from where the
   envelope is clean to 10 dB above the noise floor (the recording's, or the band's own
   when its tail is noise: :func:`tail_floor`); one line, or two with a knee.
2. One damped exponential is fitted to the complex envelope over the range by the
   matrix pencil and Gauss-Newton (:mod:`.poles`): its rate gives the frequency and the
   decay (the maximum-likelihood estimate, several times more precise than a line
   through the dB envelope, which then takes its slope) and, with the filter undone, the
   amplitude and phase extrapolated back to the sound's start.
3. Two exponentials are fitted as well. When two explain the envelope much better (the
   misfit falls at least fourfold and stays well above the noise's, and neither dies
   within :data:`MIN_PART_T60_S`):

   - further apart than :data:`RESOLVE_CYCLES` beats over the range: a **doublet**,
     two partials;
   - less than a quarter beat apart: one partial whose decay has **two stages** (two
     polarisations, a mode and its coupled twin): the faster, stronger at first, until
     the knee where the slower takes over; a looped sample shows as a second stage that
     does not decay;
   - in between: one partial that **beats** (described by the dB fit).

   Otherwise a knee found in dB (step 1) makes a two-stage decay, the first stage's
   frequency and amplitude from an exponential fitted up to the knee.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .bands import BandEnvelope
from .poles import PoleFit, amplitudes, fit_poles, matrix_pencil, zoomed_pencil
from .slopes import FLOOR_MARGIN_DB, MIN_POINTS, Slopes, fit_slopes, smoothed_db, with_slope

__all__ = ["MIN_PART_T60_S", "RESOLVE_CYCLES", "Component", "Exponential", "measure_band"]

RESOLVE_CYCLES = 1.5  # a doublet is resolved when it beats this many times within the range
MIN_PART_T60_S = 0.03  # each of two exponentials decays no faster than this
FLAT_DB = 1.0  # a stage that falls less than this over its span does not decay
_PAIR_GAIN = 0.25  # two exponentials must leave at most a quarter of one's misfit ...
_PAIR_ABOVE_NOISE = 4.0  # ... of a misfit at least four times the noise's ...
_PAIR_MIN_SHARE = 1e-6  # ... and at least this share of the energy (-60 dB)
_PAIR_WEAKEST_DB = -40.0  # the weaker of two: at most this far below the stronger
_BEAT_CYCLES = 0.25
_TAIL_F1 = 10.0
_ML_WORSE = 2.0  # the exponential's decay is kept unless it misses the dB envelope by twice
_ML_WORSE_DB = 1.0  # ... and 1 dB more than the line through it
_TAIL_COHERENT = 0.5
_LN1000 = math.log(1000.0)
_DB_PER_NEPER = 20.0 / math.log(10.0)


@dataclass(frozen=True)
class Exponential:
    """``A exp(-sigma (t - start)) cos(2 pi f (t - start) + psi)`` with ``phasor = A
    exp(j psi)`` (full scale 1.0), ``sigma`` in 1/s, ``frequency_hz`` in Hz."""

    frequency_hz: float
    phasor: complex
    sigma: float

    @property
    def amplitude(self) -> float:
        return abs(self.phasor)

    def energy(self, length_s: float) -> float:
        """Its energy within ``length_s`` seconds of the start (amplitude^2 s)."""
        a2 = self.amplitude**2
        if self.sigma * length_s < 1e-6:
            return a2 * length_s
        return a2 * (1.0 - math.exp(-2.0 * self.sigma * length_s)) / (2.0 * self.sigma)


@dataclass(frozen=True)
class Component:
    """A partial found in a band and how its decay was measured (times in s from the
    sound's first sample; levels in dB relative to its initial level).

    ``parts`` resynthesise it: their sum, except that with ``piecewise`` the one part
    decays at ``second_sigma`` after ``knee_s``. ``t60_s``, ``second_t60_s`` are None for
    a stage that does not decay; ``sustains`` when the last stage does not. One of a
    doublet names the other's frequency in ``partner_hz``.
    """

    frequency_hz: float
    phasor: complex
    parts: tuple[Exponential, ...]
    method: str
    t60_s: float | None
    knee_s: float | None
    second_t60_s: float | None
    second_sigma: float | None
    piecewise: bool
    sustains: bool
    t_start: float
    t_end: float
    start_db: float
    end_db: float
    floor_db: float | None
    rms_db: float
    r2: float
    points: int
    line_rms_db: float
    coherence: float
    beats: bool = False
    doublet: bool = False
    partner_hz: float | None = None

    @property
    def amplitude(self) -> float:
        return abs(self.phasor)

    @property
    def sigma(self) -> float:
        """Decay rate of the first stage, 1/s."""
        return self.parts[0].sigma


def _t60(sigma: float, span_s: float) -> float | None:
    """T60 (s) of a decay rate (1/s), None when it falls less than :data:`FLAT_DB` over
    ``span_s``."""
    if sigma * span_s * _DB_PER_NEPER < FLAT_DB:
        return None
    return _LN1000 / sigma


def _phasor_at(env: BandEnvelope, fit: PoleFit, k: int, start_s: float) -> complex:
    """Exponential ``k`` at ``start_s`` as a cosine's ``A exp(j psi)``, the low-pass undone.

    ``A cos(2 pi f (t - start) + psi)`` gives ``(A/2) exp(j(2 pi (f - f_bin) t + psi - 2 pi
    f_bin start))`` in the band, so ``psi`` is the envelope's phase at the start plus
    ``2 pi f_bin start``.
    """
    rate = complex(fit.rates[k])
    offset = rate.imag / (2.0 * math.pi) + 1j * (-rate.real) / (2.0 * math.pi)
    h = env.response(offset)
    amp = complex(fit.amps[k])
    log_amp = math.log(max(abs(amp), 1e-300)) + rate.real * (start_s - fit.t_ref) - math.log(max(abs(h), 1e-300))
    if log_amp > 700.0:
        return complex(math.inf)
    phase = (
        math.atan2(amp.imag, amp.real) + rate.imag * (start_s - fit.t_ref)
        - math.atan2(h.imag, h.real) + 2.0 * math.pi * env.f_bin_hz * start_s
    )
    return 2.0 * math.exp(log_amp) * complex(math.cos(phase), math.sin(phase))


def _exponentials(env: BandEnvelope, fit: PoleFit, start_s: float) -> list[Exponential]:
    return [
        Exponential(
            frequency_hz=env.f_bin_hz + complex(r).imag / (2.0 * math.pi),
            phasor=_phasor_at(env, fit, k, start_s),
            sigma=-float(complex(r).real),
        )
        for k, r in enumerate(fit.rates)
    ]


def _quality(db: np.ndarray, model_db: np.ndarray) -> tuple[float, float]:
    """RMS deviation (dB) and coefficient of determination of a model of ``db``."""
    r = db - model_db
    sse = float(r @ r)
    sst = float(((db - db.mean()) ** 2).sum())
    return math.sqrt(sse / max(db.size, 1)), (1.0 - sse / sst if sst > 0 else 1.0)


def _model_db(parts: list[Exponential], t: np.ndarray, start_s: float, width: int) -> np.ndarray:
    """The smoothed power (dB) of the sum of ``parts``' envelopes at times ``t``."""
    from scipy.ndimage import uniform_filter1d

    tau = t - start_s
    z = np.zeros(t.size, dtype=np.complex128)
    for p in parts:
        z += 0.5 * p.phasor * np.exp((-p.sigma + 2j * math.pi * p.frequency_hz) * tau)
    power = z.real**2 + z.imag**2
    if width > 1:
        power = uniform_filter1d(power, width, mode="nearest")
    return 10.0 * np.log10(np.maximum(power, 1e-300))


def _best_pair(t: np.ndarray, z: np.ndarray, dt: float, centre_rate: complex) -> PoleFit | None:
    """The better of two two-exponential fits: from a short pencil (wide pairs) and from a
    zoomed one (slow beats)."""
    best = None
    for pair in (matrix_pencil(z, dt, 2), zoomed_pencil(z, dt, 2, centre_rate)):
        if pair.size == 2 and np.all(np.isfinite(pair)):
            trial = fit_poles(t, z, pair)
            if best is None or trial.misfit < best.misfit:
                best = trial
    return best


def tail_floor(env: BandEnvelope, power: np.ndarray, t_clean: float, t_last: float) -> float:
    """The band's own noise floor (envelope power), from its tail; 0 when the tail is a
    partial still sounding.

    The tail is the last tenth of the usable envelope, and at least :data:`_TAIL_F1`
    over ``f1`` seconds (that many independent samples of noise). When one damped
    exponential explains less than :data:`_TAIL_COHERENT` of it, it is noise (a floor
    the recording's spectrum in its last quarter may have missed: coding noise that
    comes and goes, a sound under the note) and its mean power is the floor: Lundeby's
    floor from the decay's own tail, told from a looped or still ringing partial by its
    coherence.
    """
    usable = np.flatnonzero((env.t >= t_clean) & (env.t <= t_last))
    if usable.size < 2 * MIN_POINTS:
        return 0.0
    length = max(usable.size // 10, MIN_POINTS, int(math.ceil(_TAIL_F1 / (env.f1_hz * env.dt))))
    if length > usable.size // 2:
        return 0.0
    tail = usable[-length:]
    t, z = env.t[tail], env.z[tail]
    rates = matrix_pencil(z, env.dt, 1)
    if rates.size and fit_poles(t, z, rates[:1]).coherence >= _TAIL_COHERENT:
        return 0.0
    return float(np.mean(power[tail]))


def measure_band(
    env: BandEnvelope,
    *,
    noise_power: float,
    start_s: float,
    t_clean: float,
    t_last: float,
) -> list[Component]:
    """The partial(s) in a band (empty when nothing can be fitted there).

    ``noise_power`` is the band's noise power in envelope units; ``start_s`` the sound's
    start (s), to which amplitudes are extrapolated; ``t_clean``/``t_last`` the first and
    last usable times (s).
    """
    dt = env.dt
    if dt <= 0:
        return []
    width = max(1, int(round(1.0 / (env.f1_hz * dt))))
    power = env.z.real**2 + env.z.imag**2
    noise_power = max(noise_power, tail_floor(env, power, t_clean, t_last))
    db = smoothed_db(power, noise_power, width)
    slopes = fit_slopes(env.t, db, noise_power=noise_power, t_clean=t_clean, t_last=t_last, width=width)
    if slopes is None:
        return []
    a = int(np.searchsorted(env.t, slopes.t_start - 1e-12))
    b = int(np.searchsorted(env.t, slopes.t_end + 1e-12))
    t, z = env.t[a:b], env.z[a:b]
    first = matrix_pencil(z, dt, 1)
    if first.size == 0:
        return []
    one = fit_poles(t, z, first[:1])
    if not np.all(np.isfinite(one.rates)):
        return []
    fit = _Fit(env, t, z, db[a:b], width, noise_power, start_s, slopes)
    pair = _best_pair(t, z, dt, complex(one.rates[0])) if fit.misfit_above_noise(one) else None
    if pair is not None and fit.pair_explains(one, pair):
        parts = _exponentials(env, pair, start_s)
        amps = [p.amplitude for p in parts]
        if min(amps) > 0 and all(math.isfinite(v) for v in amps) and (
            20.0 * math.log10(min(amps) / max(amps)) >= _PAIR_WEAKEST_DB
        ):
            span = float(t[-1] - t[0])
            cycles = abs(parts[0].frequency_hz - parts[1].frequency_hz) * span
            inside = all(abs(p.frequency_hz - env.centre_hz) <= env.cutoff_hz for p in parts)
            if cycles >= RESOLVE_CYCLES and inside:
                return fit.doublet(parts, pair.coherence)
            if cycles < _BEAT_CYCLES:
                staged = fit.two_stage(parts, pair.coherence)
                if staged is not None:
                    return [staged]
            else:
                return [replace(c, beats=True) for c in fit.single(one)]
    return fit.single(one)


class _Fit:
    """The records one band's fits give (see :func:`measure_band`)."""

    def __init__(self, env: BandEnvelope, t: np.ndarray, z: np.ndarray, db: np.ndarray, width: int,
                 noise_power: float, start_s: float, slopes: Slopes) -> None:
        self.env, self.t, self.z, self.db = env, t, z, db
        self.width = width
        self.noise_power = noise_power
        self.start_s = start_s
        self.slopes = slopes
        self.span = float(t[-1] - t[0])

    def floor_db(self, amplitude: float) -> float | None:
        """The band's noise floor relative to a partial's initial level, dB."""
        if self.noise_power <= 0 or amplitude <= 0:
            return None
        return 10.0 * math.log10(self.noise_power) - 20.0 * math.log10(0.5 * amplitude)

    def misfit_above_noise(self, one: PoleFit) -> bool:
        """Does one exponential leave clearly more than the noise (and -60 dB)?"""
        noise = max(self.noise_power * self.t.size, _PAIR_MIN_SHARE * one.energy)
        return one.misfit >= _PAIR_ABOVE_NOISE * noise

    def pair_explains(self, one: PoleFit, pair: PoleFit) -> bool:
        """Do two exponentials explain the range much better than one?"""
        return bool(
            pair.misfit <= _PAIR_GAIN * one.misfit
            and self.misfit_above_noise(one)
            and np.all(np.isfinite(pair.rates))
            and np.all(-pair.rates.real < _LN1000 / MIN_PART_T60_S)
            and np.all(-pair.rates.real > -1.0 / max(self.span, 1e-9))  # neither grows
        )

    def _record(self, model_parts: list[Exponential], **fields) -> Component:
        level = abs(fields["phasor"])
        model = _model_db(model_parts, self.t, self.start_s, self.width)
        rms, r2 = _quality(self.db, model)
        top = 20.0 * math.log10(max(0.5 * level, 1e-300))
        base = dict(
            t_start=float(self.t[0]), t_end=float(self.t[-1]),
            start_db=float(model[0] - top), end_db=float(model[-1] - top),
            floor_db=self.floor_db(level), rms_db=rms, r2=r2, points=int(self.t.size),
            line_rms_db=self.slopes.line_rms_db,
        )
        base.update(fields)
        return Component(**base)

    def doublet(self, parts: list[Exponential], coherence: float) -> list[Component]:
        """Two partials, each with its own decay; the range and quality are the band's."""
        out = []
        for p, other in zip(parts, parts[::-1]):
            t60 = _t60(p.sigma, self.span)
            c = self._record(
                parts, frequency_hz=p.frequency_hz, phasor=p.phasor, parts=(p,), method="doublet",
                t60_s=t60, knee_s=None, second_t60_s=None, second_sigma=None, piecewise=False,
                sustains=t60 is None, coherence=coherence, doublet=True, partner_hz=other.frequency_hz,
            )
            # its own decay over the range (until it falls to 10 dB above the floor),
            # relative to its own level
            end = c.t_end
            rate_db = p.sigma * _DB_PER_NEPER
            if c.floor_db is not None and rate_db > 0:
                end = min(end, max(c.t_start, self.start_s - (c.floor_db + FLOOR_MARGIN_DB) / rate_db))
            out.append(replace(
                c,
                t_end=end,
                start_db=-rate_db * (c.t_start - self.start_s),
                end_db=-rate_db * (end - self.start_s),
            ))
        return out

    def two_stage(self, parts: list[Exponential], coherence: float) -> Component | None:
        """One partial of two exponentials at one frequency: the faster until the knee
        where the slower takes over (None unless the faster starts stronger and the knee
        falls inside the range)."""
        fast, slow = sorted(parts, key=lambda p: -p.sigma)
        if not (fast.amplitude > slow.amplitude and fast.sigma > slow.sigma):
            return None
        knee = self.start_s + math.log(fast.amplitude / slow.amplitude) / (fast.sigma - slow.sigma)
        if not (self.t[0] < knee < self.t[-1]):
            return None
        energy = [p.energy(self.span) for p in (fast, slow)]
        frequency = (fast.frequency_hz * energy[0] + slow.frequency_hz * energy[1]) / sum(energy)
        second = _t60(slow.sigma, float(self.t[-1]) - knee)
        return self._record(
            [fast, slow], frequency_hz=frequency, phasor=fast.phasor + slow.phasor, parts=(fast, slow),
            method="two-stage", t60_s=_t60(fast.sigma, knee - float(self.t[0])), knee_s=knee,
            second_t60_s=second, second_sigma=slow.sigma, piecewise=False, sustains=second is None,
            coherence=coherence,
        )

    def single(self, one: PoleFit) -> list[Component]:
        """One partial: one line (its slope the exponential's decay), or two stages found
        in dB (the first stage's exponential fitted up to the knee)."""
        env, sl = self.env, self.slopes
        if sl.knee_s is None:
            (p,) = _exponentials(env, one, self.start_s)
            ml = with_slope(sl, self.t, self.db, -p.sigma * _DB_PER_NEPER)
            if ml.rms_db <= max(_ML_WORSE * sl.rms_db, sl.rms_db + _ML_WORSE_DB):
                sl = ml
            else:
                # the exponential follows something else than the dB envelope (a burst at
                # the range's start): the line's decay, the amplitude fitted to it
                rate = complex(sl.slope_db_s / _DB_PER_NEPER, complex(one.rates[0]).imag)
                amps, misfit = amplitudes(self.t, self.z, np.array([rate]), one.t_ref)
                refit = PoleFit(rates=np.array([rate]), amps=amps, t_ref=one.t_ref, misfit=misfit, energy=one.energy)
                (p,) = _exponentials(env, refit, self.start_s)
                one = refit
            rms, r2 = sl.rms_db, sl.r2
            t60 = _t60(p.sigma, self.span)
            top = sl.at(self.start_s)
            return [Component(
                frequency_hz=p.frequency_hz, phasor=p.phasor, parts=(p,), method="line", t60_s=t60,
                knee_s=None, second_t60_s=None, second_sigma=None, piecewise=False, sustains=t60 is None,
                t_start=sl.t_start, t_end=sl.t_end, start_db=sl.at(sl.t_start) - top,
                end_db=sl.at(sl.t_end) - top, floor_db=self.floor_db(p.amplitude), rms_db=rms, r2=r2,
                points=sl.points, line_rms_db=rms, coherence=one.coherence,
            )]
        head = self.t <= sl.knee_s
        if np.count_nonzero(head) < 8:
            head = np.zeros(self.t.size, dtype=bool)
            head[:8] = True
        early = fit_poles(self.t[head], self.z[head], np.array([one.rates[0]]))
        if not np.all(np.isfinite(early.rates)):
            early = one
        (p,) = _exponentials(env, early, self.start_s)
        top = sl.at(self.start_s)
        first = _t60(-sl.slope_db_s / _DB_PER_NEPER, sl.knee_s - sl.t_start)
        second_sigma = -sl.second_slope_db_s / _DB_PER_NEPER
        second = _t60(second_sigma, sl.t_end - sl.knee_s)
        return [Component(
            frequency_hz=p.frequency_hz, phasor=p.phasor, parts=(replace(p, sigma=-sl.slope_db_s / _DB_PER_NEPER),),
            method="two-stage", t60_s=first, knee_s=sl.knee_s, second_t60_s=second, second_sigma=second_sigma,
            piecewise=True, sustains=second is None, t_start=sl.t_start, t_end=sl.t_end,
            start_db=sl.at(sl.t_start) - top, end_db=sl.at(sl.t_end) - top, floor_db=self.floor_db(p.amplitude),
            rms_db=sl.rms_db, r2=sl.r2, points=sl.points, line_rms_db=sl.line_rms_db, coherence=early.coherence,
        )]
