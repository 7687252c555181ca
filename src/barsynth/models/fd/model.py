"""The finite-difference bar as a barsynth :class:`~barsynth.models.base.Model`."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..base import Mode, Model
from ..rendering import check_sample_rate
from .design import deflection_mass, point_vector, reference_errors_cents, scheme_modes
from .table import CONSTRAINTS, FD_EXCITERS, FD_TABLE, NOTES
from .voice import FdVoice

MAX_DESCRIBED = 24


class FdModel(Model):
    """The finite-difference bar (see :mod:`barsynth.models.fd`)."""

    name = "fd"
    summary = "finite-difference bar (implicit theta scheme): any boundary, undercut profiles; struck, bowed, plucked"
    table = FD_TABLE
    note_maps = NOTES
    constraints = CONSTRAINTS
    voice_class = FdVoice
    exciters = FD_EXCITERS
    reports_reference_errors = True

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The modes the scheme rings (below Nyquist): frequency, gain (strike x pick-up shapes), T60."""
        p = self.resolve(parameters)
        found = scheme_modes(p, check_sample_rate(sample_rate), MAX_DESCRIBED)
        grid = found.grid
        total = math.sqrt(float(np.sum(deflection_mass(grid))))
        strike, pickup = point_vector(grid, p.strike_position), point_vector(grid, p.pickup_position)
        modes = []
        for f, t60, shape in zip(found.frequency_hz, found.t60_s, found.shapes.T):
            gain = float(np.dot(strike, shape) * np.dot(pickup, shape)) * total ** 2
            modes.append(Mode("mode", float(f), gain, float(t60)))
        return modes

    def errors_cents(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[float]:
        """Each described mode's error (cents) against the converged bar: see :func:`mode_errors_cents`."""
        return [float(e) for e in mode_errors_cents(parameters, sample_rate=sample_rate, count=MAX_DESCRIBED)]


MODEL = FdModel()


def mode_errors_cents(parameters: Any = None, *, sample_rate: float = 48000.0, count: int = 8) -> np.ndarray:
    """How far (cents) each of the first ``count`` modes the scheme rings at ``sample_rate`` Hz lies
    from the converged bar's (spec 1.2's closed form for a uniform bar, the extrapolated operator
    for any other profile). Negative: the grid and the step ring it flat."""
    return reference_errors_cents(MODEL.resolve(parameters), check_sample_rate(sample_rate), count)
