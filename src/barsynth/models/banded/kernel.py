"""Numba kernels of a bank of banded-waveguide loops, one loop per mode.

Source: G. Essl and P. R. Cook, "Banded waveguides: towards physical modeling of bowed bar
percussion instruments", Proc. ICMC 1999 (barsynth spec 3.1). Each loop is designed by
:func:`barsynth.models.banded.design.design_loop`. Per sample and band:

    d  = buffer[t - M]                       (the band-pass output M samples ago)
    ap = eta (d - ap[-1]) + d[-1]            (first-order Thiran all-pass)
    v  = force_in * force + g * ap
    bp = b0 (v - v[-2]) - a1 bp[-1] - a2 bp[-2]
    buffer[t] = bp;  out += out_weight * ap

and the sum is then multiplied by the level (an output gain that glides: a
:mod:`barsynth.dsp.smoothing` state, stepped a sample at a time).

The loops are a structured array, one :data:`LOOP` record per loop (from design.py); what
they carry between blocks is a :class:`LoopState` (one :data:`FILTER` record per loop, the
delay lines, the write position, and the bowed kernel's work space), so blocks of any size
give the same samples as one long block. Everything is allocated outside the kernels: a
block allocates nothing. The kernels take the state as one record; numba's dispatcher would
type that record in Python at every call (about 1 us), so the voice calls the compiled
overloads' entry points (:func:`barsynth.jitstart.compiled_for`).

With a bow (:func:`process_bowed`) the bands are coupled through the friction at the bow
point, one sample at a time: every band's all-pass output (which depends only on the past)
gives the bar's velocity at the bow, the bow table (:mod:`barsynth.dsp.friction`) gives the
force, and that force enters every band.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ...dsp.bow_stroke import FORCE, PRESSURE, SPEED, VELOCITY, held_until, line_value
from ...dsp.friction import friction_given_width, stick_width
from ...dsp.smoothing import MULTIPLICATIVE, scale

LOOP = np.dtype([
    ("b0", "f8"), ("a1", "f8"), ("a2", "f8"),  # band-pass y = b0 (v - v[-2]) - a1 y[-1] - a2 y[-2]
    ("eta", "f8"),  # all-pass coefficient
    ("gain", "f8"),  # loop gain g
    ("delay", "i8"),  # integer delay M (samples)
    ("force_in", "f8"),  # weight of the force (N): input scale x mode shape at the strike point / (fs x mass)
    ("bow_in", "f8"),  # weight of the bow's friction force: as force_in, with the mode shape at the bow
    ("bow_at", "f8"),  # mode shape at the bow: the bar's velocity there is sum(bow_at x ap)
    ("out", "f8"),  # output weight: mode shape at the pick-up (the level is the voice's output gain)
    ("mouth", "f8"),  # weight in the drive of a tube: mode shape at its mouth (resonator.py)
])
"""One loop's coefficients."""

FILTER = np.dtype([
    ("v1", "f8"), ("v2", "f8"),  # band-pass input one and two samples ago
    ("y1", "f8"), ("y2", "f8"),  # band-pass output one and two samples ago
    ("ap_x", "f8"), ("ap_y", "f8"),  # all-pass input and output one sample ago
])
"""One loop's filter states."""

CHUNK = 64
"""The most samples the bowed kernel runs as one chunk (fewer when a delay is shorter)."""

TINY = 1e-30
"""A loop whose every state and delayed value is below this (600 dB below full scale) has died
away: :func:`_flush_if_silent` sets it to exactly 0."""
FLUSH_PERIOD = 4096
"""The kernels look for loops that have died away at every multiple of this many samples from
the voice's reset (the same indices whatever the blocks: a power of two)."""


class LoopState(NamedTuple):
    """What a bank of loops carries from one block to the next."""

    filters: np.ndarray
    """(loops,) of :data:`FILTER`."""
    buffers: np.ndarray
    """(loops, 2^k) delay lines of band-pass outputs, 2^k > every delay + 1."""
    position: np.ndarray
    """(1,) int64: the write index into ``buffers``."""
    work: np.ndarray
    """(loops + 5, CHUNK): :func:`process_bowed`'s work space: all-pass outputs, friction, force,
    and the loops' ``bow_at``, ``out`` and ``mouth`` weights side by side (read every sample)."""


def empty_state(bands: int, longest_delay: int) -> LoopState:
    """Silent loops: zeroed lines and filters for ``bands`` loops, delays up to ``longest_delay``."""
    size = 1 << max(4, int(longest_delay + 2).bit_length())
    return LoopState(np.zeros(bands, dtype=FILTER), np.zeros((bands, size)), np.zeros(1, dtype=np.int64),
                     np.zeros((bands + 5, max(CHUNK, bands))))


def silence(state: LoopState) -> None:
    """Empty ``state`` in place, as :func:`empty_state` makes it: every filter, delay line and
    the work space at zero, the write index at 0."""
    state.filters[:] = 0
    state.buffers[:] = 0.0
    state.position[:] = 0
    state.work[:] = 0.0


def carried_over(state: LoopState, old_rows: np.ndarray, rows: np.ndarray, longest_delay: int) -> LoopState:
    """New loops for a changed set of modes (``rows``: the mode of each new loop, ``old_rows``
    of each old one): a mode that stays keeps its filters and its recent past, so what rings
    keeps ringing; a new mode starts silent."""
    new = empty_state(len(rows), longest_delay)
    old_mask, mask = state.buffers.shape[1] - 1, new.buffers.shape[1] - 1
    ages = np.arange(1, min(state.buffers.shape[1], new.buffers.shape[1]))  # samples ago
    for row, mode in enumerate(rows):
        found = np.flatnonzero(old_rows == mode)
        if found.size:
            old = found[0]
            new.buffers[row, (new.position[0] - ages) & mask] = state.buffers[old, (state.position[0] - ages) & old_mask]
            new.filters[row] = state.filters[old]
    return new


@njit(nogil=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _silent(v1, v2, y1, y2, ap_x, ap_y, buffers, k):  # pragma: no cover - compiled
    """Whether loop ``k`` has died away: its filter states (given) and its whole delay line below
    ``TINY``; if so its delay line is set to 0 (the caller zeroes the states).

    A loop that has died away decays geometrically through tiny and then subnormal numbers,
    whose arithmetic is many times slower: a silent 4-mode bar took 37 ms a second of sound
    after a minute, against 0.4 ms. A test in the recursions themselves cost a third of their
    speed; this one runs every ``FLUSH_PERIOD`` samples and reads the delay line only once the
    states are quiet. 600 dB below full scale, nothing audible changes."""
    if (abs(v1) >= TINY or abs(v2) >= TINY or abs(y1) >= TINY or abs(y2) >= TINY or abs(ap_x) >= TINY
            or abs(ap_y) >= TINY):
        return False
    row = buffers[k]
    for i in range(row.size):
        if abs(row[i]) >= TINY:
            return False
    row[:] = 0.0
    return True


@njit(cache=True, nogil=True, fastmath={"contract"})
def process(out, drive, pending, held, loops, state, level, start):  # pragma: no cover - compiled
    """Run the bank for ``out.size`` samples driven by a force (N): ``pending[t]`` for the
    first ``pending.size`` samples, then ``held``. ``loops``: :data:`LOOP` records;
    ``state``: the :class:`LoopState`, updated; ``level``: the output gain, a multiplicative
    :mod:`barsynth.dsp.smoothing` state (stepped a sample at a time, so the sum is exactly
    the loops' for a gain held at 1); ``start``: the sample index of ``out[0]`` counted from the
    reset (a loop that has died away is set to 0 at every ``FLUSH_PERIOD`` of it). ``drive``:
    empty, or ``out.size`` samples that get the loops' all-pass outputs weighted by their
    ``mouth`` (the bar's velocity at a tube's mouth; not scaled by the level).

    With a force known in advance the bands do not interact, so they run two at a time over
    the whole block with their states in registers (measured: twice as fast as all bands per
    sample for a 12-mode bowl).
    """
    filters, buffers, position = state.filters, state.buffers, state.position
    bands = loops.shape[0]
    mask = buffers.shape[1] - 1
    first = position[0]
    n = out.size
    n_pending = min(n, pending.size)
    out[:] = 0.0
    mouthing = drive.size > 0
    if mouthing:
        drive[:] = 0.0
    for k in range(0, bands, 2):
        j = min(k + 1, bands - 1)  # an odd last band runs beside itself, silently
        on = 1.0 if k + 1 < bands else 0.0
        la, lb, fa, fb = loops[k], loops[j], filters[k], filters[j]
        b0a, a1a, a2a, eta_a, ga, ina, outa = la.b0, la.a1, la.a2, la.eta, la.gain, la.force_in, la.out
        b0b, a1b, a2b, eta_b, gb, inb, outb = lb.b0, lb.a1, lb.a2, lb.eta, lb.gain, lb.force_in * on, lb.out * on
        mouth_a, mouth_b = la.mouth, lb.mouth * on
        ma, mb = la.delay, lb.delay
        v1a, v2a, y1a, y2a, xa, apa = fa.v1, fa.v2, fa.y1, fa.y2, fa.ap_x, fa.ap_y
        v1b, v2b, y1b, y2b, xb, apb = fb.v1, fb.v2, fb.y1, fb.y2, fb.ap_x, fb.ap_y
        pos = first
        t0 = 0
        while t0 < n:  # segments that end where a loop may be flushed
            t1 = min(n, t0 + FLUSH_PERIOD - ((start + t0) & (FLUSH_PERIOD - 1)))
            for t in range(t0, t1):
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
                if mouthing:
                    drive[t] += mouth_a * apa + mouth_b * apb
                pos = (pos + 1) & mask
            if ((start + t1) & (FLUSH_PERIOD - 1)) == 0:
                if _silent(v1a, v2a, y1a, y2a, xa, apa, buffers, k):
                    v1a = v2a = y1a = y2a = xa = apa = 0.0
                if on > 0.0 and _silent(v1b, v2b, y1b, y2b, xb, apb, buffers, j):
                    v1b = v2b = y1b = y2b = xb = apb = 0.0
            t0 = t1
        fa.v1, fa.v2, fa.y1, fa.y2, fa.ap_x, fa.ap_y = v1a, v2a, y1a, y2a, xa, apa
        if on > 0.0:
            fb.v1, fb.v2, fb.y1, fb.y2, fb.ap_x, fb.ap_y = v1b, v2b, y1b, y2b, xb, apb
    position[0] = (first + n) & mask
    scale(out, level, MULTIPLICATIVE)


@njit(cache=True, nogil=True, fastmath={"contract"})
def process_bowed(out, drive, pending, held_force, lines, start, loops, state, level):  # pragma: no cover
    """As :func:`process` (``held_force`` is its ``held``; ``drive`` the same), with a bow as well, whose controls
    are the breakpoint ``lines`` of :class:`barsynth.dsp.bow_stroke.BowControls`; ``start`` is
    the absolute sample index of ``out[0]``; the state's ``work`` is the work space. The bow's
    velocity is speed x velocity (m/s), its force pressure x force (N).

    The bar's velocity at the bow, ``v = sum(bow_at ap)``, is known before this sample's
    force, so the friction ``bow_friction(v_bow - v, F)`` is explicit: no delay-free loop, no
    iteration. And a force reaches any all-pass output only ``min(delay)`` samples later, so
    the samples go in chunks that long (at most ``CHUNK``): all bands' all-pass outputs for the
    chunk (one band at a time, states in registers), then the bar's velocity and the friction
    per sample, then all bands' band-passes. The bow's controls are read once a chunk while
    they hold still. Each sample's arithmetic is the same whatever the chunk, so any block
    size gives the same samples. (Measured on 10 s of the 4-mode bar: 12.7 ms, against 20 ms
    for all bands sample by sample with the controls read per sample.)
    """
    filters, buffers, position, work = state.filters, state.buffers, state.position, state.work
    mask = buffers.shape[1] - 1
    pos = position[0]
    n = out.size
    n_pending = min(n, pending.size)
    bands = loops.shape[0]
    chunk = CHUNK
    for k in range(bands):
        chunk = min(chunk, loops[k].delay)
    chunk = max(1, chunk)
    ap_out, friction, force_in = work[:bands], work[bands], work[bands + 1]
    bow_at, out_weight, mouth = work[bands + 2], work[bands + 3], work[bands + 4]
    for k in range(bands):
        bow_at[k], out_weight[k], mouth[k] = loops[k].bow_at, loops[k].out, loops[k].mouth
    mouthing = drive.size > 0
    j_speed = j_pressure = j_velocity = j_force = 0
    c = 0
    while c < n:
        m = min(min(chunk, n - c), FLUSH_PERIOD - ((start + c) & (FLUSH_PERIOD - 1)))
        for k in range(bands):  # all-pass outputs: they read only what was written before this chunk
            eta, delay, state = loops[k].eta, loops[k].delay, filters[k]
            x1, a = state.ap_x, state.ap_y
            for i in range(m):
                d = buffers[k, (pos + i - delay) & mask]
                a = eta * (d - a) + x1
                x1 = d
                ap_out[k, i] = a
            state.ap_x, state.ap_y = x1, a
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
                v_bar += bow_at[k] * ap_out[k, i]
                total += out_weight[k] * ap_out[k, i]
            friction[i] = friction_given_width(v_bow - v_bar, f_bow, inverse_width) if f_bow > 0.0 else 0.0
            force_in[i] = pending[c + i] if c + i < n_pending else held_force
            out[c + i] = total
            if mouthing:
                at_mouth = 0.0
                for k in range(bands):
                    at_mouth += mouth[k] * ap_out[k, i]
                drive[c + i] = at_mouth
        for k in range(bands):  # band-passes, into the delay lines
            loop, state = loops[k], filters[k]
            b0, a1, a2, w_in, w_bow, g = loop.b0, loop.a1, loop.a2, loop.force_in, loop.bow_in, loop.gain
            v1, v2, y1, y2 = state.v1, state.v2, state.y1, state.y2
            for i in range(m):
                v = w_in * force_in[i] + w_bow * friction[i] + g * ap_out[k, i]
                y = b0 * (v - v2) - a1 * y1 - a2 * y2
                v2 = v1
                v1 = v
                y2 = y1
                y1 = y
                buffers[k, (pos + i) & mask] = y
            state.v1, state.v2, state.y1, state.y2 = v1, v2, y1, y2
        pos = (pos + m) & mask
        c += m
        if ((start + c) & (FLUSH_PERIOD - 1)) == 0:
            for k in range(bands):
                f = filters[k]
                if _silent(f.v1, f.v2, f.y1, f.y2, f.ap_x, f.ap_y, buffers, k):
                    f.v1 = f.v2 = f.y1 = f.y2 = f.ap_x = f.ap_y = 0.0
    position[0] = pos
    scale(out, level, MULTIPLICATIVE)
