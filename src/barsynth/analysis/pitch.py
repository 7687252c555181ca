"""The note's fundamental: the partial that best explains the sustained spectrum.

Each strong partial is tried as f0. For each of a few families of partial ratios
(:data:`FAMILIES`: harmonic instruments, tuned bars, uniform bars), the partials found
within a tolerance of ``ratio * f0`` are "explained"; a candidate's score is the largest
share of the sustained energy one family explains (its own energy included, partials
below it never; of families that explain about as much, the one with the fewest
ratios names it: a marimba's 1:4:10 rather than "harmonic"). The score is weighed by:

- the candidate's own level: full weight within :data:`FULL_WEIGHT_DB` of the strongest
  partial, halving every further 6 dB (hum far below the note is not its f0);
- when a nominal pitch is given (a soundfont's root key), closeness to it: a Gaussian
  of :data:`NOMINAL_CENTS` cents, never below :data:`NOMINAL_FLOOR`.

A partial's energy is what it holds within the file: ``A^2 (1 - exp(-2 sigma D)) /
(2 sigma)`` for amplitude ``A``, decay rate ``sigma`` and the time ``D`` it lasts.

Ratios: T. D. Rossing, *Science of Percussion Instruments* (World Scientific, 2000):
marimba and vibraphone bars tuned 1:4:10, xylophone 1:3:6; uniform free bars
1:2.756:5.404:8.933; a clamped-free bar (a kalimba tine, a twanged ruler)
1:6.267:17.55:34.39.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["FAMILIES", "PitchChoice", "choose_f0"]

FAMILIES: dict[str, tuple[tuple[float, ...], float]] = {
    # name: (ratios to f0, tolerance in cents)
    "harmonic": (tuple(float(n) for n in range(1, 33)), 30.0),
    "tuned bar 1:4:10": ((1.0, 4.0, 10.0), 60.0),
    "tuned bar 1:3:6": ((1.0, 3.0, 6.0), 60.0),
    "free bar": ((1.0, 2.756, 5.404, 8.933, 13.345, 18.638), 60.0),
    "clamped-free bar": ((1.0, 6.267, 17.547, 34.386), 60.0),
}
FULL_WEIGHT_DB = 15.0
NOMINAL_CENTS = 150.0
NOMINAL_FLOOR = 0.05
_CANDIDATES_WITHIN_DB = 40.0
_TWIN_CENTS = 30.0  # a partial this close above f0 is its twin (a doublet), not a ratio
_TIE = 0.005  # families whose shares differ by less than this explain as much  # f0 is one of the partials within this of the strongest


@dataclass(frozen=True)
class PitchChoice:
    """The f0 chosen: its index in the partials given, the family of ratios that explains
    the sustained spectrum best from it ("" when it explains no other partial), and the
    share of the energy it explains, its own included (0-1)."""

    index: int
    family: str
    explained: float


def _cents(a: float, b: float) -> float:
    return abs(1200.0 * math.log2(a / b))


def choose_f0(
    frequencies_hz: Sequence[float],
    levels_db: Sequence[float],
    energies: Sequence[float],
    *,
    nominal_hz: float | None = None,
) -> PitchChoice | None:
    """The f0 among partials (frequencies in Hz, levels in dB, energies in any one unit).

    Returns None when there are no partials.
    """
    n = len(frequencies_hz)
    if n == 0:
        return None
    total = float(sum(energies))
    if not total > 0:
        total = 1.0
    top = max(levels_db)
    best: tuple[float, int, str, float] | None = None
    for i in range(n):
        f0 = frequencies_hz[i]
        if levels_db[i] < top - _CANDIDATES_WITHIN_DB or not f0 > 0:
            continue
        # f0 itself and a twin beside it (a doublet) are explained by any family
        twins = [j for j in range(n) if f0 * (1.0 - 1e-9) <= frequencies_hz[j]
                 and _cents(frequencies_hz[j], f0) <= _TWIN_CENTS]
        near = sum(energies[j] for j in twins)
        shares = {}
        for name, (ratios, tolerance) in FAMILIES.items():
            explained = 0.0
            for j in range(n):
                f = frequencies_hz[j]
                if f < f0 * (1.0 - 1e-9) or j in twins:
                    continue
                if any(_cents(f, r * f0) <= tolerance for r in ratios[1:]):
                    explained += energies[j]
            shares[name] = explained / total
        others = max(shares.values())
        share = others + near / total
        # of the families that explain (about) as much, the most specific: the fewest ratios
        family = ""
        if others > 0:
            family = min((name for name, v in shares.items() if v >= others - _TIE),
                         key=lambda name: len(FAMILIES[name][0]))
        weight = 0.5 ** (max(0.0, top - FULL_WEIGHT_DB - levels_db[i]) / 6.0)
        if nominal_hz is not None:
            weight *= max(NOMINAL_FLOOR, math.exp(-0.5 * (_cents(f0, nominal_hz) / NOMINAL_CENTS) ** 2))
        score = share * weight
        if best is None or score > best[0] * (1.0 + 1e-9):
            best = (score, i, family, share)
    if best is None:
        return None
    return PitchChoice(index=best[1], family=best[2], explained=best[3])
