"""Banded waveguides as a barsynth :class:`~barsynth.models.base.Model` (see :mod:`barsynth.models.banded`)."""

from __future__ import annotations

import numpy as np

from ..base import Mode, Model
from ..rendering import check_sample_rate
from .design import mode_gains, mode_shapes, mode_table, playable
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
        gain, ``mode_gains_db``) and T60 (s)."""
        p = self.resolve(parameters)
        rate = check_sample_rate(sample_rate)
        freqs, t60s, _ = mode_table(p)
        strike = mode_shapes(p, len(freqs), p.strike_position)
        pickup = mode_shapes(p, len(freqs), p.pickup_position)
        gains = mode_gains(p, len(freqs))
        return [Mode("mode", float(freqs[k]), float(strike[k] * pickup[k] * gains[k]), float(t60s[k]))
                for k in np.flatnonzero(playable(freqs, rate))]


MODEL = BandedModel()
