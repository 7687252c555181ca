"""Adding a voice's block into an instrument's mix: one pass that also gives the block's peak.

The :class:`~barsynth.playing.instrument.Instrument` adds every sounding voice's block into its
output and keeps each block's peak (to find a voice that has gone quiet). In NumPy that is
``out += block`` and ``np.max(np.abs(block))``: three passes and a temporary, about 4 us a voice
per 256-sample block, as much as a banded bar's own samples. :func:`add_and_peak` is one
compiled pass with the same results: the same additions (no fastmath) and the same maximum.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True)
def add_and_peak(out, block):  # pragma: no cover - compiled
    """``out += block`` (float64 arrays of one size) and return ``max(|block|)`` as
    ``np.max(np.abs(block))`` gives it (NaN if any sample is NaN; 0.0 for an empty block)."""
    peak = 0.0
    nan = False
    for i in range(block.size):
        x = block[i]
        out[i] += x
        size = abs(x)
        if size > peak:
            peak = size
        elif size != size:
            nan = True
    return math.nan if nan else peak
