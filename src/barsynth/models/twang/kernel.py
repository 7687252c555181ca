"""The twang's numba kernel: control frames, the oscillator bank and the free-bar bands.

Selfridge et al., AES Convention Paper 10553, 2022. :func:`process` renders samples; its
state is five records (:class:`Setup`, :class:`Controls`, :class:`Note`,
:class:`Oscillators`, :class:`Bands`) that the voice allocates in ``prepare``.

Control work (parameter ramps, vibrato, slide, coefficient design) happens once per control
frame of ``frame_len`` samples, counted from the trigger or reset, so the output does not
depend on how the caller splits a render into blocks. Each control follows its target along
a :mod:`barsynth.dsp.smoothing` ramp of ``ramp_frames`` frames (multiplicative for the
log-scaled rows, linear for the others). Inside a frame every oscillator is a rotating
complex phasor ``z_k = z_0 (r e^{jw})^k`` (equal to ``r^k cos(2 pi phase)`` of the paper's
phasor -> cosine, to rounding); the powers are tabulated once per design, so a frame of the
oscillator bank is a matrix-vector product, and ``z`` advances once per frame. Gains ramp
linearly inside a frame, so a parameter change never steps the output. Modes that have
decayed below ``CULL_LEVEL`` are skipped.

Two kernels, for the compile time of a first render after an install (measured in
benchmarks/startup.py). :func:`process` compiled with ``modes`` None is the *static* kernel,
for a note whose design stays the trigger's (no vibrato, no slide, no parameter change: a
plain render). Numba prunes the ramps and the design from it before typing them, and the
gain ramps from ``_render`` and the bands (``ramps`` None); the voice designs such a note
once, at its first render, through the plain Python of :func:`~.design.design` and
:func:`_control` (:func:`design_note`: the same doubles). It compiles in half the time of
the *dynamic* kernel (``modes`` a record), which does everything; a voice switches to that
one, for good, at its first parameter change or at a trigger of a note that moves.

Only :func:`process` is cached and called from Python; the functions it calls have no
wrappers (``_INNER``) and it calls every one of them itself: numba links a callee's code into
its caller's module and optimises and emits it again there, so a deeper call tree compiles
the same code once per level. The frame start (tables, LFO, cull) and end are written into
:func:`process`: as functions, even numba-inlined ones (``inline="always"``), they compile
slower; so do ``max()``, ``min()`` and ``int()`` (each compiles an overload), written out
here. ``settle`` (once a note) is NumPy.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numba.extending import register_jitable

from ...dsp.noise import uniform_noise
from ...dsp.smoothing import CURRENT, LEFT, TARGET, next_value, start_ramp
from .design import JITABLE, MODES_PER_GROUP, N_BANDS, N_OSC, bandpass, design
from .table import Rows


class Setup(NamedTuple):
    """What ``prepare`` fixes."""

    sample_rate: float  # Hz
    frame_len: int  # samples per control frame
    ramp_frames: int  # control frames per parameter ramp
    lambdas: np.ndarray  # 6 clamped-free, then 6 free-free eigenvalues
    mode_mask: np.ndarray  # 18 values: 1 sounds, 0 mutes
    rows: Rows  # each parameter's slot in the control vectors


class Controls(NamedTuple):
    """The parameters as control vectors (slots: :data:`~.table.ROWS`)."""

    values: np.ndarray  # in force: where each ramp is
    target: np.ndarray  # the voice's current parameters
    ramps: np.ndarray  # (slots, SMOOTHED_STATE): each slot's ramp
    kinds: np.ndarray  # each slot's ramp: smoothing.LINEAR or MULTIPLICATIVE (int64)


class Note(NamedTuple):
    """The note's clock and its noise drive."""

    scalars: np.ndarray  # the slots S (below)
    rng: np.ndarray  # the noise generator (dsp.noise)
    diff: np.ndarray  # frame_len scratch: low-passed noise x[n] - x[n-2], the bands' input
    counts: np.ndarray  # oscillators and bands computed this frame (int64)


class Oscillators(NamedTuple):
    """The 12 cantilever modes as rotating phasors."""

    z: np.ndarray  # (2, N_OSC): re, im at the frame start
    step: np.ndarray  # (2, N_OSC): r e^{jw}, re and im (one sample's rotation and decay)
    powers: np.ndarray  # (2, N_OSC, frame_len + 1): step^k, re and im
    gain: np.ndarray  # (3, N_OSC): at the frame start, step per sample, target
    active: np.ndarray  # (N_OSC,) int64: those computed this frame, first counts[0]


class Bands(NamedTuple):
    """The 6 free-bar modes: 4th-order band-passes with their decay envelopes."""

    state: np.ndarray  # (4, N_BANDS): y1, y2 of the first section, y1, y2 of the second
    coef: np.ndarray  # (4, N_BANDS): see design.bandpass
    env: np.ndarray  # (N_BANDS,): decay envelope at the frame start
    decay: np.ndarray  # (N_BANDS,): r, the envelope's factor per sample
    powers: np.ndarray  # (N_BANDS, frame_len + 1): r^k
    gain: np.ndarray  # (3, N_BANDS): at the frame start, step per sample, target
    active: np.ndarray  # (N_BANDS,) int64: those computed this frame, first counts[1]


# -- the note's scalar slots ----------------------------------------------------------------
class Scalars(NamedTuple):
    """The slots of ``Note.scalars`` (:data:`S`: each name's index, from this one list)."""

    phase: int  # drive phasor at the full-length fundamental, [0, 1)
    phase_inc: int
    lowpass: int  # one-pole low-pass state
    lowpass_k: int
    time: int  # samples since the trigger (float)
    frame_pos: int  # position inside the current control frame
    lfo_phase: int
    force: int  # 1 -> design at the next frame start even if nothing moves, gains jump
    dynamic: int  # 1 while the last design is still in force with ramps to finish
    tables: int  # 1 -> _control set new steps: tabulate their powers at this frame start
    x1: int  # low-passed noise one and two samples back (band-pass input history)
    x2: int


S = Scalars(*range(len(Scalars._fields)))
"""Each scalar's slot by name (``scal[S.phase]``)."""
N_SCALARS = len(S)

# Per-sample loops may fuse a*b+c into one FMA instruction (shorter recursion
# latency); nothing else of fast-math. The result is still deterministic.
_CONTRACT = {"contract"}
# The kernel's inner functions are only called from compiled code: no wrapper to call them
# from Python (nor a C one), and no cache of their own (process's cache holds them).
_INNER = {"nogil": True, "no_cpython_wrapper": True, "no_cfunc_wrapper": True}

CULL_LEVEL = 1e-7  # a mode whose output amplitude is below -140 dBFS is not computed
BAND_PEAK_FACTOR = 8.0  # bound on a band's output relative to its white-noise rms, for culling


def settle(controls):
    """Every control at its target now (a trigger, a reset): what ``start_ramp(ramp, kind,
    target, 0)`` does to every slot (the steps are left as they are), in NumPy: once a note,
    not worth a compiled function."""
    ramps = controls.ramps
    ramps[:, TARGET] = controls.target
    ramps[:, CURRENT] = controls.target
    ramps[:, LEFT] = 0.0
    controls.values[:] = controls.target


@njit(**_INNER)
def _follow(setup, controls, note):
    """Start of a control frame: one frame along every control's ramp (a new target starts
    a ramp from where the control is). Returns ``(design, time_s, lfo_sin)``: whether to
    design anew (anything moves, or the frame after), the time since the trigger and the
    vibrato's sine for :func:`~.design.design`."""
    sample_rate = setup.sample_rate
    rows = setup.rows
    params = controls.values
    scal = note.scalars
    moving = False
    for i in range(controls.values.size):
        ramp = controls.ramps[i]
        if controls.target[i] != ramp[TARGET]:
            start_ramp(ramp, controls.kinds[i], controls.target[i], setup.ramp_frames)
        value = next_value(ramp, controls.kinds[i])
        if value != controls.values[i] or ramp[LEFT] > 0.0:
            moving = True
        controls.values[i] = value
    time_s = scal[S.time] / sample_rate
    vibrato = params[rows.vibrato_rate_hz] > 0.0 and params[rows.vibrato_depth_hz] > 0.0
    sliding = params[rows.slide] > 0.0 and time_s <= params[rows.slide_time_s] + setup.frame_len / sample_rate
    force = scal[S.force] != 0.0
    dynamic = force or moving or vibrato or sliding
    if not dynamic and scal[S.dynamic] == 0.0:
        return False, time_s, 0.0  # nothing moves and the last design is the resting one
    # Design; a static frame right after a dynamic one designs once more, so the
    # resting state (vibrato off, slide finished, targets reached) is exact.
    scal[S.dynamic] = 1.0 if dynamic else 0.0
    lfo_sin = math.sin(2.0 * math.pi * scal[S.lfo_phase]) if vibrato else 0.0
    return True, time_s, lfo_sin


@register_jitable(**JITABLE)
def _control(setup, controls, note, modes, osc, bands, phasor_hz, norm):
    """After a design (``modes``, and :func:`~.design.design`'s ``phasor_hz`` and ``norm``):
    the oscillators' steps and the bands' coefficients, and their gains, for this frame;
    :func:`process` tabulates the steps' powers at the frame start (``S.tables``). Plain
    Python that numba compiles into the dynamic kernel (:func:`design_note` runs it as it is)."""
    sample_rate = setup.sample_rate
    frame_len = setup.frame_len
    rows = setup.rows
    params = controls.values
    scal = note.scalars
    force = scal[S.force] != 0.0
    freqs = modes.frequency_hz
    gains = modes.gain
    alphas = modes.alpha_per_s
    scal[S.phase_inc] = phasor_hz / sample_rate
    scal[S.lowpass_k] = 1.0 - math.exp(-2.0 * math.pi * params[rows.noise_cutoff_hz] / sample_rate)
    level = 10.0 ** (params[rows.level_db] / 20.0) * norm
    ramp = 1.0 / frame_len
    osc_step = osc.step
    osc_gain = osc.gain
    for j in range(N_OSC):
        r = math.exp(-alphas[j] / sample_rate)
        w = 2.0 * math.pi * freqs[j] / sample_rate
        osc_step[0, j] = r * math.cos(w)
        osc_step[1, j] = r * math.sin(w)
        g = gains[j] * level
        if force:
            osc_gain[0, j] = g
            osc_gain[1, j] = 0.0
        else:
            osc_gain[1, j] = (g - osc_gain[0, j]) * ramp
        osc_gain[2, j] = g
    band_gain = bands.gain
    for b in range(N_BANDS):
        k = 2 * MODES_PER_GROUP + b
        f = min(freqs[k], 0.499 * sample_rate)
        bandpass(f, params[rows.free_band_q], sample_rate, bands.coef, b)
        bands.decay[b] = math.exp(-alphas[k] / sample_rate)
        g = gains[k] * level
        if force:
            band_gain[0, b] = g
            band_gain[1, b] = 0.0
        else:
            band_gain[1, b] = (g - band_gain[0, b]) * ramp
        band_gain[2, b] = g
    scal[S.force] = 0.0
    scal[S.tables] = 1.0


def design_note(setup, controls, note, modes, osc, bands):
    """A static note's design, in Python, before the static kernel's first frame: what the
    dynamic kernel's first frame start after the trigger designs. The controls are settled
    (``settle``), so :func:`_follow` would move nothing, and design because of ``S.force``,
    with the vibrato's sine 0 (no vibrato); :func:`~.design.design` and :func:`_control` run
    as plain Python, with the same doubles as compiled (the same libm exp, log, log1p, sin,
    cos and pow; no fast-math there: tests/test_twang.py compares them).

    The frame after it would design the same again (``S.dynamic``): nothing moves, so
    every gain's step comes out 0.0 and every other value the same. That design is left
    out, and a voice may switch to the dynamic kernel at any frame with the same samples.
    """
    scal = note.scalars
    phasor_hz, norm = design(controls.values, setup.rows, setup.lambdas, setup.mode_mask, setup.sample_rate,
                             scal[S.time] / setup.sample_rate, 0.0, modes)
    _control(setup, controls, note, modes, osc, bands, phasor_hz, norm)
    scal[S.dynamic] = 0.0


@njit(cache=True, nogil=True, no_cfunc_wrapper=True)
def process(out, setup, controls, note, modes, osc, bands):
    """Render ``len(out)`` samples into ``out`` (float64), advancing every state record.

    Work is cut into control frames counted from the last trigger or reset; a call
    that ends inside a frame leaves ``S.frame_pos`` there and the next call goes
    on with exactly the same arithmetic, so block size never changes a sample.

    ``modes`` None compiles the static kernel, for a note whose design never changes after
    the trigger's (:func:`design_note`): no vibrato, no slide, no parameter change. Numba
    prunes :func:`_follow` and the design from it before typing them, and the gain ramps
    from ``_render`` and the bands (``ramps`` None), so it compiles in half the time.
    """
    n = out.shape[0]
    pos = np.int64(0)  # not the literal 0: _render is compiled once, for int64 (not also for Literal[int](0))
    frame_len = setup.frame_len
    lfo_step = frame_len / setup.sample_rate
    scal = note.scalars
    counts = note.counts
    z = osc.z
    osc_gain = osc.gain
    band_gain = bands.gain
    while pos < n:
        frame_pos = np.int64(scal[S.frame_pos])  # (int() would compile an overload)
        if frame_pos == 0:
            if modes is not None:
                redesign, time_s, lfo_sin = _follow(setup, controls, note)
                if redesign:
                    phasor_hz, norm = design(controls.values, setup.rows, setup.lambdas, setup.mode_mask,
                                             setup.sample_rate, time_s, lfo_sin, modes)
                    _control(setup, controls, note, modes, osc, bands, phasor_hz, norm)
            if scal[S.tables] != 0.0:  # a new design: the powers of its steps, k = 0 .. frame_len
                for j in range(N_OSC):
                    a = osc.step[0, j]
                    b = osc.step[1, j]
                    pr = 1.0
                    pi = 0.0
                    for k in range(frame_len + 1):
                        osc.powers[0, j, k] = pr
                        osc.powers[1, j, k] = pi
                        pr, pi = a * pr - b * pi, b * pr + a * pi
                for j in range(N_BANDS):
                    r = bands.decay[j]
                    e = 1.0
                    for k in range(frame_len + 1):
                        bands.powers[j, k] = e
                        e *= r
                scal[S.tables] = 0.0
            scal[S.lfo_phase] = (scal[S.lfo_phase] + controls.values[setup.rows.vibrato_rate_hz] * lfo_step) % 1.0
            # Cull: compute only the modes above CULL_LEVEL, at the larger of a gain's start
            # and target (written out: max() would compile an overload).
            n_osc = 0
            for j in range(N_OSC):
                g = osc_gain[2, j] if osc_gain[2, j] > osc_gain[0, j] else osc_gain[0, j]
                if math.sqrt(z[0, j] * z[0, j] + z[1, j] * z[1, j]) * g >= CULL_LEVEL:
                    osc.active[n_osc] = j
                    n_osc += 1
            n_bands = 0
            for j in range(N_BANDS):
                g = band_gain[2, j] if band_gain[2, j] > band_gain[0, j] else band_gain[0, j]
                if bands.env[j] * g * BAND_PEAK_FACTOR >= CULL_LEVEL:
                    bands.active[n_bands] = j
                    n_bands += 1
                else:  # not computed: start from rest if it comes back, never from stale state
                    bands.state[0, j] = 0.0
                    bands.state[1, j] = 0.0
                    bands.state[2, j] = 0.0
                    bands.state[3, j] = 0.0
            counts[0] = n_osc
            counts[1] = n_bands
        m = frame_len - frame_pos
        if n - pos < m:
            m = n - pos  # (min() would compile an overload)
        _render(out, pos, frame_pos, m, note, osc, modes)
        # The free-bar bands, two at a time (two independent recursions per loop keep the
        # FPU busy), on the noise _render left in note.diff.
        a = 0
        while a < counts[1]:
            if a + 1 < counts[1]:
                _band_pair(out, pos, note.diff, frame_pos, m, bands.active[a], bands.active[a + 1], bands, modes)
            else:
                _band(out, pos, note.diff, frame_pos, m, bands.active[a], bands, modes)
            a += 2
        frame_pos += m
        if frame_pos == frame_len:  # the frame's end: phasors and envelopes advance, ramps land
            for j in range(N_OSC):
                pr = osc.powers[0, j, frame_len]
                pi = osc.powers[1, j, frame_len]
                zr = z[0, j]
                zi = z[1, j]
                z[0, j] = zr * pr - zi * pi
                z[1, j] = zr * pi + zi * pr
                if osc_gain[1, j] != 0.0:
                    osc_gain[0, j] = osc_gain[2, j]
                    osc_gain[1, j] = 0.0
            for j in range(N_BANDS):
                bands.env[j] *= bands.powers[j, frame_len]
                if band_gain[1, j] != 0.0:
                    band_gain[0, j] = band_gain[2, j]
                    band_gain[1, j] = 0.0
            frame_pos = 0
        scal[S.frame_pos] = float(frame_pos)
        scal[S.time] += m
        pos += m


@njit(fastmath=_CONTRACT, **_INNER)
def _render(out, start, k0, m, note, osc, ramps):
    """Samples ``k0 .. k0+m-1`` of the current frame into ``out[start:start+m]``: the
    oscillators, and the free bar's noise into ``note.diff`` (:func:`process` runs the bands).
    ``ramps`` None (the static kernel: gains never ramp there) compiles without the ramps."""
    scal = note.scalars
    n_osc = note.counts[0]
    n_bands = note.counts[1]
    osc_z = osc.z
    osc_pow = osc.powers
    osc_gain = osc.gain
    osc_active = osc.active
    for i in range(m):
        out[start + i] = 0.0
    # Oscillator bank: out[k] += Re((g + k dg) z0 W[k]) -- a matrix-vector product.
    for a in range(n_osc):
        j = osc_active[a]
        zr = osc_z[0, j]
        zi = osc_z[1, j]
        g0 = osc_gain[0, j]
        dg = osc_gain[1, j]
        if ramps is None or dg == 0.0:
            cr = g0 * zr
            ci = g0 * zi
            for i in range(m):
                out[start + i] += cr * osc_pow[0, j, k0 + i] - ci * osc_pow[1, j, k0 + i]
        else:
            for i in range(m):
                g = g0 + (k0 + i) * dg
                out[start + i] += g * (zr * osc_pow[0, j, k0 + i] - zi * osc_pow[1, j, k0 + i])
    if n_bands == 0:
        return  # every band has died away: the noise is not needed
    # Free bar: noise x phasor^2 -> one-pole low-pass; the band-passes (direct form I,
    # b1 = 0, b2 = -b0) only need x[n] - x[n-2], kept in ``note.diff``.
    phase = scal[S.phase]
    inc = scal[S.phase_inc]
    lp = scal[S.lowpass]
    lpk = scal[S.lowpass_k]
    x1 = scal[S.x1]
    x2 = scal[S.x2]
    rng = note.rng
    state = rng[0]
    diff = note.diff
    for i in range(m):
        state, u = uniform_noise(state)
        lp += lpk * (u * phase * phase - lp)
        diff[i] = lp - x2
        x2 = x1
        x1 = lp
        phase += inc
        if phase >= 1.0:
            phase -= 1.0
    scal[S.phase] = phase
    scal[S.lowpass] = lp
    scal[S.x1] = x1
    scal[S.x2] = x2
    rng[0] = state


@njit(fastmath=_CONTRACT, **_INNER)
def _band(out, start, diff, k0, m, b, bands, ramps):
    """Band ``b`` (two direct-form-I sections of 2nd order) with its gain and decay, on the
    noise ``diff``, into ``out[start:start+m]`` (``ramps``: as for :func:`_render`)."""
    band_state, band_coef, band_pow, band_gain = bands.state, bands.coef, bands.powers, bands.gain
    b0a = band_coef[0, b]
    a1 = band_coef[1, b]
    a2 = band_coef[2, b]
    b0b = band_coef[3, b]
    ya1 = band_state[0, b]
    ya2 = band_state[1, b]
    yb1 = band_state[2, b]
    yb2 = band_state[3, b]
    env0 = bands.env[b]
    g0 = band_gain[0, b]
    dg = band_gain[1, b]
    if ramps is None or dg == 0.0:
        c = env0 * g0
        for i in range(m):
            ya = (b0a * diff[i] - a2 * ya2) - a1 * ya1
            yb = (b0b * (ya - ya2) - a2 * yb2) - a1 * yb1
            ya2 = ya1
            ya1 = ya
            yb2 = yb1
            yb1 = yb
            out[start + i] += yb * (c * band_pow[b, k0 + i])
    else:
        for i in range(m):
            ya = (b0a * diff[i] - a2 * ya2) - a1 * ya1
            yb = (b0b * (ya - ya2) - a2 * yb2) - a1 * yb1
            ya2 = ya1
            ya1 = ya
            yb2 = yb1
            yb1 = yb
            out[start + i] += yb * (env0 * band_pow[b, k0 + i]) * (g0 + (k0 + i) * dg)
    band_state[0, b] = ya1
    band_state[1, b] = ya2
    band_state[2, b] = yb1
    band_state[3, b] = yb2


@njit(fastmath=_CONTRACT, **_INNER)
def _band_pair(out, start, diff, k0, m, b, c, bands, ramps):
    """Two bands in one loop; the same arithmetic as :func:`_band` for each."""
    band_state, band_coef, band_pow, band_gain = bands.state, bands.coef, bands.powers, bands.gain
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
    penv = bands.env[b]
    qenv = bands.env[c]
    pg0 = band_gain[0, b]
    pdg = band_gain[1, b]
    qg0 = band_gain[0, c]
    qdg = band_gain[1, c]
    if ramps is None or (pdg == 0.0 and qdg == 0.0):
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
            out[start + i] += pyb * (pc * band_pow[b, k0 + i]) + qyb * (qc * band_pow[c, k0 + i])
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
            out[start + i] += (pyb * (penv * band_pow[b, k]) * (pg0 + k * pdg)
                       + qyb * (qenv * band_pow[c, k]) * (qg0 + k * qdg))
    band_state[0, b] = pya1
    band_state[1, b] = pya2
    band_state[2, b] = pyb1
    band_state[3, b] = pyb2
    band_state[0, c] = qya1
    band_state[1, c] = qya2
    band_state[2, c] = qyb1
    band_state[3, c] = qyb2
