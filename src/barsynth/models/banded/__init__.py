"""Banded waveguides (Essl & Cook 1999): see :mod:`barsynth.models.banded.voice`."""

from .voice import BANDED_TABLE, MODEL, BandedModel, BandedVoice, mode_table

__all__ = ["BANDED_TABLE", "MODEL", "BandedModel", "BandedVoice", "mode_table"]
