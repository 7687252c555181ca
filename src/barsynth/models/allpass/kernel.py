"""Numba kernel of the all-pass waveguide bar (barsynth spec 3.2).

The loop's four filters (designed by :mod:`barsynth.models.allpass.design`) in the order a
wave goes round::

    0 end0 (x_a -> 0 -> x_a)   1 right (x_a -> x_b)   2 endL (x_b -> L -> x_b)   3 left (x_b -> x_a)

Filter ``k`` is ``signs[k] x z^-delays[k] x`` the biquad rows ``first[k]:first[k + 1]`` of
``rows`` (``b0 b1 b2 a1 a2``, transposed direct form II, two states a row). The force (N)
goes through the strike filter into a travelling-wave velocity ``u`` (m/s), added to both
waves leaving the strike point: ``u`` enters filter ``k`` with weight ``inject[k]``
(``inject_a`` for end0 and right, ``inject_b`` for endL and left). The pick-up reads the two
waves arriving at its point (and ``u`` if the force is applied there) through the pick-up
filter.

Per sample the loop runs from ``anchor``, a filter with a delay of at least one sample (its
output depends only on the past), round to the filter before it; each filter writes its input
into its delay line, reads ``delay`` samples back and runs its rows. The coefficients travel as
one :class:`Loop`, every state as one :class:`LoopState` owned by the caller, so blocks of any
size give the same samples as one long block. numba's dispatcher would type the two records in
Python at every call (2.4 us more than plain tuples, measured: a tenth of a 256-sample block),
so the voice calls the compiled overload's entry point (:func:`barsynth.jitstart.compiled_for`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

N_FILTERS = 4


class Loop(NamedTuple):
    """The waveguide's coefficients (read only)."""

    rows: np.ndarray  # (rows, 5) biquads of the four filters, one after another
    first: np.ndarray  # int64 (5,): filter k's rows are first[k]:first[k + 1]
    delays: np.ndarray  # int64 (4,): samples
    signs: np.ndarray  # (4,): +1 or -1
    inject: np.ndarray  # (4,): weight of the strike's wave entering each filter
    pick: np.ndarray  # (2,): weights of the waves at x_a and at x_b in the pick-up
    anchor: int  # a filter with a delay of at least one sample
    strike_rows: np.ndarray  # (rows, 5): force (N) -> travelling-wave velocity (m/s)
    pickup_rows: np.ndarray  # (rows, 5): sum of the waves -> output (the level is the voice's output gain)


class LoopState(NamedTuple):
    """What the waveguide remembers between blocks."""

    buffers: np.ndarray  # (4, power of two): the delay lines
    states: np.ndarray  # (rows, 2): the loop filters' biquad states
    position: np.ndarray  # int64 (1,): the delay lines' write index
    strike_states: np.ndarray  # (strike rows, 2)
    pickup_states: np.ndarray  # (pickup rows, 2)
    outputs: np.ndarray  # (4,): each filter's output in the present sample (scratch)


@njit(cache=True, inline="always")
def _cascade(rows, states, lo, hi, x):  # pragma: no cover - compiled
    for r in range(lo, hi):
        y = rows[r, 0] * x + states[r, 0]
        states[r, 0] = rows[r, 1] * x - rows[r, 3] * y + states[r, 1]
        states[r, 1] = rows[r, 2] * x - rows[r, 4] * y
        x = y
    return x


@njit(cache=True, nogil=True, fastmath={"contract"})
def process(out, pending, held, loop, state):  # pragma: no cover - compiled
    """Run the waveguide (``loop``: a :class:`Loop`, ``state``: a :class:`LoopState`) for
    ``out.size`` samples driven by a force (N): ``pending[t]`` for the first ``pending.size``
    samples, then ``held``; velocity at the pick-up (m/s)."""
    rows, first, delays, signs, inject, pick = loop.rows, loop.first, loop.delays, loop.signs, loop.inject, loop.pick
    anchor, strike_rows, pickup_rows = loop.anchor, loop.strike_rows, loop.pickup_rows
    buffers, states, position, y = state.buffers, state.states, state.position, state.outputs
    strike_states, pickup_states = state.strike_states, state.pickup_states
    mask = buffers.shape[1] - 1
    pos = position[0]
    n_pending = min(out.size, pending.size)
    n_strike, n_pickup = strike_rows.shape[0], pickup_rows.shape[0]
    for t in range(out.size):
        force = pending[t] if t < n_pending else held
        u = _cascade(strike_rows, strike_states, 0, n_strike, force)
        k = anchor
        y[k] = signs[k] * _cascade(rows, states, first[k], first[k + 1], buffers[k, (pos - delays[k]) & mask])
        for step in range(1, N_FILTERS):
            prev = k
            k = (anchor + step) % N_FILTERS
            buffers[k, pos] = y[prev] + inject[k] * u
            y[k] = signs[k] * _cascade(rows, states, first[k], first[k + 1], buffers[k, (pos - delays[k]) & mask])
        buffers[anchor, pos] = y[k] + inject[anchor] * u
        at_a = y[0] + y[3] + inject[0] * u
        at_b = y[1] + y[2] + inject[2] * u
        v = pick[0] * at_a + pick[1] * at_b
        out[t] = _cascade(pickup_rows, pickup_states, 0, n_pickup, v)
        pos = (pos + 1) & mask
    position[0] = pos


def empty_state(loop: Loop) -> LoopState:
    """Silence: delay lines (a power-of-two length above every delay), filter states, write index."""
    size = 1 << int(max(int(loop.delays.max()), 1)).bit_length()
    return LoopState(np.zeros((N_FILTERS, size)), np.zeros((loop.rows.shape[0], 2)), np.zeros(1, dtype=np.int64),
                     np.zeros((loop.strike_rows.shape[0], 2)), np.zeros((loop.pickup_rows.shape[0], 2)),
                     np.zeros(N_FILTERS))


def silence(state: LoopState) -> None:
    """Empty ``state`` in place, as :func:`empty_state` makes it."""
    for array in state:
        array[...] = 0
