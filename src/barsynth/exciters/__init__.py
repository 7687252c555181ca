"""Exciters: strike, pluck, bow and a recorded attack, apart from the resonators they drive.

As Faust's ``strikeModel : marimbaModel``: each exciter owns its parameter rows and its
forms (:mod:`.base`: one interface); the banded, all-pass and finite-difference resonators
take any of them, in the in-advance form (a force known in advance, played through a
:class:`ForceQueue`: banded and all-pass strikes and plucks) or the coupled one (a record
solved with the resonator's step: the fd mallet and pluck, every bow). A model lists the
ones it offers in ``Model.exciters``; its voice keeps one of each (:class:`ExciterSet`). A
recorded attack (:class:`Sample`, commuted synthesis) also offers a direct form: samples heard
at the output from the trigger on (banded).
"""

from .base import DrivePoint, Exciter, ExciterSet, Force, ForceQueue, StaticPoint
from .bow import BOWED, Bow, BowSettings
from .pluck import (PLUCK_REACH, PLUCKED, POSITIONS_ALONG, Pluck, PluckHold, PluckSettings, ReleasedPluckSettings,
                    largest_deflection)
from .sample import SAMPLED, Sample, SampleSettings
from .strike import STRUCK, MalletContact, Strike, StrikeSettings, mallet_contact_s

STRUCK_OR_PLUCKED = {"excitation": ("strike", "pluck")}
EXCITERS: dict[str, type[Exciter]] = {e.name: e for e in (Strike, Pluck, Bow, Sample)}
"""Every exciter by its ``excitation`` name (a model offers some of them: ``Model.exciters``)."""

__all__ = ["BOWED", "EXCITERS", "PLUCKED", "PLUCK_REACH", "POSITIONS_ALONG", "SAMPLED", "STRUCK",
           "STRUCK_OR_PLUCKED", "Bow", "BowSettings", "DrivePoint", "Exciter", "ExciterSet", "Force", "ForceQueue",
           "MalletContact", "Pluck", "PluckHold", "PluckSettings", "ReleasedPluckSettings", "Sample",
           "SampleSettings", "StaticPoint", "Strike", "StrikeSettings", "largest_deflection", "mallet_contact_s"]
