"""Farnell's ruler twang ("Boing") and the listening test's anchor.

Source: A. Farnell, *Designing Sound*, MIT Press 2010, chapter "Boing" (Pure Data
patch ``twang.pd``), as read in barsynth spec 5; the anchor is the twang paper's
(Selfridge et al., AES Convention Paper 10553, 2022): the same patch with its
``phasor~`` replaced by a cosine.

On a trigger the drive phasor restarts at 0 and runs *down* at ``f/4 + 6 E(t)``
(``E = 3 d^64``, ``d`` falling 1 -> 0 over 7 s: an 18 Hz glide of about 110 ms); the
clamped bank ``C = c^4 sum g_k cos(2 pi r_k p)`` (``c`` falling over 1.5 s, cantilever
ratios 1, 6.267, 17.55, 34.39, gains halving from 0.5) drives noise x p^2 x C through
a 4 kHz one-pole into six ``vcf~`` band-passes (Q 80) at the free-bar ratios of
``f (1 + 0.1 E)``; out = 4 x hip~90(free + 0.2 C). Vibrato: ``depth sin(2 pi 5 t)``
added to ``f``, free-running.

Where barsynth departs from the patch, for its own rules: band-passes fade out over
the top 5 % below Nyquist instead of aliasing; frequency, depth and level changes glide
over 5 ms (:mod:`barsynth.dsp.smoothing`); a ``level_db`` scales the patch's output
(0 dB = the patch).

The package: :mod:`.table` (parameters), :mod:`.design` (the patch's constants and
envelopes), :mod:`.kernel` (the samples), :mod:`.voice` (the streaming voice), :mod:`.model`
(:class:`FarnellModel`, ``MODEL``).
"""

from .model import MODEL, FarnellModel
from .table import FARNELL_TABLE, FarnellParams
from .voice import SMOOTHING_TIME_S, FarnellVoice

__all__ = ["FARNELL_TABLE", "MODEL", "SMOOTHING_TIME_S", "FarnellModel", "FarnellParams", "FarnellVoice"]
