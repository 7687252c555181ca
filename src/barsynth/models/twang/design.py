"""The twang's coefficient design: parameters and sample rate -> its 18 modes and band-passes.

Pure functions, no state (Selfridge et al., AES Convention Paper 10553, 2022, sections 2-3).
:func:`design` is compiled into the dynamic kernel, which designs anew at every control frame
where a control, the vibrato or the slide moves; as plain Python it designs a note that
holds still (the static kernel's) and, in :func:`design_modes`, what ``describe`` reports, so
what is reported is what sounds.

Three groups of six modes, from Euler-Bernoulli physics (:mod:`barsynth.physics`): the
full-length cantilever (clamped at the finger), the short cantilever at the desk edge
(``short_length_ratio`` x the length, so its modes are 1/ratio^2 higher) and the free bar.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba.extending import register_jitable

from ..base import Mode
from .table import ROWS, TwangParams, control_vector

MODES_PER_GROUP = 6
N_OSC = 2 * MODES_PER_GROUP  # full + short cantilever oscillators
N_BANDS = MODES_PER_GROUP  # free-bar band-pass filters
N_MODES = 3 * MODES_PER_GROUP
GROUPS = ("full-cantilever", "short-cantilever", "free-bar")
BETA_M = 4.0  # the paper's second beta shape parameter
LOG_MAP_FLOOR_HZ = 1.0  # log gain mapping: x = ln(f/1 Hz) / ln(nyquist/1 Hz)
NYQUIST_TAPER = 0.05  # gains fade to 0 over the top 5 % below Nyquist; silent at/above
VIBRATO_MAX_RELATIVE_DEPTH = 0.06  # cap: 6 % (about one semitone)
SLIDE_RISE = 0.35  # slide raises the short-cantilever modes by 35 %
VIBRATO_FADE_RATE_HZ = 0.5  # below this rate the vibrato depth fades to 0 (glides home)
MIN_BAND_HZ = 20.0  # free-bar bands fade out from 30 Hz to 20 Hz and are silent below
REFERENCE_SHORT_GAIN = 0.75  # the paper's short/full ratio, used by the level scale

# design and bandpass are plain Python functions that numba compiles as part of the
# twang's dynamic kernel (its cache holds them), without a C wrapper; Python calls them as
# they are (design_modes, and the voice's design of a note that holds still).
JITABLE = {"nogil": True, "no_cfunc_wrapper": True}



class Modes(NamedTuple):
    """One design's 18 modes (full cantilever 0-5, short cantilever 6-11, free bar 12-17)."""

    frequency_hz: np.ndarray
    gain: np.ndarray  # linear, level scale not included
    alpha_per_s: np.ndarray  # decay rate: amplitude exp(-alpha t)
    log_density: np.ndarray  # (2, N_MODES) scratch: each mode's beta log-density, linear and log axis


def new_modes() -> Modes:
    return Modes(np.zeros(N_MODES), np.zeros(N_MODES), np.zeros(N_MODES), np.zeros((2, N_MODES)))


def mode_lambdas() -> np.ndarray:
    """The eigenvalues: 6 clamped-free (cantilever), then 6 free-free."""
    from ...physics import lambdas

    return np.concatenate(
        [lambdas("clamped-free", MODES_PER_GROUP), lambdas("free-free", MODES_PER_GROUP)]
    ).astype(np.float64)


@register_jitable(**JITABLE)
def design(values, rows, lambdas, mode_mask, sample_rate, time_s, lfo_sin, modes):
    """Fill ``modes`` (frequency in Hz, linear gain, decay rate alpha = pi f / Q in 1/s).

    ``values`` is the control vector (slots ``rows``, see :mod:`.table`); ``lambdas`` the 6
    cantilever then 6 free-free eigenvalues; ``mode_mask`` (18 values, 1 = sound, 0 = mute)
    multiplies the gains. ``time_s`` since the trigger drives the slide, ``lfo_sin`` in
    [-1, 1] the vibrato. Returns the drive-phasor frequency (Hz: the full-length
    fundamental, with vibrato) and the level scale ``1 / max(S_c, S_f)``: ``S_c`` the beta
    gains of the full-length modes times 1.75 (the paper's mix), ``S_f`` those of the free
    modes. It ignores the mix gains and the mask, so those act as true gains; with the
    paper's mix and ``S_c >= S_f`` a note's first sample is exactly the level.
    """
    freqs = modes.frequency_hz
    gains = modes.gain
    alphas = modes.alpha_per_s
    nyquist = 0.5 * sample_rate
    wave_const = (math.sqrt(values[rows.youngs_modulus_pa] / values[rows.density_kg_m3])
                  * values[rows.thickness_m] / math.sqrt(12.0))
    length = values[rows.length_m]
    base = wave_const / (2.0 * math.pi * length * length)
    ratio = values[rows.short_length_ratio]
    q = values[rows.q]
    shape = values[rows.shape]
    log_weight = values[rows.gain_mapping]  # 0 linear, 1 log; a cross-fade while it glides
    for n in range(MODES_PER_GROUP):
        lc = lambdas[n]
        lf = lambdas[MODES_PER_GROUP + n]
        freqs[n] = base * lc * lc
        freqs[MODES_PER_GROUP + n] = freqs[n] / (ratio * ratio)
        freqs[2 * MODES_PER_GROUP + n] = base * lf * lf
    for i in range(N_MODES):
        alphas[i] = math.pi * freqs[i] / q

    # Beta-shaped gains over the full-length cantilever and free-bar modes below
    # Nyquist, each at its own frequency, normalised so the largest is 1 (per mapping).
    log_nyq = math.log(nyquist / LOG_MAP_FLOOR_HZ)
    best_lin = -1e300
    best_log = -1e300
    for i in range(N_MODES):
        gains[i] = 0.0
    lin_lp = modes.log_density[0]
    log_lp = modes.log_density[1]
    for i in range(N_MODES):
        lin_lp[i] = -1e300
        log_lp[i] = -1e300
        if MODES_PER_GROUP <= i < 2 * MODES_PER_GROUP:
            continue  # short modes take 0.75 x the full-length gains (below)
        f = freqs[i]
        if f >= nyquist:
            continue
        x = f / nyquist
        lin_lp[i] = (shape - 1.0) * math.log(x) + (BETA_M - 1.0) * math.log1p(-x)
        xl = math.log(max(f, LOG_MAP_FLOOR_HZ * 1.000001) / LOG_MAP_FLOOR_HZ) / log_nyq
        xl = min(max(xl, 1e-9), 1.0 - 1e-9)
        log_lp[i] = (shape - 1.0) * math.log(xl) + (BETA_M - 1.0) * math.log1p(-xl)
        best_lin = max(best_lin, lin_lp[i])
        best_log = max(best_log, log_lp[i])
    for i in range(N_MODES):
        if lin_lp[i] > -1e299:
            g_lin = math.exp(lin_lp[i] - best_lin)
            g_log = math.exp(log_lp[i] - best_log)
            gains[i] = (1.0 - log_weight) * g_lin + log_weight * g_log
    sum_c = 0.0
    sum_f = 0.0
    for n in range(MODES_PER_GROUP):
        sum_c += gains[n] * (1.0 + REFERENCE_SHORT_GAIN)
        sum_f += gains[2 * MODES_PER_GROUP + n]
    norm = 1.0 / max(sum_c, sum_f) if max(sum_c, sum_f) > 0.0 else 0.0
    for n in range(MODES_PER_GROUP):
        gains[MODES_PER_GROUP + n] = gains[n] * values[rows.short_cantilever_gain]
        gains[n] *= values[rows.full_cantilever_gain]
        gains[2 * MODES_PER_GROUP + n] *= values[rows.free_bar_gain]
    for i in range(N_MODES):
        gains[i] *= mode_mask[i]

    # Vibrato: every mode moves by the same factor (the bar keeps its ratios); the
    # loudest mode swings by vibrato_depth_hz, capped at VIBRATO_MAX_RELATIVE_DEPTH.
    factor = 1.0
    vibrato_rate = values[rows.vibrato_rate_hz]
    vibrato_depth = values[rows.vibrato_depth_hz]
    if vibrato_rate > 0.0 and vibrato_depth > 0.0:
        loudest = 0
        for i in range(N_MODES):
            if gains[i] > gains[loudest]:
                loudest = i
        if gains[loudest] > 0.0:
            rel = min(vibrato_depth / freqs[loudest], VIBRATO_MAX_RELATIVE_DEPTH)
            rel *= min(1.0, vibrato_rate / VIBRATO_FADE_RATE_HZ)
            factor = 1.0 + rel * lfo_sin
    u = time_s / values[rows.slide_time_s]
    rise = 0.0 if u <= 0.0 else (1.0 if u >= 1.0 else u * u * (3.0 - 2.0 * u))  # smoothstep
    slide = 1.0 + SLIDE_RISE * values[rows.slide] * rise
    phasor_hz = freqs[0] * factor
    for i in range(N_MODES):
        f = freqs[i] * factor
        if MODES_PER_GROUP <= i < 2 * MODES_PER_GROUP:
            f *= slide
        freqs[i] = f
        # Never alias: fade out over the top NYQUIST_TAPER below Nyquist, silent above.
        edge = (nyquist - f) / (NYQUIST_TAPER * nyquist)
        if edge <= 0.0:
            gains[i] = 0.0
        elif edge < 1.0:
            gains[i] *= edge
        if i >= 2 * MODES_PER_GROUP:
            # A band-pass that low and narrow only stores energy: fade it out.
            low = (f - MIN_BAND_HZ) / (0.5 * MIN_BAND_HZ)
            if low <= 0.0:
                gains[i] = 0.0
            elif low < 1.0:
                gains[i] *= low
    return phasor_hz, norm


@register_jitable(**JITABLE)
def bandpass(centre_hz, band_q, sample_rate, coef, b):
    """Band ``b``'s coefficients into ``coef[:, b]``: (b0 of the first section, a1, a2, b0
    of the second) of two identical RBJ constant-peak band-pass sections (b1 = 0, b2 = -b0).

    Two identical sections in cascade have an equivalent noise bandwidth of
    (pi/4) centre/Q; the first section's input is scaled so white noise keeps its
    power. Scaling at the input keeps both sections' states of order one for any
    centre and Q, so sweeping a band never releases stored energy at a high gain.

    The banded model's loop band-pass (``banded.design._band_pass``) is the same RBJ
    section, but not shared: it divides by ``1 + alpha`` where this multiplies by its
    reciprocal, which differs in the last bit for 20-50 % of centres (b0, a1, a2), so
    either model would change its sounds.
    """
    w0 = 2.0 * math.pi * centre_hz / sample_rate
    alpha = math.sin(w0) / (2.0 * band_q)
    inv = 1.0 / (1.0 + alpha)
    enbw = 0.25 * math.pi * centre_hz / band_q
    coef[0, b] = alpha * inv * math.sqrt(0.5 * sample_rate / max(enbw, 1e-9))  # b0, first
    coef[1, b] = -2.0 * math.cos(w0) * inv  # a1
    coef[2, b] = (1.0 - alpha) * inv  # a2
    coef[3, b] = alpha * inv  # b0, second


def design_modes(p: TwangParams, *, sample_rate: float) -> list[Mode]:
    """Every mode the twang synthesises at the trigger (vibrato and slide at rest), as
    (group, frequency in Hz, gain, T60 in s); modes silenced by Nyquist or by a zero group
    gain are left out."""
    modes = new_modes()
    design(control_vector(p), ROWS, mode_lambdas(), np.ones(N_MODES), float(sample_rate), 0.0, 0.0, modes)
    return [Mode(group=GROUPS[i // MODES_PER_GROUP], frequency_hz=float(modes.frequency_hz[i]),
                 gain=float(modes.gain[i]), t60_s=float(math.log(1000.0) / modes.alpha_per_s[i]))
            for i in range(N_MODES) if modes.gain[i] > 0.0]
