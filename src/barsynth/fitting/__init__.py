"""Fitting barsynth's models to recordings: from a sound to a preset that sounds like it (spec 7).

:func:`fit_recording` analyses the recording (:func:`barsynth.analysis.analyze_note`), fits one
model to what it measured, renders the fit at the recording's rate and compares the two: each
partial (recording against resynthesis: cents, dB, T60 %) and the spectral distance of spec 7.3
against that of one decaying sine at f0.

- ``banded`` (:mod:`.banded`): every sustained partial a mode (ratio, T60, level) and the
  recording's own attack as the strike (commuted synthesis);
- ``twang`` (:mod:`.twang`): the ruler's physical settings behind the twang's frequencies, Q,
  gain shape and mixes;
- ``fd`` (:mod:`.fd`): the physical bar (material, length, thickness, undercut, losses).

>>> from barsynth.fitting import fit_recording                     # doctest: +SKIP
>>> fit = fit_recording(samples, 44100, model="banded")             # doctest: +SKIP
>>> fit.parameters["mode_ratios"], fit.distance_db, fit.baseline_db  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ParameterError
from .targets import Target

__all__ = ["FIT_MODELS", "Fit", "PartialComparison", "fit_recording"]

FIT_MODELS = ("banded", "twang", "fd")
MATCH_CENTS = 50.0  # a resynthesised partial this close to a recorded one is its counterpart
LONGEST_RENDER_S = 10.0
SILENT_ATTACK_DB = -120.0  # the sample exciter's quietest attack: the modes alone
ALIGN_ON = 5  # levels are aligned on the median over this many strongest matched partials
FLOOR_SEED = 7  # the noise a twang's resynthesis is measured over (see fit_recording)


@dataclass(frozen=True)
class PartialComparison:
    """One partial of the recording against its counterpart in the resynthesis (None: none found)."""

    frequency_hz: float
    level_db: float
    t60_s: float | None
    resynthesis_hz: float | None = None
    resynthesis_level_db: float | None = None
    resynthesis_t60_s: float | None = None

    @property
    def cents(self) -> float | None:
        if self.resynthesis_hz is None:
            return None
        return float(1200.0 * math.log2(self.resynthesis_hz / self.frequency_hz))

    @property
    def level_error_db(self) -> float | None:
        return None if self.resynthesis_level_db is None else float(self.resynthesis_level_db - self.level_db)

    @property
    def t60_error(self) -> float | None:
        """(resynthesis - recording) / recording T60, a fraction; None where either does not decay."""
        if self.resynthesis_t60_s is None or self.t60_s is None or not self.t60_s > 0:
            return None
        return float(self.resynthesis_t60_s / self.t60_s - 1.0)

    def to_json(self) -> dict[str, Any]:
        from ..jsonout import json_ready

        return json_ready({"frequency_hz": self.frequency_hz, "level_db": self.level_db, "t60_s": self.t60_s,
                           "resynthesis_hz": self.resynthesis_hz, "resynthesis_level_db": self.resynthesis_level_db,
                           "resynthesis_t60_s": self.resynthesis_t60_s, "cents": self.cents,
                           "level_error_db": self.level_error_db,
                           "t60_error_percent": None if self.t60_error is None else 100.0 * self.t60_error})


@dataclass(frozen=True)
class Fit:
    """A fitted preset and how close it comes to the recording."""

    model: str
    parameters: dict[str, Any]
    sample_rate: float
    analysis: Any  # barsynth.analysis.NoteAnalysis of the recording
    comparison: tuple[PartialComparison, ...]
    distance_db: float
    baseline_db: float
    resynthesis: np.ndarray = field(repr=False)
    recording: np.ndarray = field(repr=False)
    details: dict[str, Any] = field(default_factory=dict)

    def heard(self) -> np.ndarray:
        """The resynthesis as one would play it beside the recording: at the recording's rate,
        its peak at the recording's (from the onset)."""
        onset = int(round(self.analysis.onset_s * self.sample_rate))
        peak = float(np.max(np.abs(self.recording[onset:]))) if self.recording.size > onset else 0.0
        mine = float(np.max(np.abs(self.resynthesis))) if self.resynthesis.size else 0.0
        return self.resynthesis * (peak / mine) if mine > 0.0 else self.resynthesis.copy()

    def to_json(self) -> dict[str, Any]:
        """Everything a user or a script needs: the parameters, the model's own report (twang and
        fd: each partial's mode and residual), per partial recording against resynthesis, and the
        spectral distance against the one-sine baseline (spec 7.3)."""
        from ..jsonout import json_ready

        return json_ready({
            "model": self.model, "sample_rate": self.sample_rate, "f0_hz": self.analysis.f0_hz,
            "parameters": {k: v for k, v in self.parameters.items() if k != "attack_samples"},
            "attack_samples": len(self.parameters.get("attack_samples", ())),
            "spectral_distance_db": self.distance_db, "sine_baseline_db": self.baseline_db,
            "partials": [c.to_json() for c in self.comparison], **self.details})

    def preset_toml(self, *, description: str | None = None, source: str = "fitted by barsynth fit") -> str:
        """The preset file (``barsynth render MODEL --preset FILE.toml`` reads it)."""
        from ..studio.presets_file import preset_toml

        text = description or (f"fitted to a recording: f0 {self.analysis.f0_hz:.2f} Hz, "
                               f"{len(self.comparison)} partials, spectral distance {self.distance_db:.2f} dB "
                               f"(one sine: {self.baseline_db:.2f} dB)")
        return preset_toml(self.parameters, description=text, source=source, model=self.model)


def _targets(analysis: Any) -> list[Target]:
    return [Target(p.frequency_hz, p.level_db, p.t60_s) for p in analysis.partials]


def _compare(analysis: Any, resynthesis: np.ndarray, sample_rate: float) -> tuple[PartialComparison, ...]:
    """Each sustained partial of the recording (f0, those above and those below it) against the
    resynthesis' nearest (within MATCH_CENTS). The resynthesis is measured as the recording
    was, and where it was: its partials sought at the recording's partials' frequencies (a weak
    partial the fit plays is then not missed for being hard to find), after an attack as long
    as the recording's (a banded fit with the recording's attack as its strike is compared
    without it: see :func:`fit_recording`). Its levels are aligned to the recording's by the median difference
    over the :data:`ALIGN_ON` strongest matched partials (one partial's error is then not
    everyone's)."""
    from ..analysis import analyze_note

    partials = (*analysis.below_f0, *analysis.partials)
    level = {p.frequency_hz: p.level_db for p in partials}
    # a resolved doublet is sought as the recording's was found: one band, at its stronger half
    recorded = [p.frequency_hz for p in partials
                if p.doublet_hz is None or level.get(p.doublet_hz, -math.inf) <= p.level_db]
    attack_s = analysis.attack.duration_s if analysis.attack is not None else None

    def measured(where: list[float]) -> list[Any]:
        again = analyze_note(resynthesis, sample_rate, nominal_hz=analysis.f0_hz, partials_hz=where,
                             attack_s=attack_s, max_partials=max(24, len(partials)))
        return [*again.below_f0, *again.partials]

    ordered = sorted(partials, key=lambda q: q.frequency_hz)
    found = _counterparts(ordered, measured(recorded))
    if any(q is None for q in found) and len(recorded) < len(partials):  # a doublet's halves apart
        again = _counterparts(ordered, measured([p.frequency_hz for p in partials]))
        found = [q if q is not None else r for q, r in zip(found, again)]
    rows = []
    for p, near in zip(ordered, found):
        if near is None:
            rows.append(PartialComparison(p.frequency_hz, p.level_db, p.t60_s))
        else:
            rows.append(PartialComparison(p.frequency_hz, p.level_db, p.t60_s, near.frequency_hz, near.level_db,
                                          near.t60_s))
    matched = sorted((r for r in rows if r.resynthesis_level_db is not None), key=lambda r: -r.level_db)
    if matched:  # the two sounds' levels meet where the strongest partials say
        shift = float(np.median([r.level_db - r.resynthesis_level_db for r in matched[:ALIGN_ON]]))
        rows = [PartialComparison(r.frequency_hz, r.level_db, r.t60_s, r.resynthesis_hz,
                                  None if r.resynthesis_level_db is None else r.resynthesis_level_db + shift,
                                  r.resynthesis_t60_s) for r in rows]
    return tuple(rows)


def _counterparts(recorded: list[Any], found: list[Any]) -> list[Any]:
    """Each recorded partial's counterpart among ``found``: the nearest within MATCH_CENTS,
    when the recorded partial is also the one nearest to it (else None)."""
    def cents(a: float, b: float) -> float:
        return abs(1200.0 * math.log2(a / b))

    out = []
    for p in recorded:
        near = min(found, key=lambda q: cents(q.frequency_hz, p.frequency_hz), default=None)
        if near is None or cents(near.frequency_hz, p.frequency_hz) > MATCH_CENTS:
            out.append(None)
            continue
        mine = min(recorded, key=lambda r: cents(r.frequency_hz, near.frequency_hz))
        out.append(near if mine is p else None)
    return out


def _over_the_floor(resynthesis: np.ndarray, recording: np.ndarray, floor_db: float | None) -> np.ndarray:
    """``resynthesis`` with white noise (seeded) as far below its peak as the recording's noise
    floor is below the recording's. The twang's free bar is noise through band-passes: the
    analysis tells such a band from a partial only over a noise floor, and on a noiseless render
    it found 5 of a ruler's 10 partials (with the floor: all 10)."""
    if floor_db is None or not resynthesis.size or not recording.size:
        return resynthesis
    recorded, mine = float(np.max(np.abs(recording))), float(np.max(np.abs(resynthesis)))
    if recorded <= 0.0 or mine <= 0.0:
        return resynthesis
    level = mine * 10.0 ** (floor_db / 20.0) / recorded
    return resynthesis + level * np.random.default_rng(FLOOR_SEED).standard_normal(resynthesis.size)


def _render(model: str, parameters: dict[str, Any], sample_rate: float, seconds: float,
            highest_hz: float = 0.0) -> np.ndarray:
    """The fit rendered raw at ``sample_rate``. The banded model plays no mode above a quarter of
    its rate: a fit with partials up there is rendered at two, three or four times the rate (up to
    192 kHz) and brought down (``scipy.signal.resample_poly``), as a user would render it to hear
    them."""
    from ..models import get_model

    from .banded import render_factor

    m = get_model(model)
    factor = render_factor(highest_hz, sample_rate) if model == "banded" else 1
    x = m.render(parameters, duration_s=seconds, sample_rate=factor * sample_rate, normalize=False,
                 dtype=np.float64)
    if factor == 1:
        return x
    from scipy.signal import resample_poly

    return resample_poly(x, 1, factor)


def fit_recording(samples: Any, sample_rate: float, *, model: str = "banded", max_modes: int = 12,
                  nominal_hz: float | None = None, options: dict[str, Any] | None = None) -> Fit:
    """Fit ``model`` (``banded``, ``twang`` or ``fd``) to a mono recording (full scale 1.0) at
    ``sample_rate`` Hz; ``options`` go to the model's fit (twang: material, thickness_m,
    length_m; fd: material, thickness_m, width_m, bc, points; banded: excitation). Raises
    :class:`~barsynth.errors.ParameterError` (one line) when there is no note to fit."""
    from ..analysis import analyze_note
    from ..analysis.distance import sine_baseline, spectral_distance
    from ..analysis.inputs import as_signal
    from ..checks import check_whole

    x, rate = as_signal(samples, sample_rate)
    if model not in FIT_MODELS:
        raise ParameterError(f"parameter model = {model!r} is not allowed; allowed: one of {', '.join(FIT_MODELS)}")
    max_modes = check_whole("max_modes", max_modes, "modes", 1, 24)
    options = dict(options or {})
    analysis = analyze_note(x, rate, nominal_hz=nominal_hz)
    if analysis.f0_hz is None or not analysis.partials:
        reason = "; ".join(analysis.notes) if analysis.notes else "no sustained partial"
        raise ParameterError(f"the recording has no note to fit ({reason}); allowed: a recording of one struck, "
                             "plucked or twanged note")
    details: dict[str, Any] = {}
    if model == "banded":
        from .banded import fit_banded

        fitted = fit_banded(analysis, x, rate, max_modes=max_modes, nominal_hz=nominal_hz, **options)
        parameters = fitted.parameters
        details["left_out_hz"] = [p.frequency_hz for p in fitted.left_out]
    elif model == "twang":
        from .twang import fit_twang

        onset = int(round(analysis.onset_s * rate))
        fitted = fit_twang(_targets(analysis), sample_rate=rate, recording=x[onset:], **options)
        parameters = fitted.parameters
        details["modes"] = [{"frequency_hz": m.target.frequency_hz, "group": m.group, "number": m.number,
                             "model_hz": m.model_hz, "cents": m.cents} for m in fitted.matches]
        details["unmatched_hz"] = [t.frequency_hz for t in fitted.unmatched]
    else:
        from .fd import fit_fd

        fitted = fit_fd(_targets(analysis), sample_rate=rate, **options)
        parameters = fitted.parameters
        details["modes"] = [{"frequency_hz": m.target.frequency_hz, "mode": m.number, "model_hz": m.model_hz,
                             "cents": m.cents} for m in fitted.matches]
        details["unmatched_hz"] = [t.frequency_hz for t in fitted.unmatched]
        details["material_chosen_by_q"] = fitted.material_chosen_by_q
    onset = int(round(analysis.onset_s * rate))
    recording = x[onset:]
    seconds = min(LONGEST_RENDER_S, max(recording.size / rate, 0.05))
    pitch = float(parameters.get("frequency_hz", analysis.f0_hz))  # banded: the nominal pitch, where it tuned to it
    highest = max(float(f) for f in (np.array(parameters.get("mode_ratios", (1.0,))) * pitch))
    resynthesis = _render(model, parameters, rate, seconds, highest)
    modes = resynthesis
    if model == "banded" and parameters.get("excitation") == "sample":
        # the partials are compared with the modes alone: until the attack sample has faded the
        # resynthesis is the recording itself, then partly, which says nothing of the modes
        modes = _render(model, {**parameters, "attack_level_db": SILENT_ATTACK_DB}, rate, seconds, highest)
    if model == "twang":
        modes = _over_the_floor(modes, recording, analysis.noise_floor_db)
    comparison = _compare(analysis, modes, rate)
    distance = spectral_distance(recording, resynthesis, rate)
    f0 = analysis.partials[0]
    baseline = spectral_distance(recording, sine_baseline(f0.frequency_hz, f0.t60_s or math.inf, rate,
                                                          recording.size), rate)
    return Fit(model, parameters, rate, analysis, comparison, distance, baseline, resynthesis, x, details)
