"""Banded waveguides: struck, bowed or plucked bars, tuned bars, glasses and bowls.

Source: G. Essl and P. R. Cook, "Banded waveguides: towards physical modeling of bowed bar
percussion instruments", Proc. ICMC 1999 (barsynth spec 3.1); the mallet after A. Chaigne
and V. Doutaut, JASA 101 (1997).

One loop per mode, each placed exactly on its mode's frequency and decay. The model's
parts: :mod:`.table` (the parameters, :class:`BandedParams`), :mod:`.design` (modes, mode
shapes and the loops: pure), :mod:`.kernel` (the numba loops) and :mod:`.voice`
(:class:`BandedVoice`, which drives them with the exciters of :mod:`barsynth.exciters`).
"""

from __future__ import annotations

import numpy as np

from ..base import Mode, Model
from ..rendering import check_sample_rate
from .design import BAND_Q, LOWEST_HZ, LoopDesign, design_loop, mode_shapes, mode_table, playable
from .table import BANDED_TABLE, MAX_MODES, MIN_Q, BandedParams
from .voice import BandedVoice


class BandedModel(Model):
    """Banded-waveguide objects as a barsynth model."""

    name = "banded"
    summary = "banded waveguides (Essl & Cook 1999): struck, bowed or plucked bars, tuned bars, glasses, bowls"
    table = BANDED_TABLE
    voice_class = BandedVoice

    def describe(self, parameters: BandedParams | dict | None = None, *,
                 sample_rate: float = 48000.0) -> list[Mode]:
        """The modes that sound: frequency (Hz), gain (strike shape x pick-up shape) and T60 (s)."""
        p = self.resolve(parameters)
        rate = check_sample_rate(sample_rate)
        freqs, t60s, _ = mode_table(p)
        strike = mode_shapes(p, len(freqs), p.strike_position)
        pickup = mode_shapes(p, len(freqs), p.pickup_position)
        return [Mode("mode", float(freqs[k]), float(strike[k] * pickup[k]), float(t60s[k]))
                for k in np.flatnonzero(playable(freqs, rate))]


MODEL = BandedModel()

__all__ = ["BANDED_TABLE", "BAND_Q", "LOWEST_HZ", "MAX_MODES", "MIN_Q", "MODEL", "BandedModel",
           "BandedParams", "BandedVoice", "LoopDesign", "design_loop", "mode_table"]
