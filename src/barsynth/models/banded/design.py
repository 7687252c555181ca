"""Pure design of the banded model: parameters and sample rate in, modes and loops out.

Source: G. Essl and P. R. Cook, "Banded waveguides: towards physical modeling of
bowed bar percussion instruments", Proc. ICMC 1999 (barsynth spec 3.1).

The modes (:func:`mode_table`) come from physics (``tuning = physics``: a uniform
free-free bar), from a bar's geometry (``tuning = geometry``: material, size, thickness
profile and theory, :mod:`.geometry`) or from a fundamental and ratios; positions enter
through mode shapes (:func:`mode_shapes`: the uniform free-free bar's; the profiled bar's
own; with ratios, those of a free-free bar
tuned to them by its thickness profile (:func:`barsynth.physics.tuned_bar.tune_bar`),
``cos(n 2 pi x)`` around a ring, or none at all). Each mode's output has its own gain
(:func:`mode_gains`, ``mode_gains_db``).
Modes above a quarter of the sample rate are muted (a loop needs at least four samples
of delay), never folded; modes below ``LOWEST_HZ`` are left out.

Each mode is a loop ``x -> (+) -> band-pass -> delay z^-M -> all-pass A(z) -> gain g -> (+)``
(:func:`design_loop`). Where a plain implementation sets the delay to ``round(fs / f)``
and the gain from ``T60`` alone (so high modes go out of tune and decays vary with
pitch), the loop here is designed so that its pole lands *exactly* on the requested one:
``z0 = r e^{j w}`` with ``w = 2 pi f / fs`` and ``r = 10^(-3 / (T60 fs))``.
The loop ``L(z) = g H(z) A(z) z^-M`` must satisfy ``L(z0) = 1``: its phase fixes the
integer delay ``M`` and the first-order Thiran all-pass coefficient ``eta`` (solved
at ``z0`` itself, not on the unit circle), its magnitude fixes ``g``. The residue of
the loop at ``z0`` then gives the input scale that makes a unit impulse ring the
mode with unit amplitude, at any pitch and sample rate.

The band-pass is a low-Q (``BAND_Q``, or the mode's own Q when that is lower)
constant-peak section: it keeps the loop's other resonances (near 0 and ``2 f``)
down by ``|H(2f)|`` per round trip.

:func:`design_bank` puts it together: the kernel's :data:`~.kernel.LOOP` records for every
mode that sounds, and what an exciter needs to know of the object.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import ParameterError
from ...exciters import POSITIONS_ALONG, StaticPoint, largest_deflection
from ...physics import bar_frequencies, mode_shape
from ...physics.tuned_bar import TOLERANCE_CENTS, tune_bar
from .geometry import closed_form, geometry_bar
from .kernel import LOOP
from .resonator import TubeCoupling, check_tube_mode, design_coupling, tube_t60s
from .table import LOWEST_HZ, MAX_MODES, MIN_Q, BandedParams

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
    # The twang's band-pass (twang.design.bandpass) is this RBJ section too, but multiplies
    # by 1 / (1 + alpha) where this divides: other last bits, so the two are not shared.
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


# -- the object's modes ------------------------------------------------------------------------
def mode_shapes(p: BandedParams, count: int, position: Any) -> np.ndarray:
    """Each of ``count`` modes' shape at ``position`` (a fraction of the length or of the
    circumference), normalised to a mean square of 1; for an array of positions, modes x
    positions.

    ``tuning = physics``: the uniform free-free bar's bending shapes; ``tuning = geometry``: those
    of the bar of that profile in that theory (:func:`~.geometry.geometry_bar`; a uniform
    Euler–Bernoulli bar's are physics'). ``tuning = ratios``:
    ``shape = bar``, those of the free-free bar whose thickness profile puts its modes at
    ``mode_ratios`` (:func:`tuned_bar_for`; the mode of each ratio is the bar's mode of the
    same rank); ``ring``, ``cos(n 2 pi x)`` with n = 2, 3, ...; ``none``, 1 everywhere."""
    if p.tuning == "physics" or (p.tuning == "geometry" and closed_form(p)):
        return np.array([mode_shape("free-free", n, position) for n in range(1, count + 1)], dtype=float)
    if p.tuning == "geometry":
        return geometry_bar(p).shapes_at(position)
    if p.shape == "none":
        return np.ones((count, *np.shape(position)))
    if p.shape == "bar":
        rank = np.argsort(np.argsort(p.mode_ratios, kind="stable"), kind="stable")
        return tuned_bar_for(p).shapes_at(position)[rank]
    orders = np.arange(2, count + 2)
    return math.sqrt(2.0) * np.cos(np.multiply.outer(orders * 2.0 * math.pi, np.asarray(position, dtype=float)))


def tuned_bar_for(p: BandedParams):
    """The free-free bar tuned to ``p.mode_ratios`` (:func:`~barsynth.physics.tuned_bar.tune_bar`,
    kept once fitted), or :class:`ParameterError` when no bar barsynth can tune has those modes
    (every mode within ``TOLERANCE_CENTS``): the positions would then belong to no object."""
    bar = tune_bar(p.mode_ratios)
    if not bar.fits:
        worst = int(np.argmax(np.abs(bar.cents)))
        shown = ", ".join(f"{r:g}" for r in p.mode_ratios)
        raise ParameterError(f"parameter mode_ratios = {shown} with shape = bar: no free-free bar barsynth can "
                             f"tune has modes at these ratios (the nearest misses mode {worst + 1} by "
                             f"{abs(bar.cents[worst]):.0f} cents); allowed: the ratios of a bar's bending modes "
                             f"(within {TOLERANCE_CENTS:g} cent), or shape = none (positions then have no effect) "
                             "or ring")
    return bar


def mode_gains(p: BandedParams, count: int) -> np.ndarray:
    """Each of ``count`` modes' output gain, ``mode_gains_db`` as factors (1 for a mode without a
    value). Raises :class:`ParameterError` for more values than modes."""
    if len(p.mode_gains_db) > count:
        raise ParameterError(f"parameter mode_gains_db has {len(p.mode_gains_db)} values for {count} modes; "
                             "allowed: at most one gain per mode (dB)")
    gains = np.ones(count)
    gains[:len(p.mode_gains_db)] = 10.0 ** (np.array(p.mode_gains_db) / 20.0)
    return gains


def closed_form_frequencies(p: BandedParams) -> np.ndarray | None:
    """All the object's mode frequencies (Hz) where they come in closed form (``tuning =
    ratios``, ``physics``, or ``geometry`` of a uniform Euler-Bernoulli bar); None where its
    grid must be solved (:func:`.geometry.geometry_bar`)."""
    if p.tuning == "ratios":
        return p.frequency_hz * np.array(p.mode_ratios)
    if p.tuning == "geometry" and not closed_form(p):
        return None
    return bar_frequencies(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3,
                           length_m=p.length_m, thickness_m=p.thickness_m, bc="free-free", count=p.mode_count)


def mode_table(p: BandedParams) -> tuple[np.ndarray, np.ndarray, float]:
    """Frequencies (Hz), T60s (s) and mass (kg) of all the object's modes (which of them sound
    at a sample rate: :func:`playable`). Raises :class:`ParameterError` for an object that
    cannot ring (no ratios, more T60s than modes, a T60 below Q = ``MIN_Q``)."""
    freqs = closed_form_frequencies(p)
    if freqs is None:
        bar = geometry_bar(p)
        freqs, mass = bar.frequencies_hz, bar.mass_kg
    elif p.tuning != "ratios":  # physics, or geometry's uniform Euler-Bernoulli bar
        mass = p.density_kg_m3 * p.length_m * p.thickness_m * p.width_m
    else:
        if not p.mode_ratios:
            raise ParameterError("parameter mode_ratios is empty; allowed: with tuning = ratios, a list of up to "
                                 f"{MAX_MODES} ratios, each 0.25 to 200")
        mass = p.mass_kg
    t60s = np.array([p.mode_t60s_s[k] if k < len(p.mode_t60s_s) else p.q * math.log(1000.0) / (math.pi * f)
                     for k, f in enumerate(freqs)])
    if len(p.mode_t60s_s) > len(freqs):
        raise ParameterError(f"parameter mode_t60s_s has {len(p.mode_t60s_s)} values for {len(freqs)} modes; "
                             "allowed: at most one T60 per mode (s)")
    for k, (f, t60) in enumerate(zip(freqs, t60s)):
        shortest = MIN_Q * math.log(1000.0) / (math.pi * f)
        if t60 < shortest:
            raise ParameterError(f"parameter mode_t60s_s: value {k + 1} = {t60:g} is too short for a mode at "
                                 f"{f:.1f} Hz; allowed: at least {shortest:.4g} s (Q >= {MIN_Q:g})")
    return freqs, t60s, mass


def playable(freqs: np.ndarray, sample_rate: float) -> np.ndarray:
    """Which modes sound: from ``LOWEST_HZ`` to a quarter of the sample rate."""
    return (freqs >= LOWEST_HZ) & (freqs <= sample_rate / 4)


def band_refusal(p: BandedParams, freqs: np.ndarray, sample_rate: float) -> str | None:
    """The refusal of an object none of whose modes (``freqs``, Hz) sounds at ``sample_rate``
    (:func:`playable`); None where one does."""
    if playable(freqs, sample_rate).any():
        return None
    change = "frequency_hz or mode_ratios" if p.tuning == "ratios" else "length_m, thickness_m or the material"
    return (f"no mode of this object lies between {LOWEST_HZ:g} Hz and a quarter of the sample rate "
            f"({sample_rate / 4:g} Hz): with tuning = {p.tuning} its modes are at "
            f"{', '.join(f'{f:.1f}' for f in freqs)} Hz; allowed: a mode in that band (change {change}, "
            "or the sample rate)")


# -- the bank of loops -------------------------------------------------------------------------
def loop_records(designs: list[LoopDesign]) -> np.ndarray:
    """The kernel's :data:`~.kernel.LOOP` records of ``designs``: each loop takes a unit force
    sample as a unit impulse (``force_in`` = its input scale), is heard with weight 1, no bow."""
    loops = np.zeros(len(designs), dtype=LOOP)
    for name, field in (("b0", "bp_b0"), ("a1", "bp_a1"), ("a2", "bp_a2"), ("eta", "eta"), ("gain", "gain"),
                        ("delay", "delay"), ("force_in", "input_scale")):
        loops[name] = [getattr(d, field) for d in designs]
    loops["out"] = 1.0
    return loops


@dataclass(frozen=True)
class BankDesign:
    """The loops of every mode that sounds, and the object as an exciter sees it.

    ``loops``: the kernel's :data:`~.kernel.LOOP` records (their output weights are the mode
    shapes at the pick-up times each mode's gain, without the level); ``modes``: each loop's row in
    :func:`mode_table`; ``strike_point``: the object at the strike point (compliance and
    largest deflection per newton, m/N), for a pluck; ``level``: the output gain, ``level_db``
    as a factor (the voice applies it to the loops' sum, gliding to a new one); ``tube``: the
    resonator tube (:mod:`.resonator`), or None; ``frequencies_hz``, ``t60s_s``: each loop's
    mode (with the tube's pull on its mode).
    """

    loops: np.ndarray
    modes: np.ndarray
    strike_point: StaticPoint
    level: float
    tube: TubeCoupling | None = None
    frequencies_hz: np.ndarray | None = None
    t60s_s: np.ndarray | None = None

    @property
    def longest_delay(self) -> int:
        """The longest loop delay (samples)."""
        return int(self.loops["delay"].max())


def design_bank(p: BandedParams, sample_rate: float) -> BankDesign:
    """The loops for the object ``p`` at ``sample_rate`` Hz (raises :class:`ParameterError`
    when none of its modes can sound).

    Examples
    --------
    >>> from barsynth.models.banded import BANDED_TABLE
    >>> bank = design_bank(BANDED_TABLE.resolve({"tuning": "ratios", "frequency_hz": 440.0}), 48000.0)
    >>> bank.modes, bank.loops["delay"]
    (array([0, 1, 2]), array([108,  26,  10]))
    """
    freqs, t60s, mass = mode_table(p)
    check_tube_mode(p, len(freqs))
    t60s = tube_t60s(p, t60s)
    keep = playable(freqs, sample_rate)
    refusal = band_refusal(p, freqs, sample_rate)
    if refusal:
        raise ParameterError(refusal)
    modes = np.flatnonzero(keep)
    count = len(freqs)
    strike = mode_shapes(p, count, p.strike_position)[modes]
    pickup = mode_shapes(p, count, p.pickup_position)[modes]
    bow = mode_shapes(p, count, p.bow_position)[modes]
    designs = [design_loop(float(freqs[k]), float(t60s[k]), sample_rate) for k in modes]
    loops = loop_records(designs)
    input_scale = loops["force_in"].copy()
    loops["force_in"] = input_scale * strike / (sample_rate * mass)  # a force sample is an impulse F / fs
    loops["bow_in"] = input_scale * bow / (sample_rate * mass)
    loops["bow_at"] = bow
    loops["out"] = pickup * mode_gains(p, count)[modes] if p.mode_gains_db else pickup
    tube = None
    if p.tube == "on":
        loops["mouth"] = mode_shapes(p, count, p.tube_position)[modes]
        tube = design_coupling(p, freqs, t60s, modes, loops["mouth"], loops["out"], sample_rate)
    stiffness = mass * (2.0 * math.pi * freqs[modes]) ** 2  # N/m per mode
    along = mode_shapes(p, count, POSITIONS_ALONG)[modes]
    strike_point = StaticPoint(compliance_m_n=float(np.sum(strike ** 2 / stiffness)),
                              reach_m_n=largest_deflection(strike, along, stiffness))
    return BankDesign(loops, modes, strike_point, 10.0 ** (p.level_db / 20.0), tube, freqs[modes], t60s[modes])
