"""The result of analysing a note (:func:`.note.analyze_note`): frozen records with JSON.

Times are in seconds from the file's first sample; levels of partials are amplitudes in
dB re full scale (a cosine of amplitude 1.0 is 0 dB), extrapolated to the sound's start.
``to_json()`` gives JSON-safe values: ``None`` (null) for missing, infinite or NaN numbers.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from ..jsonout import json_ready
from .partial import Partial

__all__ = ["Attack", "Damped", "Decay", "NoteAnalysis", "NotePartial"]


@dataclass(frozen=True)
class Damped:
    """A damped cosine from the sound's start: ``10^(level_db/20) exp(-(t - start) ln(1000) /
    t60_s) cos(2 pi frequency_hz (t - start) + phase_rad)`` (``t60_s`` None: it holds)."""

    frequency_hz: float
    level_db: float
    t60_s: float | None
    phase_rad: float

    def to_json(self) -> dict[str, Any]:
        return json_ready(asdict(self))


@dataclass(frozen=True)
class Decay:
    """How a partial's decay was measured.

    The envelope of the partial's band, in dB, was fitted over ``range_start_s`` to
    ``range_end_s``; levels are relative to the partial's initial level (``level_db``).

    Attributes
    ----------
    method
        ``"line"`` (one slope), ``"two-stage"`` (a knee: two slopes) or ``"doublet"`` (two
        damped exponentials in one band, this partial being one of them; ``t60_s`` is its
        own, the quality the band's, the range until it falls to 10 dB above the floor;
        the partial's ``doublet_hz`` names the other, unless that one was not kept).
    t60_s
        T60 of the (first) slope, s; None when it does not decay (falls less than 1 dB
        over its span, or rises).
    range_start_s, range_end_s
        The time span fitted, s.
    range_start_db, range_end_db
        The fitted curve at the two ends, dB relative to the initial level.
    floor_db
        The band's noise floor, dB relative to the initial level (None without noise).
    rms_db
        RMS deviation of the envelope (in dB) from the fit over the range, dB.
    r2
        Coefficient of determination of the dB fit.
    points
        Envelope samples fitted.
    knee_s
        Where a two-stage decay bends, s (None for one slope).
    second_t60_s
        T60 after the knee, s (None for one slope, or when it does not decay).
    line_rms_db
        RMS deviation from a single line over the same range, dB (to compare with
        ``rms_db`` for a two-stage decay).
    sustains
        The partial does not decay by the end of the file (its last stage falls less than
        1 dB); the partial's ``t60_s`` is then None.
    """

    method: str
    t60_s: float | None
    range_start_s: float
    range_end_s: float
    range_start_db: float
    range_end_db: float
    floor_db: float | None
    rms_db: float
    r2: float
    points: int
    knee_s: float | None = None
    second_t60_s: float | None = None
    line_rms_db: float = 0.0
    sustains: bool = False

    @property
    def range_db(self) -> float:
        """How far the fit falls over its range, dB."""
        return self.range_start_db - self.range_end_db

    def to_json(self) -> dict[str, Any]:
        return json_ready({**asdict(self), "range_db": self.range_db})


@dataclass(frozen=True)
class NotePartial:
    """A sustained partial of a note.

    Attributes
    ----------
    frequency_hz
        Frequency, Hz.
    ratio
        ``frequency_hz / f0_hz``.
    level_db
        Initial amplitude, dB re full scale (a cosine of amplitude 1.0 is 0 dB),
        extrapolated to the sound's start.
    t60_s
        Time to decay by 60 dB, s (the first slope of a two-stage decay); None when the
        partial does not decay within the file (see ``decay.sustains``; a looped sample).
    phase_rad
        Phase of the cosine at the start, rad: the partial is ``10^(level_db/20)
        exp(-(t - start) ln(1000)/T60) cos(2 pi f (t - start) + phase_rad)``.
    decay
        How the decay was measured (:class:`Decay`).
    beats
        The partial beats: two components too close to resolve in this file.
    doublet_hz
        For one of a resolved doublet, the frequency of the other (Hz); else None.
    components
        The damped cosines (:class:`Damped`) that resynthesise it: their sum -- two for a
        two-stage decay of two exponentials -- except that after a knee found in dB
        (``decay.knee_s`` with one component) the decay goes on at ``decay.second_t60_s``.
    """

    frequency_hz: float
    ratio: float
    level_db: float
    t60_s: float | None
    phase_rad: float
    decay: Decay
    beats: bool = False
    doublet_hz: float | None = None
    components: tuple[Damped, ...] = ()

    def as_partial(self) -> Partial:
        """This partial as a :class:`~barsynth.analysis.Partial` (``t60_s`` inf when it
        does not decay)."""
        return Partial(self.frequency_hz, self.level_db, math.inf if self.t60_s is None else self.t60_s)

    def to_json(self) -> dict[str, Any]:
        out = {k: v for k, v in asdict(self).items() if k not in ("decay", "components")}
        out["decay"] = self.decay.to_json()
        out["components"] = [c.to_json() for c in self.components]
        return json_ready(out)


@dataclass(frozen=True)
class Attack:
    """The attack: what is left of the sound once the sustained partials are taken out,
    from the start until it has died away.

    Attributes
    ----------
    duration_s
        From the start to the end of the attack, s (0 when there is none to speak of).
    energy_db
        Its energy, dB re the whole sound's energy (None when there is no attack).
    centroid_hz
        Its spectral centroid, Hz (None when there is no attack).
    """

    duration_s: float
    energy_db: float | None
    centroid_hz: float | None

    def to_json(self) -> dict[str, Any]:
        return json_ready(asdict(self))


@dataclass(frozen=True)
class NoteAnalysis:
    """A note's analysis (:func:`barsynth.analysis.analyze_note`).

    Attributes
    ----------
    sample_rate
        Hz.
    duration_s
        The file's duration, s.
    onset_s
        The onset (spec 7.1): the first sample within 40 dB of the peak, less 3 ms, s.
    start_s
        Where the note is struck, s (:func:`.onset.strike_at`: after a quiet lead-in, the
        first 1 ms frame 20 dB above it; else the first sample above -80 dB of the peak),
        robust to noise before the strike, which the onset is not. Partials are
        extrapolated to it and the attack is measured from it.
    f0_hz
        The note's fundamental (``partials[0]``), Hz; None when no partial was found.
    f0_family
        The family of ratios that, from f0, explains the sustained spectrum best
        (``"harmonic"``, ``"tuned bar 1:4:10"``, ``"tuned bar 1:3:6"``, ``"free bar"``,
        ``"clamped-free bar"``); None without f0 or when f0 explains no other partial.
    f0_explained
        The share of the sustained partials' energy that family explains (0 to 1).
    partials
        The sustained partials at or above f0, by frequency (the first is f0).
    below_f0
        Sustained components below f0 (hum, rumble), by frequency; their ``ratio`` is
        below 1 and they are not references of ratios.
    attack
        The attack (:class:`Attack`).
    looped
        The strongest partials do not decay within the file (a sample cut at its loop).
    noise_floor_db
        RMS level of the noise in the file's last quarter, dB re full scale (None for
        none).
    """

    sample_rate: float
    duration_s: float
    onset_s: float
    start_s: float
    f0_hz: float | None
    f0_family: str | None
    f0_explained: float | None
    partials: tuple[NotePartial, ...]
    below_f0: tuple[NotePartial, ...]
    attack: Attack
    looped: bool
    noise_floor_db: float | None
    notes: tuple[str, ...] = field(default=())

    @property
    def f0_index(self) -> int | None:
        """Index of the f0 partial in ``partials`` (0), None without f0."""
        return 0 if self.partials else None

    def to_json(self) -> dict[str, Any]:
        """Every field; nested records as dicts; ``f0_index`` too."""
        return json_ready({
            "sample_rate": self.sample_rate,
            "duration_s": self.duration_s,
            "onset_s": self.onset_s,
            "start_s": self.start_s,
            "f0_hz": self.f0_hz,
            "f0_index": self.f0_index,
            "f0_family": self.f0_family,
            "f0_explained": self.f0_explained,
            "looped": self.looped,
            "noise_floor_db": self.noise_floor_db,
            "attack": self.attack.to_json(),
            "partials": [p.to_json() for p in self.partials],
            "below_f0": [p.to_json() for p in self.below_f0],
            "notes": list(self.notes),
        })
