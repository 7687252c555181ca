"""Numba kernels of the ruler twang (Selfridge et al., AES Convention Paper 10553, 2022).

Pure functions over plain arrays; the voice in :mod:`barsynth.models.twang` owns
the state. Two pieces:

* :func:`design` turns a parameter vector into the 18 modes (6 full-length
  cantilever, 6 short cantilever, 6 free-bar): frequency, gain and decay rate.
  ``describe`` and the voice both call it, so what is reported is what sounds.
* :func:`process` renders samples. Control work (parameter smoothing, vibrato,
  slide, coefficient design) happens once per control frame of ``frame_len``
  samples, counted from the voice's reset, so the output does not depend on how
  the caller splits a render into blocks. Inside a frame every oscillator is a
  rotating complex phasor ``z_k = z_0 (r e^{jw})^k`` (equal to ``r^k cos(2 pi phase)``
  of the paper's phasor -> cosine, to rounding); the powers are tabulated once per
  design, so a frame of the oscillator bank is a vectorised matrix-vector product,
  and ``z`` advances once per frame. Gains ramp linearly inside a frame, so a
  parameter change never steps the output. Modes that have decayed below
  ``CULL_LEVEL`` are skipped.

The index constants below follow the order of ``TWANG_TABLE`` in ``twang.py``;
``twang.py`` asserts that the two agree.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..dsp.noise import uniform_noise

# -- parameter vector layout (order of the twang parameter table) ----------------------
P_YOUNGS = 0
P_DENSITY = 1
P_LENGTH = 2
P_THICKNESS = 3
P_Q = 4
P_SHAPE = 5
P_GAIN_MAPPING = 6  # 0 = linear, 1 = logarithmic (smoothed: a cross-fade of the two)
P_VIB_RATE = 7
P_VIB_DEPTH = 8
P_SLIDE = 9  # 0 = off, 1 = on (smoothed)
P_SLIDE_TIME = 10
P_SHORT_RATIO = 11
P_FULL_GAIN = 12
P_SHORT_GAIN = 13
P_FREE_GAIN = 14
P_NOISE_CUTOFF = 15
P_BAND_Q = 16
P_LEVEL_DB = 17
N_PARAMS = 18

# -- fixed model constants (documented in the parameter table's notes) ------------------
MODES_PER_GROUP = 6
N_OSC = 2 * MODES_PER_GROUP  # full + short cantilever oscillators
N_BANDS = MODES_PER_GROUP  # free-bar band-pass filters
N_MODES = 3 * MODES_PER_GROUP
BETA_M = 4.0  # the paper's second beta shape parameter
LOG_MAP_FLOOR_HZ = 1.0  # log gain mapping: x = ln(f/1 Hz) / ln(nyquist/1 Hz)
NYQUIST_TAPER = 0.05  # gains fade to 0 over the top 5 % below Nyquist; silent at/above
VIBRATO_MAX_RELATIVE_DEPTH = 0.06  # cap: 6 % (about one semitone)
SLIDE_RISE = 0.35  # slide raises the short-cantilever modes by 35 %
VIBRATO_FADE_RATE_HZ = 0.5  # below this rate the vibrato depth fades to 0 (glides home)
MIN_BAND_HZ = 20.0  # free-bar bands fade out from 30 Hz to 20 Hz and are silent below
REFERENCE_SHORT_GAIN = 0.75  # the paper's short/full ratio, used by the level scale

# -- scalar state layout ------------------------------------------------------------------
S_PHASE = 0  # drive phasor at the full-length fundamental, [0, 1)
S_PHASE_INC = 1
S_LOWPASS = 2  # one-pole low-pass state
S_LOWPASS_K = 3
S_TIME = 4  # samples since the trigger (float)
S_FRAME_POS = 5  # position inside the current control frame
S_LFO_PHASE = 6
S_FORCE = 7  # 1 -> design at the next frame start even if nothing moves
S_DYNAMIC = 8  # 1 while the last design is still in force with ramps to finish
S_X1 = 9  # low-passed noise one and two samples back (band-pass input history)
S_X2 = 10
N_SCALARS = 11

# Per-sample loops may fuse a*b+c into one FMA instruction (shorter recursion
# latency); nothing else of fast-math. The result is still deterministic.
_CONTRACT = {"contract"}

CULL_LEVEL = 1e-7  # a mode whose output amplitude is below -140 dBFS is not computed
BAND_PEAK_FACTOR = 8.0  # bound on a band's output relative to its white-noise rms, for culling


@njit(cache=True, nogil=True)
def _smoothstep(u):
    if u <= 0.0:
        return 0.0
    if u >= 1.0:
        return 1.0
    return u * u * (3.0 - 2.0 * u)


@njit(cache=True, nogil=True)
def design(params, lambdas, mode_mask, sample_rate, time_s, lfo_sin, freqs, gains, alphas):
    """Fill ``freqs``, ``gains`` (linear) and ``alphas`` (1/s) for the 18 modes.

    ``lambdas`` holds the 6 cantilever then the 6 free-free eigenvalues;
    ``mode_mask`` (18 values, 1 = sound, 0 = mute) multiplies the gains. Modes are
    ordered full cantilever (0-5), short cantilever (6-11), free bar (12-17).
    ``time_s`` since the trigger drives the slide, ``lfo_sin`` in [-1, 1] the vibrato.
    Returns the drive-phasor frequency (the full-length fundamental, with vibrato) and
    the level scale ``1 / max(S_c, S_f)``: ``S_c`` the beta gains of the full-length
    modes times 1.75 (the paper's mix), ``S_f`` those of the free modes. It ignores
    the mix gains and the mask, so those act as true gains; with the paper's mix
    and ``S_c >= S_f`` a note's first sample is exactly the level.
    """
    nyquist = 0.5 * sample_rate
    wave_const = math.sqrt(params[P_YOUNGS] / params[P_DENSITY]) * params[P_THICKNESS] / math.sqrt(12.0)
    length = params[P_LENGTH]
    base = wave_const / (2.0 * math.pi * length * length)
    ratio = params[P_SHORT_RATIO]
    q = params[P_Q]
    shape = params[P_SHAPE]
    log_weight = params[P_GAIN_MAPPING]
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
    lin_lp = np.empty(N_MODES)
    log_lp = np.empty(N_MODES)
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
        gains[MODES_PER_GROUP + n] = gains[n] * params[P_SHORT_GAIN]
        gains[n] *= params[P_FULL_GAIN]
        gains[2 * MODES_PER_GROUP + n] *= params[P_FREE_GAIN]
    for i in range(N_MODES):
        gains[i] *= mode_mask[i]

    # Vibrato: every mode moves by the same factor (the bar keeps its ratios); the
    # loudest mode swings by vibrato_depth_hz, capped at VIBRATO_MAX_RELATIVE_DEPTH.
    factor = 1.0
    if params[P_VIB_RATE] > 0.0 and params[P_VIB_DEPTH] > 0.0:
        loudest = 0
        for i in range(N_MODES):
            if gains[i] > gains[loudest]:
                loudest = i
        if gains[loudest] > 0.0:
            rel = min(params[P_VIB_DEPTH] / freqs[loudest], VIBRATO_MAX_RELATIVE_DEPTH)
            rel *= min(1.0, params[P_VIB_RATE] / VIBRATO_FADE_RATE_HZ)
            factor = 1.0 + rel * lfo_sin
    slide = 1.0 + SLIDE_RISE * params[P_SLIDE] * _smoothstep(time_s / params[P_SLIDE_TIME])
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


@njit(cache=True, nogil=True)
def _bandpass(centre_hz, band_q, sample_rate, gains_out, b):
    """RBJ constant-peak band-pass section coefficients (b1 = 0, b2 = -b0).

    Two identical sections in cascade have an equivalent noise bandwidth of
    (pi/4) centre/Q; the first section's input is scaled so white noise keeps its
    power. Scaling at the input keeps both sections' states of order one for any
    centre and Q, so sweeping a band never releases stored energy at a high gain.
    """
    w0 = 2.0 * math.pi * centre_hz / sample_rate
    alpha = math.sin(w0) / (2.0 * band_q)
    inv = 1.0 / (1.0 + alpha)
    enbw = 0.25 * math.pi * centre_hz / band_q
    gains_out[0, b] = alpha * inv * math.sqrt(0.5 * sample_rate / max(enbw, 1e-9))  # b0, first
    gains_out[1, b] = -2.0 * math.cos(w0) * inv  # a1
    gains_out[2, b] = (1.0 - alpha) * inv  # a2
    gains_out[3, b] = alpha * inv  # b0, second



@njit(cache=True, nogil=True)
def _control(params, target, log_mask, smooth_k, lambdas, mode_mask, sample_rate, frame_len,
             scal, osc_pow, osc_gain, band_coef, band_pow, band_gain,
             freqs, gains, alphas):
    """Start of a control frame: smooth, and if anything moves, design anew."""
    converged = True
    for i in range(N_PARAMS):
        if params[i] != target[i]:
            if log_mask[i]:
                lt = math.log(target[i])
                v = math.exp(lt + (math.log(params[i]) - lt) * (1.0 - smooth_k))
            else:
                v = target[i] + (params[i] - target[i]) * (1.0 - smooth_k)
            if abs(v - target[i]) <= 1e-9 * max(abs(target[i]), 1e-12):
                v = target[i]
            else:
                converged = False
            params[i] = v
    time_s = scal[S_TIME] / sample_rate
    vibrato = params[P_VIB_RATE] > 0.0 and params[P_VIB_DEPTH] > 0.0
    sliding = params[P_SLIDE] > 0.0 and time_s <= params[P_SLIDE_TIME] + frame_len / sample_rate
    force = scal[S_FORCE] != 0.0
    dynamic = force or (not converged) or vibrato or sliding
    if not dynamic and scal[S_DYNAMIC] == 0.0:
        return  # nothing moves and the last design is the resting one
    # Design; a static frame right after a dynamic one designs once more, so the
    # resting state (vibrato off, slide finished, targets reached) is exact.
    scal[S_DYNAMIC] = 1.0 if dynamic else 0.0
    lfo_sin = math.sin(2.0 * math.pi * scal[S_LFO_PHASE]) if vibrato else 0.0
    phasor_hz, norm = design(params, lambdas, mode_mask, sample_rate, time_s, lfo_sin,
                             freqs, gains, alphas)
    scal[S_PHASE_INC] = phasor_hz / sample_rate
    scal[S_LOWPASS_K] = 1.0 - math.exp(-2.0 * math.pi * params[P_NOISE_CUTOFF] / sample_rate)
    level = 10.0 ** (params[P_LEVEL_DB] / 20.0) * norm
    ramp = 1.0 / frame_len
    for j in range(N_OSC):
        r = math.exp(-alphas[j] / sample_rate)
        w = 2.0 * math.pi * freqs[j] / sample_rate
        a = r * math.cos(w)
        b = r * math.sin(w)
        # powers (r e^{jw})^k, k = 0 .. frame_len (the last advances z by a frame)
        pr = 1.0
        pi = 0.0
        for k in range(frame_len + 1):
            osc_pow[0, j, k] = pr
            osc_pow[1, j, k] = pi
            pr, pi = a * pr - b * pi, b * pr + a * pi
        g = gains[j] * level
        if force:
            osc_gain[0, j] = g
            osc_gain[1, j] = 0.0
        else:
            osc_gain[1, j] = (g - osc_gain[0, j]) * ramp
        osc_gain[2, j] = g
    for b in range(N_BANDS):
        k = 2 * MODES_PER_GROUP + b
        f = min(freqs[k], 0.499 * sample_rate)
        _bandpass(f, params[P_BAND_Q], sample_rate, band_coef, b)
        r = math.exp(-alphas[k] / sample_rate)
        e = 1.0
        for i in range(frame_len + 1):
            band_pow[b, i] = e
            e *= r
        g = gains[k] * level
        if force:
            band_gain[0, b] = g
            band_gain[1, b] = 0.0
        else:
            band_gain[1, b] = (g - band_gain[0, b]) * ramp
        band_gain[2, b] = g
    scal[S_FORCE] = 0.0


@njit(cache=True, nogil=True)
def _cull(scal, osc_z, osc_gain, band_env, band_gain, band_state, osc_active, band_active):
    """Choose the modes worth computing this frame; returns (n_osc, n_bands)."""
    n_osc = 0
    for j in range(N_OSC):
        amp = math.sqrt(osc_z[0, j] ** 2 + osc_z[1, j] ** 2)
        if amp * max(osc_gain[0, j], osc_gain[2, j]) >= CULL_LEVEL:
            osc_active[n_osc] = j
            n_osc += 1
    n_bands = 0
    for b in range(N_BANDS):
        if band_env[b] * max(band_gain[0, b], band_gain[2, b]) * BAND_PEAK_FACTOR >= CULL_LEVEL:
            band_active[n_bands] = b
            n_bands += 1
        else:  # not computed: start from rest if it comes back, never from stale state
            band_state[0, b] = 0.0
            band_state[1, b] = 0.0
            band_state[2, b] = 0.0
            band_state[3, b] = 0.0
    return n_osc, n_bands


@njit(cache=True, nogil=True)
def process(out, params, target, log_mask, smooth_k, lambdas, mode_mask, sample_rate, frame_len,
            scal, rng, osc_z, osc_pow, osc_gain, band_state, band_coef, band_env,
            band_pow, band_gain, freqs, gains, alphas, excitation, osc_active, band_active,
            counts):
    """Render ``len(out)`` samples into ``out`` (float64), advancing every state array.

    Work is cut into control frames counted from the last trigger or reset; a call
    that ends inside a frame leaves ``S_FRAME_POS`` there and the next call goes
    on with exactly the same arithmetic, so block size never changes a sample.
    """
    n = out.shape[0]
    pos = 0
    lfo_step = frame_len / sample_rate
    while pos < n:
        frame_pos = int(scal[S_FRAME_POS])
        if frame_pos == 0:
            _control(params, target, log_mask, smooth_k, lambdas, mode_mask, sample_rate, frame_len,
                     scal, osc_pow, osc_gain, band_coef, band_pow, band_gain,
                     freqs, gains, alphas)
            scal[S_LFO_PHASE] = (scal[S_LFO_PHASE] + params[P_VIB_RATE] * lfo_step) % 1.0
            counts[0], counts[1] = _cull(scal, osc_z, osc_gain, band_env, band_gain, band_state,
                                         osc_active, band_active)
        m = min(n - pos, frame_len - frame_pos)
        _render(out, pos, frame_pos, m, scal, rng, osc_z, osc_pow, osc_gain, band_state,
                band_coef, band_env, band_pow, band_gain, excitation, osc_active,
                band_active, counts[0], counts[1])
        frame_pos += m
        if frame_pos == frame_len:
            _end_frame(frame_len, osc_z, osc_pow, osc_gain, band_env, band_pow, band_gain)
            frame_pos = 0
        scal[S_FRAME_POS] = float(frame_pos)
        scal[S_TIME] += m
        pos += m


@njit(cache=True, nogil=True)
def _end_frame(frame_len, osc_z, osc_pow, osc_gain, band_env, band_pow, band_gain):
    """Advance phasors and envelopes by one frame; ramps land on their targets."""
    for j in range(N_OSC):
        pr = osc_pow[0, j, frame_len]
        pi = osc_pow[1, j, frame_len]
        zr = osc_z[0, j]
        zi = osc_z[1, j]
        osc_z[0, j] = zr * pr - zi * pi
        osc_z[1, j] = zr * pi + zi * pr
        if osc_gain[1, j] != 0.0:
            osc_gain[0, j] = osc_gain[2, j]
            osc_gain[1, j] = 0.0
    for b in range(N_BANDS):
        band_env[b] *= band_pow[b, frame_len]
        if band_gain[1, b] != 0.0:
            band_gain[0, b] = band_gain[2, b]
            band_gain[1, b] = 0.0


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def _render(out, start, k0, m, scal, rng, osc_z, osc_pow, osc_gain, band_state, band_coef,
            band_env, band_pow, band_gain, excitation, osc_active, band_active, n_osc, n_bands):
    """Samples ``k0 .. k0+m-1`` of the current frame into ``out[start:start+m]``."""
    dst = out[start:start + m]
    dst[:] = 0.0
    # Oscillator bank: out[k] += Re((g + k dg) z0 W[k]) -- a matrix-vector product.
    for a in range(n_osc):
        j = osc_active[a]
        zr = osc_z[0, j]
        zi = osc_z[1, j]
        g0 = osc_gain[0, j]
        dg = osc_gain[1, j]
        wr = osc_pow[0, j, k0:k0 + m]
        wi = osc_pow[1, j, k0:k0 + m]
        if dg == 0.0:
            cr = g0 * zr
            ci = g0 * zi
            for i in range(m):
                dst[i] += cr * wr[i] - ci * wi[i]
        else:
            for i in range(m):
                g = g0 + (k0 + i) * dg
                dst[i] += g * (zr * wr[i] - zi * wi[i])
    if n_bands == 0:
        return  # every band has died away: the noise is not needed
    # Free bar: noise x phasor^2 -> one-pole low-pass; the band-passes (direct form I,
    # b1 = 0, b2 = -b0) only need x[n] - x[n-2], kept in ``excitation``.
    phase = scal[S_PHASE]
    inc = scal[S_PHASE_INC]
    lp = scal[S_LOWPASS]
    lpk = scal[S_LOWPASS_K]
    x1 = scal[S_X1]
    x2 = scal[S_X2]
    state = rng[0]
    diff = excitation[:m]
    for i in range(m):
        state, u = uniform_noise(state)
        lp += lpk * (u * phase * phase - lp)
        diff[i] = lp - x2
        x2 = x1
        x1 = lp
        phase += inc
        if phase >= 1.0:
            phase -= 1.0
    scal[S_PHASE] = phase
    scal[S_LOWPASS] = lp
    scal[S_X1] = x1
    scal[S_X2] = x2
    rng[0] = state
    # Bands two at a time: two independent recursions per loop keep the FPU busy.
    a = 0
    while a < n_bands:
        b = band_active[a]
        c = band_active[a + 1] if a + 1 < n_bands else -1
        if c < 0:
            _band(dst, diff, k0, m, b, band_state, band_coef, band_env, band_pow, band_gain)
        else:
            _band_pair(dst, diff, k0, m, b, c, band_state, band_coef, band_env,
                       band_pow, band_gain)
        a += 2


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def _band(dst, diff, k0, m, b, band_state, band_coef, band_env, band_pow, band_gain):
    """One 4th-order band (two direct-form-I sections) with its gain and decay."""
    b0a = band_coef[0, b]
    a1 = band_coef[1, b]
    a2 = band_coef[2, b]
    b0b = band_coef[3, b]
    ya1 = band_state[0, b]
    ya2 = band_state[1, b]
    yb1 = band_state[2, b]
    yb2 = band_state[3, b]
    env0 = band_env[b]
    g0 = band_gain[0, b]
    dg = band_gain[1, b]
    epow = band_pow[b, k0:k0 + m]
    if dg == 0.0:
        c = env0 * g0
        for i in range(m):
            ya = (b0a * diff[i] - a2 * ya2) - a1 * ya1
            yb = (b0b * (ya - ya2) - a2 * yb2) - a1 * yb1
            ya2 = ya1
            ya1 = ya
            yb2 = yb1
            yb1 = yb
            dst[i] += yb * (c * epow[i])
    else:
        for i in range(m):
            ya = (b0a * diff[i] - a2 * ya2) - a1 * ya1
            yb = (b0b * (ya - ya2) - a2 * yb2) - a1 * yb1
            ya2 = ya1
            ya1 = ya
            yb2 = yb1
            yb1 = yb
            dst[i] += yb * (env0 * epow[i]) * (g0 + (k0 + i) * dg)
    band_state[0, b] = ya1
    band_state[1, b] = ya2
    band_state[2, b] = yb1
    band_state[3, b] = yb2


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def _band_pair(dst, diff, k0, m, b, c, band_state, band_coef, band_env, band_pow,
               band_gain):
    """Two bands in one loop; the same arithmetic as :func:`_band` for each."""
    pb0a = band_coef[0, b]
    pa1 = band_coef[1, b]
    pa2 = band_coef[2, b]
    pb0b = band_coef[3, b]
    qb0a = band_coef[0, c]
    qa1 = band_coef[1, c]
    qa2 = band_coef[2, c]
    qb0b = band_coef[3, c]
    pya1 = band_state[0, b]
    pya2 = band_state[1, b]
    pyb1 = band_state[2, b]
    pyb2 = band_state[3, b]
    qya1 = band_state[0, c]
    qya2 = band_state[1, c]
    qyb1 = band_state[2, c]
    qyb2 = band_state[3, c]
    penv = band_env[b]
    qenv = band_env[c]
    pg0 = band_gain[0, b]
    pdg = band_gain[1, b]
    qg0 = band_gain[0, c]
    qdg = band_gain[1, c]
    ppow = band_pow[b, k0:k0 + m]
    qpow = band_pow[c, k0:k0 + m]
    if pdg == 0.0 and qdg == 0.0:
        pc = penv * pg0
        qc = qenv * qg0
        for i in range(m):
            d = diff[i]
            pya = (pb0a * d - pa2 * pya2) - pa1 * pya1
            qya = (qb0a * d - qa2 * qya2) - qa1 * qya1
            pyb = (pb0b * (pya - pya2) - pa2 * pyb2) - pa1 * pyb1
            qyb = (qb0b * (qya - qya2) - qa2 * qyb2) - qa1 * qyb1
            pya2 = pya1
            pya1 = pya
            pyb2 = pyb1
            pyb1 = pyb
            qya2 = qya1
            qya1 = qya
            qyb2 = qyb1
            qyb1 = qyb
            dst[i] += pyb * (pc * ppow[i]) + qyb * (qc * qpow[i])
    else:
        for i in range(m):
            d = diff[i]
            pya = (pb0a * d - pa2 * pya2) - pa1 * pya1
            qya = (qb0a * d - qa2 * qya2) - qa1 * qya1
            pyb = (pb0b * (pya - pya2) - pa2 * pyb2) - pa1 * pyb1
            qyb = (qb0b * (qya - qya2) - qa2 * qyb2) - qa1 * qyb1
            pya2 = pya1
            pya1 = pya
            pyb2 = pyb1
            pyb1 = pyb
            qya2 = qya1
            qya1 = qya
            qyb2 = qyb1
            qyb1 = qyb
            k = k0 + i
            dst[i] += (pyb * (penv * ppow[i]) * (pg0 + k * pdg)
                       + qyb * (qenv * qpow[i]) * (qg0 + k * qdg))
    band_state[0, b] = pya1
    band_state[1, b] = pya2
    band_state[2, b] = pyb1
    band_state[3, b] = pyb2
    band_state[0, c] = qya1
    band_state[1, c] = qya2
    band_state[2, c] = qyb1
    band_state[3, c] = qyb2
