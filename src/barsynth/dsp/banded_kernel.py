"""Numba kernel of a bank of banded-waveguide loops (barsynth spec 3.1).

Source: G. Essl and P. R. Cook, "Banded waveguides", Proc. ICMC 1999. One loop per
mode, designed by :func:`barsynth.dsp.banded.design_loop`. Per sample and band:

    d  = buffer[t - M]                       (the band-pass output M samples ago)
    ap = eta (d - ap[-1]) + d[-1]            (first-order Thiran all-pass)
    v  = input_weight * force + g * ap
    bp = b0 (v - v[-2]) - a1 bp[-1] - a2 bp[-2]
    buffer[t] = bp;  out += output_weight * ap

Every state lives in arrays owned by the caller, so blocks of any size give the
same samples as one long block.
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
def process(out, pending, held, coeffs, delays, buffers, states, position):
    """Run the bank for ``out.size`` samples driven by a force (N): ``pending[t]`` for
    the first ``pending.size`` samples, then ``held``.

    ``buffers`` is (bands, 2^k) with 2^k > every delay; ``position[0]`` is the write
    index, carried between calls. With a force known in advance the bands do not
    interact, so they run two at a time over the whole block with their states in
    registers (measured: twice as fast as all bands per sample for a 12-mode bowl).
    """
    bands = coeffs.shape[0]
    mask = buffers.shape[1] - 1
    start = position[0]
    n = out.size
    n_pending = min(n, pending.size)
    out[:] = 0.0
    for k in range(0, bands, 2):
        j = min(k + 1, bands - 1)  # an odd last band runs beside itself, silently
        on = 1.0 if k + 1 < bands else 0.0
        b0a, a1a, a2a = coeffs[k, C_B0], coeffs[k, C_A1], coeffs[k, C_A2]
        eta_a, ga, ina, outa = coeffs[k, C_ETA], coeffs[k, C_GAIN], coeffs[k, C_IN], coeffs[k, C_OUT]
        b0b, a1b, a2b = coeffs[j, C_B0], coeffs[j, C_A1], coeffs[j, C_A2]
        eta_b, gb, inb, outb = coeffs[j, C_ETA], coeffs[j, C_GAIN], coeffs[j, C_IN] * on, coeffs[j, C_OUT] * on
        ma, mb = delays[k], delays[j]
        v1a, v2a, y1a, y2a = states[k, S_V1], states[k, S_V2], states[k, S_Y1], states[k, S_Y2]
        xa, apa = states[k, S_AP_X], states[k, S_AP_Y]
        v1b, v2b, y1b, y2b = states[j, S_V1], states[j, S_V2], states[j, S_Y1], states[j, S_Y2]
        xb, apb = states[j, S_AP_X], states[j, S_AP_Y]
        pos = start
        for t in range(n):
            f = pending[t] if t < n_pending else held
            da = buffers[k, (pos - ma) & mask]
            db = buffers[j, (pos - mb) & mask]
            apa = eta_a * (da - apa) + xa
            apb = eta_b * (db - apb) + xb
            xa = da
            xb = db
            va = ina * f + ga * apa
            vb = inb * f + gb * apb
            ya = b0a * (va - v2a) - a1a * y1a - a2a * y2a
            yb = b0b * (vb - v2b) - a1b * y1b - a2b * y2b
            v2a = v1a
            v1a = va
            y2a = y1a
            y1a = ya
            v2b = v1b
            v1b = vb
            y2b = y1b
            y1b = yb
            buffers[k, pos] = ya
            if on > 0.0:
                buffers[j, pos] = yb
            out[t] += outa * apa + outb * apb
            pos = (pos + 1) & mask
        states[k, S_V1], states[k, S_V2], states[k, S_Y1], states[k, S_Y2] = v1a, v2a, y1a, y2a
        states[k, S_AP_X], states[k, S_AP_Y] = xa, apa
        if on > 0.0:
            states[j, S_V1], states[j, S_V2], states[j, S_Y1], states[j, S_Y2] = v1b, v2b, y1b, y2b
            states[j, S_AP_X], states[j, S_AP_Y] = xb, apb
    position[0] = (start + n) & mask


def empty_bank(bands: int, longest_delay: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zeroed buffers, states and write position for ``bands`` loops."""
    size = 1 << max(4, int(longest_delay + 2).bit_length())
    return np.zeros((bands, size)), np.zeros((bands, N_STATES)), np.zeros(1, dtype=np.int64)
