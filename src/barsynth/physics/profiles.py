"""Thickness profiles of non-uniform bars: uniform, undercut (parabolic, circular), sampled.

Source: barsynth spec 1.5 and 1.6; undercut tuned bars as in T. D. Rossing, Science of
Percussion Instruments (World Scientific 2000), ch. 5, and A. Chaigne and V. Doutaut,
JASA 101 (1997) (a bar thinned under its middle lowers its first mode much more than
its second, which tunes f2/f1 from 2.76 towards 4).

A profile gives the thickness along the bar relative to the full thickness ``h0``,
as a function of the position ``x`` as a fraction of the length (0 to 1):

- ``uniform``: 1 everywhere;
- ``parabolic``: an undercut ``width`` long (fraction of the length, centred) whose
  depth is a parabola, ``depth`` (fraction of ``h0``) at the middle and 0 at its edges;
- ``circular``: the same cut made by a circular saw: a circular arc through the cut's
  edges and the middle (its shape depends on the bar's length and thickness);
- ``samples``: relative thicknesses at equally spaced points from one end to the
  other, joined by straight lines.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..checks import show_value
from ..errors import ParameterError

PROFILE_KINDS = ("uniform", "parabolic", "circular", "samples")
THINNEST = 0.02
"""The thinnest a profile may make the bar, as a fraction of its full thickness."""


@dataclass(frozen=True)
class Profile:
    """A thickness profile (see the module docstring).

    Examples
    --------
    >>> cut = Profile("parabolic", depth=0.5, width=0.5)
    >>> cut.relative_thickness(np.array([0.0, 0.25, 0.5]), length_m=0.4, thickness_m=0.02).tolist()
    [1.0, 1.0, 0.5]
    """

    kind: str = "uniform"
    depth: float = 0.0
    width: float = 0.5
    samples: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in PROFILE_KINDS:
            raise ParameterError(f"parameter profile = {show_value(self.kind)} is unknown; allowed: one of "
                                 f"{', '.join(PROFILE_KINDS)}")
        if self.kind in ("parabolic", "circular"):
            if not 0.0 <= self.depth <= 1.0 - THINNEST:
                raise ParameterError(f"parameter undercut_depth = {self.depth!r} is out of range; allowed: 0 to "
                                     f"{1.0 - THINNEST:g} (fraction of the thickness)")
            if not 0.0 < self.width <= 1.0:
                raise ParameterError(f"parameter undercut_width = {self.width!r} is out of range; allowed: above 0 "
                                     "to 1 (fraction of the length)")
        if self.kind == "samples":
            if len(self.samples) < 2:
                raise ParameterError(f"parameter profile_samples has {len(self.samples)} values; allowed: with "
                                     f"profile = samples, at least 2 relative thicknesses, each {THINNEST:g} to 1")
            for k, value in enumerate(self.samples):
                if not THINNEST <= value <= 1.0:
                    raise ParameterError(f"parameter profile_samples: value {k + 1} = {value!r} is out of range; "
                                         f"allowed: {THINNEST:g} to 1 (fraction of the thickness)")

    def relative_thickness(self, x: np.ndarray, *, length_m: float, thickness_m: float) -> np.ndarray:
        """``h(x) / h0`` at positions ``x`` (fractions of the length, 0 to 1)."""
        x = np.asarray(x, dtype=np.float64)
        if self.kind == "uniform" or (self.kind != "samples" and self.depth == 0.0):
            return np.ones_like(x)
        if self.kind == "samples":
            return np.interp(x, np.linspace(0.0, 1.0, len(self.samples)), np.asarray(self.samples, dtype=np.float64))
        u = (x - 0.5) / (0.5 * self.width)  # -1 .. 1 across the cut
        inside = np.abs(u) < 1.0
        if self.kind == "parabolic":
            cut = self.depth * (1.0 - u * u)
        else:  # a circular arc through the cut's edges and its deepest point (metres, then relative)
            # depth of the arc below its chord at offset o from the middle: s - o^2 / (R + sqrt(R^2 - o^2)),
            # with R = (c^2 + s^2) / (2 s); written with 1/R so a shallow cut (R huge) stays exact
            sagitta = self.depth * thickness_m
            half_chord = 0.5 * self.width * length_m
            curvature = 2.0 * sagitta / (half_chord ** 2 + sagitta ** 2)  # 1 / R
            offset = np.minimum(np.abs(x - 0.5) * length_m, half_chord)
            rise = curvature * offset ** 2 / (1.0 + np.sqrt(np.maximum(1.0 - (curvature * offset) ** 2, 0.0)))
            cut = (sagitta - rise) / thickness_m
        return np.where(inside, 1.0 - np.clip(cut, 0.0, None), 1.0)

    def describe(self) -> str:
        if self.kind == "uniform":
            return "uniform"
        if self.kind == "samples":
            return f"sampled at {len(self.samples)} points"
        return f"{self.kind} undercut {self.depth:.3f} deep over {self.width:g} of the length"
