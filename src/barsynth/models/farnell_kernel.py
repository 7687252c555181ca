"""Numba kernel of Farnell's ruler twang and its anchor (barsynth spec 5).

Source: A. Farnell, *Designing Sound*, MIT Press 2010, chapter "Boing" (the Pure
Data patch ``twang.pd``). Every signal is computed per sample, as in the patch, so
the output does not depend on the block size. The state lives in one float64
vector (indices ``S_*``) and the six band-pass states in a (2, 6) array.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..dsp.noise import uniform_noise

# -- constants read from the patch (spec 5) -----------------------------------------
LFO_HZ = 5.0  # free-running vibrato sine
CLAMP_FALL_S = 1.5  # clamped envelope c(t): 1 -> 0 linearly
PITCH_FALL_S = 7.0  # pitch envelope d(t): 1 -> 0 linearly, raised to the 64th power
GLIDE_DRIVE_HZ = 6.0  # the drive phasor starts 6 * 3 = 18 Hz above f/4
GLIDE_BANDS = 0.1  # the free bands start 0.1 * 3 = 30 % sharp
GLIDE_SCALE = 3.0
CLAMPED_RATIOS = (1.0, 6.267, 17.55, 34.39)
CLAMPED_GAINS = (0.5, 0.25, 0.125, 0.0625)
FREE_RATIOS = (1.0, 2.7565, 5.40392, 8.93295, 13.3443, 18.6379)
BAND_Q = 80.0
LOWPASS_HZ = 4000.0
HIGHPASS_HZ = 90.0
CLAMPED_MIX = 0.2
OUTPUT_GAIN = 4.0
NYQUIST_TAPER = 0.05  # bands fade over the top 5 % below Nyquist (the patch would alias)
SMOOTHING_TIME_S = 0.005  # frequency and depth follow a change within a few ms

# -- parameter vector ---------------------------------------------------------------
P_FREQUENCY = 0
P_DEPTH = 1
P_ANCHOR = 2
P_LEVEL_DB = 3
N_PARAMS = 4

# -- state vector -------------------------------------------------------------------
S_TIME = 0  # samples since the trigger (-1: never triggered)
S_CLOCK = 1  # samples since reset: the free-running LFO
S_PHASE = 2  # drive phasor phase, [0, 1)
S_LOWPASS = 3
S_HP_LAST = 4
S_FREQ = 5  # smoothed frequency and depth
S_DEPTH = 6
S_RNG = 7  # (the noise state is kept in a uint64 array)
N_STATE = 8

_RATIOS = np.array(CLAMPED_RATIOS)
_GAINS = np.array(CLAMPED_GAINS)
_FREE = np.array(FREE_RATIOS)


@njit(cache=True, nogil=True)
def envelopes(t_s):
    """(c(t), E(t)) at ``t_s`` seconds after the trigger: the clamped envelope and the
    glide term ``3 d(t)^64``."""
    c = max(0.0, 1.0 - t_s / CLAMP_FALL_S)
    d = max(0.0, 1.0 - t_s / PITCH_FALL_S)
    d2 = d * d
    d4 = d2 * d2
    d8 = d4 * d4
    d16 = d8 * d8
    d32 = d16 * d16
    return c, GLIDE_SCALE * d32 * d32


@njit(cache=True, nogil=True)
def process(out, trace, params, sample_rate, state, rng, bands):
    """Render ``len(out)`` samples. ``trace`` (shape (3, n) or (0, 0)) receives the
    drive signal, the clamped bank C(t) and the free-bar sum, for measurement."""
    n = out.shape[0]
    tracing = trace.shape[0] == 3
    smooth = 1.0 - math.exp(-1.0 / (SMOOTHING_TIME_S * sample_rate))
    lp_k = min(1.0, 2.0 * math.pi * LOWPASS_HZ / sample_rate)
    hp_c = 1.0 - 2.0 * math.pi * HIGHPASS_HZ / sample_rate
    hp_gain = 0.5 * (1.0 + hp_c)
    vcf_in = 2.0 - 2.0 / (BAND_Q + 2.0)
    nyquist = 0.5 * sample_rate
    level = OUTPUT_GAIN * 10.0 ** (params[P_LEVEL_DB] / 20.0)
    anchor = params[P_ANCHOR] != 0.0
    x_rng = rng[0]
    for i in range(n):
        state[S_FREQ] += smooth * (params[P_FREQUENCY] - state[S_FREQ])
        state[S_DEPTH] += smooth * (params[P_DEPTH] - state[S_DEPTH])
        f = state[S_FREQ] + state[S_DEPTH] * math.sin(2.0 * math.pi * LFO_HZ * state[S_CLOCK] / sample_rate)
        state[S_CLOCK] += 1.0
        sound = 0.0
        drive = 0.0
        clamped = 0.0
        free = 0.0
        if state[S_TIME] >= 0.0:
            c, glide = envelopes(state[S_TIME] / sample_rate)
            state[S_TIME] += 1.0
            phase = state[S_PHASE]
            drive = math.cos(2.0 * math.pi * phase) if anchor else phase
            c2 = c * c
            bank = 0.0
            for k in range(4):
                bank += _GAINS[k] * math.cos(2.0 * math.pi * _RATIOS[k] * drive)
            clamped = c2 * c2 * bank
            # falling phasor at -(f/4 + 6 E)
            phase -= (0.25 * f + GLIDE_DRIVE_HZ * glide) / sample_rate
            phase -= math.floor(phase)
            state[S_PHASE] = phase
            x_rng, u = uniform_noise(x_rng)
            state[S_LOWPASS] += lp_k * (u * drive * drive * clamped - state[S_LOWPASS])
            centre = f * (1.0 + GLIDE_BANDS * glide)
            x_in = state[S_LOWPASS]
            for b in range(6):
                fc = centre * _FREE[b]
                edge = (nyquist - fc) / (NYQUIST_TAPER * nyquist)
                if edge <= 0.0:
                    continue
                cf = 2.0 * math.pi * fc / sample_rate
                r = max(0.0, 1.0 - cf / BAND_Q)
                rc = r * math.cos(cf)
                rs = r * math.sin(cf)
                re = bands[0, b]
                im = bands[1, b]
                new_re = vcf_in * (1.0 - r) * x_in + rc * re - rs * im
                bands[1, b] = rs * re + rc * im
                bands[0, b] = new_re
                free += new_re * min(1.0, edge)
            sound = free + CLAMPED_MIX * clamped
        # Pd's hip~ at 90 Hz, then x4 and the level
        node = sound + hp_c * state[S_HP_LAST]
        out[i] = level * hp_gain * (node - state[S_HP_LAST])
        state[S_HP_LAST] = node
        if tracing:
            trace[0, i] = drive
            trace[1, i] = clamped
            trace[2, i] = free
    rng[0] = x_rng
