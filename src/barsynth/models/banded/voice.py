"""Banded-waveguide bars, bowls and glasses: struck or plucked (spec 3.1).

Source: G. Essl and P. R. Cook, "Banded waveguides: towards physical modeling of
bowed bar percussion instruments", Proc. ICMC 1999; the mallet after Chaigne and
Doutaut, JASA 101 (1997).

One loop per mode (:mod:`barsynth.dsp.banded`), each placed exactly on its mode's
frequency and decay. The modes come either from physics (``tuning = physics``: a
uniform free–free bar of the given material and size) or from a fundamental and a
list of mode ratios and T60s (``tuning = ratios``: tuned bars, glasses, bowls, or a
user's own object). Positions enter through mode shapes: the free–free bar's
shapes for bars, ``cos(n 2 pi x)`` (n = 2, 3, ...) around a ring for glasses and
bowls. The output is the object's velocity at the pick-up point (m/s), times
``level_db``.

Excitations: ``strike`` (a Hertzian mallet: mass, velocity, hardness as contact
time), ``bow`` (a stroke of a bow: friction at the bow point from the bow table of
:mod:`barsynth.dsp.friction`, fed back into every band each sample), ``pluck``
(held at the strike point with a displacement, then released). A new strike,
stroke or pluck adds to whatever is still ringing: nothing is cleared.
Modes above a quarter of the sample rate are muted (a loop needs at least four
samples of delay), never folded; modes below 20 Hz are left out.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import kernel as K
from .design import design_loop
from ...errors import ParameterError
from ...parameters import CHOICE, FLOATS, INT, Parameter, ParameterTable
from ..base import Mode, resolve_parameters
from ..rendering import check_block_size, check_dtype, check_sample_rate
from ..shared import (PLUCKED, STRUCK_OR_PLUCKED, PLUCK_DOC, POSITIONS_ALONG, BarModel, BowedBarVoice, add_force, bar_size_parameters,
                     bow_parameters, largest_deflection, level_parameter, mallet_force, mallet_parameters,
                     pluck_force)

MAX_MODES = 24
MIN_Q = 3.0  # below this a mode is not a ringing loop (see dsp.banded)
LOWEST_HZ = 20.0

PHYSICS = {"tuning": ("physics",)}
RATIOS = {"tuning": ("ratios",)}

BANDED_TABLE = ParameterTable(
    "banded",
    [
        Parameter("tuning", "", None, None, "physics",
                  "where the modes come from: physics (a uniform free-free bar of the material and size "
                  "below) or ratios (frequency_hz x mode_ratios, with mode_t60s_s)",
                  kind=CHOICE, choices=("physics", "ratios")),
        *bar_size_parameters("tuning = physics: ", PHYSICS),
        Parameter("mode_count", "", 1, MAX_MODES, 4, "tuning = physics: how many modes", kind=INT, when=PHYSICS),
        Parameter("frequency_hz", "Hz", 20.0, 5000.0, 220.0, "tuning = ratios: the fundamental", scale="log",
                  when=RATIOS),
        Parameter("mode_ratios", "", 0.25, 200.0, (1.0, 4.0, 10.0),
                  "tuning = ratios: each mode's frequency / frequency_hz", kind=FLOATS, max_items=MAX_MODES,
                  when=RATIOS),
        Parameter("mode_t60s_s", "s", 0.005, 120.0, (),
                  "T60 of the first modes, in order (the rest follow q)", kind=FLOATS, max_items=MAX_MODES),
        Parameter("q", "", MIN_Q, 10000.0, 300.0,
                  "quality factor of every mode without its own T60: T60 = Q ln(1000) / (pi f)", scale="log"),
        Parameter("shape", "", None, None, "bar",
                  "tuning = ratios: mode shapes for positions: bar (free-free bending modes) or ring "
                  "(cos(n 2 pi x), n = 2, 3, ... around a glass or bowl)", kind=CHOICE, choices=("bar", "ring"),
                  when=RATIOS),
        Parameter("mass_kg", "kg", 0.001, 100.0, 0.3, "tuning = ratios: the object's mass", scale="log", when=RATIOS),
        Parameter("excitation", "", None, None, "strike",
                  "what a trigger does: strike (a mallet), bow (a bow stroke) or pluck (a release)",
                  kind=CHOICE, choices=("strike", "bow", "pluck")),
        Parameter("strike_position", "", 0.0, 1.0, 0.1,
                  "where it is struck or plucked: fraction of the length (bar) or of the circumference (ring)",
                  when=STRUCK_OR_PLUCKED),
        Parameter("pickup_position", "", 0.0, 1.0, 0.0,
                  "where its velocity is picked up, as strike_position"),
        *mallet_parameters(),
        Parameter("pluck_displacement_mm", "mm", 0.01, 20.0, 1.0, PLUCK_DOC, scale="log", when=PLUCKED),
        Parameter("release_time_ms", "ms", 0.05, 20.0, 0.5, "how long a pluck's release takes", scale="log",
                  when=PLUCKED),
        *bow_parameters(),
        level_parameter(),
    ],
)


def _shapes(p: Any, count: int, position: Any) -> np.ndarray:
    """Each mode's shape at ``position`` (fraction), normalised to a mean square of 1 (for an
    array of positions: modes x positions)."""
    if p.tuning == "physics" or p.shape == "bar":
        from ...physics import mode_shape

        return np.array([mode_shape("free-free", n, position) for n in range(1, count + 1)], dtype=float)
    orders = np.arange(2, count + 2)
    return math.sqrt(2.0) * np.cos(np.multiply.outer(orders * 2.0 * math.pi, np.asarray(position, dtype=float)))


def mode_table(parameters: Any, sample_rate: float) -> tuple[np.ndarray, np.ndarray, float, list[str]]:
    """Frequencies (Hz), T60s (s) and mass (kg) of the modes, and a note for each muted one."""
    p = parameters
    if p.tuning == "physics":
        from ...physics import bar_frequencies

        freqs = bar_frequencies(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3,
                                length_m=p.length_m, thickness_m=p.thickness_m, bc="free-free",
                                count=p.mode_count)
        mass = p.density_kg_m3 * p.length_m * p.thickness_m * p.width_m
    else:
        if not p.mode_ratios:
            raise ParameterError("parameter mode_ratios is empty; allowed: with tuning = ratios, a list of up to "
                                 f"{MAX_MODES} ratios, each 0.25 to 200")
        freqs = p.frequency_hz * np.array(p.mode_ratios)
        mass = p.mass_kg
    t60s = np.array([p.mode_t60s_s[k] if k < len(p.mode_t60s_s) else p.q * math.log(1000.0) / (math.pi * f)
                     for k, f in enumerate(freqs)])
    if len(p.mode_t60s_s) > len(freqs):
        raise ParameterError(f"parameter mode_t60s_s has {len(p.mode_t60s_s)} values for {len(freqs)} modes; "
                             "allowed: at most one T60 per mode (s)")
    notes = []
    for k, (f, t60) in enumerate(zip(freqs, t60s)):
        shortest = MIN_Q * math.log(1000.0) / (math.pi * f)
        if t60 < shortest:
            raise ParameterError(f"parameter mode_t60s_s: value {k + 1} = {t60:g} is too short for a mode at "
                                 f"{f:.1f} Hz; allowed: at least {shortest:.4g} s (Q >= {MIN_Q:g})")
        if f > sample_rate / 4:
            notes.append(f"mode {k + 1} at {f:.1f} Hz muted: above a quarter of the sample rate")
        elif f < LOWEST_HZ:
            notes.append(f"mode {k + 1} at {f:.2f} Hz left out: below {LOWEST_HZ:g} Hz")
    return freqs, t60s, mass, notes


def _playable(freqs: np.ndarray, sample_rate: float) -> np.ndarray:
    return (freqs >= LOWEST_HZ) & (freqs <= sample_rate / 4)


class BandedVoice(BowedBarVoice):
    """Streaming banded-waveguide voice: ``prepare`` / ``reset`` / ``trigger`` / ``process``.

    Examples
    --------
    >>> voice = BandedVoice({"tuning": "ratios", "frequency_hz": 440}, sample_rate=48000)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> block.shape, bool(abs(block).max() > 0)
    ((256,), True)
    """

    def prepare(self, sample_rate: float, max_block: int | None = None) -> None:
        """Set the sample rate (Hz), design the loops and reset. A refused rate changes nothing."""
        rate = check_sample_rate(sample_rate)
        previous = getattr(self, "sample_rate", None)
        self.sample_rate = rate
        try:
            self._design()
        except Exception:
            if previous is not None:  # the loops designed for it are still in place
                self.sample_rate = previous
            raise
        self.reset()

    def _design(self) -> None:
        p, rate = self._params, self.sample_rate
        freqs, t60s, mass, _ = mode_table(p, rate)
        keep = _playable(freqs, rate)
        if not keep.any():
            raise ParameterError(f"no mode of this object lies between {LOWEST_HZ:g} Hz and a quarter of the "
                                 f"sample rate ({rate / 4:g} Hz): its modes are at "
                                 f"{', '.join(f'{f:.1f}' for f in freqs)} Hz")
        index = np.flatnonzero(keep)
        strike = _shapes(p, len(freqs), p.strike_position)[index]
        pickup = _shapes(p, len(freqs), p.pickup_position)[index]
        bow = _shapes(p, len(freqs), p.bow_position)[index]
        designs = [design_loop(float(freqs[k]), float(t60s[k]), rate) for k in index]
        coeffs = np.zeros((len(designs), K.N_COEFFS))
        for row, (d, s, o, b) in enumerate(zip(designs, strike, pickup, bow)):
            coeffs[row, [K.C_B0, K.C_A1, K.C_A2, K.C_ETA, K.C_GAIN]] = d.bp_b0, d.bp_a1, d.bp_a2, d.eta, d.gain
            coeffs[row, K.C_IN] = d.input_scale * s / (rate * mass)  # a force sample is an impulse F / fs
            coeffs[row, K.C_OUT] = o * 10.0 ** (p.level_db / 20.0)
            coeffs[row, K.C_BOW_IN] = d.input_scale * b / (rate * mass)
            coeffs[row, K.C_BOW_AT] = b
        self._coeffs = coeffs
        self._delays = np.array([d.delay for d in designs], dtype=np.int64)
        self._freqs, self._strike_shape, self._mass, self._index = freqs[index], strike, mass, index
        self._along = _shapes(p, len(freqs), POSITIONS_ALONG)[index]  # for a pluck's largest deflection

    def reset(self) -> None:
        """Silence: every loop emptied, nothing pending."""
        self._buffers, self._states, self._position = K.empty_bank(len(self._delays), int(self._delays.max()))
        self._pending = np.zeros(0)
        self._tail = 0.0
        self._bow = self._new_bow()

    def set_parameters(self, **values: Any) -> None:
        """Change parameters (validated); the loops are redesigned, what rings keeps ringing."""
        params = resolve_parameters(MODEL, {**BANDED_TABLE.as_dict(self._params), **values})
        old, old_index = self._params, self._index
        self._params = params
        try:
            self._design()
        except Exception:
            self._params = old
            raise
        if not (np.array_equal(self._index, old_index) and self._buffers.shape[1] >= int(self._delays.max()) + 2):
            self._carry_over(old_index)
        self._glide_bow(old, params)

    def _carry_over(self, old_index: np.ndarray) -> None:
        """New loops for a changed set of modes: each mode that stays keeps its state and
        its recent past (what rings keeps ringing); a new mode starts silent."""
        buffers, states, position = K.empty_bank(len(self._delays), int(self._delays.max()))
        old_mask, mask = self._buffers.shape[1] - 1, buffers.shape[1] - 1
        ages = np.arange(1, min(self._buffers.shape[1], buffers.shape[1]))  # samples ago
        for row, mode in enumerate(self._index):
            found = np.flatnonzero(old_index == mode)
            if found.size:
                buffers[row, (position[0] - ages) & mask] = self._buffers[found[0], (self._position[0] - ages) & old_mask]
                states[row] = self._states[found[0]]
        self._buffers, self._states, self._position = buffers, states, position

    def trigger(self) -> None:
        """Strike, start a bow stroke, or pluck now, on top of whatever still rings."""
        p = self._params
        if p.excitation == "bow":
            self._start_stroke()
        elif p.excitation == "strike":
            self._pending, self._tail = add_force(self._pending, self._tail, mallet_force(p, self.sample_rate), 0.0)
        else:  # pluck: the force that holds the strike point out, then let go
            omega = 2.0 * math.pi * self._freqs
            stiffness = self._mass * omega ** 2  # N/m per mode
            compliance = float(np.sum(self._strike_shape ** 2 / stiffness))  # m/N
            reach = largest_deflection(self._strike_shape, self._along, stiffness)
            self._pending, self._tail = add_force(self._pending, self._tail,
                                                  *pluck_force(p, compliance, self.sample_rate, reach))

    def process(self, num_samples: int, *, dtype: Any = np.float32) -> np.ndarray:
        """The next ``num_samples`` samples: velocity at the pick-up (m/s) times the level."""
        dtype = check_dtype(dtype)
        n = check_block_size(num_samples)
        out = np.empty(n)
        now = self._bow.now
        bowed = min(n, max(0, self._bow.lifted_at - now))  # the bowed kernel runs exactly while the bow touches
        if bowed:
            self._run(out, 0, bowed, now)
        if bowed < n:
            self._run(out, bowed, n)
        self._bow.now = now + n
        return out.astype(dtype, copy=False)

    def _run(self, out: np.ndarray, start: int, stop: int, bow_index: int | None = None) -> None:
        """Run samples ``start:stop`` of this block; with the bow if ``bow_index`` (the
        absolute index of ``out[0]``) is given."""
        pending = self._pending[start:] if start < self._pending.size else self._pending[:0]
        if bow_index is None:
            K.process(out[start:stop], pending, self._tail, self._coeffs, self._delays, self._buffers,
                      self._states, self._position)
        else:
            K.process_bowed(out[start:stop], pending, self._tail, self._bow.lines, bow_index + start,
                            self._coeffs, self._delays, self._buffers, self._states, self._position)
        if stop == out.size:
            self._pending = self._pending[stop:]


class BandedModel(BarModel):
    """Banded-waveguide objects as a barsynth model (see the module docstring)."""

    reports_reference_errors = False
    name = "banded"
    summary = "banded waveguides (Essl & Cook 1999): struck, bowed or plucked bars, tuned bars, glasses, bowls"
    table = BANDED_TABLE

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The modes that sound: frequency, gain (strike shape x pick-up shape) and T60."""
        p = resolve_parameters(self, parameters)
        rate = check_sample_rate(sample_rate)
        freqs, t60s, _, _ = mode_table(p, rate)
        strike = _shapes(p, len(freqs), p.strike_position)
        pickup = _shapes(p, len(freqs), p.pickup_position)
        keep = _playable(freqs, rate)
        return [Mode("mode", float(freqs[k]), float(strike[k] * pickup[k]), float(t60s[k]))
                for k in np.flatnonzero(keep)]


MODEL = BandedModel()
BandedModel.voice_class = BandedVoice
BandedVoice.model = MODEL
