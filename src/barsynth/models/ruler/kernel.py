"""Numba kernel of the ruler engine: a bar on the finite-difference grid with one-sided contacts.

Sources: S. Bilbao, Numerical Sound Synthesis (Wiley 2009), ch. 7 (the theta scheme for the
bar) and S. Bilbao, A. Torin and V. Chatziioannou, "Numerical modeling of collisions in
musical instruments", Acta Acustica 101 (2015) (contact forces as the discrete gradient of a
penalty potential, solved with the step by Newton's method: a scheme whose energy only
losses lower, for any contact stiffness). With the grid operator ``M, K, C`` of
:mod:`barsynth.physics.grid` and ``k = 1 / sample_rate``,

    M (u+ - 2u + u-) / k^2 = -K (theta u + (1 - theta) (u+ + u-) / 2) - C (u+ - u-) / (2k)
                             + f_gravity + sum_e (-sign_e) J_e t_e

where each contact ``e`` (a desk node, the desk's edge, a finger, a bridge) meets the bar at
``J_e . u`` (a node, or two neighbours interpolated), its penetration is
``eta_e = sign_e (J_e . u - offset_e)`` (``sign`` +1: it presses from above, -1: from below)
and its force ``t_e`` is the discrete gradient ``(V(eta+) - V(eta-)) / (eta+ - eta-)`` of
``V = k_e [eta]_+^(a+1) / (a + 1)`` plus a damping ``r_e d(eta)/dt`` while it is pressed,
never pulling (a one-sided contact's force is at least 0). Each step solves the pentadiagonal
system for ``u+`` by Newton's method, whose Jacobian ``A + sum_e dt_e/d(eta) J_e J_e^T`` is
pentadiagonal too (``J_e`` touches two neighbours at most): one ``L D L^T`` factorisation per
iteration, kept while the contacts' slopes do not change and none of them moves (a slide
factors anew each step). With linear contacts
(``a = 1``) a step whose contacts neither meet nor part is linear: one iteration solves it exactly.

What it reads and writes comes as named records (NamedTuples of arrays; scalars that change are
one-row structured arrays): :class:`Scheme`, :class:`Bar`, :class:`Contacts`, :class:`Edge`
(the moving desk edge of a slide) and :class:`Output`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ...dsp.smoothing import MULTIPLICATIVE, next_value
from .desk import process_desk

PAD = 2
"""Node vectors carry two zeros before and after (the five-point stencils need no tests)."""

MAX_NEWTON_STEPS = 60
ABSOLUTE_TOLERANCE_M = 1e-15
RELATIVE_TOLERANCE = 1e-8


class Scheme(NamedTuple):
    """The step, fixed until the parameters change (see :mod:`.design`)."""

    bands: np.ndarray
    """(8, padded n): B's coefficients of nodes i, i-1, i+1, i-2, i+2, then (C/k)'s of i, i-1, i+1."""
    system: np.ndarray
    """(3, padded n): A's diagonal, ``A[i, i+1]`` and ``A[i, i+2]``."""
    gravity: np.ndarray
    """The weight on each node (N, padded; negative: down)."""
    step_rate: float
    """Steps per second (Hz): one a sample."""
    linear: bool
    """Every contact's exponent is 1: a step whose contacts neither meet nor part is solved in one iteration."""


class Bar(NamedTuple):
    """The bar's state: displacements now and a step ago (m, padded), and the solver's scratch."""

    u: np.ndarray
    u_prev: np.ndarray
    v: np.ndarray
    """The next displacements while a step is solved."""
    rhs: np.ndarray
    residual: np.ndarray
    factors: np.ndarray
    """(3, padded n): l1, l2 and 1/d of the Jacobian's ``L D L^T``."""


CONTACT_FIELDS = ("first", "w0", "w1", "stiffness", "damping", "offset", "sign", "exponent")


class Contacts(NamedTuple):
    """Every contact of the bar, one entry each (see the module docstring)."""

    first: np.ndarray
    """(int64) The padded index of the first node it touches; it also touches the next with ``w1``."""
    w0: np.ndarray
    w1: np.ndarray
    stiffness: np.ndarray
    """k_e (N/m^exponent); 0: the contact is away (a desk node beyond the edge)."""
    damping: np.ndarray
    """r_e (N s/m), while pressed."""
    offset: np.ndarray
    """Where its surface is (m): the bar's displacement at which it starts to press."""
    sign: np.ndarray
    """+1: it presses down from above (a finger); -1: up from below (the desk, a bridge)."""
    exponent: np.ndarray
    two_sided: np.ndarray
    """(bool) It holds the bar both ways (a pinned bridge): a spring, no contact."""
    on_desk: np.ndarray
    """(bool) Its force also drives the desk."""
    eta_plus: np.ndarray
    eta_prev: np.ndarray
    force: np.ndarray
    """t_e (N) at the iterate: the contact's push on the bar along ``-sign J``."""
    potential_force: np.ndarray
    """The discrete gradient's part of ``t_e`` (N); the rest is damping."""
    slope: np.ndarray
    """dt_e / d(eta+) at the iterate (N/m)."""
    factored: np.ndarray
    """The slopes the factors were made with."""
    regime: np.ndarray
    """(int64) Which piece of its force law each contact is on (a change means another iteration)."""


EDGE_STATE = np.dtype([("steps", np.int64)])
"""Steps since the slide began."""


class Edge(NamedTuple):
    """The desk's edge and what moves with it during a slide (the hand pulls the ruler back)."""

    x_m: np.ndarray
    """The moving nodes' positions along the bar (m, padded)."""
    cell_low: np.ndarray
    cell_high: np.ndarray
    """Each node's cell ``[x - dx/2, x + dx/2]`` within the bar (m, padded)."""
    desk_nodes: np.ndarray
    """(int64) The contact indices of the desk under each node (padded index = node)."""
    edge: int
    """The contact index of the edge (-1: none)."""
    finger: int
    """The contact index of the finger (-1: none): it keeps its distance behind the edge (the
    finger presses near the edge while the other hand pulls the ruler back under it)."""
    finger_back_m: float
    desk_stiffness_n_m2: float
    desk_damping_n_s_m2: float
    radiation_pa_s2_m2: float
    """Pressure at 1 m per unit volume acceleration, times the width (Pa per (m/s^2 x m))."""
    start_m: float
    """The edge's position before the slide (m)."""
    slide_m: float
    """How far the edge moves toward the tip (m); 0: no slide."""
    slide_steps: int
    desk_covers_edge: bool
    """The desk lies under the bar up to the edge (a ruler); otherwise only the edge touches (a bridge)."""
    state: np.ndarray
    """One :data:`EDGE_STATE` row."""


OUTPUT_STATE = np.dtype([("track", np.bool_), ("lost_losses_j", np.float64), ("lost_contact_j", np.float64),
                         ("iterations", np.int64), ("steps", np.int64), ("most_iterations", np.int64),
                         ("unconverged", np.int64)])
"""Whether the energy the losses and the contacts' damping take is summed (J), and the solver's
counts: iterations, steps, the most iterations a step took, steps that ran out of iterations
(taken as they stood)."""


class Output(NamedTuple):
    """The sound: the bar's radiation, the desk's, their mix and the level."""

    radiation: np.ndarray
    """Pressure at 1 m per node acceleration (Pa / (m/s^2), padded): the overhang beyond the edge."""
    force: np.ndarray
    """Scratch: the force on the desk (N) each sample of a chunk."""
    desk_sound: np.ndarray
    """Scratch: the desk's pressure (Pa) each sample of a chunk."""
    desk: object
    """The desk's modal bank (:func:`barsynth.models.ruler.desk.desk_bank`)."""
    bar_gain: float
    desk_gain: float
    rest_force_n: float
    """The force on the desk at rest (N: the ruler's weight and the finger's press), which the desk
    already bears: its modes hear only the change."""
    level: np.ndarray
    """The output gain as a :mod:`barsynth.dsp.smoothing` state (multiplicative)."""
    state: np.ndarray
    """One :data:`OUTPUT_STATE` row."""


# The contact functions are compiled on their own and only called from process (as the fd
# kernel's exciters are): no wrappers, no cache of their own. The three called every step
# (_contact_terms, _residual, _solve_in_place) are inlined: passing the records to a call each
# time cost 13 % of the default twang (5.5x -> 6.3x real time).
_INNER = {"nogil": True, "no_cpython_wrapper": True, "no_cfunc_wrapper": True, "fastmath": {"contract"},
          "error_model": "numpy"}


@njit(**_INNER)
def _potential(eta, k, a, two_sided):  # pragma: no cover - compiled
    """``V(eta) = k [eta]^(a+1) / (a+1)`` (J): one-sided, or of ``|eta|`` when two-sided."""
    p = abs(eta) if two_sided else max(eta, 0.0)
    if p == 0.0:
        return 0.0
    return k * p * p / 2.0 if a == 1.0 else k * p ** (a + 1.0) / (a + 1.0)


@njit(**_INNER)
def _derivative(eta, k, a, two_sided):  # pragma: no cover - compiled
    """``V'(eta)`` (N)."""
    if two_sided:
        return k * eta if a == 1.0 else k * np.sign(eta) * abs(eta) ** a
    if eta <= 0.0:
        return 0.0
    return k * eta if a == 1.0 else k * eta ** a


@njit(**_INNER)
def _second(eta, k, a, two_sided):  # pragma: no cover - compiled
    """``V''(eta)`` (N/m)."""
    if a == 1.0:
        return k if (two_sided or eta > 0.0) else 0.0
    p = abs(eta) if two_sided else eta
    return k * a * p ** (a - 1.0) if p > 0.0 else 0.0


@njit(**_INNER)
def _gradient(after, before, k, a, two_sided):  # pragma: no cover - compiled
    """The discrete gradient ``(V(after) - V(before)) / (after - before)`` (N) and its derivative
    in ``after`` (N/m); at coinciding arguments ``V'`` and ``V'' / 2`` of their middle."""
    gap = after - before
    if abs(gap) <= 1e-6 * (abs(after) + abs(before)) + 1e-300:  # (below, the slope's quotient cancels)
        middle = 0.5 * (after + before)
        return _derivative(middle, k, a, two_sided), 0.5 * _second(middle, k, a, two_sided)
    phi = (_potential(after, k, a, two_sided) - _potential(before, k, a, two_sided)) / gap
    return phi, (_derivative(after, k, a, two_sided) - phi) / gap


@njit(inline='always', **_INNER)
def _contact_terms(contacts, v, u, u_prev, half_rate):  # pragma: no cover - compiled
    """Each contact's force and slope at the iterate ``v``. Returns whether the last linearisation
    may not have been exact (a contact changed the piece of its law it is on, or one meets or parts
    within the step: its force is not linear there), whether a slope differs from the factored
    one, and the force on the desk (N)."""
    inexact = False
    refactor = False
    on_desk = 0.0
    first, w0, w1 = contacts.first, contacts.w0, contacts.w1
    for e in range(first.size):
        k = contacts.stiffness[e]
        if k == 0.0:
            continue
        q = first[e]
        sign, offset = contacts.sign[e], contacts.offset[e]
        eta_plus = sign * (w0[e] * v[q] + w1[e] * v[q + 1] - offset)
        eta_now = sign * (w0[e] * u[q] + w1[e] * u[q + 1] - offset)
        eta_prev = sign * (w0[e] * u_prev[q] + w1[e] * u_prev[q + 1] - offset)
        two = contacts.two_sided[e]
        a = contacts.exponent[e]
        if a == 1.0 and (two or (eta_plus > 0.0 and eta_prev > 0.0)):  # the linear piece
            phi = 0.5 * k * (eta_plus + eta_prev)
            dphi = 0.5 * k
        elif not two and eta_plus <= 0.0 and eta_prev <= 0.0:  # apart
            phi = 0.0
            dphi = 0.0
        else:
            phi, dphi = _gradient(eta_plus, eta_prev, k, a, two)
        force, slope = phi, dphi
        if two or eta_now > 0.0:  # pressed: damped
            r = contacts.damping[e]
            force += r * (eta_plus - eta_prev) * half_rate
            slope += r * half_rate
        regime = (1 if eta_plus > 0.0 else 0) + (2 if eta_prev > 0.0 else 0)
        if not two:
            if regime == 1 or regime == 2:
                inexact = True
            if force < 0.0:  # a contact only pushes
                force = 0.0
                slope = 0.0
                regime += 4
        if regime != contacts.regime[e]:
            inexact = True
            contacts.regime[e] = regime
        contacts.eta_plus[e] = eta_plus
        contacts.eta_prev[e] = eta_prev
        contacts.force[e] = force
        contacts.potential_force[e] = phi
        contacts.slope[e] = slope
        if slope != contacts.factored[e]:
            refactor = True
        if contacts.on_desk[e]:
            on_desk += force
    return inexact, refactor, on_desk


@njit(inline='always', **_INNER)
def _residual(bar, scheme, contacts):  # pragma: no cover - compiled
    """``bar.residual <- A (v + u-) - rhs + sum_e sign_e J_e t_e``."""
    v, u_prev, rhs, res = bar.v, bar.u_prev, bar.rhs, bar.residual
    a0, a1, a2 = scheme.system[0], scheme.system[1], scheme.system[2]
    end = v.size - PAD
    for q in range(PAD, end):
        res[q] = (a0[q] * (v[q] + u_prev[q]) + a1[q] * (v[q + 1] + u_prev[q + 1])
                  + a1[q - 1] * (v[q - 1] + u_prev[q - 1]) + a2[q] * (v[q + 2] + u_prev[q + 2])
                  + a2[q - 2] * (v[q - 2] + u_prev[q - 2])) - rhs[q]
    first = contacts.first
    for e in range(first.size):
        if contacts.stiffness[e] == 0.0:
            continue
        push = contacts.sign[e] * contacts.force[e]
        q = first[e]
        res[q] += push * contacts.w0[e]
        res[q + 1] += push * contacts.w1[e]


@njit(inline='always', **_INNER)
def _solve_in_place(x, factors):  # pragma: no cover - compiled
    """``x <- J^-1 x`` with the factors of :func:`_factor`."""
    l1, l2, inv_d = factors[0], factors[1], factors[2]
    end = x.size - PAD
    for q in range(PAD, end):
        x[q] = x[q] - l1[q] * x[q - 1] - l2[q] * x[q - 2]
    for q in range(end - 1, PAD - 1, -1):
        x[q] = x[q] * inv_d[q] - l1[q + 1] * x[q + 1] - l2[q + 2] * x[q + 2]


_PLACING = {"cache": True, "nogil": True, "fastmath": {"contract"}, "error_model": "numpy"}
"""The edge's placement is also called from Python (when a note starts), so it keeps its wrapper."""


@njit(**_PLACING)
def place_edge(edge, contacts, output, x_edge):  # pragma: no cover - compiled
    """Put the edge at ``x_edge`` (m along the bar): the desk under each node by how much of its
    cell lies on the desk, the edge contact interpolated there, the radiating overhang beyond it.
    Continuous in ``x_edge``: a slide moves the contact region without a jump in the potential."""
    x, low, high = edge.x_m, edge.cell_low, edge.cell_high
    end = x.size - PAD
    for q in range(PAD, end):
        beyond = max(0.0, high[q] - max(low[q], x_edge))
        output.radiation[q] = edge.radiation_pa_s2_m2 * beyond
        if edge.desk_covers_edge:
            on = max(0.0, min(high[q], x_edge) - low[q])
            e = edge.desk_nodes[q]
            contacts.stiffness[e] = edge.desk_stiffness_n_m2 * on
            contacts.damping[e] = edge.desk_damping_n_s_m2 * on
    if edge.edge >= 0:
        _interpolate(edge, contacts, edge.edge, x_edge)
    if edge.finger >= 0:
        _interpolate(edge, contacts, edge.finger, x_edge - edge.finger_back_m)
    for e in range(contacts.factored.size):  # the Jacobian moved with them: factor it anew
        contacts.factored[e] = np.nan


@njit(**_PLACING)
def _interpolate(edge, contacts, e, x):  # pragma: no cover - compiled
    """Contact ``e`` at ``x`` (m along the bar), linearly between the nodes around it."""
    nodes = edge.x_m
    end = nodes.size - PAD
    q = PAD
    while q + 1 < end - 1 and nodes[q + 1] <= x:
        q += 1
    w1 = min(max((x - nodes[q]) / (nodes[q + 1] - nodes[q]), 0.0), 1.0)
    contacts.first[e] = q
    contacts.w0[e] = 1.0 - w1
    contacts.w1[e] = w1


@njit(cache=True, nogil=True, fastmath={"contract"}, error_model="numpy")
def process(out, scheme, bar, contacts, edge, output):  # pragma: no cover - compiled
    """Advance the ruler ``out.size`` samples; ``out`` gets the mixed pressure (Pa at 1 m) x level.

    Per step: the right-hand side ``B u + (C/k) u- + f_gravity``; Newton's method on ``u+`` from
    ``2u - u-`` (one pentadiagonal solve an iteration, the factors kept while the contacts'
    slopes stay); the radiation (the overhang's summed acceleration) and the force on the desk.
    Per chunk the desk's bank turns that force into its sound; the two are mixed.
    """
    u, u_prev, v, rhs = bar.u, bar.u_prev, bar.v, bar.rhs
    end = u.size - PAD
    rate = scheme.step_rate
    half_rate = 0.5 * rate
    bands = scheme.bands
    b0, bl1, br1, bl2, br2, c0, cl, cr = bands[0], bands[1], bands[2], bands[3], bands[4], bands[5], bands[6], bands[7]
    gravity = scheme.gravity
    radiation = output.radiation
    state = output.state[0]
    edge_state = edge.state[0]
    chunk = output.force.size
    level = output.level
    for start in range(0, out.size, chunk):
        stop = min(out.size, start + chunk)
        for t in range(start, stop):
            if edge.slide_m > 0.0 and edge_state.steps <= edge.slide_steps:
                phase = edge_state.steps / edge.slide_steps
                moved = edge.slide_m * (0.5 - 0.5 * np.cos(np.pi * phase))
                place_edge(edge, contacts, output, edge.start_m + moved)
                edge_state.steps += 1
            for q in range(PAD, end):
                rhs[q] = (b0[q] * u[q] + bl1[q] * u[q - 1] + br1[q] * u[q + 1] + bl2[q] * u[q - 2]
                          + br2[q] * u[q + 2] + c0[q] * u_prev[q] + cl[q] * u_prev[q - 1]
                          + cr[q] * u_prev[q + 1] + gravity[q])
                v[q] = 2.0 * u[q] - u_prev[q]
            inexact, refactor, on_desk = _contact_terms(contacts, v, u, u_prev, half_rate)
            iterations = 0
            previous_move = 0.0
            for _ in range(MAX_NEWTON_STEPS):
                _residual(bar, scheme, contacts)
                if refactor:
                    _factor_bands(bar.factors, scheme.system, contacts)
                res = bar.residual
                _solve_in_place(res, bar.factors)
                largest_move = 0.0
                largest = 0.0
                for q in range(PAD, end):
                    v[q] -= res[q]
                    largest_move = max(largest_move, abs(res[q]))
                    largest = max(largest, abs(v[q]))
                iterations += 1
                inexact, refactor, on_desk = _contact_terms(contacts, v, u, u_prev, half_rate)
                if scheme.linear and not inexact:
                    break  # linear on unchanged pieces: this iteration was exact
                tolerance = ABSOLUTE_TOLERANCE_M + RELATIVE_TOLERANCE * largest
                if largest_move <= tolerance:
                    break
                if iterations > 1 and largest_move * largest_move <= tolerance * previous_move:
                    break  # converging quadratically: the next move would be within the tolerance
                previous_move = largest_move
            if iterations >= MAX_NEWTON_STEPS:
                state.unconverged += 1
            state.iterations += iterations
            state.steps += 1
            if iterations > state.most_iterations:
                state.most_iterations = iterations
            # the step: energy taken, then the state moves on, the sound summed on the way
            if state.track:
                lost = 0.0
                for q in range(PAD, end):
                    w = v[q] - u_prev[q]
                    lost += w * (c0[q] * w + cl[q] * (v[q - 1] - u_prev[q - 1]) + cr[q] * (v[q + 1] - u_prev[q + 1]))
                state.lost_losses_j += 0.25 * lost
                damped = 0.0
                for e in range(contacts.first.size):
                    if contacts.stiffness[e] != 0.0:
                        damped += (contacts.force[e] - contacts.potential_force[e]) * (
                            contacts.eta_plus[e] - contacts.eta_prev[e])
                state.lost_contact_j += 0.5 * damped
            pressure = 0.0
            for q in range(PAD, end):
                now = u[q]
                pressure += radiation[q] * (v[q] - 2.0 * now + u_prev[q])
                u_prev[q] = now
                u[q] = v[q]
            pressure *= rate * rate
            output.force[t - start] = on_desk - output.rest_force_n
            out[t] = pressure
        n = stop - start
        process_desk(output.force[:n], output.desk_sound[:n], output.desk)
        for t in range(start, stop):
            out[t] = (output.bar_gain * out[t] + output.desk_gain * output.desk_sound[t - start]) * next_value(
                level, MULTIPLICATIVE)


@njit(**_INNER)
def _factor_bands(factors, system, contacts):  # pragma: no cover - compiled
    """``L D L^T`` of ``A + sum_e slope_e J_e J_e^T`` (``A``'s bands in ``system``) into ``factors``
    (l1, l2, 1/d), the contacts' slopes remembered as ``factored``."""
    l1, l2, inv_d = factors[0], factors[1], factors[2]
    a0, a1, a2 = system[0], system[1], system[2]
    n = a0.size
    for q in range(n):  # l1 <- the diagonal, l2 <- the first band, then factored in place
        l1[q] = a0[q]
        l2[q] = a1[q]
    first = contacts.first
    for e in range(first.size):
        s = contacts.slope[e]
        contacts.factored[e] = s
        if s == 0.0 or contacts.stiffness[e] == 0.0:
            continue
        q = first[e]
        w0, w1 = contacts.w0[e], contacts.w1[e]
        l1[q] += s * w0 * w0
        l1[q + 1] += s * w1 * w1
        l2[q] += s * w0 * w1
    end = n - PAD
    d_1 = d_2 = 1.0  # d of rows q-1, q-2 (unused before the first rows)
    m1_prev = 0.0  # L[q-1, q-2]
    band_prev = 0.0  # A[q-1, q]
    for q in range(PAD, end):
        diag, band = l1[q], l2[q]
        lq2 = a2[q - 2] / d_2 if q >= PAD + 2 else 0.0
        lq1 = (band_prev - lq2 * d_2 * m1_prev) / d_1 if q >= PAD + 1 else 0.0
        d = diag - lq1 * lq1 * d_1 - lq2 * lq2 * d_2
        inv_d[q] = 1.0 / d
        l1[q] = lq1
        l2[q] = lq2
        band_prev = band
        m1_prev = lq1
        d_2 = d_1
        d_1 = d
    for q in range(end, n):
        l1[q] = 0.0
        l2[q] = 0.0
