"""The all-pass (generalised) waveguide bar: struck or plucked (spec 3.2).

Sources: S. A. Van Duyne and J. O. Smith, "A simplified approach to modeling
dispersion caused by stiffness in strings and plates", Proc. ICMC 1994; J. S. Abel
and J. O. Smith, "Robust design of very high-order allpass dispersion filters",
Proc. DAFx 2006; J. Rauhala and V. Välimäki, "Tunable dispersion filter design for
piano synthesis", IEEE Signal Processing Letters 13 (2006); G. Essl and P. R. Cook,
"Banded waveguides", Proc. ICMC 1999 (the comparison of the three bar models); the
mallet after A. Chaigne and V. Doutaut, JASA 101 (1997).

A digital waveguide for the bar's two travelling bending waves. The strike and
pick-up points split it into four filters round one loop (from ``x_a``, the
nearer point to the ``x = 0`` end, to that end and back; ``x_a`` to ``x_b``; ``x_b``
to the far end and back; ``x_b`` to ``x_a``), each a delay, a sign and a chain of
all-pass sections fitted to the phase the bending waves gather there
(``v = sqrt(a w)``, so ``x lambda(w)`` with ``lambda = L sqrt(w / a)``), with the
ends' reflections (``-j`` free or clamped, ``-1`` pinned) and a correction for the
near field folded in so that the loop's resonances fall on the uniform bar's
modes (:func:`barsynth.physics.bar_frequencies`). ``allpass_order`` sections in
all; :func:`allpass_design` explains the fit and reports every resonance against
physics (``describe`` lists them). Losses: each filter holds its share (its length)
of a gain and up to three minimum-phase shelves fitted so that every mode decays
with ``T60 = q ln(1000) / (pi f)``.

Strike: a Hertzian mallet (:class:`barsynth.exciters.Strike`) whose force enters
both travelling waves at ``strike_position`` through ``1 / (4 rho A v(w))`` (the
waves' share of a point force). Pluck (:class:`barsynth.exciters.Pluck`): the strike
point held out by a force and let go; where that would take a force without bound
(near a clamped or pinned end) the force is capped so that no point moves more than
``PLUCK_REACH`` times the displacement, in the real bar or in the waveguide's own
(whose clamped ends move: see below, so a pluck or a strike at a clamped end sounds,
at a bounded level, like one near it). Output: the sum of the two waves at
``pickup_position`` (m/s) times ``level_db``. A new strike adds to what rings; nothing
is cleared, and a change of parameters that rebuilds the waveguide leaves the old one
ringing beside the new one.

What it misses, and so what this model is for (a measured comparison, not the
recommended path): the near field. Its frequencies are right (folded into the
fit), its mode shapes are the travelling waves' only: a free end reads half of
what a real one does, and a clamped end moves (a real one does not). Short
filters (points close together or close to an end) cannot follow their own phase
at the lowest modes with few sections, so levels there are approximate; the
loop's frequencies and decays are what the fit protects first.

The package: ``table`` (parameters), ``design`` (parameters -> filters and their report,
from ``targets``, ``plan``, ``loss``, ``fitting`` and ``injection``), ``kernel`` (numba),
``voice`` (the voice), ``model`` (the model).

Examples
--------
>>> import numpy as np
>>> model = MODEL
>>> modes = model.describe({"bc": "clamped-free"}, sample_rate=48000)
>>> [(m.group, round(m.frequency_hz, 1)) for m in modes[:3]]
[('fitted', 90.7), ('fitted', 568.6), ('fitted', 1592.2)]
>>> x = model.render({"bc": "clamped-free"}, duration_s=0.1, sample_rate=48000, normalize=False)
>>> x.shape, bool(np.isfinite(x).all()), float(abs(x).max()) > 0.0
((4800,), True, True)
"""

from .design import AllpassDesign, Filter, ModeFit, allpass_design, design_for
from .injection import response
from .table import BOUNDARY_CONDITIONS, TABLE, AllpassParams
from .model import MODEL, AllpassModel
from .voice import AllpassVoice

ALLPASS_TABLE = TABLE

__all__ = ["ALLPASS_TABLE", "BOUNDARY_CONDITIONS", "MODEL", "TABLE", "AllpassDesign", "AllpassModel",
           "AllpassParams", "AllpassVoice", "Filter", "ModeFit", "allpass_design", "design_for", "response"]
