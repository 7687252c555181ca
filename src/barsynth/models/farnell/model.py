"""Farnell's twang as a barsynth :class:`~barsynth.models.base.Model` (see :mod:`barsynth.models.farnell`)."""

from __future__ import annotations

from typing import Any

from ..base import Mode, Model
from ..rendering import check_sample_rate
from .design import patch_modes
from .table import FARNELL_TABLE, NOTES
from .voice import FarnellVoice


class FarnellModel(Model):
    """Farnell's twang as a barsynth model (see the package docstring)."""

    name = "farnell"
    summary = "Farnell's ruler twang, Designing Sound 2010 (and, with anchor=true, the paper's anchor)"
    table = FARNELL_TABLE
    note_maps = NOTES
    voice_class = FarnellVoice

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The modes at rest (after the glide): the drive and clamped partials and the
        free bands. Gains are the patch's; T60 is that of the band-pass (free) or of
        the clamped envelope's c^4 fall (reported as the time to -60 dB)."""
        return patch_modes(self.resolve(parameters), sample_rate=check_sample_rate(sample_rate))


MODEL = FarnellModel()
