"""Banded waveguides: struck, bowed or plucked bars, tuned bars, glasses and bowls.

Source: G. Essl and P. R. Cook, "Banded waveguides: towards physical modeling of bowed bar
percussion instruments", Proc. ICMC 1999 (barsynth spec 3.1); the mallet after A. Chaigne
and V. Doutaut, JASA 101 (1997).

One loop per mode, each placed exactly on its mode's frequency and decay. The model's
parts: :mod:`.table` (the parameters, :class:`BandedParams`), :mod:`.design` (modes, mode
shapes and the loops: pure), :mod:`.kernel` (the numba loops) and :mod:`.voice`
(:class:`BandedVoice`, which drives them with the exciters of :mod:`barsynth.exciters`) and
:mod:`.model` (:class:`BandedModel`, ``MODEL``).
"""

from .design import BAND_Q, LOWEST_HZ, LoopDesign, design_loop, mode_table
from .model import MODEL, BandedModel
from .table import BANDED_TABLE, MAX_MODES, MIN_Q, BandedParams
from .voice import BandedVoice

__all__ = ["BANDED_TABLE", "BAND_Q", "LOWEST_HZ", "MAX_MODES", "MIN_Q", "MODEL", "BandedModel",
           "BandedParams", "BandedVoice", "LoopDesign", "design_loop", "mode_table"]
