"""Numba kernel of a bank of banded-waveguide loops (barsynth spec 3.1).

Source: G. Essl and P. R. Cook, "Banded waveguides", Proc. ICMC 1999. One loop per
mode, designed by :func:`barsynth.dsp.banded.design_loop`. Per sample and band:

    d  = buffer[t - M]                       (the band-pass output M samples ago)
    ap = eta (d - ap[-1]) + d[-1]            (first-order Thiran all-pass)
    v  = input_weight * force + g * ap
    bp = b0 (v - v[-2]) - a1 bp[-1] - a2 bp[-2]
    buffer[t] = bp;  out += output_weight * ap

The bands are updated side by side for each sample (their recursions are
independent, so the processor overlaps them). Every state lives in arrays owned by
the caller, so blocks of any size give the same samples as one long block.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# coefficient columns
C_B0 = 0
C_A1 = 1
C_A2 = 2
C_ETA = 3
C_GAIN = 4
C_IN = 5  # input weight: loop input scale x mode shape at the excitation point / (fs x mass)
C_OUT = 6  # output weight: mode shape at the pick-up point
N_COEFFS = 7

# state columns
S_V1 = 0
S_V2 = 1
S_Y1 = 2
S_Y2 = 3
S_AP_X = 4
S_AP_Y = 5
N_STATES = 6


@njit(cache=True, fastmath={"contract"})
def process(out, force, coeffs, delays, buffers, states, position):
    """Run the bank for ``out.size`` samples driven by ``force`` (one value a sample).

    ``buffers`` is (bands, 2^k) with 2^k > every delay; ``position[0]`` is the write
    index, carried between calls.
    """
    bands = coeffs.shape[0]
    mask = buffers.shape[1] - 1
    pos = position[0]
    for t in range(out.size):
        f = force[t]
        acc = 0.0
        for k in range(bands):
            d = buffers[k, (pos - delays[k]) & mask]
            ap = coeffs[k, C_ETA] * (d - states[k, S_AP_Y]) + states[k, S_AP_X]
            states[k, S_AP_X] = d
            states[k, S_AP_Y] = ap
            v = coeffs[k, C_IN] * f + coeffs[k, C_GAIN] * ap
            y = (coeffs[k, C_B0] * (v - states[k, S_V2]) - coeffs[k, C_A1] * states[k, S_Y1]
                 - coeffs[k, C_A2] * states[k, S_Y2])
            states[k, S_V2] = states[k, S_V1]
            states[k, S_V1] = v
            states[k, S_Y2] = states[k, S_Y1]
            states[k, S_Y1] = y
            buffers[k, pos] = y
            acc += coeffs[k, C_OUT] * ap
        out[t] = acc
        pos = (pos + 1) & mask
    position[0] = pos


def empty_bank(bands: int, longest_delay: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zeroed buffers, states and write position for ``bands`` loops."""
    size = 1 << max(4, int(longest_delay + 2).bit_length())
    return np.zeros((bands, size)), np.zeros((bands, N_STATES)), np.zeros(1, dtype=np.int64)
