"""The all-pass waveguide bar as a barsynth :class:`~barsynth.models.base.Model` (see
:mod:`barsynth.models.allpass`)."""

from __future__ import annotations

from typing import Any

from ..base import Mode, Model
from ..rendering import check_sample_rate
from .design import design_for
from .table import ALLPASS_EXCITERS, CONSTRAINTS, NOTES, TABLE
from .voice import AllpassVoice


class AllpassModel(Model):
    """The all-pass waveguide bar as a barsynth model (see :mod:`barsynth.models.allpass`)."""

    name = "allpass"
    summary = ("all-pass (generalised) waveguide bar (Van Duyne & Smith 1994): travelling bending waves "
               "through fitted dispersion filters, struck or plucked; a measured comparison")
    table = TABLE
    note_maps = NOTES
    constraints = CONSTRAINTS
    voice_class = AllpassVoice
    exciters = ALLPASS_EXCITERS

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The resonances the waveguide will play, from its own filters: frequency, gain
        (velocity per unit impulse x mass: for a real bar the product of the two mode
        shapes) and T60. Groups: ``fitted`` (in the fitted band), ``unfitted`` (above it,
        where the filters are not fitted), ``spurious`` (the loop's own resonances below the
        first mode, which the strike and pick-up filters keep far down)."""
        design = design_for(self.resolve(parameters), check_sample_rate(sample_rate))
        modes = [Mode("fitted" if m.fitted else "unfitted", m.model_hz, m.gain, m.model_t60_s)
                 for m in design.modes]
        return modes + [Mode("spurious", f, g, t60) for f, g, t60 in design.spurious]


MODEL = AllpassModel()
