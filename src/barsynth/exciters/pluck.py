"""A pluck: the bar held out at a point, then let go over a short release.

Source: barsynth spec 3.1 (excitations). The force that holds the strike point
``pluck_displacement_mm`` out follows from the bar's static compliance there; it is released
along a raised cosine over ``release_time_ms``. Near a clamped or pinned end (or at a node
of every mode a model keeps) holding the point out takes a force without bound, and the rest
of the bar would follow: there the force is capped so that no point moves more than
:data:`PLUCK_REACH` times the displacement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, cast

import numpy as np

from ..dsp.mallet import release_ramp
from ..parameters import Parameter
from .base import DrivePoint, Exciter, Force

PLUCK_REACH = 10.0
"""A pluck moves no point of the bar more than this many times ``pluck_displacement_mm``.
Ordinary plucks never reach it (a cantilever plucked at a tenth of its length from the clamp
moves its tip 14.5 times as far, at a seventh 10 times; a free-free bar's ends at most 2.6
times), so their sound is unchanged."""

PLUCK_DOC = ("how far the strike point is held out before a pluck's release (near a clamped or pinned end "
             f"less: no point of the bar is held out more than {PLUCK_REACH:g} times this)")
PLUCKED = {"excitation": ("pluck",)}
POSITIONS_ALONG = np.linspace(0.0, 1.0, 201)
"""Where a bar's largest deflection is looked for (fractions of its length)."""


def largest_deflection(at_strike: np.ndarray, along: np.ndarray, stiffness: np.ndarray) -> float:
    """The bar's largest static deflection per newton at the strike point (m/N), from its modes:
    ``max_x |sum_n phi_n(x) phi_n(a) / k_n|`` for the shapes ``at_strike`` (``phi_n(a)``, one per
    mode), ``along`` (``phi_n(x)``, modes x positions) and modal stiffnesses ``k_n = m w_n^2``."""
    if along.size == 0:
        return 0.0
    return float(np.max(np.abs((at_strike / stiffness) @ along)))


@dataclass(frozen=True)
class PluckHold:
    """The pluck as a resonator solves it: its point held out ``displacement_m`` (m), then let go."""

    displacement_m: float

    def force_n(self, drive: DrivePoint) -> float:
        """The force (N) that holds the point out: the displacement over the compliance, capped so
        no point moves more than ``PLUCK_REACH`` x the displacement; 0 where nothing gives."""
        give = max(drive.compliance_m_n, drive.reach_m_n / PLUCK_REACH)
        force = self.displacement_m / give if give > 0.0 else 0.0
        return force if math.isfinite(force) else 0.0  # a give so small it underflows: nothing moves measurably


class PluckSettings(Protocol):
    """What a pluck reads from a model's record: its rows (:meth:`Pluck.parameters`)."""

    @property
    def pluck_displacement_mm(self) -> float: ...


class ReleasedPluckSettings(PluckSettings, Protocol):
    """... and, for the in-advance form, the release row (``Pluck.parameters(release=True)``)."""

    @property
    def release_time_ms(self) -> float: ...


class Pluck(Exciter[PluckSettings]):
    """A pluck, from a model's ``pluck_displacement_mm`` (and ``release_time_ms`` for the
    in-advance form)."""

    name = "pluck"
    summary = "a release"
    in_advance = True  # the force released over release_time_ms (banded, all-pass)
    coupled = True  # the bar held out, then let go with the step (fd)

    @staticmethod
    def parameters(*, release: bool = True) -> list[Parameter]:
        """Its rows; ``release=False`` for a model that only takes the coupled form (the bar let go
        at once, its step being the release)."""
        rows = [Parameter("pluck_displacement_mm", "mm", 0.01, 20.0, 1.0, PLUCK_DOC, scale="log", when=PLUCKED)]
        if release:
            rows.append(Parameter("release_time_ms", "ms", 0.05, 20.0, 0.5, "how long a pluck's release takes",
                                  scale="log", when=PLUCKED))
        return rows

    def coupling(self) -> PluckHold:
        """The point held out, for a resonator that lets it go with its own step: the coupled form."""
        return PluckHold(self.settings.pluck_displacement_mm * 1e-3)

    def force(self, drive: DrivePoint) -> Force:
        """The force change of letting go (N per sample, over the release along a raised cosine),
        and the change that stays after it: the in-advance form (it reads ``release_time_ms``)."""
        held = -self.coupling().force_n(drive)
        release_s = cast(ReleasedPluckSettings, self.settings).release_time_ms * 1e-3
        return Force(release_ramp(held, release_s, self.sample_rate), held)
