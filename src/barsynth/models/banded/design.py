"""Design of one banded-waveguide loop: band-pass, fractional delay and loop gain.

Source: G. Essl and P. R. Cook, "Banded waveguides: towards physical modeling of
bowed bar percussion instruments", Proc. ICMC 1999 (barsynth spec 3.1). Each mode
is a loop ``x -> (+) -> band-pass -> delay z^-M -> all-pass A(z) -> gain g -> (+)``.

Where a plain implementation sets the delay to ``round(fs / f)`` and the gain from
``T60`` alone (so high modes go out of tune and decays vary with pitch), the loop
here is designed so that its pole lands *exactly* on the requested one:
``z0 = r e^{j w}`` with ``w = 2 pi f / fs`` and ``r = 10^(-3 / (T60 fs))``.
The loop ``L(z) = g H(z) A(z) z^-M`` must satisfy ``L(z0) = 1``: its phase fixes the
integer delay ``M`` and the first-order Thiran all-pass coefficient ``eta`` (solved
at ``z0`` itself, not on the unit circle), its magnitude fixes ``g``. The residue of
the loop at ``z0`` then gives the input scale that makes a unit impulse ring the
mode with unit amplitude, at any pitch and sample rate.

The band-pass is a low-Q (``BAND_Q``, or the mode's own Q when that is lower)
constant-peak section: it keeps the loop's other resonances (near 0 and ``2 f``)
down by ``|H(2f)|`` per round trip.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

BAND_Q = 6.0
"""Quality factor of each loop's band-pass (broad: the sharp resonance is the loop's)."""


@dataclass(frozen=True)
class LoopDesign:
    """One mode's loop, ready for the kernel.

    ``bp_b0, bp_a1, bp_a2``: band-pass ``y = b0 (x - x[-2]) - a1 y[-1] - a2 y[-2]``;
    ``delay``: integer delay M (samples); ``eta``: all-pass coefficient; ``gain``: g;
    ``input_scale``: input gain for a unit-amplitude mode per unit impulse;
    ``pole_radius``: r per sample.
    """

    frequency_hz: float
    t60_s: float
    sample_rate: float
    bp_b0: float
    bp_a1: float
    bp_a2: float
    delay: int
    eta: float
    gain: float
    input_scale: float
    pole_radius: float


def _band_pass(w: float, q: float) -> tuple[float, float, float]:
    alpha = math.sin(w) / (2.0 * q)
    norm = 1.0 + alpha
    return alpha / norm, -2.0 * math.cos(w) / norm, (1.0 - alpha) / norm


def _h(z: complex, b0: float, a1: float, a2: float) -> tuple[complex, complex]:
    """H(z) and dH/dz of the band-pass."""
    u = 1.0 / z
    num, den = b0 * (1.0 - u * u), 1.0 + a1 * u + a2 * u * u
    dnum, dden = -2.0 * b0 * u, a1 + 2.0 * a2 * u
    dh_du = (dnum * den - num * dden) / (den * den)
    return num / den, dh_du * (-u * u)


def _a(z: complex, eta: float) -> tuple[complex, complex]:
    """A(z) = (eta + z^-1) / (1 + eta z^-1) and dA/dz."""
    u = 1.0 / z
    den = 1.0 + eta * u
    da_du = (1.0 - eta * eta) / (den * den)
    return (eta + u) / den, da_du * (-u * u)


def _allpass_phase_error(eta: float, z0: complex, target: float) -> float:
    value, _ = _a(z0, eta)
    return math.remainder(cmath.phase(value) - target, 2.0 * math.pi)


def design_loop(frequency_hz: float, t60_s: float, sample_rate: float, *, band_q: float = BAND_Q) -> LoopDesign:
    """The loop whose pole is exactly at ``frequency_hz`` with decay ``t60_s``.

    ``frequency_hz`` must lie in (0, sample_rate / 4]; ``t60_s`` > 0. Checking the
    caller's values with one-line messages is the model's job; this raises
    ``ValueError`` on values it cannot design for.
    """
    if not 0.0 < frequency_hz <= sample_rate / 4.0 or not t60_s > 0.0:
        raise ValueError(f"cannot design a loop for f = {frequency_hz} Hz, T60 = {t60_s} s at {sample_rate} Hz")
    w = 2.0 * math.pi * frequency_hz / sample_rate
    r = 10.0 ** (-3.0 / (t60_s * sample_rate))
    z0 = cmath.rect(r, w)
    # A mode broader than the band-pass would need a loop gain above 1: widen the band to it.
    band_q = min(band_q, math.pi * frequency_hz * t60_s / math.log(1000.0))
    b0, a1, a2 = _band_pass(w, band_q)
    h0, dh0 = _h(z0, b0, a1, a2)
    # Phase: arg H(z0) - M w + arg A(z0) = -2 pi. The all-pass covers 0.5..1.5 samples.
    needed = (2.0 * math.pi + cmath.phase(h0)) / w  # total delay the delay line + all-pass must give
    delay = int(math.floor(needed - 0.5))
    target = -(2.0 * math.pi + cmath.phase(h0) - delay * w)  # the all-pass phase at z0
    # On the unit circle the all-pass phase is -2 atan(k tan(w/2)), k = (1 - eta) / (1 + eta):
    # solve that exactly, then correct for z0 lying just inside the circle (secant steps).
    k = math.tan(-target / 2.0) / math.tan(w / 2.0)
    eta = (1.0 - k) / (1.0 + k)
    previous, e_previous = eta + 1e-6, _allpass_phase_error(eta + 1e-6, z0, target)
    for _ in range(8):
        error = _allpass_phase_error(eta, z0, target)
        if error == 0.0 or error == e_previous:
            break
        eta, previous, e_previous = eta - error * (eta - previous) / (error - e_previous), eta, error
    a0, da0 = _a(z0, eta)
    gain = r ** delay / (abs(h0) * abs(a0))
    if not 0.0 < gain < 1.0:
        raise ValueError(f"loop gain {gain} for f = {frequency_hz} Hz, T60 = {t60_s} s is not below 1")
    # L(z) = g H A z^-M with L(z0) = 1: L'(z0) = dH/H + dA/A - M/z0.
    dl = dh0 / h0 + da0 / a0 - delay / z0
    # The output is taken after the all-pass: T(z) = L / (g (1 - L)), residue -1 / (g L'(z0)).
    amplitude = 2.0 * abs(-1.0 / (gain * dl) / z0)
    return LoopDesign(frequency_hz, t60_s, sample_rate, b0, a1, a2, delay, eta, gain, 1.0 / amplitude, r)
