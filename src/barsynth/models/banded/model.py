"""Banded waveguides as a barsynth :class:`~barsynth.models.base.Model` (see :mod:`barsynth.models.banded`)."""

from __future__ import annotations

import math

import numpy as np

from ..base import Mode, Model
from ..rendering import check_sample_rate
from .design import design_bank, mode_gains, mode_shapes, mode_table, playable
from .resonator import check_tube_mode, heard_mode, tube_t60s
from .table import BANDED_EXCITERS, BANDED_TABLE, BandedParams
from .voice import BandedVoice


class BandedModel(Model):
    """Banded-waveguide objects as a barsynth model."""

    name = "banded"
    summary = "banded waveguides (Essl & Cook 1999): struck, bowed or plucked bars, tuned bars, glasses, bowls"
    table = BANDED_TABLE
    voice_class = BandedVoice
    exciters = BANDED_EXCITERS

    def describe(self, parameters: BandedParams | dict | None = None, *,
                 sample_rate: float = 48000.0) -> list[Mode]:
        """The modes that sound: frequency (Hz), gain (strike shape x pick-up shape x the mode's own
        gain, ``mode_gains_db``) and T60 (s). With a tube, the mode it is tuned to has its pull
        (``tube_damping``) in its T60 and the tube's sound in its gain (strike shape x |pick-up
        shape x own gain + what the tube makes of the mode|, the motor open, once the tube's own
        start has died away), and a last entry ``tube`` gives the tube's own resonance and T60
        (gain 0: it sounds only through the mode)."""
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
            k = p.tube_mode - 1
            sign = math.copysign(1.0, gains[k] if gains[k] else strike[k])  # (the sign the mode had)
            if strike[k]:
                level, t60s[k] = heard_mode(gains[k] / strike[k], tube.through_tube, float(freqs[k]),
                                            float(t60s[k]), tube.design)
                gains[k] = sign * abs(strike[k]) * level
            extra = [Mode("tube", tube.design.frequency_hz, 0.0, tube.design.t60_s)]
        return [Mode("mode", float(freqs[k]), float(gains[k]), float(t60s[k]))
                for k in np.flatnonzero(playable(freqs, rate))] + extra


MODEL = BandedModel()
