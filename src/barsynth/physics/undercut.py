"""Tuning a bar by undercutting: the depth that gives a target f2/f1 (spec 1.5, 1.6).

Source: T. D. Rossing, Science of Percussion Instruments (2000), ch. 5 (marimba and
vibraphone bars tuned to 1 : 4, xylophone bars to 1 : 3); the modes of the undercut bar
come from the grid operator of the chosen theory (:func:`barsynth.physics.theory.bar_modes_hz`:
Euler–Bernoulli's :func:`~barsynth.physics.grid.grid_modes` by default, or Timoshenko's
two-field grid, which a thick wooden bar needs to really ring 1 : 4: a depth tuned in
Euler–Bernoulli leaves a 40 x 5 x 2 cm rosewood bar near 1 : 3.85, spec 8.1). Thinning the
middle of a free-free bar lowers its first mode much more than its second, so f2/f1
rises from 2.756 (uniform) as the cut deepens; the tuner finds the depth by bracketed
root finding on that ratio, and reports f3/f1 there (a real marimba's third partial
usually falls short of 10).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..checks import check_whole
from ..errors import ParameterError
from .materials import PLAIN_SHEAR_COEFFICIENT
from .profiles import THINNEST, Profile


@dataclass(frozen=True)
class UndercutTuning:
    """The result: the undercut (a :class:`Profile`), its modes (Hz) and their ratios to the first."""

    profile: Profile
    frequencies_hz: np.ndarray
    target_ratio: float
    theory: str = "euler-bernoulli"
    shear_modulus_pa: float | None = None
    shear_coefficient: float | None = None

    @property
    def ratios(self) -> np.ndarray:
        return self.frequencies_hz / self.frequencies_hz[0]

    def to_json(self) -> dict:
        out = {"kind": self.profile.kind, "undercut_depth": self.profile.depth,
               "undercut_width": self.profile.width, "target_ratio": self.target_ratio,
               "frequencies_hz": self.frequencies_hz.tolist(), "ratios": self.ratios.tolist(),
               "f2_over_f1": float(self.ratios[1]), "f3_over_f1": float(self.ratios[2]) if self.ratios.size > 2 else None,
               "theory": self.theory}
        if self.theory == "timoshenko":
            out.update(shear_modulus_pa=self.shear_modulus_pa, shear_coefficient=self.shear_coefficient)
        return out


def tune_undercut(*, youngs_modulus_pa: float, density_kg_m3: float, length_m: float, thickness_m: float,
                  width_m: float = 0.04, target_ratio: float = 4.0, kind: str = "parabolic",
                  undercut_width: float = 0.6, count: int = 4, points: int = 120, theory: str = "euler-bernoulli",
                  shear_modulus_pa: float | None = None, shear_coefficient: float | None = None) -> UndercutTuning:
    """The undercut depth (fraction of the thickness) at which a free-free bar's f2/f1 is ``target_ratio``.

    ``theory`` is ``"euler-bernoulli"`` (default) or ``"timoshenko"``, which needs
    ``shear_modulus_pa`` (``G``, Pa) and takes ``shear_coefficient`` (``kappa``, default 5/6;
    :func:`~barsynth.physics.theory.shear_constants` gives Cowper's from a Poisson ratio).
    The modes come from the grid of ``points`` nodes, Richardson extrapolated.

    Examples
    --------
    >>> tuned = tune_undercut(youngs_modulus_pa=12e9, density_kg_m3=850.0, length_m=0.38, thickness_m=0.02)
    >>> round(float(tuned.ratios[1]), 4), 0.0 < tuned.profile.depth < 1.0
    (4.0, True)
    """
    from scipy.optimize import brentq

    from .theory import bar_modes_hz, check_theory

    check_theory(theory)
    if theory == "euler-bernoulli":
        shear_modulus_pa = shear_coefficient = None
    elif shear_coefficient is None:  # (the kappa bar_modes_hz takes, recorded in the result; a missing G it refuses)
        shear_coefficient = PLAIN_SHEAR_COEFFICIENT
    count = check_whole("count", count, "modes", minimum=2, maximum=24)
    if not (isinstance(target_ratio, (int, float)) and math.isfinite(target_ratio)):
        raise ParameterError(f"parameter target_ratio = {target_ratio!r} is not a number; allowed: above 2.756")
    bar = dict(youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3, length_m=length_m,
               thickness_m=thickness_m, width_m=width_m, bc="free-free", points=points, theory=theory,
               shear_modulus_pa=shear_modulus_pa, shear_coefficient=shear_coefficient)

    def modes(depth: float) -> np.ndarray:
        return bar_modes_hz(count=max(count, 3), profile=Profile(kind, depth=depth, width=undercut_width), **bar)

    def miss(depth: float) -> float:
        f = modes(depth)
        return f[1] / f[0] - target_ratio

    deepest = 1.0 - THINNEST
    low, high = miss(0.0) + target_ratio, miss(deepest) + target_ratio
    if not low < target_ratio < high:
        raise ParameterError(f"parameter target_ratio = {target_ratio:g} cannot be reached by a {kind} undercut "
                             f"{undercut_width:g} of the length wide; allowed: {low:.4f} to {high:.4f} "
                             "(f2/f1, dimensionless)")
    depth = brentq(miss, 0.0, deepest, xtol=1e-10, rtol=1e-12)
    return UndercutTuning(Profile(kind, depth=depth, width=undercut_width), modes(depth)[:count], float(target_ratio),
                          theory, shear_modulus_pa, shear_coefficient)
