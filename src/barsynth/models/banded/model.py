"""Banded waveguides as a barsynth :class:`~barsynth.models.base.Model` (see :mod:`barsynth.models.banded`)."""

from __future__ import annotations

import math

import numpy as np

from ..base import Mode, Model
from ..rendering import check_sample_rate
from .design import design_bank, mode_gains, mode_shapes, mode_table, playable
from .resonator import check_tube_mode, heard_mode, tube_t60s
from .table import BANDED_EXCITERS, BANDED_TABLE, CONSTRAINTS, NOTES, BandedParams
from .voice import BandedVoice


class BandedModel(Model):
    """Banded-waveguide objects as a barsynth model."""

    name = "banded"
    summary = "banded waveguides (Essl & Cook 1999): struck, bowed or plucked bars, tuned bars, glasses, bowls"
    table = BANDED_TABLE
    note_maps = NOTES
    constraints = CONSTRAINTS
    voice_class = BandedVoice
    exciters = BANDED_EXCITERS

    def describe(self, parameters: BandedParams | dict | None = None, *,
                 sample_rate: float = 48000.0) -> list[Mode]:
        """The modes that sound: frequency (Hz), gain (strike shape x pick-up shape x the mode's own
        gain, ``mode_gains_db``) and T60 (s).

        With a tube, every mode it hears (its shape at the mouth not 0) has the tube's forced
        sound in its gain: strike shape x |pick-up shape x own gain + what the tube makes of the
        mode|, the motor open (the tube's own ringing near a mode it is not tuned to dies within
        its resonance's T60, tens of ms). The mode the tube is tuned to is given as it is heard
        (:func:`.resonator.heard_mode`): its direct sound, pulled by ``tube_damping``, plus the
        tube's response to it, two exponentials whose sum blooms and lasts longer than the mode
        alone; its T60 and gain are what :func:`barsynth.analysis.measure_partial` measures of that
        sum from 30 ms after the strike until it has fallen 60 dB. A last entry ``tube`` gives the
        tube's own resonance and T60 (gain 0: it sounds only through the modes)."""
        p = self.resolve(parameters)
        rate = check_sample_rate(sample_rate)
        freqs, t60s, _ = mode_table(p)
        check_tube_mode(p, len(freqs))
        t60s = tube_t60s(p, t60s)
        strike = mode_shapes(p, len(freqs), p.strike_position)
        pickup = mode_shapes(p, len(freqs), p.pickup_position)
        gains = strike * pickup * mode_gains(p, len(freqs))
        extra = []
        if p.tube == "on":
            tube = design_bank(p, rate).tube
            mouth = mode_shapes(p, len(freqs), p.tube_position)
            tuned = p.tube_mode - 1
            for k in np.flatnonzero(playable(freqs, rate)):
                if not strike[k] or not mouth[k]:
                    continue
                sign = math.copysign(1.0, gains[k] if gains[k] else strike[k])  # (the sign the mode had)
                direct = gains[k] / strike[k]
                if k == tuned:
                    level, t60s[k] = heard_mode(direct, tube.through_tube, float(freqs[k]), float(t60s[k]),
                                                tube.design)
                else:
                    response = tube.design.response_to_mode(float(freqs[k]), float(t60s[k]))
                    level = abs(direct + tube.gain * mouth[k] * response)
                gains[k] = sign * abs(strike[k]) * level
            extra = [Mode("tube", tube.design.frequency_hz, 0.0, tube.design.t60_s)]
        return [Mode("mode", float(freqs[k]), float(gains[k]), float(t60s[k]))
                for k in np.flatnonzero(playable(freqs, rate))] + extra


MODEL = BandedModel()
