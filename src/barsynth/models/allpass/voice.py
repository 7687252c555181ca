"""The all-pass (generalised) waveguide bar: struck or plucked (spec 3.2).

Sources: S. A. Van Duyne and J. O. Smith, "A simplified approach to modeling
dispersion caused by stiffness in strings and plates", Proc. ICMC 1994; J. S. Abel
and J. O. Smith, "Robust design of very high-order allpass dispersion filters",
Proc. DAFx 2006; J. Rauhala and V. Välimäki, "Tunable dispersion filter design for
piano synthesis", IEEE Signal Processing Letters 13 (2006); G. Essl and P. R. Cook,
"Banded waveguides", Proc. ICMC 1999 (the comparison of the three bar models); the
mallet after A. Chaigne and V. Doutaut, JASA 101 (1997).

A digital waveguide for the bar's two travelling bending waves. The strike and
pick-up points split it into four filters round one loop (from ``x_a``, the
nearer point to the ``x = 0`` end, to that end and back; ``x_a`` to ``x_b``; ``x_b``
to the far end and back; ``x_b`` to ``x_a``), each a delay, a sign and a chain of
all-pass sections fitted to the phase the bending waves gather there
(``v = sqrt(a w)``, so ``x lambda(w)`` with ``lambda = L sqrt(w / a)``), with the
ends' reflections (``-j`` free or clamped, ``-1`` pinned) and a correction for the
near field folded in so that the loop's resonances fall on the uniform bar's
modes (:func:`barsynth.physics.bar_frequencies`). ``allpass_order`` sections in
all; :func:`barsynth.models.allpass.design.allpass_design` explains the fit and
reports every resonance against physics (``describe`` lists them). Losses: each
filter holds its share (its length) of a gain and up to three minimum-phase shelves
fitted so that every mode decays with ``T60 = q ln(1000) / (pi f)``.

Strike: a Hertzian mallet (as :mod:`barsynth.models.banded`) whose force enters
both travelling waves at ``strike_position`` through ``1 / (4 rho A v(w))`` (the
waves' share of a point force). Pluck: the strike point held out by a force and
let go; where that would take a force without bound (near a clamped or pinned end) the
force is capped so that no point moves more than ``PLUCK_REACH`` times the displacement,
in the real bar or in the waveguide's own (whose clamped ends move: see below, so a pluck
or a strike at a clamped end sounds, at a bounded level, like one near it). Output: the sum of the two waves at
``pickup_position`` (m/s) times ``level_db``. A new strike adds to what rings; nothing
is cleared, and a change of parameters that rebuilds the waveguide leaves the old one
ringing beside the new one.

What it misses, and so what this model is for (a measured comparison, not the
recommended path): the near field. Its frequencies are right (folded into the
fit), its mode shapes are the travelling waves' only: a free end reads half of
what a real one does, and a clamped end moves (a real one does not). Short
filters (points close together or close to an end) cannot follow their own phase
at the lowest modes with few sections, so levels there are approximate; the
loop's frequencies and decays are what the fit protects first.

Examples
--------
>>> model = AllpassModel()
>>> modes = model.describe({"bc": "clamped-free"}, sample_rate=48000)
>>> [(m.group, round(m.frequency_hz, 1)) for m in modes[:3]]
[('fitted', 90.7), ('fitted', 568.6), ('fitted', 1592.2)]
>>> x = model.render({"bc": "clamped-free"}, duration_s=0.1, sample_rate=48000, normalize=False)
>>> x.shape, bool(np.isfinite(x).all()), float(abs(x).max()) > 0.0
((4800,), True, True)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import kernel as K
from .design import AllpassDesign, design_for
from ...parameters import CHOICE, INT, Parameter, ParameterTable
from ..base import Mode, resolve_parameters
from ..rendering import check_block_size, check_dtype, check_sample_rate, check_seed, render_voice
from ..shared import (PLUCKED, STRUCK_OR_PLUCKED, PLUCK_DOC, POSITIONS_ALONG, add_force, bar_size_parameters, largest_deflection, level_parameter,
                     mallet_force, mallet_parameters, pluck_force)

BOUNDARY_CONDITIONS = ("free-free", "clamped-free", "clamped-clamped", "pinned-pinned", "clamped-pinned")
FADE_S = 0.010  # a replaced waveguide that has rung long enough fades out over this time
MAX_RETIRED = 3  # replaced waveguides still ringing at once (beyond that the oldest fades out)
RETIRE_T60S = 2.0  # a replaced waveguide rings on for this many of its longest T60 (-120 dB)
LONGEST_RETIREMENT_S = 120.0
NEAREST_END = 1e-3
"""A pluck's force is reckoned for a point no closer to an end than this (fraction of the length):
the filters cannot place the strike point much closer (their fit leaves a point 1e-9 from a
pinned end moving at up to 1 % of a wave's amplitude, where the real bar gives nothing), so
the force the real bar would need there (growing as the point nears the end) is not applied
to a point that still moves."""

ALLPASS_TABLE = ParameterTable(
    "allpass",
    [
        *bar_size_parameters(),
        Parameter("bc", "", None, None, "free-free",
                  "boundary conditions: the x = 0 end first (clamped-free: clamped at 0, free at the far end)",
                  kind=CHOICE, choices=BOUNDARY_CONDITIONS),
        Parameter("allpass_order", "", 1, 64, 24,
                  "all-pass sections round the loop in all (an upper limit: a bar that needs fewer gets "
                  "fewer); more fits more modes, closer", kind=INT),
        Parameter("q", "", 3.0, 10000.0, 300.0,
                  "quality factor of every mode: T60 = Q ln(1000) / (pi f)", scale="log"),
        Parameter("excitation", "", None, None, "strike",
                  "what a trigger does: strike (a mallet) or pluck (a release)",
                  kind=CHOICE, choices=("strike", "pluck")),
        Parameter("strike_position", "", 0.0, 1.0, 0.1, "where it is struck or plucked: fraction of the length",
                  when=STRUCK_OR_PLUCKED),
        Parameter("pickup_position", "", 0.0, 1.0, 0.0, "where its velocity is picked up: fraction of the length"),
        *mallet_parameters(),
        Parameter("pluck_displacement_mm", "mm", 0.01, 20.0, 1.0, PLUCK_DOC, scale="log", when=PLUCKED),
        Parameter("release_time_ms", "ms", 0.05, 20.0, 0.5, "how long a pluck's release takes", scale="log",
                  when=PLUCKED),
        level_parameter(),
    ],
)


def _reckoned(position: float) -> float:
    """The strike point for a pluck's force: at least ``NEAREST_END`` from either end."""
    return min(max(position, NEAREST_END), 1.0 - NEAREST_END)


class _Engine:
    """One built waveguide: the design's arrays and the kernel's state."""

    def __init__(self, design: AllpassDesign, gain: float):
        filters = design.filters
        self.design, self.gain = design, gain
        self.rows = np.ascontiguousarray(np.vstack([f.sections for f in filters]).reshape(-1, 5))
        self.first = np.cumsum([0] + [len(f.sections) for f in filters]).astype(np.int64)
        self.delays = np.array([f.delay for f in filters], dtype=np.int64)
        self.signs = np.array([f.sign for f in filters])
        ia, ib = (1.0, 0.0) if design.strike_at_a else (0.0, 1.0)
        self.inject = np.array([ia, ia, ib, ib])
        self.pick = np.array([1.0, 0.0]) if design.pickup_at_a else np.array([0.0, 1.0])
        self.anchor = int(np.argmax(self.delays))
        self.strike_rows = np.ascontiguousarray(design.injection)
        self.pickup_rows = np.ascontiguousarray(design.pickup)
        self.clear()

    def clear(self) -> None:
        (self.buffers, self.states, self.position, self.strike_states,
         self.pickup_states) = K.empty_state(self.rows, self.delays, self.strike_rows, self.pickup_rows)

    def same_shape(self, other: "_Engine") -> bool:
        """Whether ``other``'s state fits this waveguide (then what rings can carry over)."""
        return (np.array_equal(self.first, other.first) and np.array_equal(self.delays, other.delays)
                and self.strike_rows.shape == other.strike_rows.shape
                and self.pickup_rows.shape == other.pickup_rows.shape
                and self.buffers.shape == other.buffers.shape)

    def take_state(self, other: "_Engine") -> None:
        self.buffers, self.states, self.position = other.buffers, other.states, other.position
        self.strike_states, self.pickup_states = other.strike_states, other.pickup_states

    def run(self, out: np.ndarray, pending: np.ndarray, held: float) -> None:
        K.process(out, pending, held, self.gain, self.rows, self.first, self.delays, self.signs, self.inject,
                  self.pick, self.anchor, self.buffers, self.states, self.position, self.strike_rows,
                  self.strike_states, self.pickup_rows, self.pickup_states)


class _Retired:
    """A replaced waveguide that rings on (with the force it was given) until ``left``
    samples are done, fading out over the last ``fade``: deterministic in samples, so
    blocks of any size still give the same output."""

    def __init__(self, engine: _Engine, pending: np.ndarray, held: float, left: int, fade: int):
        self.engine, self.pending, self.held, self.left, self.fade = engine, pending, held, left, fade

    def add_to(self, out: np.ndarray) -> bool:
        """Add its next samples to ``out``; False once it is done."""
        count = min(out.size, self.left)
        part = np.empty(count)
        self.engine.run(part, self.pending, self.held)
        self.pending = self.pending[count:]
        out[:count] += part * np.minimum(1.0, (self.left - np.arange(count)) / self.fade)
        self.left -= count
        return self.left > 0


class AllpassVoice:
    """Streaming all-pass waveguide voice: ``prepare`` / ``reset`` / ``trigger`` / ``process``.

    Examples
    --------
    >>> voice = AllpassVoice({"allpass_order": 16}, sample_rate=48000)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> block.shape, block.dtype.name, bool(abs(block).max() > 0)
    ((256,), 'float32', True)
    """

    restarts_on_trigger = False
    can_release = False
    uses_seed = False

    def __init__(self, parameters: Any = None, *, sample_rate: float = 48000.0, seed: int | None = 0):
        self._params = resolve_parameters(MODEL, parameters)
        check_seed(seed)  # the model is deterministic; the seed is accepted for the common interface
        self._engine: _Engine | None = None
        self.prepare(sample_rate)

    @property
    def parameters(self) -> Any:
        return self._params

    @property
    def design(self) -> AllpassDesign:
        """The waveguide in use (its ``modes`` report what it will play)."""
        return self._engine.design

    def prepare(self, sample_rate: float, max_block: int | None = None) -> None:
        """Set the sample rate (Hz), build the waveguide and reset. A refused rate changes nothing."""
        rate = check_sample_rate(sample_rate)
        engine = self._build(self._params, rate)
        self.sample_rate, self._engine = rate, engine
        self.reset()

    def _build(self, p: Any, rate: float) -> _Engine:
        return _Engine(design_for(p, rate), 10.0 ** (p.level_db / 20.0))

    def reset(self) -> None:
        """Silence: the waveguide emptied, nothing pending."""
        self._engine.clear()
        self._retired: list[_Retired] = []
        self._pending = np.zeros(0)
        self._tail = 0.0

    def set_parameters(self, **values: Any) -> None:
        """Change parameters (validated); what rings keeps ringing. If the waveguide keeps its
        shape (a new level, mallet, ...) it carries on with the new coefficients; otherwise
        the old one rings on beside the new one (with the strike it was given) for
        ``RETIRE_T60S`` of its longest T60, then fades out, and new strikes go to the new one."""
        params = resolve_parameters(MODEL, {**ALLPASS_TABLE.as_dict(self._params), **values})
        engine = self._build(params, self.sample_rate)
        old = self._engine
        if engine.same_shape(old):
            engine.take_state(old)
        else:
            self._retire(old)
            self._pending, self._tail = np.zeros(0), 0.0
        self._params, self._engine = params, engine

    def _retire(self, engine: _Engine) -> None:
        fade = max(1, int(round(FADE_S * self.sample_rate)))
        longest = max((m.model_t60_s for m in engine.design.modes if m.fitted), default=0.0)
        left = int(round(min(RETIRE_T60S * longest, LONGEST_RETIREMENT_S) * self.sample_rate)) + fade
        self._retired.append(_Retired(engine, self._pending, self._tail, left, fade))
        for gone in self._retired[:-MAX_RETIRED]:  # too many: the oldest fade out now
            gone.left = min(gone.left, gone.fade)

    def trigger(self) -> None:
        """Strike or pluck now, on top of whatever still rings."""
        p = self._params
        if p.excitation == "strike":
            change = mallet_force(p, self.sample_rate), 0.0
        else:  # pluck: the force that holds the strike point out, then let go
            change = pluck_force(p, self._compliance(), self.sample_rate, self._reach())
        self._pending, self._tail = add_force(self._pending, self._tail, *change)

    def _compliance(self) -> float:
        """Static compliance of the bar at the strike point (m/N), from its fitted modes."""
        from ...physics import mode_shape

        p, modes = self._params, [m for m in self.design.modes if m.fitted]
        mass = p.density_kg_m3 * p.length_m * p.thickness_m * p.width_m
        return sum(float(mode_shape(p.bc, m.number, _reckoned(p.strike_position))) ** 2
                   / (mass * (2.0 * math.pi * m.physics_hz) ** 2) for m in modes)

    def _reach(self) -> float:
        """The largest static deflection per newton at the strike point (m/N), of the real bar and of
        the waveguide's own (travelling-wave shapes: its clamped ends move), whichever is larger:
        a pluck moves neither more than ``PLUCK_REACH`` times its displacement."""
        from ...physics import mode_shape
        from ...physics.modes import travelling_wave_shape

        p, modes = self._params, [m for m in self.design.modes if m.fitted]
        if not modes:
            return 0.0
        mass = p.density_kg_m3 * p.length_m * p.thickness_m * p.width_m
        stiffness = np.array([mass * (2.0 * math.pi * m.physics_hz) ** 2 for m in modes])
        reach = 0.0
        for shape in (mode_shape, travelling_wave_shape):
            at = np.array([float(shape(p.bc, m.number, _reckoned(p.strike_position))) for m in modes])
            along = np.array([shape(p.bc, m.number, POSITIONS_ALONG) for m in modes])
            reach = max(reach, largest_deflection(at, along, stiffness))
        return reach

    def process(self, num_samples: int, *, dtype: Any = np.float32) -> np.ndarray:
        """The next ``num_samples`` samples: velocity at the pick-up (m/s) times the level."""
        dtype = check_dtype(dtype)
        n = check_block_size(num_samples)
        out = np.empty(n)
        self._engine.run(out, self._pending, self._tail)
        self._retired = [r for r in self._retired if r.add_to(out)]
        self._pending = self._pending[n:]
        return out.astype(dtype, copy=False)


class AllpassModel:
    """The all-pass waveguide bar as a barsynth model (see the module docstring)."""

    reports_reference_errors = False
    name = "allpass"
    summary = ("all-pass (generalised) waveguide bar (Van Duyne & Smith 1994): travelling bending waves "
               "through fitted dispersion filters, struck or plucked; a measured comparison")
    table = ALLPASS_TABLE

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The resonances the waveguide will play, from its own filters: frequency, gain
        (velocity per unit impulse x mass: for a real bar the product of the two mode
        shapes) and T60. Groups: ``fitted`` (in the fitted band), ``unfitted`` (above it,
        where the filters are not fitted), ``spurious`` (the loop's own resonances below the
        first mode, which the strike and pick-up filters keep far down)."""
        p = resolve_parameters(self, parameters)
        design = design_for(p, check_sample_rate(sample_rate))
        modes = [Mode("fitted" if m.fitted else "unfitted", m.model_hz, m.gain, m.model_t60_s)
                 for m in design.modes]
        return modes + [Mode("spurious", f, g, t60) for f, g, t60 in design.spurious]

    def voice(self, parameters: Any = None, *, sample_rate: float = 48000.0, seed: int | None = 0) -> AllpassVoice:
        return AllpassVoice(parameters, sample_rate=sample_rate, seed=seed)

    def render(self, parameters: Any = None, *, duration_s: float = 2.0, sample_rate: float = 48000.0,
               seed: int | None = 0, normalize: bool = True, dtype: Any = np.float32) -> np.ndarray:
        """One strike or pluck, offline (peak at -1 dBFS unless ``normalize`` is false)."""
        return render_voice(self.voice(parameters, sample_rate=sample_rate, seed=seed), duration_s,
                            normalize=normalize, dtype=dtype)


MODEL = AllpassModel()
