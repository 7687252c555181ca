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


def check_tube_mode(p, count: int) -> None:
    """Refuse a ``tube_mode`` the object does not have."""
    if p.tube == "on" and p.tube_mode > count:
        raise ParameterError(f"parameter tube_mode = {p.tube_mode} is not allowed for an object of {count} modes; "
                             f"allowed: 1 to {count}")


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
    if not rows.size:
        raise ParameterError(f"parameter tube_mode = {p.tube_mode}: that mode ({freqs[k]:.1f} Hz) does not sound at "
                             f"{sample_rate:g} Hz; allowed: a mode that sounds")
    target = float(freqs[k]) * 2.0 ** (p.tube_detune_cents / 1200.0)
    try:
        design = design_tube(target, p.tube_radius_m, sample_rate)
    except ValueError:
        longest = 343.0 / (4.0 * target) / 0.6
        raise ParameterError(f"parameter tube_radius_m = {p.tube_radius_m:g} is not allowed for a tube at "
                             f"{target:.1f} Hz at {sample_rate:g} Hz; allowed: less than {longest:.3g} m (the end "
                             "correction within a quarter wavelength), with the tube below an eighth of the sample "
                             "rate") from None
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
