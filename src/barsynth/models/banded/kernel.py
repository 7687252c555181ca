"""Numba kernel of a bank of banded-waveguide loops (barsynth spec 3.1).

Source: G. Essl and P. R. Cook, "Banded waveguides", Proc. ICMC 1999. One loop per
mode, designed by :func:`barsynth.models.banded.design.design_loop`. Per sample and band:

    d  = buffer[t - M]                       (the band-pass output M samples ago)
    ap = eta (d - ap[-1]) + d[-1]            (first-order Thiran all-pass)
    v  = input_weight * force + g * ap
    bp = b0 (v - v[-2]) - a1 bp[-1] - a2 bp[-2]
    buffer[t] = bp;  out += output_weight * ap

Every state lives in arrays owned by the caller, so blocks of any size give the
same samples as one long block.

With a bow (:func:`process_bowed`) the bands are coupled through the friction at
the bow point, one sample at a time: every band's all-pass output (which depends
only on the past) gives the bar's velocity at the bow, the bow table
(:mod:`barsynth.dsp.friction`) gives the force, and that force enters every band.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...dsp.bow_stroke import FORCE, PRESSURE, SPEED, VELOCITY, held_until, line_value
from ...dsp.friction import friction_given_width, stick_width

# coefficient columns
C_B0 = 0
C_A1 = 1
C_A2 = 2
C_ETA = 3
C_GAIN = 4
C_IN = 5  # input weight: loop input scale x mode shape at the excitation point / (fs x mass)
C_OUT = 6  # output weight: mode shape at the pick-up point
C_BOW_IN = 7  # bow force weight: as C_IN, with the mode shape at the bow
C_BOW_AT = 8  # mode shape at the bow (bar velocity there = sum of C_BOW_AT x ap)
N_COEFFS = 9

# state columns
S_V1 = 0
S_V2 = 1
S_Y1 = 2
S_Y2 = 3
S_AP_X = 4
S_AP_Y = 5
N_STATES = 6


@njit(cache=True, nogil=True, fastmath={"contract"})
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


@njit(cache=True, nogil=True, fastmath={"contract"})
def process_bowed(out, pending, held_force, lines, start, coeffs, delays, buffers, states, position):
    """As :func:`process` (``held_force`` is its ``held``), with a bow as well, whose
    controls are the breakpoint ``lines`` of :class:`barsynth.dsp.bow_stroke.BowControls`;
    ``start`` is the absolute sample index of ``out[0]``. The bow's velocity is speed x velocity (m/s), its
    force pressure x force (N).

    The bar's velocity at the bow, ``v = sum(C_BOW_AT ap)``, is known before this
    sample's force, so the friction ``bow_friction(v_bow - v, F)`` is explicit: no
    delay-free loop, no iteration. And a force reaches any all-pass output only
    ``min(delays)`` samples later, so the samples go in chunks that long: all
    bands' all-pass outputs for the chunk (one band at a time, states in
    registers), then the bar's velocity and the friction per sample, then all
    bands' band-passes. The bow's controls are read once a chunk while they hold
    still. Each sample's arithmetic is the same whatever the chunk, so any block
    size gives the same samples. (Measured on 10 s of the 4-mode bar: 12.7 ms,
    against 20 ms for all bands sample by sample with the controls read per sample.)
    """
    mask = buffers.shape[1] - 1
    pos = position[0]
    n = out.size
    n_pending = min(n, pending.size)
    bands = coeffs.shape[0]
    chunk = max(1, min(64, delays.min()))
    ap_out = np.empty((bands, chunk))
    friction = np.empty(chunk)
    force_in = np.empty(chunk)
    j_speed = j_pressure = j_velocity = j_force = 0
    for c in range(0, n, chunk):
        m = min(chunk, n - c)
        for k in range(bands):  # all-pass outputs: they read only what was written before this chunk
            eta, delay = coeffs[k, C_ETA], delays[k]
            x1, a = states[k, S_AP_X], states[k, S_AP_Y]
            for i in range(m):
                d = buffers[k, (pos + i - delay) & mask]
                a = eta * (d - a) + x1
                x1 = d
                ap_out[k, i] = a
            states[k, S_AP_X], states[k, S_AP_Y] = x1, a
        # The bow's controls: held through the whole chunk (most of a stroke), or per sample.
        x = float(start + c)
        speed, j_speed, until = held_until(lines[SPEED], x, j_speed)
        pressure, j_pressure, until_p = held_until(lines[PRESSURE], x, j_pressure)
        velocity, j_velocity, until_v = held_until(lines[VELOCITY], x, j_velocity)
        force, j_force, until_f = held_until(lines[FORCE], x, j_force)
        held = min(min(until, until_p), min(until_v, until_f)) >= x + m
        v_bow, f_bow = speed * velocity, pressure * force
        inverse_width = 1.0 / stick_width(f_bow) if f_bow > 0.0 else 0.0
        for i in range(m):  # the bar at the bow, the friction, the output
            if not held and i > 0:
                x = float(start + c + i)
                speed, j_speed = line_value(lines[SPEED], x, j_speed)
                pressure, j_pressure = line_value(lines[PRESSURE], x, j_pressure)
                velocity, j_velocity = line_value(lines[VELOCITY], x, j_velocity)
                force, j_force = line_value(lines[FORCE], x, j_force)
                v_bow, f_bow = speed * velocity, pressure * force
                inverse_width = 1.0 / stick_width(f_bow) if f_bow > 0.0 else 0.0
            v_bar = 0.0
            total = 0.0
            for k in range(bands):
                v_bar += coeffs[k, C_BOW_AT] * ap_out[k, i]
                total += coeffs[k, C_OUT] * ap_out[k, i]
            friction[i] = friction_given_width(v_bow - v_bar, f_bow, inverse_width) if f_bow > 0.0 else 0.0
            force_in[i] = pending[c + i] if c + i < n_pending else held_force
            out[c + i] = total
        for k in range(bands):  # band-passes, into the delay lines
            b0, a1, a2 = coeffs[k, C_B0], coeffs[k, C_A1], coeffs[k, C_A2]
            w_in, w_bow, g = coeffs[k, C_IN], coeffs[k, C_BOW_IN], coeffs[k, C_GAIN]
            v1, v2, y1, y2 = states[k, S_V1], states[k, S_V2], states[k, S_Y1], states[k, S_Y2]
            for i in range(m):
                v = w_in * force_in[i] + w_bow * friction[i] + g * ap_out[k, i]
                y = b0 * (v - v2) - a1 * y1 - a2 * y2
                v2 = v1
                v1 = v
                y2 = y1
                y1 = y
                buffers[k, (pos + i) & mask] = y
            states[k, S_V1], states[k, S_V2], states[k, S_Y1], states[k, S_Y2] = v1, v2, y1, y2
        pos = (pos + m) & mask
    position[0] = pos


def empty_bank(bands: int, longest_delay: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zeroed buffers, states and write position for ``bands`` loops."""
    size = 1 << max(4, int(longest_delay + 2).bit_length())
    return np.zeros((bands, size)), np.zeros((bands, N_STATES)), np.zeros(1, dtype=np.int64)
