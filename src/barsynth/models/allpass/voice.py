"""The all-pass waveguide bar's voice: a strike or a pluck into the designed loop.

The voice builds the waveguide for its parameters (:func:`.design.design_for`), drives it with
the force of its exciter (the model's: :class:`~barsynth.exciters.Strike` or
:class:`~barsynth.exciters.Pluck`, in their in-advance form: a force known in advance, played
through a :class:`~barsynth.exciters.ForceQueue`) and reads the pick-up (m/s, times ``level_db``: an
output gain on everything the voice plays, which glides to a new level over
:data:`~barsynth.dsp.smoothing.LEVEL_GLIDE_S`). A new strike adds to what rings. A change of
parameters that keeps the waveguide's shape (the level, the mallet) carries its state over; one
that rebuilds it leaves the old waveguide ringing beside the new one (with the force it was
given) for ``RETIRE_T60S`` of its longest T60, then fading out over ``FADE_S``.

That fade is a table of exact gains ``d / fade`` read by the samples ``d`` left, not a
:mod:`barsynth.dsp.smoothing` ramp: a linear ramp steps by adding ``-1 / fade`` (its gains drift
from ``d / fade`` by rounding), and a retired waveguide is read by its end, not stepped from
now; its length in whole samples is smoothing's (:func:`~barsynth.dsp.smoothing.ramp_steps`).
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from ...dsp.smoothing import (LEVEL_GLIDE_S, MULTIPLICATIVE, SMOOTHED_STATE, TARGET, ramp_steps, scale,
                              start_ramp_now)
from ...exciters import POSITIONS_ALONG, ExciterSet, ForceQueue, largest_deflection
from ...jitstart import compiled_for
from ..base import Voice
from . import kernel as K
from .design import AllpassDesign, design_for
from .table import AllpassParams

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



def _reckoned(position: float) -> float:
    """The strike point for a pluck's force: at least ``NEAREST_END`` from either end."""
    return min(max(position, NEAREST_END), 1.0 - NEAREST_END)


class _StrikePoint:
    """The bar at the strike point as an exciter sees it (a
    :class:`~barsynth.exciters.DrivePoint`), from the waveguide's fitted modes: worked out when
    first read (a pluck reads it; a strike does not), then kept for this waveguide."""

    def __init__(self, p: AllpassParams, design: AllpassDesign):
        self._p, self._modes = p, [m for m in design.modes if m.fitted]

    @cached_property
    def compliance_m_n(self) -> float:
        """Static compliance of the bar at the strike point (m/N), from its fitted modes."""
        from ...physics import mode_shape

        p, modes = self._p, self._modes
        mass = p.density_kg_m3 * p.length_m * p.thickness_m * p.width_m
        return sum(float(mode_shape(p.bc, m.number, _reckoned(p.strike_position))) ** 2
                   / (mass * (2.0 * math.pi * m.physics_hz) ** 2) for m in modes)

    @cached_property
    def reach_m_n(self) -> float:
        """The largest static deflection per newton at the strike point (m/N), of the real bar and of
        the waveguide's own (travelling-wave shapes: its clamped ends move), whichever is larger:
        a pluck moves neither more than ``PLUCK_REACH`` times its displacement."""
        from ...physics import mode_shape
        from ...physics.modes import travelling_wave_shape

        p, modes = self._p, self._modes
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


class _Engine:
    """One built waveguide: the design, its kernel coefficients and the kernel's state."""

    def __init__(self, design: AllpassDesign):
        filters = design.filters
        self.design = design
        delays = np.array([f.delay for f in filters], dtype=np.int64)
        ia, ib = (1.0, 0.0) if design.strike_at_a else (0.0, 1.0)
        self.loop = K.Loop(
            rows=np.ascontiguousarray(np.vstack([f.sections for f in filters]).reshape(-1, 5)),
            first=np.cumsum([0] + [len(f.sections) for f in filters]).astype(np.int64),
            delays=delays,
            signs=np.array([f.sign for f in filters]),
            inject=np.array([ia, ia, ib, ib]),
            pick=np.array([1.0, 0.0]) if design.pickup_at_a else np.array([0.0, 1.0]),
            anchor=int(np.argmax(delays)),
            strike_rows=np.ascontiguousarray(design.injection),
            pickup_rows=np.ascontiguousarray(design.pickup),
        )
        self.state = K.empty_state(self.loop)
        self._run = None  # process compiled for these records, resolved at the first run (jitstart.compiled_for)

    def clear(self) -> None:
        K.silence(self.state)

    def same_shape(self, other: _Engine) -> bool:
        """Whether ``other``'s state fits this waveguide (then what rings can carry over)."""
        mine, theirs = self.loop, other.loop
        return (np.array_equal(mine.first, theirs.first) and np.array_equal(mine.delays, theirs.delays)
                and mine.strike_rows.shape == theirs.strike_rows.shape
                and mine.pickup_rows.shape == theirs.pickup_rows.shape
                and self.state.buffers.shape == other.state.buffers.shape)

    def take_state(self, other: _Engine) -> None:
        self.state = other.state

    def run(self, out: np.ndarray, force: ForceQueue) -> None:
        """``out.size`` samples driven by ``force`` (advanced past them)."""
        run = self._run
        if run is None:  # process's dispatcher would type the two records at every call (~2.4 us)
            run = self._run = compiled_for(K.process, out, force.pending, force.held, self.loop, self.state)
        run(out, force.pending, force.held, self.loop, self.state)
        if force.pending.size:  # (nothing pending, as most blocks: nothing to advance)
            force.advance(out.size)


class _Retired:
    """A replaced waveguide that rings on (with the force it was given) until ``left`` samples
    are done, fading out linearly over the last ``fade``: deterministic in samples, so blocks
    of any size still give the same output."""

    def __init__(self, engine: _Engine, force: ForceQueue, left: int, fade: int):
        self.engine, self.force, self.left, self.fade = engine, force, left, fade

    def add_to(self, out: np.ndarray, scratch: np.ndarray, fade_gains: np.ndarray) -> bool:
        """Add its next samples to ``out`` (computed in ``scratch``, pieces of its size; the fade's
        gains ``d / fade`` at ``d`` samples from the end are ``fade_gains[d]``); False once done."""
        count = min(out.size, self.left)
        for start in range(0, count, scratch.size):
            size = min(count - start, scratch.size)
            part = scratch[:size]
            self.engine.run(part, self.force)
            fading = max(0, self.left - self.fade + 1)  # from here on the gain is below one
            if fading < size:
                tail = part[fading:]
                np.multiply(tail, fade_gains[self.left - size + 1:self.left - fading + 1][::-1], out=tail)
            piece = out[start:start + size]
            np.add(piece, part, out=piece)
            self.left -= size
        return self.left > 0


class AllpassVoice(Voice):
    """Streaming all-pass waveguide voice: ``prepare`` / ``reset`` / ``trigger`` / ``process``.

    Examples
    --------
    >>> voice = AllpassVoice({"allpass_order": 16}, sample_rate=48000)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> block.shape, block.dtype.name, bool(abs(block).max() > 0)
    ((256,), 'float32', True)
    """

    _params: AllpassParams

    @property
    def design(self) -> AllpassDesign:
        """The waveguide in use (its ``modes`` report what it will play)."""
        return self._engine.design

    def _build(self) -> _Engine:
        return _Engine(design_for(self._params, self.sample_rate))

    def _level_gain(self) -> float:
        """The output gain: ``level_db`` as a factor."""
        return 10.0 ** (self._params.level_db / 20.0)

    def _prepare(self) -> None:
        self._engine = self._build()
        self._strike_point = _StrikePoint(self._params, self._engine.design)
        self._fade = ramp_steps(FADE_S, self.sample_rate)
        self._fade_gains = np.arange(self._fade + 1) / self._fade
        self._part = np.empty(self.max_block)
        self._level = np.zeros(SMOOTHED_STATE)  # the output gain (multiplicative), a step a sample
        self._scale = None  # smoothing.scale's compiled entry point, resolved at the first render

    def _reset(self) -> None:
        self._engine.clear()
        self._exciters = ExciterSet(self.model.exciters, self._params, self.sample_rate)
        self._retired: list[_Retired] = []
        self._force = ForceQueue()
        self._level[:] = 0.0
        start_ramp_now(self._level, MULTIPLICATIVE, self._level_gain(), 0)

    def _update(self, old: AllpassParams) -> None:
        """What rings keeps ringing: the same shape carries on with the new coefficients; a new
        shape retires the old waveguide (new strikes go to the new one). A new level glides
        there over ``LEVEL_GLIDE_S``; the exciters read the new settings."""
        engine = self._build()
        level = self._level_gain()
        if level != self._level[TARGET]:
            start_ramp_now(self._level, MULTIPLICATIVE, level, ramp_steps(LEVEL_GLIDE_S, self.sample_rate))
        if engine.same_shape(self._engine):
            engine.take_state(self._engine)
        else:
            self._retire(self._engine)
            self._force = ForceQueue()
        self._engine = engine
        self._strike_point = _StrikePoint(self._params, engine.design)
        self._exciters.update(self._params)

    def _retire(self, engine: _Engine) -> None:
        longest = max((m.model_t60_s for m in engine.design.modes if m.fitted), default=0.0)
        left = int(round(min(RETIRE_T60S * longest, LONGEST_RETIREMENT_S) * self.sample_rate)) + self._fade
        self._retired.append(_Retired(engine, self._force, left, self._fade))
        for gone in self._retired[:-MAX_RETIRED]:  # too many: the oldest fade out now
            gone.left = min(gone.left, gone.fade)

    def trigger(self) -> None:
        """Strike or pluck now, on top of whatever still rings: every exciter of the model gives
        its force in advance."""
        self._force.add(*self._exciters[self._params.excitation].force(self._strike_point))

    def _render(self, out: np.ndarray) -> None:
        """Velocity at the pick-up (m/s) of the waveguide and of the retired ones, times the level
        (in place)."""
        self._engine.run(out, self._force)
        if self._retired:
            self._retired = [r for r in self._retired if r.add_to(out, self._part, self._fade_gains)]
        run = self._scale
        if run is None:  # the dispatcher would type the arguments at every call (jitstart.compiled_for)
            run = self._scale = compiled_for(scale, out, self._level, MULTIPLICATIVE)
        run(out, self._level, MULTIPLICATIVE)

