"""The banded voice: a bank of loops (one per mode) driven by a strike, a pluck or a bow.

Source: G. Essl and P. R. Cook, "Banded waveguides: towards physical modeling of bowed bar
percussion instruments", Proc. ICMC 1999 (barsynth spec 3.1); the mallet after A. Chaigne
and V. Doutaut, JASA 101 (1997).

The resonator is :mod:`.design` (modes and loops) run by :mod:`.kernel`; the exciters are
the model's (:attr:`BandedModel.exciters <barsynth.models.banded.BandedModel.exciters>`), one
of each kept by the voice: one that offers a force known in advance (a strike, a pluck) adds it
to a :class:`~barsynth.exciters.ForceQueue` the kernel plays out; the bow, coupled (its
friction depends on the bar's velocity under it), starts a stroke whose lines
(:meth:`Bow.coupling <barsynth.exciters.Bow.coupling>`) the bowed kernel solves each sample.
A recorded attack (:class:`~barsynth.exciters.Sample`) strikes the loops with an ideal impulse
through the same queue and adds its direct sound, the attack resampled to the voice's rate, to
the output from the trigger on (a second queue, read after the loops). A new strike, stroke,
pluck or attack adds to whatever still rings: nothing is cleared. The output is the object's
velocity at the pick-up point (m/s), plus any attack, times ``level_db`` (an output gain that
glides to a new level over :data:`~barsynth.dsp.smoothing.LEVEL_GLIDE_S`).
"""

from __future__ import annotations

import numpy as np

from ...dsp.bow_stroke import BowControls
from ...dsp.smoothing import (LEVEL_GLIDE_S, MULTIPLICATIVE, SMOOTHED_STATE, TARGET, ramp_steps, scale,
                              start_ramp_now)
from ...exciters import Bow, ExciterSet, ForceQueue
from ...jitstart import compiled_for
from ..base import Voice
from . import kernel as K
from .design import BankDesign, design_bank
from .table import BandedParams


class BandedVoice(Voice):
    """Streaming banded-waveguide voice: ``prepare`` / ``reset`` / ``trigger`` / ``release`` /
    ``set_parameters`` / ``process``.

    Examples
    --------
    >>> voice = BandedVoice({"tuning": "ratios", "frequency_hz": 440}, sample_rate=48000, max_block=256)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> block.shape, bool(abs(block).max() > 0)
    ((256,), True)
    """

    can_release = True  # a bow stroke stops

    _params: BandedParams
    _bank: BankDesign
    _state: K.LoopState
    _forces: ForceQueue
    _exciters: ExciterSet
    _stroke: BowControls
    _level: np.ndarray
    _heard: ForceQueue

    def _prepare(self) -> None:
        """Design the loops for ``self.sample_rate`` (raises for an object with no mode that can
        sound, or settings an exciter refuses) and allocate their state, the level's and the
        work space of a direct sound."""
        ExciterSet.check(self.model.exciters, self._params, self.sample_rate)
        bank = design_bank(self._params, self.sample_rate)
        self._bank = bank
        self._state = K.empty_state(len(bank.modes), bank.longest_delay)
        self._level = np.zeros(SMOOTHED_STATE)  # the output gain (multiplicative), a step a sample
        self._level_then = np.zeros(SMOOTHED_STATE)  # the level as a block began: the direct sound's
        self._direct = np.zeros(self.max_block)  # a piece of the direct sound, times the level
        self._run = self._run_bowed = None  # the kernels compiled for these records (jitstart.compiled_for)

    def _reset(self) -> None:
        """Silence: every loop emptied, no force or direct sound pending, the bow off the bar; the
        level as it is set."""
        K.silence(self._state)
        self._forces = ForceQueue()
        self._heard = ForceQueue()  # (not a force: samples heard at the output, the attack)
        self._exciters = ExciterSet(self.model.exciters, self._params, self.sample_rate)
        self._stroke = self._exciters.of(Bow).coupling()  # the bow's lines: the bowed kernel reads them
        self._level[:] = 0.0
        start_ramp_now(self._level, MULTIPLICATIVE, self._bank.level, 0)

    def _update(self, old: BandedParams) -> None:
        """The loops are redesigned at once; what rings keeps ringing; a new level glides there
        over ``LEVEL_GLIDE_S``; the exciters follow (a new bow setting glides). A new
        ``mode_gains_db`` (or position) takes effect at once: ``CrossfadingVoice`` fades it in."""
        ExciterSet.check(self.model.exciters, self._params, self.sample_rate)
        bank, previous = design_bank(self._params, self.sample_rate), self._bank
        self._bank = bank
        if bank.level != self._level[TARGET]:
            start_ramp_now(self._level, MULTIPLICATIVE, bank.level, ramp_steps(LEVEL_GLIDE_S, self.sample_rate))
        if not (np.array_equal(bank.modes, previous.modes)
                and self._state.buffers.shape[1] >= bank.longest_delay + 2):
            self._state = K.carried_over(self._state, previous.modes, bank.modes, bank.longest_delay)
        self._exciters.update(self._params)

    def trigger(self) -> None:
        """Excite now with the chosen exciter (strike, pluck, bow stroke, recorded attack), on top
        of whatever still rings."""
        exciter = self._exciters[self._params.excitation]
        if exciter.in_advance:  # a strike's pulse, a pluck's release, an ideal impulse: played out by the kernel
            self._forces.add(*exciter.force(self._bank.strike_point))
        else:  # coupled, the bow: the bowed kernel solves its stroke
            exciter.start()
        if exciter.direct:  # a recorded attack: heard from now on
            self._heard.add(exciter.direct_sound())

    def release(self) -> None:
        """Stop a bow stroke now: the bow slows to rest, damps the bar, and is lifted.
        (A bow that is not moving, a strike or a pluck is left as it is.)"""
        self._exciters.release()

    def warm_up(self) -> None:
        """Load (or compile) now the level's scaling of a recorded attack (its first block would
        otherwise); the bowed kernel is resolved at its first block (docs/contract.md)."""
        scale(np.zeros(1), np.zeros(SMOOTHED_STATE), MULTIPLICATIVE)

    @property
    def driven_until(self) -> int:
        """The sample index at which the bow is lifted (until another stroke)."""
        return self._exciters.driven_until

    def _render(self, out: np.ndarray) -> None:
        """``out.size`` samples of velocity at the pick-up (m/s) times the level. The bowed
        kernel runs exactly while the bow touches; the kernels apply the level in place; nothing
        is allocated."""
        n, bow, forces, heard = out.size, self._stroke, self._forces, self._heard.pending
        now = bow.now
        bowed = min(n, max(0, bow.lifted_at - now))
        loops, state, level = self._bank.loops, self._state, self._level
        if heard.size:
            self._level_then[:] = level  # the direct sound steps through the same gains as the loops
        # The kernels are called through their compiled entry points: the dispatcher would type
        # the state record at every call. Resolved at the first use (a struck voice never compiles
        # the bowed kernel); a bow's first block resolves the plain kernel too, for when it lifts.
        if self._run is None:
            self._run = compiled_for(K.process, out, forces.pending, forces.held, loops, state, level, now)
        if bowed:
            part = out if bowed == n else out[:bowed]
            run = self._run_bowed
            if run is None:
                run = self._run_bowed = compiled_for(K.process_bowed, part, forces.pending, forces.held, bow.lines,
                                                     now, loops, state, level)
            run(part, forces.pending, forces.held, bow.lines, now, loops, state, level)
        if bowed < n:
            pending = forces.pending if bowed == 0 else forces.from_sample(bowed)
            self._run(out if bowed == 0 else out[bowed:], pending, forces.held, loops, state, level, now + bowed)
        bow.now = now + n
        if forces.pending.size:
            forces.advance(n)
        if heard.size:
            self._add_heard(out, heard)
            self._heard.advance(n)

    def _add_heard(self, out: np.ndarray, heard: np.ndarray) -> None:
        """Add the direct sound still to come (``heard``) to the block ``out``, times the level it
        began with, stepped a sample at a time as the kernels stepped it (in pieces of the work
        space, allocating nothing)."""
        level, work = self._level_then, self._direct
        m = min(out.size, heard.size)
        for start in range(0, m, work.size):
            stop = min(m, start + work.size)
            piece = work[:stop - start]
            piece[:] = heard[start:stop]
            scale(piece, level, MULTIPLICATIVE)
            out[start:stop] += piece
