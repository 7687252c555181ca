"""The kalimba: a steel tine clamped behind a bridge, plucked near its tip (spec 9.4).

Sources: D. M. F. Chapman, "The tones of the kalimba (African thumb piano)", J. Acoust. Soc.
Am. 131(1), 945-950 (2012) (the tine clamped at the load point, simply supported at the bridge,
free at the tip; as D. Ludwigsen, JASA 153, A227 (2023), describes it: docs/kalimba.md); and the
engine's (:mod:`barsynth.models.ruler`): S. Bilbao, Numerical Sound Synthesis (Wiley 2009),
ch. 7 (the bar's theta scheme), S. Bilbao, A. Torin and V. Chatziioannou, Acta Acustica 101
(2015) (a contact as the discrete gradient of a penalty potential, solved with the step).

The tine is the ruler engine's finite-difference bar, clamped at its back end (under the
pressure bar), lifted by the bridge ``back_length_m`` in front of the clamp by
``bridge_height_mm`` (the preload that keeps it pressed there), free at the tip beyond it. The
bridge is a one-sided contact from below (the tine may lift off it) or pinned (a spring both
ways). A thumb pushes the tine down near the tip and lets go; the sound is the vibrating part's
radiation (its summed acceleration, a small source at 1 m). There is no desk.

Modules: :mod:`.table` (:class:`KalimbaParams`) and :mod:`.model` (:class:`KalimbaModel`, ``MODEL``).
"""

from .model import MODEL, KalimbaModel, KalimbaVoice, kalimba_setup, tine_modes
from .table import KALIMBA_TABLE, KalimbaParams

__all__ = ["KALIMBA_TABLE", "MODEL", "KalimbaModel", "KalimbaParams", "KalimbaVoice", "kalimba_setup", "tine_modes"]
