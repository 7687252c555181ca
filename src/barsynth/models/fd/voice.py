"""The finite-difference bar's voice: the scheme of :mod:`.design` stepped by :mod:`.kernel`.

The exciters (the model's, one of each kept by the voice) are taken in their coupled forms
(:meth:`barsynth.exciters.Exciter.coupling`), each solved with the step by a record of its own:
the mallet (:class:`~barsynth.exciters.MalletContact`) by the kernel's ``MalletPoint``, the
bow's lines (:class:`~barsynth.dsp.bow_stroke.BowControls`) by its ``BowPoint``; a pluck
(:class:`~barsynth.exciters.PluckHold`) sets the bar to its static deflection under the
force that holds the point out, and lets go.
"""

from __future__ import annotations

import numpy as np

from ...dsp.bow_stroke import BowControls
from ...dsp.smoothing import LEVEL_GLIDE_S, MULTIPLICATIVE, SMOOTHED_STATE, TARGET, ramp_steps, start_ramp_now
from ...exciters import Bow, ExciterSet, Pluck, Strike
from ...jitstart import compiled_for
from ..base import Voice
from . import kernel as K
from .design import Design, design, history_size, plucked_shape
from .table import FdParams



class FdVoice(Voice):
    """Streaming finite-difference bar: ``prepare`` / ``reset`` / ``trigger`` / ``release`` / ``process``.

    Examples
    --------
    >>> voice = FdVoice({"bc": "clamped-free", "points": 40}, sample_rate=44100)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> block.shape, bool(abs(block).max() > 0)
    ((256,), True)
    """

    can_release = True
    _params: FdParams
    _exciters: ExciterSet
    _stroke: BowControls

    def _prepare(self) -> None:
        self._design = design(self._params, self.sample_rate)  # refuses an unstable scheme: nothing changed

    def _reset(self) -> None:
        """Silence: the bar at rest, no mallet, the bow lifted."""
        self._exciters = ExciterSet(self.model.exciters, self._params, self.sample_rate)
        self._stroke = self._exciters.of(Bow).coupling()  # the bow's lines: the kernel reads them
        self._allocate(self._design)

    def _allocate(self, new: Design) -> None:
        """The state for the grid and the output filter of ``new``, at rest."""
        size = new.scheme.bands.shape[1]  # node vectors are padded for the kernel
        self._bar = K.Bar(np.zeros(size), np.zeros(size), np.zeros(size))
        self._mallet_state = np.zeros(1, K.MALLET_STATE)
        self._bow_state = np.zeros(1, K.BOW_STATE)
        self._output_state = np.zeros(1, K.OUTPUT_STATE)
        self._history = np.zeros(history_size(new.taps))
        self._level = np.zeros(SMOOTHED_STATE)
        start_ramp_now(self._level, MULTIPLICATIVE, new.level, 0)
        self._use(new)

    def _use(self, new: Design) -> None:
        """The kernel's records: the design ``new`` around the present state."""
        p = self._params
        mallet = self._exciters.of(Strike).coupling()
        self._design = new
        self._mallet = K.MalletPoint(new.strike.at, new.strike.response, new.strike.gain, mallet.mass_kg,
                                     mallet.stiffness, mallet.exponent, self._mallet_state)
        self._bow_point = K.BowPoint(new.bow.at, new.bow.response, 0.5 * new.scheme.step_rate * new.bow.gain,
                                     p.bow_solver == "newton", self._bow_state)
        self._pickup = K.Pickup(new.pickup, self._level, new.taps, self._history, self._output_state)
        self._run = None  # process compiled for these records, resolved at the next render (jitstart.compiled_for)

    def _update(self, old: FdParams) -> None:
        """On the same grid what rings keeps ringing (a new step keeps its velocities) and a new
        level glides there over ``LEVEL_GLIDE_S`` (:mod:`barsynth.dsp.smoothing`); a new grid
        (another size or another theory) starts silent. The exciters follow (a new bow velocity or force glides there)."""
        p = self._params
        new = design(p, self.sample_rate)
        self._exciters.update(p)  # (before the mallet's record is made anew)
        if new.grid.mass.size != self._design.grid.mass.size or p.theory != old.theory:
            self._allocate(new)
        else:
            if p.oversampling != old.oversampling:
                self._change_step(old.oversampling, p.oversampling, new.taps)
            if new.level != self._level[TARGET]:
                start_ramp_now(self._level, MULTIPLICATIVE, new.level, ramp_steps(LEVEL_GLIDE_S, self.sample_rate))
            self._use(new)

    def _change_step(self, old_steps: int, new_steps: int, taps: np.ndarray) -> None:
        """Keep the bar's and the mallet's velocities through a change of step, and resample the
        decimation filter's past to the new step, so the output carries on. (Going to one step
        a sample, the output keeps what lies near Nyquist, unfiltered.)"""
        ratio = old_steps / new_steps  # k_new / k_old
        bar = self._bar
        bar.u_prev[:] = bar.u - (bar.u - bar.u_prev) * ratio
        z = self._mallet_state["z_m"]
        self._mallet_state["z_prev_m"] = z - (z - self._mallet_state["z_prev_m"]) * ratio
        old, written = self._history, int(self._output_state["written"][0])
        if old_steps == 1:  # no past was kept: the last output stands for it
            past = np.full(2, self._output_state["last"][0])
        else:
            past = old[(written - 1 - np.arange(old.size)) & (old.size - 1)]  # newest first, one old step apart
        ages = np.arange(history_size(taps)) * ratio  # the new steps' ages, in old steps (0 = the newest value)
        self._history = np.interp(ages, np.arange(past.size), past)[::-1].copy()
        self._output_state["written"] = 0  # the next write goes at 0: the newest value sits at the end

    def trigger(self) -> None:
        """Excite now with the chosen exciter, on top of whatever still rings: each coupled form
        meets the bar through its own record."""
        exciter = self._exciters[self._params.excitation]
        if isinstance(exciter, Strike):  # the mallet arrives at the bar as it is now
            here = float(np.dot(self._mallet.at, self._bar.u))  # (pads are zero in both)
            self._mallet_state["z_m"] = here
            self._mallet_state["z_prev_m"] = here - exciter.coupling().velocity_m_s / self._design.scheme.step_rate
            self._mallet_state["touching"] = True
        elif isinstance(exciter, Pluck):  # held out, let go with the next step
            shape = K.padded(plucked_shape(exciter.coupling(), self._design.grid, self._params.strike_position))
            self._bar.u[:] += shape
            self._bar.u_prev[:] += shape
        else:  # the bow: a stroke of its lines, which the kernel reads
            exciter.start()

    def release(self) -> None:
        """Stop a bow stroke now: the bow slows to rest, damps the bar, and is lifted.
        (A bow that is not moving, a strike or a pluck is left as it is.)"""
        self._exciters.release()

    @property
    def driven_until(self) -> int:
        """The sample index at which the bow is lifted (until another stroke)."""
        return self._exciters.driven_until

    def _render(self, out: np.ndarray) -> None:
        """Velocity at the pick-up (m/s) times the level."""
        bow = self._stroke
        run = self._run
        if run is None:  # process's dispatcher would type the records at every call (~6 us)
            run = self._run = compiled_for(K.process, out, self._design.scheme, self._bar, self._mallet,
                                           self._bow_point, bow.lines, bow.now, self._pickup)
        run(out, self._design.scheme, self._bar, self._mallet, self._bow_point, bow.lines, bow.now, self._pickup)
        bow.now += out.size
