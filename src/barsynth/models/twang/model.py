"""The ruler twang as a barsynth :class:`~barsynth.models.base.Model` (see :mod:`barsynth.models.twang`)."""

from __future__ import annotations

from typing import Any

from ..base import Mode, Model
from ..constraints import check_constraints
from ..rendering import check_sample_rate
from .design import design_modes
from .table import CONSTRAINTS, NOTES, TWANG_TABLE
from .voice import TwangVoice


class TwangModel(Model):
    """The ruler twang as a barsynth model (see the package docstring)."""

    name = "twang"
    summary = "ruler twanged over a desk edge (Selfridge et al., AES 2022)"
    table = TWANG_TABLE
    note_maps = NOTES
    constraints = CONSTRAINTS
    voice_class = TwangVoice

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """Every mode at the trigger (vibrato and slide at rest); silenced ones left out."""
        return design_modes(self.resolve(parameters), sample_rate=check_sample_rate(sample_rate))

    def check_renderable(self, voice: TwangVoice) -> None:
        """A ruler none of whose modes is audible (all below 20 Hz, at or above Nyquist, or
        at zero gain) would render silence: refused (its declared constraint)."""
        check_constraints(CONSTRAINTS, voice.parameters, voice.sample_rate)


MODEL = TwangModel()
