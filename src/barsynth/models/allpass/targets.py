"""The bar's targets: the phase each of the all-pass waveguide's filters must give.

A bending wave of angular frequency ``w`` travels with phase velocity ``v = sqrt(a w)``,
``a = sqrt(E I / (rho A))``, so over the bar's length it lags ``lambda(w) = L sqrt(w / a)``
radians; a mode of the uniform bar lies where ``lambda = lambda_n``
(:func:`barsynth.physics.lambdas`). The strike point and the pick-up point split the bar at
``x_a <= x_b`` (fractions of the length) into four filters around one loop::

    end0:   x_a -> 0 -> x_a    lag 2 x_a lambda + psi_0 + delta_0
    right:  x_a -> x_b         lag (x_b - x_a) lambda
    endL:   x_b -> L -> x_b    lag 2 (1 - x_b) lambda + psi_L + delta_L
    left:   x_b -> x_a         the same filter as ``right``

``psi`` is the phase lag of the travelling wave's reflection at an end: ``pi / 2`` (a factor
``-j``) at a free or a clamped end, ``pi`` at a pinned one (K. F. Graff, *Wave Motion in
Elastic Solids*, 1975, ch. 3). ``delta`` folds in what the travelling waves miss, the near
field: it is the smooth function that is zero far from the ends' coupling and makes the round
trip ``2 lambda + psi_0 + psi_L + delta`` a multiple of ``2 pi`` exactly at every
``lambda_n``, so the modes fall where ``cos(lambda) cosh(lambda) = 1`` (and the other
characteristic equations) put them. It is large only for the first mode of a cantilever
(``lambda_1 = 1.875`` instead of ``pi / 2``). Frequencies ``w`` are in rad/sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

HALF_PI = 0.5 * math.pi
END_LAG = {"free": HALF_PI, "clamped": HALF_PI, "pinned": math.pi}
"""Phase lag of a travelling bending wave's reflection at each kind of end (rad)."""


@dataclass(frozen=True)
class Bar:
    """The uniform bar as the design sees it: bending constant, length, mass, ends, sample rate."""

    bending: float  # a = sqrt(E I / (rho A)), m^2/s
    length_m: float
    mass_kg: float
    bc: str
    sample_rate: float

    def lam(self, w):
        """Phase lag over the length of a travelling wave at ``w`` (rad/sample)."""
        return self.length_m * np.sqrt(np.asarray(w, dtype=float) * self.sample_rate / self.bending)

    def w_of_lam(self, lam):
        return (np.asarray(lam, dtype=float) / self.length_m) ** 2 * self.bending / self.sample_rate

    @property
    def ends(self) -> tuple[str, str]:
        left, right = self.bc.split("-")
        return left, right


def _smooth_steps(x: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Through ``(xs, ys)`` with zero slope at every point (raised-cosine steps), flat outside."""
    x = np.asarray(x, dtype=float)
    if xs.size == 1:
        return np.full(x.shape, ys[0])
    i = np.clip(np.searchsorted(xs, x) - 1, 0, xs.size - 2)
    s = np.clip((x - xs[i]) / (xs[i + 1] - xs[i]), 0.0, 1.0)
    return ys[i] + (ys[i + 1] - ys[i]) * 0.5 * (1.0 - np.cos(np.pi * s))


class Targets:
    """The physical lag of each of the loop's filters (end0, middle, endL) at any ``w``."""

    def __init__(self, bar: Bar, a: float, b: float, lam_top: float):
        from ...physics import lambdas

        self.bar, self.a, self.b = bar, a, b
        left, right = bar.ends
        self.psi = (END_LAG[left], END_LAG[right])
        count = max(2, int(lam_top / math.pi) + 3)
        self.lam_n = np.asarray(lambdas(bar.bc, count), dtype=float)
        rt = 2.0 * self.lam_n + self.psi[0] + self.psi[1]
        self.loop_count = np.round(rt / (2.0 * math.pi))
        self.delta_n = 2.0 * math.pi * self.loop_count - rt
        near = [0.0 if end == "pinned" else 1.0 for end in (left, right)]
        total = sum(near) or 1.0
        self.share = (near[0] / total, near[1] / total)

    def delta(self, w):
        return _smooth_steps(self.bar.lam(w), self.lam_n, self.delta_n)

    def lags(self, w) -> np.ndarray:
        """Shape (3, n): end0, middle, endL."""
        lam, d = self.bar.lam(w), self.delta(w)
        return np.stack([2.0 * self.a * lam + self.psi[0] + self.share[0] * d,
                         (self.b - self.a) * lam,
                         2.0 * (1.0 - self.b) * lam + self.psi[1] + self.share[1] * d])
