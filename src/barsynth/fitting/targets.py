"""What a fit aims at: the sustained partials measured in a recording (frequency, level, T60)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Target", "article", "cents", "strongest"]


@dataclass(frozen=True)
class Target:
    """One measured partial: frequency (Hz), initial level (dB re full scale, a cosine of
    amplitude 1 is 0 dB) and T60 (s; None where it does not decay within the recording)."""

    frequency_hz: float
    level_db: float
    t60_s: float | None = None


def cents(a: float | np.ndarray, b: float | np.ndarray) -> float | np.ndarray:
    """How far ``a`` is above ``b``, in cents."""
    return 1200.0 * np.log2(np.asarray(a, dtype=float) / np.asarray(b, dtype=float))


def strongest(targets: list[Target], *, within_db: float = 40.0, at_most: int = 24) -> list[Target]:
    """The targets within ``within_db`` of the strongest, at most ``at_most`` of them (the
    strongest), sorted by frequency."""
    usable = [t for t in targets if math.isfinite(t.frequency_hz) and t.frequency_hz > 0 and math.isfinite(t.level_db)]
    if not usable:
        return []
    top = max(t.level_db for t in usable)
    kept = sorted((t for t in usable if t.level_db >= top - within_db), key=lambda t: -t.level_db)[:at_most]
    return sorted(kept, key=lambda t: t.frequency_hz)


def article(word: str) -> str:
    """``"an"`` before a vowel (an acrylic ruler), else ``"a"`` (a steel bar)."""
    return "an" if word[:1].lower() in "aeiou" else "a"
