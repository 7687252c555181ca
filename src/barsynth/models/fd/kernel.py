"""Numba kernel of the implicit finite-difference bar (barsynth spec 3.3).

Sources: S. Bilbao, Numerical Sound Synthesis (Wiley 2009), ch. 7 (the theta scheme for
the bar, the bow solved by Newton's method); A. Chaigne and V. Doutaut, JASA 101 (1997)
(the Hertzian mallet coupled to the bar). With the grid operator ``M, K, C`` of
:mod:`barsynth.physics.grid` and time step ``k = 1 / sample_rate``, the scheme

    M (u+ - 2u + u-) / k^2 = -K (theta u + (1 - theta) (u+ + u-) / 2) - C (u+ - u-) / (2k) + f

is solved each step for ``s = u+ + u-`` from

    A s = B u + (C / k) u- + f,   A = M/k^2 + (1 - theta) K / 2 + C / (2k),   B = 2M/k^2 - theta K

with ``A`` (pentadiagonal, symmetric positive definite) factored once as ``L D L^T``.
Forces enter at points through interpolation vectors (already free of rigid-body
parts for a free-free bar). Each step is first solved without them; a force at a
point then adds ``F A^-1 J`` to the solution, so the point's next displacement is
linear in ``F``. The mallet's contact force is the discrete gradient of the contact
energy (a scalar equation, solved by bisection: energy-conserving, never a gain);
the bow's friction is either solved with the step (Newton on the scalar equation for
the relative velocity, the dynamic stick-slip form) or taken from the previous step
(the simplified forced-oscillation form).

What the kernel reads and writes comes as a few named records (NamedTuples of arrays and
numbers; the scalars that change are one-row structured arrays): the :class:`Scheme`
(the step's coefficients), the :class:`Bar` (its state), each exciter at its point
(:class:`MalletPoint`, :class:`BowPoint`) and the :class:`Pickup` (the output filter). A
further force or contact at a point (a finger, a desk) would be one more such record and
one more term added to the step's solution, as the mallet and the bow are.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ...dsp.bow_stroke import FORCE, PRESSURE, SPEED, VELOCITY, line_value
from ...dsp.friction import friction_given_width, friction_slope, stick_width
from ...dsp.smoothing import MULTIPLICATIVE, next_value

MAX_NEWTON_STEPS = 40
MAX_CONTACT_STEPS = 80

PAD = 2
"""Every node vector is stored with two zeros before and after it, so the five-point
stencils and the substitutions need no tests at the ends."""


class Scheme(NamedTuple):
    """The step, fixed until the parameters change (see :func:`barsynth.models.fd.design.scheme`)."""

    bands: np.ndarray
    """(8, padded n): B's coefficients of nodes i, i-1, i+1, i-2, i+2, then (C/k)'s of i,
    i - reach, i + reach (``loss_reach``)."""
    factors: np.ndarray
    """(3, padded n): l1, l2 and 1/d of ``A = L D L^T``."""
    step_rate: float
    """Scheme steps per second (Hz): the output rate x ``substeps``."""
    substeps: int
    """Scheme steps per output sample (oversampling)."""
    loss_reach: int
    """How far apart the unknowns are that the losses ``C`` couple: 1 on the Euler–Bernoulli
    grid (a tridiagonal Laplacian), 2 on the interleaved two-field grid (deflections only);
    no other value."""


class Bar(NamedTuple):
    """The bar's state: displacements now and a step ago (m, padded), and the step's scratch."""

    u: np.ndarray
    u_prev: np.ndarray
    s: np.ndarray
    """``u+ + u-`` while a step is solved (its pads stay 0)."""


MALLET_STATE = np.dtype([("z_m", np.float64), ("z_prev_m", np.float64), ("touching", np.bool_)])
"""The mallet's position now and a step ago (m), and whether it may still touch."""


class MalletPoint(NamedTuple):
    """A Hertzian mallet (:meth:`barsynth.exciters.Strike.coupling`) at its point on the grid."""

    at: np.ndarray
    """The point's interpolation vector (padded): the bar's displacement there is ``at . u``."""
    response: np.ndarray
    """``A^-1`` times the point's force vector (padded)."""
    gain_m_n: float
    """The bar's displacement there per newton of this step's force (m/N)."""
    mass_kg: float
    stiffness: float
    """Contact stiffness (N/m^exponent)."""
    exponent: float
    state: np.ndarray
    """One :data:`MALLET_STATE` row."""


BOW_STATE = np.dtype([("dv_m_s", np.float64)])
"""The bow's last relative velocity (m/s): Newton's starting point, the explicit form's input."""


class BowPoint(NamedTuple):
    """The bow's friction (:mod:`barsynth.dsp.friction`) at its point on the grid."""

    at: np.ndarray
    response: np.ndarray
    gain_m_s_n: float
    """eta: the bow point's velocity per newton of bow force within one step (m/s/N)."""
    newton: bool
    """Solved with each step (True) or from the step before (False)."""
    state: np.ndarray
    """One :data:`BOW_STATE` row."""


OUTPUT_STATE = np.dtype([("written", np.int64), ("last", np.float64)])
"""Where the next value goes in the decimation filter's history, and the last output before
the level (m/s)."""


class Pickup(NamedTuple):
    """The pick-up and the output: velocity there, low-passed and decimated, times the level."""

    at: np.ndarray
    """The pick-up's interpolation vector (padded, rigid-body motion removed)."""
    level: np.ndarray
    """The output gain as a :mod:`barsynth.dsp.smoothing` state (multiplicative), a step a sample."""
    taps: np.ndarray
    """The decimation filter's FIR (``[1]`` at one step a sample)."""
    history: np.ndarray
    """Its recent input, a power-of-two ring."""
    state: np.ndarray
    """One :data:`OUTPUT_STATE` row."""


def padded(vector: np.ndarray) -> np.ndarray:
    out = np.zeros(vector.size + 2 * PAD)
    out[PAD:-PAD] = vector
    return out


def solve(r: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """``A^-1 r`` for a plain (unpadded) vector, with the kernel's factors: the forward and
    backward substitutions of ``L D L^T``. Plain Python floats (IEEE doubles, the same
    arithmetic as compiled code without fast-math): a design solves two, well under a
    millisecond each at the default 100 nodes, where compiling it cost 0.15 s of a first render."""
    l1, l2, inv_d = (row.tolist() for row in factors)
    s = padded(r).tolist()  # r (its pads 0), then s in place
    end = len(s) - PAD
    for q in range(PAD, end):
        s[q] = s[q] - l1[q] * s[q - 1] - l2[q] * s[q - 2]
    for q in range(end - 1, PAD - 1, -1):
        s[q] = s[q] * inv_d[q] - l1[q + 1] * s[q + 1] - l2[q + 2] * s[q + 2]
    return np.array(s[PAD:-PAD])


# The exciters' functions are compiled on their own (numba's inline="always" would type and
# lower their bodies again at every call: _potential four times) and only ever called from
# process: no Python or C wrapper, no cache of their own; contract as process.
_INNER = {"nogil": True, "no_cpython_wrapper": True, "no_cfunc_wrapper": True, "fastmath": {"contract"}}


@njit(**_INNER)
def _potential(squeeze, stiffness, exponent):  # pragma: no cover - compiled
    """The contact spring's energy ``k d^(p+1) / (p+1)`` (J) at a squeeze ``d`` (m)."""
    return stiffness * squeeze ** (exponent + 1.0) / (exponent + 1.0) if squeeze > 0.0 else 0.0


@njit(**_INNER)
def _gradient(after, before, stiffness, exponent):  # pragma: no cover - compiled
    """The discrete gradient ``(V(after) - V(before)) / (after - before)`` of the contact energy (N)."""
    gap = after - before
    if abs(gap) <= 1e-12 * (abs(after) + abs(before)) + 1e-300:
        middle = 0.5 * (after + before)
        return stiffness * middle ** exponent if middle > 0.0 else 0.0
    return (_potential(after, stiffness, exponent) - _potential(before, stiffness, exponent)) / gap


@njit(**_INNER)
def _contact_force(free_squeeze, give, before, stiffness, exponent):  # pragma: no cover - compiled
    """The mallet force F (N) with ``F = gradient(free_squeeze - give F, before)``: the squeeze
    next step falls by ``give`` (m/N) per newton. The right side falls as F grows, so the root
    is unique and lies in ``[0, gradient(free_squeeze, before)]``: bisection finds it."""
    high = _gradient(free_squeeze, before, stiffness, exponent)
    if high <= 0.0:
        return 0.0
    low = 0.0
    for _ in range(MAX_CONTACT_STEPS):
        middle = 0.5 * (low + high)
        if middle - _gradient(free_squeeze - give * middle, before, stiffness, exponent) > 0.0:
            high = middle
        else:
            low = middle
        if high - low <= 1e-14 * high:
            break
    return 0.5 * (low + high)


@njit(**_INNER)
def _mallet(s, u_prev, mallet, rate):  # pragma: no cover - compiled
    """The mallet's force (N) this step, given the step solved without it (``s``); moves the mallet."""
    state = mallet.state[0]
    at = mallet.at
    bar_next = bar_before = 0.0
    for q in range(PAD, s.size - PAD):
        bar_next += at[q] * (s[q] - u_prev[q])
        bar_before += at[q] * u_prev[q]
    mass = mallet.mass_kg
    give = 1.0 / (mass * rate * rate) + mallet.gain_m_n  # next step's squeeze lost per newton (m/N)
    z, z_prev = state.z_m, state.z_prev_m
    free = 2.0 * z - z_prev - bar_next  # next step's squeeze without this step's force
    force = _contact_force(free, give, z_prev - bar_before, mallet.stiffness, mallet.exponent)
    z_next = 2.0 * z - z_prev - force / (mass * rate * rate)
    state.z_prev_m = z
    state.z_m = z_next
    if force == 0.0 and free < 0.0 and z_next < z:  # apart, and the mallet moving away
        state.touching = False
    return force


@njit(**_INNER)
def _friction(s, u_prev, u, bow, lines, x, j_speed, j_velocity, j_force, pressure, rate):  # pragma: no cover
    """The bow's friction force (N) this step, and the lines' pieces."""
    end = s.size - PAD
    at_bow = bow.at
    state = bow.state[0]
    speed, j_speed = line_value(lines[SPEED], x, j_speed)
    velocity, j_velocity = line_value(lines[VELOCITY], x, j_velocity)
    force_set, j_force = line_value(lines[FORCE], x, j_force)
    v_bow, f_bow = speed * velocity, pressure * force_set
    inverse_width = 1.0 / stick_width(f_bow)
    eta = bow.gain_m_s_n
    if bow.newton:
        # the bar's velocity at the bow without the bow, then dv + eta F phi(dv) = v_bow - v0
        v0 = 0.0
        for q in range(PAD, end):
            v0 += at_bow[q] * (s[q] - 2.0 * u_prev[q])
        v0 *= 0.5 * rate
        target = v_bow - v0
        low, high = target - eta * f_bow, target + eta * f_bow
        dv = min(max(state.dv_m_s, low), high)
        for _ in range(MAX_NEWTON_STEPS):
            g = dv + eta * friction_given_width(dv, f_bow, inverse_width) - target
            if g == 0.0:
                break
            if g > 0.0:
                high = dv
            else:
                low = dv
            slope = 1.0 + eta * friction_slope(dv, f_bow, inverse_width)
            following = dv - g / slope if slope > 0.0 else 0.5 * (low + high)
            if not low <= following <= high:
                following = 0.5 * (low + high)
            if abs(following - dv) <= 1e-13 * (1.0 + abs(dv)):
                dv = following
                break
            dv = following
    else:  # the friction of the bar's velocity one step ago
        v_then = 0.0
        for q in range(PAD, end):
            v_then += at_bow[q] * (u[q] - u_prev[q])
        dv = v_bow - v_then * rate
    state.dv_m_s = dv
    return friction_given_width(dv, f_bow, inverse_width), j_speed, j_velocity, j_force


@njit(cache=True, nogil=True, fastmath={"contract"})
def process(out, scheme, bar, mallet, bow, lines, start, pickup):  # pragma: no cover - compiled
    """Advance the bar ``out.size`` output samples; ``out`` gets the pick-up velocity (m/s) x level.

    ``lines``, ``start``: the bow's controls (:mod:`barsynth.dsp.bow_stroke`) and the absolute
    index of ``out[0]``. With ``scheme.substeps = N > 1`` the scheme runs N steps per output
    sample and the pick-up velocity passes the low-pass FIR ``pickup.taps`` before every N-th
    value is kept.

    Each step is solved first without the exciters; the mallet's force (the discrete gradient
    of the contact spring's energy between the last and the next step, Bilbao 2009: a strike
    never adds energy, however short the contact is against the step) and the bow's friction
    are then solved with it and added through their points' responses.
    """
    u, u_prev, s = bar.u, bar.u_prev, bar.s
    end = u.size - PAD
    rate = scheme.step_rate
    bands, factors = scheme.bands, scheme.factors
    b0, bl1, br1, bl2, br2, c0, cl, cr = bands[0], bands[1], bands[2], bands[3], bands[4], bands[5], bands[6], bands[7]
    reach = scheme.loss_reach
    l1, l2, inv_d = factors[0], factors[1], factors[2]
    mallet_response, bow_response = mallet.response, bow.response
    at_pickup = pickup.at
    mallet_state = mallet.state[0]
    output = pickup.state[0]
    level = pickup.level
    substeps = scheme.substeps
    taps, history = pickup.taps, pickup.history
    history_mask = history.size - 1
    h = output.written
    j_speed = j_pressure = j_velocity = j_force = np.int64(0)  # int64, not Literal[int](0): _friction compiles once
    for step in range(out.size * substeps):
        t = step // substeps
        # A s = B u + (C/k) u-: the right-hand side formed inside the forward substitution
        # (the last two values of each substitution ride in registers: the recurrences are the critical path;
        # so do the stencils' neighbours, loaded once each: numba cannot tell that s is apart from u. The
        # two-field grid's losses reach two apart: its u- is loaded where it is used, as a third window of
        # registers spilled and cost the Euler-Bernoulli bar 15 %)
        s1 = s2 = 0.0
        u_l2, u_l1, u_0, u_r1 = u[PAD - 2], u[PAD - 1], u[PAD], u[PAD + 1]
        if reach == 1:
            p_l1, p_0 = u_prev[PAD - 1], u_prev[PAD]
            for q in range(PAD, end):
                u_r2, p_r1 = u[q + 2], u_prev[q + 1]
                r = (b0[q] * u_0 + bl1[q] * u_l1 + br1[q] * u_r1 + bl2[q] * u_l2 + br2[q] * u_r2
                     + c0[q] * p_0 + cl[q] * p_l1 + cr[q] * p_r1)
                value = (r - l2[q] * s2) - l1[q] * s1
                s[q] = value
                s2 = s1
                s1 = value
                u_l2, u_l1, u_0, u_r1 = u_l1, u_0, u_r1, u_r2
                p_l1, p_0 = p_0, p_r1
        else:
            for q in range(PAD, end):
                u_r2 = u[q + 2]
                r = (b0[q] * u_0 + bl1[q] * u_l1 + br1[q] * u_r1 + bl2[q] * u_l2 + br2[q] * u_r2
                     + c0[q] * u_prev[q] + cl[q] * u_prev[q - 2] + cr[q] * u_prev[q + 2])
                value = (r - l2[q] * s2) - l1[q] * s1
                s[q] = value
                s2 = s1
                s1 = value
                u_l2, u_l1, u_0, u_r1 = u_l1, u_0, u_r1, u_r2
        x = (start + t) + (step % substeps) / substeps  # the bow's clock, in output samples
        pressure, j_pressure = line_value(lines[PRESSURE], x, j_pressure)
        touching = mallet_state.touching
        s1 = s2 = 0.0
        moved = 0.0
        if pressure <= 0.0 and not touching:  # nothing touches: the backward substitution also steps the bar
            for q in range(end - 1, PAD - 1, -1):
                value = (s[q] * inv_d[q] - l2[q + 2] * s2) - l1[q + 1] * s1
                s2 = s1
                s1 = value
                following = value - u_prev[q]
                now = u[q]
                moved += at_pickup[q] * (following - now)
                u_prev[q] = now
                u[q] = following
        else:
            for q in range(end - 1, PAD - 1, -1):
                value = (s[q] * inv_d[q] - l2[q + 2] * s2) - l1[q + 1] * s1
                s[q] = value
                s2 = s1
                s1 = value
            if touching:
                force = _mallet(s, u_prev, mallet, rate)
                for q in range(PAD, end):
                    s[q] += force * mallet_response[q]
            if pressure > 0.0:
                friction, j_speed, j_velocity, j_force = _friction(
                    s, u_prev, u, bow, lines, x, j_speed, j_velocity, j_force, pressure, rate)
                for q in range(PAD, end):
                    s[q] += friction * bow_response[q]
            for q in range(end - 1, PAD - 1, -1):  # the step, in the same order as above
                following = s[q] - u_prev[q]
                now = u[q]
                moved += at_pickup[q] * (following - now)
                u_prev[q] = now
                u[q] = following
        # out: the pick-up velocity, straight or through the decimation filter
        if substeps == 1:
            output.last = moved * rate
            out[t] = output.last * next_value(level, MULTIPLICATIVE)
        else:
            history[h] = moved * rate
            if step % substeps == substeps - 1:
                acc = 0.0
                for j in range(taps.size):
                    acc += taps[j] * history[(h - j) & history_mask]
                output.last = acc
                out[t] = acc * next_value(level, MULTIPLICATIVE)
            h = (h + 1) & history_mask
    output.written = h
