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

With a resonator tube (:mod:`.resonator`) the kernels also give the bar's velocity at the
tube's mouth, which drives the tube (:func:`barsynth.dsp.tube.run_tube`, with the motor); its
sound, times the same level, is added to the output. The damper pedal scales the loops' gains
(:func:`.resonator.damper_factors`), gliding every ``DAMPER_STEP`` samples counted from the
reset, so blocks of any size still give the same samples.
"""

from __future__ import annotations

import numpy as np

from ...dsp.bow_stroke import BowControls
from ...dsp.smoothing import (
    CURRENT,
    LEFT,
    LEVEL_GLIDE_S,
    LINEAR,
    MULTIPLICATIVE,
    SMOOTHED_STATE,
    TARGET,
    ramp_steps,
    scale,
    start_ramp_now,
)
from ...dsp.tube import empty_tube, run_tube
from ...exciters import Bow, ExciterSet, ForceQueue
from ...jitstart import compiled_for
from ..base import Voice
from . import kernel as K
from .design import BankDesign, design_bank
from .resonator import DAMPER_GLIDE_S, DAMPER_STEP, MOTOR_GLIDE_S, TUBE_GLIDE_S, damper_factors
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
        self._drive = np.zeros(self.max_block)  # the bar's velocity at the tube's mouth
        self._tube_out = np.zeros(self.max_block)  # the tube's sound
        self._no_drive = np.zeros(0)  # no tube: the kernels give no drive
        self._tube_state, self._tube_line = empty_tube(self.sample_rate)
        self._tube_coefficients = np.zeros(6)  # (a tube switched off rings out with its last ones)
        self._tube_gain = np.zeros(SMOOTHED_STATE)  # the tube's output gain (linear: 0 when off)
        self._motor_depth = np.zeros(SMOOTHED_STATE)  # the motor's depth (linear: 0 when stopped)
        self._level_tube = np.zeros(SMOOTHED_STATE)  # the level as a piece began: the tube's
        self._follow_bank()

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
        self._tube_state[:] = 0.0
        self._tube_line[:] = 0.0
        for state, target in ((self._tube_gain, self._tube_target()), (self._motor_depth, self._depth_target())):
            state[:] = 0.0
            start_ramp_now(state, LINEAR, target, 0)
        self._tube_running = self._bank.tube is not None
        pressed = 1.0 if self._params.damper == "down" else 0.0
        self._press_from, self._press_at, self._press_to = pressed, 0, pressed  # (value, from sample, target)
        self._pressed = -1.0  # the press the loops' gains were last set for
        self._set_gains(0)

    # -- the tube, the motor, the damper -----------------------------------------------------
    def _tube_target(self) -> float:
        return self._bank.tube.gain if self._bank.tube is not None else 0.0

    def _depth_target(self) -> float:
        p = self._params
        return p.motor_depth if p.tube == "on" and p.motor_rate_hz > 0.0 else 0.0

    def _follow_bank(self) -> None:
        """The new bank's loop gains without the damper, the damper's factors, the tube's
        coefficients and the motor's phase step."""
        bank, p = self._bank, self._params
        self._free_gains = bank.loops["gain"].copy()
        self._damper_factors = damper_factors(bank.loops, bank.frequencies_hz, bank.t60s_s, p.damper_t60_s,
                                              self.sample_rate)
        if bank.tube is not None:
            self._tube_coefficients = bank.tube.design.coefficients
        self._motor_step = 2.0 * np.pi * p.motor_rate_hz / self.sample_rate if p.tube == "on" else 0.0

    def _press_value(self, at: int) -> float:
        """How far the damper is pressed (0 to 1) at sample ``at`` (from the reset)."""
        moved = (at - self._press_at) / (DAMPER_GLIDE_S * self.sample_rate)
        if self._press_to > self._press_from:
            return min(self._press_to, self._press_from + moved)
        return max(self._press_to, self._press_from - moved)

    def _press(self, target: float) -> None:
        """Press (1) or lift (0) the damper from now, gliding."""
        now = self._stroke.now
        self._press_from, self._press_at, self._press_to = self._press_value(now), now, target

    def _set_gains(self, at: int) -> None:
        """The loops' gains for the damper as it is at the ``DAMPER_STEP`` that sample ``at`` lies in."""
        pressed = self._press_value(max(at - at % DAMPER_STEP, self._press_at))
        if pressed != self._pressed:
            loops = self._bank.loops
            loops["gain"] = self._free_gains if pressed == 0.0 else self._free_gains * self._damper_factors ** pressed
            self._pressed = pressed

    def _update(self, old: BandedParams) -> None:
        """The loops are redesigned at once; what rings keeps ringing; a new level glides there
        over ``LEVEL_GLIDE_S``; the exciters follow (a new bow setting glides). A new
        ``mode_gains_db`` (or position) takes effect at once: ``CrossfadingVoice`` fades it in.
        The tube's gain (and the tube switched on or off) glides over ``TUBE_GLIDE_S``, the motor's
        depth (and the motor started or stopped) over ``MOTOR_GLIDE_S``, its rate keeps the phase;
        the damper is pressed or lifted over ``DAMPER_GLIDE_S``; a new tube (size, mode, tuning)
        takes effect at once."""
        ExciterSet.check(self.model.exciters, self._params, self.sample_rate)
        bank, previous, p = design_bank(self._params, self.sample_rate), self._bank, self._params
        self._bank = bank
        self._follow_bank()
        self._pressed = -1.0
        if p.damper != old.damper:
            self._press(1.0 if p.damper == "down" else 0.0)
        self._set_gains(self._stroke.now)
        if bank.tube is None and self._tube_running and np.array_equal(bank.modes, previous.modes):
            bank.loops["mouth"] = previous.loops["mouth"]  # a tube switched off: still driven while it glides out
        if bank.tube is not None and not self._tube_running:  # (a tube gone silent starts empty)
            self._tube_state[:] = 0.0
            self._tube_line[:] = 0.0
            self._tube_running = True
        for state, target, glide in ((self._tube_gain, self._tube_target(), TUBE_GLIDE_S),
                                     (self._motor_depth, self._depth_target(), MOTOR_GLIDE_S)):
            if target != state[TARGET]:
                start_ramp_now(state, LINEAR, target, ramp_steps(glide, self.sample_rate))
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
        if self._params.damper == "release" and self._press_to > 0.0:
            self._press(0.0)

    def release(self) -> None:
        """Stop a bow stroke now: the bow slows to rest, damps the bar, and is lifted.
        (A bow that is not moving, a strike or a pluck is left as it is.) With ``damper =
        release`` the damper is pressed (and lifted by the next trigger)."""
        self._exciters.release()
        if self._params.damper == "release":
            self._press(1.0)

    def warm_up(self) -> None:
        """Load (or compile) now the level's scaling of a recorded attack (its first block would
        otherwise); the bowed kernel is resolved at its first block (docs/contract.md)."""
        scale(np.zeros(1), np.zeros(SMOOTHED_STATE), MULTIPLICATIVE)

    @property
    def driven_until(self) -> int:
        """The sample index at which the bow is lifted (until another stroke)."""
        return self._exciters.driven_until

    def _render(self, out: np.ndarray) -> None:
        """``out.size`` samples: the pieces of :meth:`_render_piece`, ending where the damper's
        glide steps and, with a tube, within the work space."""
        bow, forces = self._stroke, self._forces
        now = bow.now
        if (self._run is not None and bow.lifted_at <= now and self._pressed == self._press_to
                and not self._tube_running and not self._heard.pending.size):
            # The common block: only the loops ring (the bow off the bar, the damper still, no tube,
            # no attack still heard), so _render_piece would run the plain kernel over the whole
            # block and nothing else: the same call, without its bookkeeping (the fixed cost of
            # every block, about 1.5 us of Python, against 0.6 us for the kernel's call).
            self._run(out, self._no_drive, forces.pending, forces.held, self._bank.loops, self._state, self._level,
                      now)
            bow.now = now + out.size
            if forces.pending.size:
                forces.advance(out.size)
            return
        longest = self.max_block if self._tube_running else out.size
        n, done = out.size, 0
        while done < n:
            now = self._stroke.now
            stop = min(n, done + longest)
            if self._pressed != self._press_to:  # the damper glides: its gains change every DAMPER_STEP
                self._set_gains(now)
                stop = min(stop, done + DAMPER_STEP - now % DAMPER_STEP)
            self._render_piece(out[done:stop])
            done = stop

    def _render_piece(self, out: np.ndarray) -> None:
        """``out.size`` samples of velocity at the pick-up (m/s), plus the tube's sound, times the
        level. The bowed kernel runs exactly while the bow touches; the kernels apply the level in
        place; nothing is allocated."""
        n, bow, forces, heard = out.size, self._stroke, self._forces, self._heard.pending
        now = bow.now
        bowed = min(n, max(0, bow.lifted_at - now))
        loops, state, level = self._bank.loops, self._state, self._level
        if heard.size:
            self._level_then[:] = level  # the direct sound steps through the same gains as the loops
        tube = self._tube_running
        drive = self._drive[:n] if tube else self._no_drive
        if tube:
            self._level_tube[:] = level
        # The kernels are called through their compiled entry points: the dispatcher would type
        # the state record at every call. Resolved at the first use (a struck voice never compiles
        # the bowed kernel); a bow's first block resolves the plain kernel too, for when it lifts.
        if self._run is None:
            self._run = compiled_for(K.process, out, drive, forces.pending, forces.held, loops, state, level, now)
        if bowed:
            part = out if bowed == n else out[:bowed]
            part_drive = drive if not tube or bowed == n else drive[:bowed]
            run = self._run_bowed
            if run is None:
                run = self._run_bowed = compiled_for(K.process_bowed, part, part_drive, forces.pending, forces.held,
                                                     bow.lines, now, loops, state, level)
            run(part, part_drive, forces.pending, forces.held, bow.lines, now, loops, state, level)
        if bowed < n:
            pending = forces.pending if bowed == 0 else forces.from_sample(bowed)
            part_drive = drive if not tube or bowed == 0 else drive[bowed:]
            self._run(out if bowed == 0 else out[bowed:], part_drive, pending, forces.held, loops, state, level,
                      now + bowed)
        bow.now = now + n
        if forces.pending.size:
            forces.advance(n)
        if heard.size:
            self._add_heard(out, heard)
            self._heard.advance(n)
        if tube:
            self._add_tube(out, drive)

    def _add_tube(self, out: np.ndarray, drive: np.ndarray) -> None:
        """Add the tube's sound, driven by ``drive``, times the level as the piece began (stepped as
        the kernels stepped it); a tube switched off runs until its gain has glided to 0."""
        sound = self._tube_out[:out.size]
        run_tube(sound, drive, self._tube_coefficients, self._tube_state, self._tube_line, self._tube_gain,
                 self._motor_depth, self._motor_step)
        scale(sound, self._level_tube, MULTIPLICATIVE)
        out += sound
        gain = self._tube_gain
        if self._bank.tube is None and gain[CURRENT] == 0.0 and gain[LEFT] <= 0.0:
            self._tube_running = False

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
