"""The result of measuring a partial (:class:`Partial`) and the ratios of partials' frequencies."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..jsonout import json_number

__all__ = ["Partial", "partial_ratios"]


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
