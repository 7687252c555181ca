"""Fitting the banded-waveguide model to a recording: its partials as modes, its attack as the strike.

Each sustained partial of the analysis (:func:`barsynth.analysis.analyze_note`) becomes a mode:
``frequency_hz`` is the note's f0, ``mode_ratios`` each partial's frequency / f0 (so the preset
plays at any pitch with the same ratios), ``mode_t60s_s`` each partial's T60 (the first slope of
a two-stage decay) and ``mode_gains_db`` its level. The positions cannot be known from one
recording, so ``shape = none`` (every mode at its own level wherever it is struck).

Levels are calibrated, not derived: the model is rendered once with every gain at 0 dB and
each mode's amplitude measured by least squares with its known frequency and T60
(:func:`.modal.mode_amplitudes`); a mode's gain is the recording's level minus that. The common
part of the gains goes into ``level_db`` (the output gain), so the preset rendered raw comes out
at the recording's level.

The excitation is the recording's own attack (``excitation = sample``, commuted synthesis: see
:mod:`barsynth.exciters.sample`): the recording minus its resynthesised partials (the analysis'
damped cosines, hum below f0 included) over the attack the analysis measured (20 to 100 ms),
from 3 ms before the onset, faded out over its last third, peak-normalised, with
``attack_level_db`` at the level it had against the partials. The mallet's hardness is also
estimated, for ``excitation = strike``: the hardness whose force pulse has the spectral centroid
nearest (on a log scale) to the attack's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..analysis.records import NoteAnalysis, NotePartial
from ..errors import ParameterError
from .modal import damped_sum, mode_amplitudes

__all__ = ["BandedFit", "fit_banded"]

WITHIN_DB = 60.0  # partials this far below the strongest are left out
LEAD_S = 0.003  # the attack starts this long before the onset
LONGEST_ATTACK_S = 0.1  # the sample exciter's longest attack (barsynth.exciters.sample.MAX_ATTACK_S)
CALIBRATION_S = 0.5
MIN_T60_S, MAX_T60_S = 0.005, 120.0
NOMINAL_CENTS = 50.0  # an f0 further than this from the nominal pitch: tune to the nominal pitch
LN1000 = math.log(1000.0)


@dataclass(frozen=True)
class BandedFit:
    """The fitted preset (``parameters``, the banded table's names) and the partials it used
    (``modes``: in mode order) and left out (``left_out``: weaker ones beyond ``max_modes``,
    those the model cannot play above a quarter of the rate)."""

    parameters: dict[str, Any]
    modes: tuple[NotePartial, ...]
    left_out: tuple[NotePartial, ...] = field(default=())
    calibration_db: tuple[float, ...] = field(default=())


def _chosen(analysis: NoteAnalysis, max_modes: int) -> tuple[list[NotePartial], list[NotePartial]]:
    partials = list(analysis.partials)
    if not partials or analysis.f0_hz is None:
        raise ParameterError("the recording has no note to fit (no sustained partial with a fundamental); "
                             "allowed: a recording of one struck or plucked note")
    f0 = partials[0]
    partials = [*analysis.below_f0, *partials]  # what lies below f0 sounds too: modes with ratios < 1
    top = max(p.level_db for p in partials)
    audible = [p for p in partials if p.level_db >= top - WITHIN_DB]
    rest = sorted((p for p in audible if p is not f0), key=lambda p: -p.level_db)[:max_modes - 1]
    chosen = sorted([f0, *rest], key=lambda p: p.frequency_hz)
    return chosen, [p for p in partials if p not in chosen]


def _t60(p: NotePartial) -> float:
    t60 = p.t60_s if p.t60_s is not None else (p.decay.t60_s if p.decay is not None else None)
    if t60 is None or not math.isfinite(t60):
        return MAX_T60_S  # does not decay within the recording (a loop): as long as the model allows
    return float(min(max(t60, MIN_T60_S), MAX_T60_S))


def _hardness(centroid_hz: float | None, sample_rate: float) -> float:
    """The mallet hardness whose pulse's spectral centroid is nearest ``centroid_hz`` (log scale)."""
    from ..dsp.mallet import hertz_stiffness, mallet_pulse
    from ..exciters.strike import mallet_contact_s

    if centroid_hz is None or not math.isfinite(centroid_hz) or centroid_hz <= 0.0:
        return 0.7  # the model's default
    best = (math.inf, 0.7)
    for hardness in np.linspace(0.0, 1.0, 41):
        pulse = mallet_pulse(mass_kg=0.03, velocity_m_s=1.0, sample_rate=sample_rate,
                             stiffness=hertz_stiffness(mallet_contact_s(float(hardness)), 0.03))
        spectrum = np.abs(np.fft.rfft(pulse, 1 << 14)) ** 2
        freqs = np.fft.rfftfreq(1 << 14, 1.0 / sample_rate)
        keep = freqs >= 20.0
        centroid = float((freqs[keep] * spectrum[keep]).sum() / max(spectrum[keep].sum(), 1e-300))
        miss = abs(math.log(centroid / centroid_hz))
        if miss < best[0]:
            best = (miss, round(float(hardness), 3))
    return best[1]


def _attack_span(analysis: NoteAnalysis, recording: np.ndarray, sample_rate: float) -> tuple[int, int, int]:
    """(first sample, end, start) of the attack in ``recording``: from :data:`LEAD_S` before
    the start to :data:`LONGEST_ATTACK_S` after it (what the sample exciter holds), at most a
    third of the sound after the start. Longer than the attack the analysis judged (the
    strike's broadband burst): what follows it, before the partials alone remain (a
    resonator tube's ring, modes too weak or short to be partials), is part of the strike."""
    start = int(round(analysis.start_s * sample_rate))
    length_s = min(LONGEST_ATTACK_S - LEAD_S, max(recording.size - start, 0) / sample_rate / 3.0)
    lo = max(0, start - int(round(LEAD_S * sample_rate)))
    hi = min(recording.size, start + int(round(length_s * sample_rate)))
    return lo, hi, start


def _attack(analysis: NoteAnalysis, recording: np.ndarray, sample_rate: float, modes: list[NotePartial],
            played: np.ndarray) -> tuple[np.ndarray, float]:
    """The attack residual (peak 1) and its peak (full scale) before normalising: the recording
    less what the fit's modes will play there (``played``: each mode's complex amplitude at the
    attack's first sample, with the phase the model gives it) and less the partials left out,
    so that attack and modes together give the recording back until the fade."""
    lo, hi, start = _attack_span(analysis, recording, sample_rate)
    if hi <= lo:
        return np.zeros(1), 0.0
    span = hi - lo
    synth = damped_sum(span, sample_rate, [p.frequency_hz for p in modes], [_t60(p) for p in modes], played)
    others = [c for p in (*analysis.below_f0, *analysis.partials) if not any(p is m for m in modes)
              for c in p.components]
    if others:
        synth += damped_sum(span, sample_rate, [c.frequency_hz for c in others], [c.t60_s for c in others],
                            [10.0 ** (c.level_db / 20.0) * np.exp(1j * c.phase_rad) for c in others],
                            start=start - lo)
    residual = recording[lo:hi] - synth
    ramp_in = min(residual.size, max(1, int(round(0.001 * sample_rate))))
    residual[:ramp_in] *= 0.5 - 0.5 * np.cos(np.pi * (np.arange(ramp_in) + 0.5) / ramp_in)
    fade = max(1, residual.size // 3)
    residual[-fade:] *= 0.5 + 0.5 * np.cos(np.pi * (np.arange(fade) + 0.5) / fade)
    peak = float(np.abs(residual).max())
    return (residual / peak if peak > 0.0 else residual), peak


def render_factor(highest_hz: float, sample_rate: float) -> int:
    """The banded model plays no mode above a quarter of its rate: the factor (1 to 4, at most
    192 kHz) of the rate to render at so that ``highest_hz`` sounds."""
    factor = 1
    while highest_hz >= factor * sample_rate / 4.0 and factor < 4 and (factor + 1) * sample_rate <= 192000:
        factor += 1
    return factor


def _calibration(parameters: dict[str, Any], sample_rate: float, frequencies: list[float],
                 t60s: list[float]) -> np.ndarray:
    """Each mode's complex amplitude at the trigger in the model's raw output with every gain
    at 0 dB (no attack): its level and the phase the strike gives it."""
    from ..models import get_model

    model = get_model("banded")
    probe = {**parameters, "mode_gains_db": (), "attack_level_db": -120.0, "level_db": 0.0}
    rate = sample_rate * render_factor(max(frequencies), sample_rate)
    longest = max(t60s)
    seconds = min(CALIBRATION_S, max(0.05, 0.5 * longest))
    x = model.render(probe, duration_s=seconds, sample_rate=rate, normalize=False, dtype=np.float64)
    modes = model.describe(probe, sample_rate=rate)
    if len(modes) != len(frequencies):
        raise ParameterError(f"the banded model plays {len(modes)} of the {len(frequencies)} modes fitted at "
                             f"{rate:g} Hz; allowed: modes between 20 Hz and a quarter of the rate")
    skip = int(round(0.01 * rate))  # past every loop's first trip round (its delay)
    amplitudes = mode_amplitudes(x, rate, [m.frequency_hz for m in modes], [m.t60_s for m in modes],
                                 fit_from=min(skip, x.size // 4))
    return amplitudes


def fit_banded(analysis: NoteAnalysis, recording: np.ndarray, sample_rate: float, *, max_modes: int = 12,
               excitation: str = "sample", nominal_hz: float | None = None) -> BandedFit:
    """The banded preset that plays ``recording`` (mono float64 at ``sample_rate`` Hz) back; see
    the module docstring. ``excitation`` ``"sample"`` (its own attack) or ``"strike"`` (a mallet);
    ``nominal_hz`` (Hz, a soundfont's root key): the pitch to tune to when the analysis' f0 lies
    more than :data:`NOMINAL_CENTS` from it (the ratios are then taken against it)."""
    from ..models import get_model

    table = get_model("banded").table
    row = {p.name: p for p in table}
    chosen, left_out = _chosen(analysis, min(max_modes, row["mode_ratios"].max_items))
    f0 = float(analysis.f0_hz)
    if nominal_hz is not None and abs(1200.0 * math.log2(f0 / nominal_hz)) > NOMINAL_CENTS:
        f0 = float(nominal_hz)  # the partial taken for f0 is not the pitch the note is played at
    if not row["frequency_hz"].minimum <= f0 <= row["frequency_hz"].maximum:
        what = "the nominal pitch" if f0 != float(analysis.f0_hz) else "the note's fundamental"
        raise ParameterError(f"{what}, {f0:.6g} Hz, is out of the banded model's range; allowed: "
                             f"{row['frequency_hz'].minimum:g} to {row['frequency_hz'].maximum:g} Hz")
    ratios = [p.frequency_hz / f0 for p in chosen]
    keep = [row["mode_ratios"].minimum <= r <= row["mode_ratios"].maximum for r in ratios]
    left_out += [p for p, k in zip(chosen, keep) if not k]
    chosen = [p for p, k in zip(chosen, keep) if k]
    ratios = [r for r, k in zip(ratios, keep) if k]
    if not chosen:
        raise ParameterError(f"no partial of the recording lies within the banded model's ratios of {f0:.6g} Hz; "
                             f"allowed: {row['mode_ratios'].minimum:g} to {row['mode_ratios'].maximum:g} times it")
    t60s = [_t60(p) for p in chosen]
    velocity = row["mallet_velocity_m_s"].default
    parameters: dict[str, Any] = {
        "tuning": "ratios", "frequency_hz": f0, "mode_ratios": tuple(float(r) for r in ratios),
        "mode_t60s_s": tuple(float(t) for t in t60s), "shape": "none", "excitation": excitation,
        "mallet_hardness": _hardness(analysis.attack.centroid_hz if analysis.attack else None, sample_rate),
    }
    calibration = _calibration({**parameters, "excitation": "sample"}, sample_rate,
                               [p.frequency_hz for p in chosen], t60s)
    calibration_db = 20.0 * np.log10(np.maximum(np.abs(calibration), 1e-30))
    # the modes start at the trigger, which plays the attack's first sample: LEAD_S before the
    # recording's start, where each partial was that much louder
    lo, _, start = _attack_span(analysis, recording, sample_rate)
    lead_s = (start - lo) / sample_rate
    measured = np.array([p.level_db + 20.0 * math.log10(math.e) * LN1000 * lead_s / t for p, t in zip(chosen, t60s)])
    gains = measured - calibration_db
    level = float(min(max(np.max(gains), row["level_db"].minimum), row["level_db"].maximum))
    lo_db, hi_db = row["mode_gains_db"].minimum, row["mode_gains_db"].maximum
    parameters["mode_gains_db"] = tuple(float(min(max(g - level, lo_db), hi_db)) for g in gains)
    parameters["level_db"] = level
    if excitation == "sample":
        played = calibration * 10.0 ** ((level + np.array(parameters["mode_gains_db"])) / 20.0)
        attack, peak = _attack(analysis, recording, sample_rate, chosen, played)
        parameters.update(attack_samples=tuple(round(float(v), 6) + 0.0 for v in attack),
                          attack_rate_hz=int(round(sample_rate)), attack_pitch_hz=f0)
        # the attack against the modes as in the recording: in the model's raw output the modes
        # are the recording's scaled by 10^(-level/20); the attack scales with velocity / (1 m/s)
        attack_db = (20.0 * math.log10(peak) - level - 20.0 * math.log10(velocity)) if peak > 0.0 else -120.0
        parameters["attack_level_db"] = float(min(max(attack_db, row["attack_level_db"].minimum),
                                                  row["attack_level_db"].maximum))
    return BandedFit(parameters, tuple(chosen), tuple(left_out), tuple(float(c) for c in calibration_db))
