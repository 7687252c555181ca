"""One smoothing primitive for every parameter glide: linear or multiplicative ramps in seconds.

After JUCE's ``SmoothedValue``: a value moves to each new target along a straight line
(``LINEAR``: gains, positions, mixes) or a geometric one (``MULTIPLICATIVE``: frequencies,
lengths, Q, anything on a log scale; both ends must be positive) in a set number of steps,
then holds. A new target mid-ramp starts a new ramp from where the value is.

The state is a small float64 array (``SMOOTHED_STATE`` slots: current, target, step, steps
left), so numba kernels carry it between blocks and step it with :func:`next_value`; the
:class:`SmoothedValue` class wraps the same functions for Python callers.

Every model's parameter glides use it (the bar models' level, the twangs' controls). Two
envelopes read by sample index keep their own arithmetic, with their lengths from
:func:`ramp_steps`: a bow's stroke and its velocity and force glides
(:mod:`barsynth.dsp.bow_stroke`: breakpoint lines the kernel reads at any sample) and the
fade-out of a replaced all-pass waveguide (:mod:`barsynth.models.allpass.voice`: exact gains
read from its end); why, each module says.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

LINEAR = 0
MULTIPLICATIVE = 1
CURRENT, TARGET, STEP, LEFT = 0, 1, 2, 3
SMOOTHED_STATE = 4
KINDS = {"linear": LINEAR, "multiplicative": MULTIPLICATIVE}

LEVEL_GLIDE_S = 0.020
"""A bar model's new ``level_db`` is reached over this time (s), multiplicatively (equal steps
of dB), a step a sample: the output gain of the banded, all-pass and finite-difference voices."""


@njit(cache=True, inline="always")
def start_ramp(state, kind, target, steps):  # pragma: no cover - compiled
    """Glide ``state`` to ``target`` over ``steps`` steps (``steps`` <= 0: jump there now)."""
    state[TARGET] = target
    current = state[CURRENT]
    if steps <= 0 or current == target:
        state[CURRENT] = target
        state[LEFT] = 0.0
        return
    if kind == LINEAR:
        state[STEP] = (target - current) / steps
    else:
        state[STEP] = math.exp(math.log(target / current) / steps)
    state[LEFT] = steps


start_ramp_now = start_ramp.py_func
""":func:`start_ramp` called from Python (an event, not a block): the same arithmetic, without
loading (or compiling) a kernel for it."""


@njit(cache=True, inline="always")
def next_value(state, kind):  # pragma: no cover - compiled
    """One step along the ramp; the value after it (the target once the ramp has ended)."""
    left = state[LEFT]
    if left > 0.0:
        left -= 1.0
        state[LEFT] = left
        if left <= 0.0:
            state[CURRENT] = state[TARGET]
        elif kind == LINEAR:
            state[CURRENT] += state[STEP]
        else:
            state[CURRENT] *= state[STEP]
    return state[CURRENT]


@njit(cache=True)
def skip(state, kind, steps):  # pragma: no cover - compiled
    """Advance ``steps`` steps at once; the value after them."""
    left = state[LEFT]
    if left <= 0.0:
        return state[CURRENT]
    if steps >= left:
        state[CURRENT] = state[TARGET]
        state[LEFT] = 0.0
    elif kind == LINEAR:
        state[CURRENT] += state[STEP] * steps
        state[LEFT] = left - steps
    else:
        state[CURRENT] *= state[STEP] ** steps
        state[LEFT] = left - steps
    return state[CURRENT]


@njit(cache=True, nogil=True)
def scale(out, state, kind):  # pragma: no cover - compiled
    """Multiply ``out`` in place by the value, stepped once a sample (``out[t]`` by the value
    after ``t + 1`` steps); once the ramp has ended, by the held value (a held 1 leaves ``out``
    as it is). Allocates nothing."""
    n = out.size
    t = 0
    while t < n and state[LEFT] > 0.0:
        out[t] *= next_value(state, kind)
        t += 1
    gain = state[CURRENT]
    if gain != 1.0:
        for i in range(t, n):
            out[i] *= gain


def ramp_steps(ramp_s: float, step_rate: float) -> int:
    """Whole steps in a ramp of ``ramp_s`` seconds at ``step_rate`` steps a second (at least 1)."""
    return max(1, int(round(ramp_s * step_rate)))


class SmoothedValue:
    """A value that glides to each target in ``ramp_s`` seconds at ``step_rate`` steps a second.

    Examples
    --------
    >>> gain = SmoothedValue(1.0, ramp_s=0.001, step_rate=4000, kind="linear")
    >>> gain.set_target(0.0)
    >>> [gain.next_value() for _ in range(5)]
    [0.75, 0.5, 0.25, 0.0, 0.0]
    >>> pitch = SmoothedValue(100.0, ramp_s=0.002, step_rate=1000, kind="multiplicative")
    >>> pitch.set_target(400.0); round(pitch.next_value(), 9), pitch.is_smoothing
    (200.0, True)
    """

    def __init__(self, value: float, *, ramp_s: float, step_rate: float, kind: str = "linear"):
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {', '.join(KINDS)}, not {kind!r}")
        self.kind = KINDS[kind]
        self.state = np.zeros(SMOOTHED_STATE)
        self.state[CURRENT] = self.state[TARGET] = value
        self.reset(step_rate, ramp_s)

    def reset(self, step_rate: float, ramp_s: float) -> None:
        """Set the step rate (steps a second) and ramp length (s); the value jumps to its target."""
        self.steps = ramp_steps(ramp_s, step_rate)
        self.set_current_and_target(self.state[TARGET])

    def set_current_and_target(self, value: float) -> None:
        """Jump to ``value`` now."""
        start_ramp(self.state, self.kind, float(value), 0)

    def set_target(self, value: float) -> None:
        """Glide from the present value to ``value`` over the ramp."""
        if value != self.state[TARGET]:  # (the same target again: the ramp carries on)
            start_ramp(self.state, self.kind, float(value), self.steps)

    def next_value(self) -> float:
        return float(next_value(self.state, self.kind))

    def skip(self, steps: int) -> float:
        return float(skip(self.state, self.kind, float(steps)))

    @property
    def current(self) -> float:
        return float(self.state[CURRENT])

    @property
    def target(self) -> float:
        return float(self.state[TARGET])

    @property
    def is_smoothing(self) -> bool:
        return bool(self.state[LEFT] > 0.0)
