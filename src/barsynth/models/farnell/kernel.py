"""The numba kernel of Farnell's ruler twang and its anchor (barsynth spec 5).

A. Farnell, *Designing Sound*, MIT Press 2010, chapter "Boing" (the Pure Data patch
``twang.pd``). Every signal is computed per sample, as in the patch, so the output does
not depend on the block size. The state is two records the voice allocates in ``prepare``:
:class:`Controls` (the anchor switch and the ramps of frequency, depth and level) and
:class:`Patch` (the clocks, phasor and filters).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ...dsp.noise import uniform_noise
from ...dsp.smoothing import LINEAR, MULTIPLICATIVE, next_value
from .design import (BAND_Q, CLAMPED_GAINS, CLAMPED_MIX, CLAMPED_RATIOS, FREE_RATIOS, GLIDE_BANDS, GLIDE_DRIVE_HZ,
                     HIGHPASS_HZ, LFO_HZ, LOWPASS_HZ, NYQUIST_TAPER, OUTPUT_GAIN, envelopes)


class Controls(NamedTuple):
    """What the parameters set: the anchor switch and three dsp.smoothing ramps."""

    anchor: bool  # the drive is cos(2 pi phase) instead of the phasor
    frequency_hz: np.ndarray  # ramp of f (multiplicative)
    depth_hz: np.ndarray  # ramp of the vibrato depth (linear)
    gain: np.ndarray  # ramp of the output gain 10^(level_db/20) (linear)


class Patch(NamedTuple):
    """The patch's state."""

    scalars: np.ndarray  # the slots S (below)
    rng: np.ndarray  # the noise generator (dsp.noise)
    bands: np.ndarray  # (2, 6): each vcf~'s complex state, re and im


class Scalars(NamedTuple):
    """The slots of ``Patch.scalars`` (:data:`S`: each name's index, from this one list)."""

    time: int  # samples since the trigger (-1: never triggered)
    clock: int  # samples since reset: the free-running LFO
    phase: int  # drive phasor phase, [0, 1)
    lowpass: int
    hp_last: int


S = Scalars(*range(len(Scalars._fields)))
"""Each scalar's slot by name (``state[S.phase]``)."""
N_SCALARS = len(S)

LANES = ("drive", "clamped", "free")  # what process() can trace, in its rows

TINY = 1e-30
"""A filter state smaller than this (600 dB below full scale) is set to 0: once a note has
died away its filters decay geometrically through tiny and subnormal numbers, whose arithmetic
made a silent voice about 6 times slower (46-75 ms a second of sound against 8 ms)."""

_RATIOS = np.array(CLAMPED_RATIOS)
_GAINS = np.array(CLAMPED_GAINS)
_FREE = np.array(FREE_RATIOS)


@njit(cache=True, nogil=True)
def process(out, lanes, sample_rate, controls, patch):
    """Render ``len(out)`` samples. ``lanes`` (shape (3, n), or (0, 0) for none) receives
    the drive signal, the clamped bank C(t) and the free-bar sum, for measurement."""
    n = out.shape[0]
    tracing = lanes.shape[0] == 3
    lp_k = min(1.0, 2.0 * math.pi * LOWPASS_HZ / sample_rate)
    hp_c = 1.0 - 2.0 * math.pi * HIGHPASS_HZ / sample_rate
    hp_gain = 0.5 * (1.0 + hp_c)
    vcf_in = 2.0 - 2.0 / (BAND_Q + 2.0)
    nyquist = 0.5 * sample_rate
    anchor = controls.anchor
    state = patch.scalars
    bands = patch.bands
    x_rng = patch.rng[0]
    for i in range(n):
        f_hz = next_value(controls.frequency_hz, MULTIPLICATIVE)
        depth = next_value(controls.depth_hz, LINEAR)
        level = OUTPUT_GAIN * next_value(controls.gain, LINEAR)
        f = f_hz + depth * math.sin(2.0 * math.pi * LFO_HZ * state[S.clock] / sample_rate)
        state[S.clock] += 1.0
        sound = 0.0
        drive = 0.0
        clamped = 0.0
        free = 0.0
        if state[S.time] >= 0.0:
            c, glide = envelopes(state[S.time] / sample_rate)
            state[S.time] += 1.0
            phase = state[S.phase]
            drive = math.cos(2.0 * math.pi * phase) if anchor else phase
            c2 = c * c
            bank = 0.0
            for k in range(4):
                bank += _GAINS[k] * math.cos(2.0 * math.pi * _RATIOS[k] * drive)
            clamped = c2 * c2 * bank
            # falling phasor at -(f/4 + 6 E)
            phase -= (0.25 * f + GLIDE_DRIVE_HZ * glide) / sample_rate
            phase -= math.floor(phase)
            state[S.phase] = phase
            x_rng, u = uniform_noise(x_rng)
            lowpass = state[S.lowpass] + lp_k * (u * drive * drive * clamped - state[S.lowpass])
            state[S.lowpass] = lowpass if abs(lowpass) >= TINY else 0.0
            centre = f * (1.0 + GLIDE_BANDS * glide)
            x_in = state[S.lowpass]
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
                new_im = rs * re + rc * im
                if abs(new_re) < TINY and abs(new_im) < TINY:
                    new_re = 0.0
                    new_im = 0.0
                bands[1, b] = new_im
                bands[0, b] = new_re
                free += new_re * min(1.0, edge)
            sound = free + CLAMPED_MIX * clamped
        # Pd's hip~ at 90 Hz, then x4 and the level
        node = sound + hp_c * state[S.hp_last]
        out[i] = level * hp_gain * (node - state[S.hp_last])
        state[S.hp_last] = node if abs(node) >= TINY else 0.0
        if tracing:
            lanes[0, i] = drive
            lanes[1, i] = clamped
            lanes[2, i] = free
    patch.rng[0] = x_rng
