"""A bow's controls over time: stroke (speed and pressure) and glides of its settings.

Source: barsynth spec 3.1 (a bowed bar sustains while the bow moves and stops when
it stops). A stroke is a set of straight-line breakpoints in absolute sample time:
the bow presses and speeds up together over a ramp, moves for the stroke's length,
slows to rest over a ramp while still pressing (a resting bow damps the bar), and
is lifted a little later. Starting a stroke while one sounds carries on from the
present speed and pressure; a new bow velocity or force glides there in a straight
line. Nothing jumps.

The four lines (speed and pressure as fractions, velocity in m/s, force in N) are
kept in one array that the bowed kernel reads per sample with :func:`line_value`,
so every value is a function of the absolute sample index only: blocks of any size
give exactly the samples of one long block, and no per-sample arrays are built
(measured: building them with NumPy cost as much as the bowed kernel itself).

Why these are not :mod:`barsynth.dsp.smoothing` ramps, although a glide of the bow's
velocity or force is a parameter glide (its length is smoothing's
:func:`~barsynth.dsp.smoothing.ramp_steps`): a stroke is an envelope of several
breakpoints set in advance (press, move, slow, rest, lift), which a ramp that only
knows its next target cannot hold; the kernel reads each line at any sample index
(``value(row, index)``, ``held_until`` to skip a held stretch) instead of stepping a
state once a sample; and a line's value is ``v0 + (v1 - v0) (x - t0) / (t1 - t0)``,
where a linear ramp adds ``(v1 - v0) / steps`` once a step: the rounding differs, so
the bowed sounds would change. The velocity and force glides share the stroke's
lines, so one reader serves all four.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

LIFT_DELAY_S = 0.5
"""How long a stopped bow rests on the bar (damping it) before it is lifted (s)."""
SPEED, PRESSURE, VELOCITY, FORCE = 0, 1, 2, 3
"""Rows of :attr:`BowControls.lines`: bow speed and pressure as fractions (0 to 1) of the
set bow velocity (m/s) and bow force (N). The bow's velocity is speed x velocity, its
force pressure x force."""
POINTS = 5  # breakpoints per line (unused ones repeat the last)


@njit(cache=True, inline="always")
def line_value(line, x, j):  # pragma: no cover - compiled
    """Value of breakpoint ``line`` (row 0 times, row 1 values) at sample index ``x``.

    ``j`` is the piece found for an earlier (not later) ``x``; returns ``(value, j)``.
    Before the first breakpoint and after the last the line holds its end values.
    """
    last = line.shape[1] - 1
    while j < last and line[0, j + 1] <= x:
        j += 1
    if x < line[0, 0]:
        return line[1, 0], j
    if j == last:
        return line[1, last], j
    v0 = line[1, j]
    v1 = line[1, j + 1]
    if v1 == v0:  # a held level (most of a stroke): no division
        return v0, j
    return v0 + (v1 - v0) * ((x - line[0, j]) / (line[0, j + 1] - line[0, j])), j


@njit(cache=True, inline="always")
def held_until(line, x, j):  # pragma: no cover - compiled
    """``(value, j, until)``: the line's value at ``x`` and, when it holds that value
    from ``x`` on, the index of its next breakpoint (infinity after the last), else ``x``."""
    value, j = line_value(line, x, j)
    last = line.shape[1] - 1
    if x < line[0, 0]:
        return value, j, line[0, 0] if line[1, 0] == value else x
    if j == last:
        return value, j, np.inf
    if line[1, j] == line[1, j + 1]:
        return value, j, line[0, j + 1]
    return value, j, x


class BowControls:
    """The bow's speed, pressure, velocity and force as breakpoint lines in sample time.

    Examples
    --------
    >>> bow = BowControls(velocity_m_s=0.3, force_n=2.0)
    >>> bow.start(duration=100, ramp=10, lift_delay=20)
    >>> bow.value(SPEED, 5), bow.value(SPEED, 50), bow.value(SPEED, 150), bow.value(PRESSURE, 125)
    (0.5, 1.0, 0.0, 1.0)
    >>> bow.lifted_at
    140
    """

    def __init__(self, *, velocity_m_s: float, force_n: float) -> None:
        self.now = 0
        self.lines = np.zeros((4, 2, POINTS))
        self._set(SPEED, (0.0, 0.0))
        self._set(PRESSURE, (0.0, 0.0))
        self._set(VELOCITY, (0.0, velocity_m_s))
        self._set(FORCE, (0.0, force_n))

    def _set(self, row: int, *points: tuple[float, float]) -> None:
        times, values = [], []
        for time, value in points:  # a later point wins where times repeat
            if times and time <= times[-1]:
                times.pop()
                values.pop()
            times.append(float(time))
            values.append(float(value))
        padding = POINTS - len(times)
        self.lines[row, 0] = times + times[-1:] * padding
        self.lines[row, 1] = values + values[-1:] * padding
        if row == PRESSURE:  # (read at every block of a voice: kept, not computed there)
            self._lifted_at = int(math.ceil(self.lines[PRESSURE, 0, -1]))

    def value(self, row: int, index: int) -> float:
        """One line's value at a sample index."""
        return float(line_value(self.lines[row], float(index), 0)[0])

    def start(self, *, duration: int, ramp: int, lift_delay: int) -> None:
        """Bow from now: press and speed up over ``ramp`` samples, move for ``duration``, stop, lift."""
        now = self.now
        speed, pressure = self.value(SPEED, now), self.value(PRESSURE, now)
        moving = now + ramp * (1.0 - speed)
        stopping = max(moving, now + duration)
        self._set(SPEED, (now, speed), (moving, 1.0), (stopping, 1.0), (stopping + ramp, 0.0))
        self._set(PRESSURE, (now, pressure), (now + ramp * (1.0 - pressure), 1.0),
                  (stopping + ramp + lift_delay, 1.0), (stopping + 2 * ramp + lift_delay, 0.0))

    def stop(self, *, ramp: int, lift_delay: int) -> None:
        """Slow the bow to rest from now (``ramp`` samples from full speed), then lift it.
        A bow already at rest (stopping, lifted, or never started) is left as it is."""
        now = self.now
        speed, pressure = self.value(SPEED, now), self.value(PRESSURE, now)
        times, speeds = self.lines[SPEED]
        if speed == 0.0 and not np.any(speeds[times > now] > 0.0):
            return
        resting = now + ramp * speed
        self._set(SPEED, (now, speed), (resting, 0.0))
        self._set(PRESSURE, (now, pressure), (resting + lift_delay, pressure),
                  (resting + lift_delay + ramp * pressure, 0.0))

    def glide(self, row: int, target: float, length: int) -> None:
        """Move the bow velocity or force from its present value to ``target`` over ``length`` samples."""
        now = self.now
        self._set(row, (now, self.value(row, now)), (now + max(1, length), target))

    @property
    def lifted_at(self) -> int:
        """The first sample index from which the bow is off the bar (until another stroke)."""
        return self._lifted_at  # (the pressure line's last time, rounded up: set with the line)
