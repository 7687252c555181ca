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
"""

from __future__ import annotations


import numpy as np
from numba import njit

from ...dsp.bow_stroke import FORCE, PRESSURE, SPEED, VELOCITY, line_value
from ...dsp.friction import friction_given_width, friction_slope, stick_width

# scalar state (the `scalars` array)
X_MALLET = 0  # mallet position (m)
X_MALLET_PREV = 1
X_MALLET_ON = 2  # 1 while the mallet may touch
X_DV = 3  # the bow's last relative velocity (m/s): Newton's starting point, the explicit form's input
X_HISTORY = 4  # write position in the decimation filter's history
X_LAST = 5  # the last output value before the level (m/s)
N_SCALARS = 6

# constants (the `constants` array)
K_MALLET_MASS = 0
K_MALLET_STIFFNESS = 1
K_MALLET_EXPONENT = 2
K_SAMPLE_RATE = 3
K_NEWTON = 4  # 1: the bow by Newton with each step, 0: explicit
K_BOW_GAIN = 5  # eta: bow-point velocity per newton of bow force within one step (m/s/N)
K_LEVEL = 6
K_SUBSTEPS = 7  # scheme steps per output sample (oversampling); above 1 the output is low-passed and decimated
K_MALLET_GAIN = 8  # gamma: the bar's displacement at the mallet per newton of this step's force (m/N)
N_CONSTANTS = 9

MAX_NEWTON_STEPS = 40
MAX_CONTACT_STEPS = 80


def factor(diagonal: np.ndarray, first: np.ndarray, second: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``L D L^T`` of a symmetric pentadiagonal matrix: ``(l1, l2, 1 / d)``, where ``l1[i]``
    and ``l2[i]`` are ``L[i, i-1]`` and ``L[i, i-2]``."""
    n = diagonal.size
    l1, l2, d = np.zeros(n), np.zeros(n), np.zeros(n)
    for i in range(n):
        if i >= 2:
            l2[i] = second[i - 2] / d[i - 2]
        if i >= 1:
            l1[i] = (first[i - 1] - (l2[i] * d[i - 2] * l1[i - 1] if i >= 2 else 0.0)) / d[i - 1]
        d[i] = diagonal[i] - l1[i] ** 2 * (d[i - 1] if i >= 1 else 0.0) - l2[i] ** 2 * (d[i - 2] if i >= 2 else 0.0)
        if not d[i] > 0.0:
            raise ValueError("the step matrix is not positive definite")
    return l1, l2, 1.0 / d


PAD = 2
"""Every node vector is stored with two zeros before and after it, so the five-point
stencils and the substitutions need no tests at the ends."""


def padded(vector: np.ndarray) -> np.ndarray:
    out = np.zeros(vector.size + 2 * PAD)
    out[PAD:-PAD] = vector
    return out


def stencils(b: np.ndarray, c: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's coefficient rows from the dense matrices ``B``, ``C / k`` and ``A``.

    ``bands`` rows, each padded: B's coefficients of nodes i, i-1, i+1, i-2, i+2, then
    (C/k)'s of i, i-1, i+1. ``factors`` rows, padded: l1, l2 and 1/d of ``A = L D L^T``.
    """
    n = b.shape[0]
    bands = np.zeros((8, n + 2 * PAD))
    for row, (matrix, offset) in enumerate(((b, 0), (b, -1), (b, 1), (b, -2), (b, 2), (c, 0), (c, -1), (c, 1))):
        for i in range(n):
            j = i + offset
            if 0 <= j < n:
                bands[row, PAD + i] = matrix[i, j]
    l1, l2, inv_d = factor(np.diagonal(a).copy(), np.diagonal(a, 1).copy(), np.diagonal(a, 2).copy())
    return bands, np.array([padded(l1), padded(l2), padded(inv_d)])


def solve(r: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """``A^-1 r`` for a plain (unpadded) vector, with the kernel's factors."""
    s = np.zeros(r.size + 2 * PAD)
    _solve(padded(r), factors[0], factors[1], factors[2], s)
    return s[PAD:-PAD]


@njit(cache=True, inline="always")
def _solve(r, l1, l2, inv_d, s):  # pragma: no cover - compiled
    """``s = A^-1 r`` on padded vectors (``s``'s pads stay 0)."""
    end = r.size - PAD
    for q in range(PAD, end):
        s[q] = r[q] - l1[q] * s[q - 1] - l2[q] * s[q - 2]
    for q in range(end - 1, PAD - 1, -1):
        s[q] = s[q] * inv_d[q] - l1[q + 1] * s[q + 1] - l2[q + 2] * s[q + 2]


@njit(cache=True, inline="always")
def _potential(squeeze, stiffness, exponent):  # pragma: no cover - compiled
    """The contact spring's energy ``k d^(p+1) / (p+1)`` (J) at a squeeze ``d`` (m)."""
    return stiffness * squeeze ** (exponent + 1.0) / (exponent + 1.0) if squeeze > 0.0 else 0.0


@njit(cache=True, inline="always")
def _gradient(after, before, stiffness, exponent):  # pragma: no cover - compiled
    """The discrete gradient ``(V(after) - V(before)) / (after - before)`` of the contact energy (N)."""
    gap = after - before
    if abs(gap) <= 1e-12 * (abs(after) + abs(before)) + 1e-300:
        middle = 0.5 * (after + before)
        return stiffness * middle ** exponent if middle > 0.0 else 0.0
    return (_potential(after, stiffness, exponent) - _potential(before, stiffness, exponent)) / gap


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
def _friction(s, u_prev, at_bow, lines, x, j_speed, j_velocity, j_force, pressure, scalars, newton, eta,
              rate, u):  # pragma: no cover - compiled
    """The bow's friction force (N) this step, and the lines' pieces."""
    end = s.size - PAD
    speed, j_speed = line_value(lines[SPEED], x, j_speed)
    velocity, j_velocity = line_value(lines[VELOCITY], x, j_velocity)
    force_set, j_force = line_value(lines[FORCE], x, j_force)
    v_bow, f_bow = speed * velocity, pressure * force_set
    inverse_width = 1.0 / stick_width(f_bow)
    if newton:
        # the bar's velocity at the bow without the bow, then dv + eta F phi(dv) = v_bow - v0
        v0 = 0.0
        for q in range(PAD, end):
            v0 += at_bow[q] * (s[q] - 2.0 * u_prev[q])
        v0 *= 0.5 * rate
        target = v_bow - v0
        low, high = target - eta * f_bow, target + eta * f_bow
        dv = min(max(scalars[X_DV], low), high)
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
    scalars[X_DV] = dv
    return friction_given_width(dv, f_bow, inverse_width), j_speed, j_velocity, j_force


@njit(cache=True, nogil=True, fastmath={"contract"})
def process(out, u, u_prev, bands, factors, contact, bow, pickup, lines, start, scalars, constants, taps, history):
    """Advance the bar ``out.size`` output samples; ``out`` gets the pick-up velocity (m/s) x level.

    Node vectors are padded (:data:`PAD`). ``bands`` and ``factors``: see
    :func:`stencils`. ``contact`` rows: the mallet point's interpolation vector (for
    the bar's displacement there) and ``A^-1`` times its force vector; ``bow`` rows:
    the same for the bow point. ``pickup`` row: the pick-up interpolation vector
    with rigid-body motion removed. ``lines``, ``start``: the bow's controls
    (:mod:`barsynth.dsp.bow_stroke`) and the absolute index of ``out[0]``. With
    ``constants[K_SUBSTEPS] = N > 1`` the scheme runs N steps per output sample and
    the pick-up velocity passes the low-pass FIR ``taps`` (its recent past in
    ``history``, a power-of-two ring) before every N-th value is kept.

    The mallet's force is implicit: the discrete gradient of the contact spring's
    energy between the last and the next step (Bilbao 2009), solved with the step,
    so a strike never adds energy, however short the contact is against the step.
    """
    size = u.size
    end = size - PAD
    rate = constants[K_SAMPLE_RATE]
    b0, bl1, br1, bl2, br2, c0, cl1, cr1 = bands[0], bands[1], bands[2], bands[3], bands[4], bands[5], bands[6], bands[7]
    l1, l2, inv_d = factors[0], factors[1], factors[2]
    at_mallet, mallet_response = contact[0], contact[1]
    at_bow, bow_response = bow[0], bow[1]
    at_pickup = pickup[0]
    s = np.zeros(size)
    mass, stiffness, exponent = constants[K_MALLET_MASS], constants[K_MALLET_STIFFNESS], constants[K_MALLET_EXPONENT]
    give = 1.0 / (mass * rate * rate) + constants[K_MALLET_GAIN]  # next step's squeeze lost per newton (m/N)
    newton = constants[K_NEWTON] > 0.5
    eta = constants[K_BOW_GAIN]
    level = constants[K_LEVEL]
    substeps = int(constants[K_SUBSTEPS])
    history_mask = history.size - 1
    h = int(scalars[X_HISTORY])
    j_speed = j_pressure = j_velocity = j_force = 0
    for step in range(out.size * substeps):
        t = step // substeps
        # A s = B u + (C/k) u-: the right-hand side formed inside the forward substitution
        # (the last two values of each substitution ride in registers: the recurrences are the critical path)
        s1 = s2 = 0.0
        for q in range(PAD, end):
            r = (b0[q] * u[q] + bl1[q] * u[q - 1] + br1[q] * u[q + 1] + bl2[q] * u[q - 2] + br2[q] * u[q + 2]
                 + c0[q] * u_prev[q] + cl1[q] * u_prev[q - 1] + cr1[q] * u_prev[q + 1])
            value = (r - l2[q] * s2) - l1[q] * s1
            s[q] = value
            s2 = s1
            s1 = value
        x = (start + t) + (step % substeps) / substeps  # the bow's clock, in output samples
        pressure, j_pressure = line_value(lines[PRESSURE], x, j_pressure)
        mallet = scalars[X_MALLET_ON] > 0.5
        s1 = s2 = 0.0
        moved = 0.0
        if pressure <= 0.0 and not mallet:  # nothing touches: the backward substitution also steps the bar
            for q in range(end - 1, PAD - 1, -1):
                value = (s[q] * inv_d[q] - l2[q + 2] * s2) - l1[q + 1] * s1
                s2 = s1
                s1 = value
                following = value - u_prev[q]
                moved += at_pickup[q] * (following - u[q])
                u_prev[q] = u[q]
                u[q] = following
        else:
            for q in range(end - 1, PAD - 1, -1):
                value = (s[q] * inv_d[q] - l2[q + 2] * s2) - l1[q + 1] * s1
                s[q] = value
                s2 = s1
                s1 = value
            if mallet:
                bar_next = bar_before = 0.0
                for q in range(PAD, end):
                    bar_next += at_mallet[q] * (s[q] - u_prev[q])
                    bar_before += at_mallet[q] * u_prev[q]
                z, z_prev = scalars[X_MALLET], scalars[X_MALLET_PREV]
                free = 2.0 * z - z_prev - bar_next  # next step's squeeze without this step's force
                force = _contact_force(free, give, z_prev - bar_before, stiffness, exponent)
                for q in range(PAD, end):
                    s[q] += force * mallet_response[q]
                z_next = 2.0 * z - z_prev - force / (mass * rate * rate)
                scalars[X_MALLET_PREV] = z
                scalars[X_MALLET] = z_next
                if force == 0.0 and free < 0.0 and z_next < z:  # apart, and the mallet moving away
                    scalars[X_MALLET_ON] = 0.0
            if pressure > 0.0:
                friction, j_speed, j_velocity, j_force = _friction(
                    s, u_prev, at_bow, lines, x, j_speed, j_velocity, j_force, pressure, scalars, newton, eta, rate, u)
                for q in range(PAD, end):
                    s[q] += friction * bow_response[q]
            for q in range(end - 1, PAD - 1, -1):  # the step, in the same order as above
                following = s[q] - u_prev[q]
                moved += at_pickup[q] * (following - u[q])
                u_prev[q] = u[q]
                u[q] = following
        # out: the pick-up velocity, straight or through the decimation filter
        if substeps == 1:
            scalars[X_LAST] = moved * rate
            out[t] = scalars[X_LAST] * level
        else:
            history[h] = moved * rate
            if step % substeps == substeps - 1:
                acc = 0.0
                for j in range(taps.size):
                    acc += taps[j] * history[(h - j) & history_mask]
                scalars[X_LAST] = acc
                out[t] = acc * level
            h = (h + 1) & history_mask
    scalars[X_HISTORY] = h
