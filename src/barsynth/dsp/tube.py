"""A resonator tube under a bar: closed at the bottom, open at the top, as a digital waveguide.

Sources: the bar-tube coupling after V. Doutaut, D. Matignon and A. Chaigne, "Numerical
simulations of xylophones. II. Time-domain modeling of the resonator and of the radiated
sound pressure", JASA 104(3), 1998 (a 1-D tube driven by the bar above its mouth); the open
end after H. Levine and J. Schwinger, "On the radiation of sound from an unflanged circular
pipe", Phys. Rev. 73, 1948 (|R| ~ 1 - (ka)^2 / 2 at low ka, end correction 0.6 a); wall
losses after N. H. Fletcher and T. D. Rossing, *The Physics of Musical Instruments*, 2nd ed.,
ch. 8 (alpha ~ 3e-5 sqrt(f) / a nepers per metre in air; A. H. Benade, JASA 44, 1968).

The pressure wave going down the tube leaves the mouth, runs ``N`` samples (down and back:
the closed end reflects it with +1), loses ``W(z)`` to the walls and ``A(z)`` (a first-order
Thiran all-pass) places the round trip to a fraction of a sample; at the mouth the open end
reflects ``R(z) = -P(z)``, ``P`` a one-pole low-pass matched to Levine & Schwinger's low-ka
magnitude, and what is not reflected radiates: the pressure at the mouth ``(1 + R) u`` (a
high-pass: a small tube radiates its low resonance weakly), which is the tube's sound. The
drive (the bar's velocity at the mouth) enters the down-going wave at the mouth.

    u = A W z^-N d          (the wave arriving back at the mouth)
    d = -P u + k x          (reflected, plus the drive x)
    y = (1 - P) u           (the pressure at the mouth: radiated)

The round trip is placed by :func:`design_tube` so that the tube's first (quarter-wave)
resonance, the pole of ``1 / (1 + P W A z^-N)``, lies exactly at the requested frequency:
the phase delays of the reflection and wall filters count, so the effective length comes out
with its end correction instead of assuming 0.6 a. ``k`` normalises the drive-to-sound
transfer to 1 at that frequency.

Simplified: the coupling is one way (the bar drives the tube; the tube's pull on the bar is
left to the model using it, as extra damping of the tuned mode); the wall loss is fitted by a
one-pole low-pass at the first two resonances (the sqrt(f) law is matched there, not
everywhere); the reflection is fitted only in its low-ka limit; the mouth is a point.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from .smoothing import LINEAR, next_value

SPEED_OF_SOUND_M_S = 343.0
"""Speed of sound in air at 20 degrees C (m/s)."""
END_CORRECTION = 0.6
"""The open end's end correction of an unflanged pipe, in radii (Levine & Schwinger: 0.6133)."""
WALL_LOSS = 3e-5
"""Visco-thermal wall loss in air: alpha = WALL_LOSS sqrt(f) / a nepers per metre (f in Hz, a in m;
Fletcher & Rossing ch. 8)."""
LONGEST_TUBE_S = 1.0 / (2.0 * 10.0)
"""The longest round trip a tube state holds (s): a tube tuned down to 10 Hz."""

TUBE_STATE = 8
W1, AP_X, AP_Y, P1, PHASE, POS = 0, 1, 2, 3, 4, 5
"""Slots of a tube's filter state: wall filter output, all-pass input and output, reflection
filter output, the motor's phase (rad) and the write index (as a float)."""


@dataclass(frozen=True)
class TubeDesign:
    """A tube's round trip, ready for :func:`run_tube`.

    ``delay``: N (samples); ``eta``: the all-pass coefficient; ``wall_b0, wall_a1``: the wall
    loss ``w = b0 x + a1 w[-1]``; ``reflection_p``: the open end's pole (``P(z) = (1 - p) / (1 -
    p z^-1)``); ``drive_in``: k, the drive-to-sound transfer's normalisation; ``frequency_hz``:
    the first resonance (the pole's angle); ``t60_s``: its decay; ``length_m``: the length of
    tube the round trip's propagation stands for (c (N + the all-pass's delay) / (2 fs); the
    filters' lag is its end correction).
    """

    frequency_hz: float
    radius_m: float
    sample_rate: float
    delay: int
    eta: float
    wall_b0: float
    wall_a1: float
    reflection_p: float
    drive_in: float
    t60_s: float
    length_m: float

    @property
    def coefficients(self) -> np.ndarray:
        """``[N, eta, wall_b0, wall_a1, p, k]`` for :func:`run_tube`."""
        return np.array([self.delay, self.eta, self.wall_b0, self.wall_a1, self.reflection_p, self.drive_in])

    def _parts(self, z: complex) -> tuple[complex, complex]:
        u = 1.0 / z
        p = self.reflection_p
        reflect = (1.0 - p) / (1.0 - p * u)
        wall = self.wall_b0 / (1.0 - self.wall_a1 * u)
        allpass = (self.eta + u) / (1.0 + self.eta * u)
        return reflect, wall * allpass * u ** self.delay

    def transfer(self, z: complex) -> complex:
        """The drive-to-sound transfer H(z) (times k: 1 in magnitude at the resonance)."""
        reflect, trip = self._parts(z)
        return self.drive_in * (1.0 - reflect) * trip / (1.0 + reflect * trip)

    def response_to_mode(self, frequency_hz: float, t60_s: float) -> complex:
        """H at a mode's pole ``r e^{j w}``: what the tube makes of a drive that rings at
        ``frequency_hz`` with ``t60_s`` (the forced part; its own ringing decays at ``t60_s``
        of the tube)."""
        r = 10.0 ** (-3.0 / (t60_s * self.sample_rate)) if math.isfinite(t60_s) else 1.0
        return self.transfer(cmath.rect(r, 2.0 * math.pi * frequency_hz / self.sample_rate))


    def resonance_near(self, frequency_hz: float) -> tuple[float, float]:
        """The tube's resonance nearest ``frequency_hz`` (its first, or a higher one near an odd
        multiple): ``(frequency_hz, t60_s)`` of the pole of ``1 / (1 + P W A z^-N)`` found by
        Newton steps from ``e^{j 2 pi frequency_hz / fs}``."""
        z = cmath.rect(1.0, 2.0 * math.pi * frequency_hz / self.sample_rate)
        def loop(z: complex) -> complex:
            reflect, trip = self._parts(z)
            return 1.0 + reflect * trip

        for _ in range(60):
            h = 1e-7 * abs(z)
            step = loop(z) * h / (loop(z + h) - loop(z))
            if not cmath.isfinite(step):
                return math.nan, math.nan
            z -= step if abs(step) < 0.01 else 0.01 * step / abs(step)
            if abs(step) < 1e-13:
                break
        r = abs(z)
        t60_s = -3.0 / (self.sample_rate * math.log10(r)) if r < 1.0 else math.inf
        return cmath.phase(z) * self.sample_rate / (2.0 * math.pi), t60_s


def reflection_pole(radius_m: float, sample_rate: float, speed_m_s: float = SPEED_OF_SOUND_M_S) -> float:
    """The pole p of ``P(z) = (1 - p) / (1 - p z^-1)``, whose magnitude falls as 1 - (ka)^2 / 2 at
    low ka (Levine & Schwinger): p / (1 - p)^2 = (fs a / c)^2."""
    s2 = (sample_rate * radius_m / speed_m_s) ** 2
    return ((2.0 * s2 + 1.0) - math.sqrt(4.0 * s2 + 1.0)) / (2.0 * s2)


def wall_loss_filter(frequency_hz: float, radius_m: float, length_m: float,
                     sample_rate: float) -> tuple[float, float]:
    """``(b0, a1)`` of a one-pole low-pass whose magnitude is the round trip's wall loss
    exp(-2 L alpha(f)) at the tube's first two resonances (f and 3 f), alpha =
    ``WALL_LOSS`` sqrt(f) / a; a constant gain where no pole in [0, 1) fits."""
    from scipy.optimize import brentq

    def loss(f: float) -> float:  # nepers a round trip
        return 2.0 * length_m * WALL_LOSS * math.sqrt(f) / radius_m

    w1, w3 = (2.0 * math.pi * f / sample_rate for f in (frequency_hz, 3.0 * frequency_hz))
    wanted = loss(3.0 * frequency_hz) / loss(frequency_hz)

    def log_shape(q: float, w: float) -> float:  # ln of |(1 - q) / (1 - q e^-jw)|
        return math.log(1.0 - q) - 0.5 * math.log(1.0 - 2.0 * q * math.cos(w) + q * q)

    def mismatch(q: float) -> float:
        # with gain g: ln g + s(w): the ratio of the two losses must be `wanted`
        s1, s3 = log_shape(q, w1), log_shape(q, w3)
        gain = -loss(frequency_hz) - s1  # ln g so that the loss at f is right
        return (-(gain + s3)) / loss(frequency_hz) - wanted

    q = 0.0
    if w3 < math.pi and mismatch(0.0) < 0.0 < mismatch(0.999):
        q = brentq(mismatch, 0.0, 0.999, xtol=1e-14)
    g = math.exp(-loss(frequency_hz) - log_shape(q, w1))
    return g * (1.0 - q), q


def design_tube(frequency_hz: float, radius_m: float, sample_rate: float, *,
                speed_m_s: float = SPEED_OF_SOUND_M_S) -> TubeDesign:
    """The tube of inner radius ``radius_m`` whose first resonance rings at ``frequency_hz``.

    Raises ``ValueError`` where no tube fits (its end correction alone longer than a quarter
    wavelength, or a round trip under two samples); the model says so in its own words.

    Examples
    --------
    >>> tube = design_tube(220.0, 0.025, 48000.0)
    >>> round(tube.frequency_hz, 6), round(tube.length_m, 3), round(tube.t60_s, 2)
    (220.0, 0.374, 0.85)
    """
    if not 0.0 < frequency_hz < sample_rate / 8.0:
        raise ValueError(f"no tube at {frequency_hz} Hz for a sample rate of {sample_rate} Hz")
    length_m = speed_m_s / (4.0 * frequency_hz) - END_CORRECTION * radius_m
    if not length_m > 0.0:
        raise ValueError(f"a tube of radius {radius_m} m cannot resonate at {frequency_hz} Hz: its end correction "
                         "exceeds a quarter wavelength")
    w = 2.0 * math.pi * frequency_hz / sample_rate
    p = reflection_pole(radius_m, sample_rate, speed_m_s)
    b0, a1 = wall_loss_filter(frequency_hz, radius_m, length_m, sample_rate)

    def filters(z: complex) -> complex:  # P(z) W(z)
        u = 1.0 / z
        return (1.0 - p) / (1.0 - p * u) * b0 / (1.0 - a1 * u)

    def allpass(z: complex, eta: float) -> complex:
        u = 1.0 / z
        return (eta + u) / (1.0 + eta * u)

    # The pole z0 = r e^{jw} of 1 / (1 + P W A z^-N): P W A z0^-N = -1. Phase: arg(P W) + arg A
    # - N w = -pi; the all-pass covers 0.5 to 1.5 samples. Magnitude: r^N = |P W A|(z0).
    r = 1.0
    eta = 0.0
    delay = 0
    for _ in range(6):
        z0 = cmath.rect(r, w)
        needed = (math.pi + cmath.phase(filters(z0))) / w  # samples of delay and all-pass
        delay = int(math.floor(needed - 0.5))
        if delay < 2:
            raise ValueError(f"a tube at {frequency_hz} Hz is too short for {sample_rate} Hz")
        target = -(needed - delay) * w  # the all-pass's phase at z0
        k = math.tan(-target / 2.0) / math.tan(w / 2.0)
        eta = (1.0 - k) / (1.0 + k)
        for _ in range(8):  # the all-pass's phase at z0 inside the circle: secant steps
            e0 = math.remainder(cmath.phase(allpass(z0, eta)) - target, 2.0 * math.pi)
            e1 = math.remainder(cmath.phase(allpass(z0, eta + 1e-7)) - target, 2.0 * math.pi)
            if e0 == 0.0 or e1 == e0:
                break
            eta -= e0 * 1e-7 / (e1 - e0)
        r = abs(filters(z0) * allpass(z0, eta)) ** (1.0 / delay)
    length_m = speed_m_s * needed / sample_rate / 2.0  # the propagation; the filters' lag is the end correction
    design = TubeDesign(frequency_hz, radius_m, sample_rate, delay, eta, b0, a1, p, 1.0,
                        -3.0 / (sample_rate * math.log10(r)), length_m)
    gain = abs(design.transfer(cmath.rect(1.0, w)))
    return TubeDesign(frequency_hz, radius_m, sample_rate, delay, eta, b0, a1, p, 1.0 / gain, design.t60_s,
                      design.length_m)


def empty_tube(sample_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """A silent tube: its filter state (``TUBE_STATE`` values) and a delay line long enough
    for any tube down to ``1 / (2 LONGEST_TUBE_S)`` Hz at ``sample_rate``."""
    size = 1 << int(math.ceil(sample_rate * LONGEST_TUBE_S) + 4).bit_length()
    return np.zeros(TUBE_STATE), np.zeros(size)


@njit(cache=True, nogil=True, fastmath={"contract"})
def run_tube(out, drive, coefficients, state, line, gain, depth, motor_step):  # pragma: no cover - compiled
    """The tube's sound for ``out.size`` samples, written to ``out``, driven by ``drive`` (the
    bar's velocity at the mouth, m/s), times ``gain`` and the motor.

    ``coefficients``: :attr:`TubeDesign.coefficients`; ``state``: ``TUBE_STATE`` values and
    ``line`` the delay line (a power of two long), both carried between blocks; ``gain`` and
    ``depth``: :mod:`barsynth.dsp.smoothing` states (linear) of the tube's output gain and the
    motor's depth, stepped a sample at a time; ``motor_step``: the motor's phase step a sample
    (rad). The motor (rotating discs in the tube's top) scales the sound by
    ``1 - depth (1 - cos phase) / 2``: open at phase 0, closed by ``depth`` at phase pi.
    """
    delay = int(coefficients[0])
    eta, b0, a1, p, k = coefficients[1], coefficients[2], coefficients[3], coefficients[4], coefficients[5]
    w1, ap_x, ap_y, p1, phase = state[W1], state[AP_X], state[AP_Y], state[P1], state[PHASE]
    pos = int(state[POS])
    mask = line.size - 1
    two_pi = 2.0 * math.pi
    for t in range(out.size):
        x = line[(pos - delay) & mask]
        w1 = b0 * x + a1 * w1
        ap_y = eta * (w1 - ap_y) + ap_x
        ap_x = w1
        u = ap_y
        p1 = (1.0 - p) * u + p * p1
        line[pos] = k * drive[t] - p1
        pos = (pos + 1) & mask
        g = next_value(gain, LINEAR)
        d = next_value(depth, LINEAR)
        out[t] = g * (1.0 - 0.5 * d * (1.0 - math.cos(phase))) * (u - p1)
        phase += motor_step
        if phase >= two_pi:
            phase -= two_pi
    state[W1], state[AP_X], state[AP_Y], state[P1], state[PHASE] = w1, ap_x, ap_y, p1, phase
    state[POS] = pos
