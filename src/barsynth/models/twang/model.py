"""The ruler twang as a barsynth :class:`~barsynth.models.base.Model` (see :mod:`barsynth.models.twang`)."""

from __future__ import annotations

from typing import Any

from ...errors import ParameterError
from ..base import Mode, Model
from ..rendering import check_sample_rate
from .design import design_modes
from .table import NOTES, TWANG_TABLE
from .voice import TwangVoice

AUDIBLE_MIN_HZ = 20.0  # an offline render needs one mode at least this high


class TwangModel(Model):
    """The ruler twang as a barsynth model (see the package docstring)."""

    name = "twang"
    summary = "ruler twanged over a desk edge (Selfridge et al., AES 2022)"
    table = TWANG_TABLE
    note_maps = NOTES
    voice_class = TwangVoice

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """Every mode at the trigger (vibrato and slide at rest); silenced ones left out."""
        return design_modes(self.resolve(parameters), sample_rate=check_sample_rate(sample_rate))

    def check_renderable(self, voice: TwangVoice) -> None:
        """A ruler none of whose modes is audible (all below 20 Hz, at or above Nyquist, or
        at zero gain) would render silence: refused."""
        modes = design_modes(voice.parameters, sample_rate=voice.sample_rate)
        if not any(m.frequency_hz >= AUDIBLE_MIN_HZ for m in modes):
            raise ParameterError(
                f"parameters put every mode of this ruler below {AUDIBLE_MIN_HZ:g} Hz, at or above "
                f"Nyquist ({voice.sample_rate / 2:g} Hz) or at zero gain; allowed: settings with "
                "at least one audible mode (change length, thickness or material, or the sample_rate)"
            )


MODEL = TwangModel()
