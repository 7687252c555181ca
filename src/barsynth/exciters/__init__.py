"""Exciters: strike, pluck and bow, apart from the resonators they drive.

As Faust's ``strikeModel : marimbaModel``: each exciter owns its parameter rows and its
force; the banded, all-pass and finite-difference resonators take any of them, in the
uncoupled form (a force known in advance, played through a :class:`ForceQueue`) or the
coupled one (solved with the resonator's step: the fd mallet, every bow).
"""

from .base import DrivePoint, Exciter, ForceQueue
from .bow import BOWED, Bow
from .pluck import PLUCK_REACH, PLUCKED, POSITIONS_ALONG, Pluck, largest_deflection
from .strike import STRUCK, MalletContact, Strike, mallet_contact_s

STRUCK_OR_PLUCKED = {"excitation": ("strike", "pluck")}
EXCITERS: dict[str, type[Exciter]] = {e.name: e for e in (Strike, Pluck, Bow)}
"""Every exciter by its ``excitation`` name."""

__all__ = ["BOWED", "EXCITERS", "PLUCKED", "PLUCK_REACH", "POSITIONS_ALONG", "STRUCK", "STRUCK_OR_PLUCKED", "Bow",
           "DrivePoint", "Exciter", "ForceQueue", "MalletContact", "Pluck", "Strike", "largest_deflection",
           "mallet_contact_s"]
