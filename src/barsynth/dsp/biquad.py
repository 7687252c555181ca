"""A biquad filter section with carried state, and the high-pass that says what can be heard.

Coefficients after R. Bristow-Johnson, "Cookbook formulae for audio EQ biquad filter
coefficients"; the section runs in transposed direct form II, so blocks of any size give the
samples of one long block. (Written here rather than taken from ``scipy.signal``, whose
import costs a plain render about 0.15 s and tens of MiB: tests/test_startup.py.)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

AUDIBLE_FROM_HZ = 20.0  # below this a component moves air but is not heard as sound


def high_pass(cutoff_hz: float, sample_rate: float, q: float = 1.0 / math.sqrt(2.0)) -> np.ndarray:
    """``[b0, b1, b2, a1, a2]`` (a0 = 1) of a 2nd-order high-pass (Butterworth for the default Q)."""
    w = 2.0 * math.pi * cutoff_hz / sample_rate
    alpha = math.sin(w) / (2.0 * q)
    a0 = 1.0 + alpha
    b = (1.0 + math.cos(w)) / 2.0
    return np.array([b / a0, -2.0 * b / a0, b / a0, -2.0 * math.cos(w) / a0, (1.0 - alpha) / a0])


@njit(cache=True, nogil=True)
def run_biquad(x, coeffs, state, out):  # pragma: no cover - compiled
    """Filter ``x`` into ``out`` (same size); ``state`` (2 values) carries over between blocks."""
    b0, b1, b2, a1, a2 = coeffs[0], coeffs[1], coeffs[2], coeffs[3], coeffs[4]
    s1, s2 = state[0], state[1]
    for n in range(x.size):
        v = x[n]
        y = b0 * v + s1
        s1 = b1 * v - a1 * y + s2
        s2 = b2 * v - a2 * y
        out[n] = y
    state[0], state[1] = s1, s2
