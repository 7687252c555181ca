"""The constants of Farnell's patch, its envelopes, and the modes it sounds at rest.

A. Farnell, *Designing Sound*, MIT Press 2010, chapter "Boing" (the Pure Data patch
``twang.pd``), as read in barsynth spec 5. Pure: no state.
"""

from __future__ import annotations

import math

from numba import njit

from ..base import Mode
from .table import FarnellParams

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


def patch_modes(p: FarnellParams, *, sample_rate: float) -> list[Mode]:
    """The modes at rest (after the glide): the drive's clamped partials (Hz; the patch's
    gains; T60 the time for the c^4 fall to reach -60 dB) and the free bands (T60 of the
    band-pass); bands at or above Nyquist left out."""
    drive = 0.25 * p.frequency_hz
    modes = []
    clamp_t60 = CLAMP_FALL_S * (1.0 - 10.0 ** (-60.0 / 80.0))  # c^4 = 1e-3
    for ratio, gain in zip(CLAMPED_RATIOS, CLAMPED_GAINS):
        f = drive * ratio
        if f < sample_rate / 2:
            modes.append(Mode("clamped", f, gain * CLAMPED_MIX, clamp_t60))
    for ratio in FREE_RATIOS:
        fc = p.frequency_hz * ratio
        cf = 2.0 * math.pi * fc / sample_rate
        edge = (sample_rate / 2 - fc) / (NYQUIST_TAPER * sample_rate / 2)
        if edge <= 0.0:
            continue
        r = max(1e-12, 1.0 - cf / BAND_Q)
        t60 = math.log(1000.0) / (-math.log(r) * sample_rate) if r < 1.0 else math.inf
        modes.append(Mode("free-bar", fc, min(1.0, edge), t60))
    return modes
