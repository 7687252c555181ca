"""The physical twang: a ruler clamped by a finger, slapping on a desk (spec 9).

Sources: S. Bilbao, Numerical Sound Synthesis (Wiley 2009), ch. 7 (the bar's theta scheme);
S. Bilbao, A. Torin and V. Chatziioannou, Acta Acustica 101 (2015) (collisions as the discrete
gradient of a penalty potential, solved with the step); C. Selfridge et al., AES 2022 (the twang
paper: the mechanism it scripts, section 3.4, and its future work, section 7.1); A. W. Leissa,
Vibration of Plates (NASA SP-160, 1969) for the desk.

The ruler lies on a desk, its overhang beyond the edge; a finger presses it down behind the edge;
a hand bends the tip down and lets go. The ruler is a finite-difference bar (free at both ends)
over its whole length; the desk is a one-sided penalty contact under it up to the edge (the edge
bearing as a centimetre more); the finger a one-sided spring and damper from above, pressing with
its force. Swinging up, the ruler leaves the desk between finger and edge and rings as the long
cantilever; swinging down it slaps on the desk and bears on the edge, ringing as the short one.
The sound is the overhang's radiation (its summed acceleration, as a small source at 1 m) and the
desk's modes, driven by the contact forces (:mod:`.desk`), mixed by ``desk_balance``.

Modules: :mod:`.table` (:class:`RulerParams`), :mod:`.design` (the engine's setup and records),
:mod:`.statics` (rest and held shapes), :mod:`.kernel` (the numba step), :mod:`.desk` (the desk),
:mod:`.voice` (the engine's voice) and :mod:`.model` (:class:`RulerModel`, ``MODEL``).
"""

from .model import MODEL, RulerModel, RulerVoice, ruler_setup
from .table import RULER_TABLE, RulerParams

__all__ = ["MODEL", "RULER_TABLE", "RulerModel", "RulerParams", "RulerVoice", "ruler_setup"]
