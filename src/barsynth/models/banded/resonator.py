"""The banded model's resonator tube, vibraphone motor and damper pedal: their table rows and design.

A tube under the bar (:mod:`barsynth.dsp.tube`: closed at the bottom, open at the top, its
first resonance on a chosen mode) is driven by the bar's velocity at its mouth (the loops'
all-pass outputs weighted by the mode shapes at ``tube_position``) and its sound is added to
the bar's (Doutaut, Matignon & Chaigne, JASA 104(3), 1998, couple a 1-D tube to the bar's
radiation in the time domain). The tube's pull on the bar is not simulated: the tuned mode
instead decays faster by ``tube_damping`` (a tube radiates energy the bar loses: its
resonators make a marimba's fundamental louder and shorter, Fletcher & Rossing ch. 19;
Bork et al., Acustica 85, 1999). The vibraphone's motor turns discs in the tubes' tops: the
tube's sound is modulated by ``1 - depth (1 - cos 2 pi rate t) / 2`` (open at the trigger);
the rest of the sound is left as it is. The damper pedal presses felt on the bar: every loop
gets the extra damping of a T60 of ``damper_t60_s``, pressed and lifted over
``DAMPER_GLIDE_S``.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np

from ...dsp.tube import TubeDesign, design_tube
from ...errors import ParameterError
from ...parameters import CHOICE, INT, Compare, Parameter

TUBE_ON = {"tube": ("on",)}
MOTOR_ON = {**TUBE_ON, "motor_rate_hz": Compare(">", 0.0)}
DAMPED = {"damper": ("down", "release")}
DAMPER_GLIDE_S = 0.010
"""The damper is pressed or lifted over this time (s)."""
DAMPER_STEP = 32
"""The damper's glide moves the loops' gains every this many samples (counted from the reset)."""
MOTOR_GLIDE_S = 0.050
"""A new motor depth (or the motor stopping or starting) glides over this time (s)."""
TUBE_GLIDE_S = 0.020
"""A new ``tube_gain_db`` (or the tube switched on or off) glides over this time (s)."""


def resonator_parameters(max_modes: int) -> list[Parameter]:
    """The rows of the tube, the motor and the damper (every one off by default)."""
    return [
        Parameter("tube", "", None, None, "none",
                  "a resonator tube under the bar (closed at the bottom, open at the top, its first resonance on "
                  "mode tube_mode): none or on", kind=CHOICE, choices=("none", "on")),
        Parameter("tube_mode", "", 1, max_modes, 1, "the mode (in order) the tube is tuned to", kind=INT,
                  when=TUBE_ON),
        Parameter("tube_radius_m", "m", 0.005, 0.1, 0.025,
                  "inner radius a (radiation and wall losses; length = c / 4f - ~0.6 a)", scale="log",
                  when=TUBE_ON),
        Parameter("tube_detune_cents", "cents", -100.0, 100.0, 0.0,
                  "the tube's resonance re its mode", when=TUBE_ON),
        Parameter("tube_position", "", 0.0, 1.0, 0.5,
                  "where along the bar the tube's mouth is (fraction of the length): its drive is the "
                  "bar's velocity there", when=TUBE_ON),
        Parameter("tube_gain_db", "dB", -40.0, 30.0, 6.0,
                  "the tube's sound at its resonance re the bar's velocity at its mouth", when=TUBE_ON),
        Parameter("tube_damping", "", 0.0, 10.0, 0.5,
                  "the tuned mode's extra damping by the tube, as a multiple of its own (its T60 / "
                  "(1 + tube_damping)): the energy the tube radiates is the bar's", when=TUBE_ON),
        Parameter("motor_rate_hz", "Hz", 0.0, 12.0, 0.0,
                  "the vibraphone's motor, turning discs in the tube's top (tremolo rate; 0: off)",
                  when=TUBE_ON),
        Parameter("motor_depth", "", 0.0, 1.0, 0.5,
                  "how far the discs close the tube (0: not at all, 1: silent when closed)", when=MOTOR_ON),
        Parameter("damper", "", None, None, "up",
                  "the damper pedal: up (the bar rings), down (felt pressed on the bar) or release (pressed by a "
                  "release, lifted by the next trigger)", kind=CHOICE, choices=("up", "down", "release")),
        Parameter("damper_t60_s", "s", 0.01, 2.0, 0.08,
                  "the damper's own T60: pressed, every mode's decay adds its damping", scale="log", when=DAMPED),
    ]


@dataclass(frozen=True)
class TubeCoupling:
    """A tube as the bank drives it: its ``design``, the ``row`` of the loop of the mode it is
    tuned to, its output ``gain`` (``tube_gain_db`` as a factor) and ``ratio``, the tube's sound
    at that mode over the mode's direct sound (complex: what the tube adds is ``1 + ratio``;
    ``nan`` where the pick-up hears no direct sound of that mode)."""

    design: TubeDesign
    row: int
    gain: float
    ratio: complex
    through_tube: complex
    """The tube's sound of the tuned mode, per unit of the mode's velocity (its shape at the
    mouth x the tube's transfer at the mode's pole x ``gain``)."""


def tube_t60s(p, t60s: np.ndarray) -> np.ndarray:
    """The modes' T60s with the tube's pull on its mode (``tube_damping``): unchanged without a tube."""
    if p.tube != "on" or p.tube_mode > len(t60s):
        return t60s
    t60s = t60s.copy()
    t60s[p.tube_mode - 1] /= 1.0 + p.tube_damping
    return t60s


def tube_mode_refusal(p, count: int) -> str | None:
    """The refusal of a ``tube_mode`` an object of ``count`` modes does not have (None: it has it)."""
    if p.tube == "on" and p.tube_mode > count:
        return f"parameter tube_mode = {p.tube_mode} is not allowed for an object of {count} modes; allowed: 1 to {count}"
    return None


def check_tube_mode(p, count: int) -> None:
    """Refuse a ``tube_mode`` the object does not have."""
    refusal = tube_mode_refusal(p, count)
    if refusal:
        raise ParameterError(refusal)


def tube_sounds_refusal(p, freqs: np.ndarray, sounds: bool, sample_rate: float) -> str | None:
    """The refusal of a tube tuned to a mode (of ``freqs``, Hz) that does not sound at
    ``sample_rate`` (``sounds``: whether it does)."""
    if p.tube != "on" or sounds:
        return None
    return (f"parameter tube_mode = {p.tube_mode}: that mode ({freqs[p.tube_mode - 1]:.1f} Hz) does not sound at "
            f"{sample_rate:g} Hz; allowed: a mode that sounds")


def tube_for(p, frequency_hz: float, sample_rate: float) -> TubeDesign:
    """The tube of ``p`` tuned to its mode at ``frequency_hz`` (detuned by ``tube_detune_cents``);
    refused (one line) where no tube of ``tube_radius_m`` fits at ``sample_rate``."""
    target = frequency_hz * 2.0 ** (p.tube_detune_cents / 1200.0)
    try:
        return design_tube(target, p.tube_radius_m, sample_rate)
    except ValueError:
        longest = 343.0 / (4.0 * target) / 0.6
        raise ParameterError(f"parameter tube_radius_m = {p.tube_radius_m:g} is not allowed for a tube at "
                             f"{target:.1f} Hz at {sample_rate:g} Hz; allowed: less than {longest:.3g} m (the end "
                             "correction within a quarter wavelength), with the tube below an eighth of the sample "
                             "rate") from None


def design_coupling(p, freqs: np.ndarray, t60s: np.ndarray, modes: np.ndarray, mouth: np.ndarray,
                    direct: np.ndarray, sample_rate: float) -> TubeCoupling | None:
    """The tube of ``p`` (None without one) tuned to its mode's frequency in ``freqs`` (all the
    object's modes, Hz), for the loops of ``modes`` (rows of ``freqs``) whose shapes at the mouth
    are ``mouth`` and whose direct output weights are ``direct``; ``t60s``: with the tube's pull."""
    if p.tube != "on":
        return None
    check_tube_mode(p, len(freqs))
    k = p.tube_mode - 1
    rows = np.flatnonzero(modes == k)
    refusal = tube_sounds_refusal(p, freqs, bool(rows.size), sample_rate)
    if refusal:
        raise ParameterError(refusal)
    design = tube_for(p, float(freqs[k]), sample_rate)
    row = int(rows[0])
    gain = 10.0 ** (p.tube_gain_db / 20.0)
    through = gain * mouth[row] * design.response_to_mode(float(freqs[k]), float(t60s[k]))
    ratio = through / direct[row] if direct[row] != 0.0 else complex(math.nan, math.nan)
    return TubeCoupling(design, row, gain, ratio, through)


def damper_factors(loops: np.ndarray, freqs: np.ndarray, t60s: np.ndarray, damper_t60_s: float,
                   sample_rate: float) -> np.ndarray:
    """Each loop's gain factor that adds the damping of a T60 of ``damper_t60_s`` to its mode
    (``freqs``, ``t60s``: each loop's): the factor c that puts the loop's gain where its pole's
    radius is r 10^(-3 / (damper_t60_s fs)) at the same angle, 1 / |L(z1)| (so 1 / T60 becomes
    1 / T60 + 1 / damper_t60_s)."""
    from .design import _a, _h

    extra = 10.0 ** (-3.0 / (damper_t60_s * sample_rate))
    factors = np.empty(len(loops))
    for i, (loop, f, t60) in enumerate(zip(loops, freqs, t60s)):
        r = 10.0 ** (-3.0 / (t60 * sample_rate)) * extra
        z1 = cmath.rect(r, 2.0 * math.pi * f / sample_rate)
        h, _ = _h(z1, loop["b0"], loop["a1"], loop["a2"])
        a, _ = _a(z1, loop["eta"])
        factors[i] = 1.0 / abs(loop["gain"] * h * a * z1 ** -int(loop["delay"]))
    return factors


HEARD_FROM_S = 0.03
"""The heard decay is measured from this long after the strike (s): past the mallet's contact
and the tube's entry, as barsynth's tests measure a struck mode."""
HEARD_CARRIER_HZ, HEARD_RATE = 1000.0, 8000.0
"""The heard envelope is measured on a cosine of this frequency (Hz) at this sample rate (Hz)."""


def heard_envelope(direct: float, through: complex, frequency_hz: float, t60_s: float, tube: TubeDesign,
                   times_s: np.ndarray) -> np.ndarray:
    """The complex envelope (re ``e^{j 2 pi frequency_hz t}``) of a mode ringing at
    ``frequency_hz`` with ``t60_s`` heard with its tube: its direct sound ``direct`` plus the
    tube's, ``through`` (the tube's forced response, :attr:`TubeCoupling.through_tube`) less the
    tube's own ringing that starts it from rest (the tube near its resonance as one pole, at
    ``tube.frequency_hz`` with ``tube.t60_s``: its response to ``e^{s t}`` is ``H(s) (e^{s t} -
    e^{p t})``), at ``times_s`` after the strike:

        E(t) = e^{-a t} (direct + through (1 - e^{(a - b + j (w_tube - w)) t}))

    ``a``, ``b``: the mode's and the tube's decay rates (ln 1000 / T60, 1/s)."""
    a = math.log(1000.0) / t60_s
    b = math.log(1000.0) / tube.t60_s
    shift = 2.0 * math.pi * (tube.frequency_hz - frequency_hz)
    start = 1.0 - np.exp((a - b + 1j * shift) * times_s)
    return np.exp(-a * times_s) * (direct + through * start)


def heard_end_s(direct: float, through: complex, frequency_hz: float, t60_s: float, tube: TubeDesign) -> float:
    """When the heard envelope (:func:`heard_envelope`, same arguments) has fallen 60 dB below
    its peak (s after the strike): the end of the span :func:`heard_mode` measures."""
    t = np.arange(0.0, 3.0 * max(t60_s, tube.t60_s), 1.0 / HEARD_RATE)
    size = np.abs(heard_envelope(direct, through, frequency_hz, t60_s, tube, t))
    peak = int(np.argmax(size))
    below = np.flatnonzero(size[peak:] < 1e-3 * size[peak])
    return float(t[peak + int(below[0])]) if below.size else float(t[-1])


def heard_mode(direct: float, through: complex, frequency_hz: float, t60_s: float,
               tube: TubeDesign) -> tuple[float, float]:
    """The tuned mode as it is heard with its tube: ``(amplitude, t60_s)`` as
    :func:`barsynth.analysis.measure_partial` measures its heard envelope
    (:func:`heard_envelope`, on a cosine of ``HEARD_CARRIER_HZ``) from ``HEARD_FROM_S`` after the
    strike until it has fallen 60 dB below its peak, the amplitude taken back to the strike with
    that T60.

    The sum is two exponentials, not one: a tube slower than its mode (``b < a``) carries the sound
    on after the mode has gone; a faster one blooms in over ``1 / (b - a)`` and the sum then decays
    with the mode. Either way the heard decay is longer than the mode's own (pulled) T60, and the
    heard amplitude lies between ``|direct|`` and ``|direct + through|``; its one T60 depends on
    where it is measured from (hence ``HEARD_FROM_S``)."""
    from ...analysis import measure_partial

    end_s = heard_end_s(direct, through, frequency_hz, t60_s, tube)
    t = np.arange(0.0, end_s, 1.0 / HEARD_RATE)
    envelope = heard_envelope(direct, through, frequency_hz, t60_s, tube, t)
    first, end = round(HEARD_FROM_S * HEARD_RATE), t.size
    sound = np.real(envelope[first:end] * np.exp(2j * np.pi * HEARD_CARRIER_HZ * t[first:end]))
    partial = measure_partial(sound, HEARD_RATE, HEARD_CARRIER_HZ)
    heard_t60 = partial.t60_s
    level = 10.0 ** (partial.level_db / 20.0)
    if math.isfinite(heard_t60):
        level *= 10.0 ** (3.0 * HEARD_FROM_S / heard_t60)
    return float(level), float(heard_t60)
