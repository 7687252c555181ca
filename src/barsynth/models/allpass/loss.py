"""The all-pass waveguide's losses: a gain and first-order low shelves per filter.

Each filter holds its share (its length) of the round trip's loss, a gain and up to three
first-order low shelves (minimum phase, gain below one at every frequency) fitted in relative
terms so that mode n loses ``w_n tau_n / (2 q)`` nepers per round trip of group delay
``tau_n``: ``T60_n = q ln(1000) / (pi f_n)``. The shelves' phase is part of the fit (the
design redesigns them for the group delays the fit gave). Frequencies ``w`` in rad/sample.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ...numerics import levenberg_marquardt, numeric_jacobian_rows

MAX_SHELF_NEPERS = 10.0  # deepest loss of one shelf (at Nyquist) or of the gain
SHELF_POLES = (-0.995, -0.98, -0.95, -0.9, -0.8, -0.6, -0.3, 0.0, 0.4)  # starting points of the loss fit


def _shelf_lag(b: float, c: float, w: np.ndarray) -> np.ndarray:
    """Lag (rad) of ``(1 + b z^-1) / (1 + c z^-1)``."""
    s, co = np.sin(w), np.cos(w)
    return np.arctan2(b * s, 1.0 + b * co) - np.arctan2(c * s, 1.0 + c * co)


def _shelf_loss(b: float, c: float, w: np.ndarray) -> np.ndarray:
    """``-ln |(1 + b z^-1) / (1 + c z^-1)|`` (nepers)."""
    co = np.cos(w)
    return 0.5 * (np.log1p(c * c + 2.0 * c * co) - np.log1p(b * b + 2.0 * b * co))


@dataclass(frozen=True)
class Loss:
    """A gain below one times first-order low shelves, each ``(1 + b z^-1) / (1 + c z^-1)``
    scaled to unit gain at DC: minimum phase, and below one at every frequency."""

    gain: float
    shelves: tuple[tuple[float, float], ...] = ()

    def nepers(self, w) -> np.ndarray:
        """``-ln |G(w)|``."""
        w = np.asarray(w, dtype=float)
        out = np.full(w.shape, -math.log(self.gain))
        for b, c in self.shelves:
            out = out + _shelf_loss(b, c, w) - math.log((1.0 + c) / (1.0 + b))
        return out

    def lag(self, w) -> np.ndarray:
        w = np.asarray(w, dtype=float)
        out = np.zeros(w.shape)
        for b, c in self.shelves:
            out = out + _shelf_lag(b, c, w)
        return out

    def rows(self) -> np.ndarray:
        """Biquad rows ``b0 b1 b2 a1 a2``: two shelves a row (the gain in the first)."""
        out = []
        for start in range(0, max(len(self.shelves), 1), 2):
            num, den, k = np.array([1.0]), np.array([1.0]), self.gain if start == 0 else 1.0
            for b, c in self.shelves[start:start + 2]:
                num, den, k = np.convolve(num, [1.0, b]), np.convolve(den, [1.0, c]), k * (1.0 + c) / (1.0 + b)
            num, den = np.pad(num, (0, 3 - num.size)), np.pad(den, (0, 3 - den.size))
            out.append([k * num[0], k * num[1], k * num[2], den[1], den[2]])
        return np.array(out)


def _shelf(c: float, nyquist_nepers: float) -> tuple[float, float]:
    """``(b, c)`` of the unit-DC shelf with pole ``-c`` that loses ``nyquist_nepers`` at Nyquist."""
    kappa = math.exp(-nyquist_nepers) * (1.0 - c) / (1.0 + c)  # (1 - b) / (1 + b)
    return (1.0 - kappa) / (1.0 + kappa), c


def design_loss(w_modes: np.ndarray, loss_modes: np.ndarray) -> Loss:
    """The :class:`Loss` whose nepers best match ``loss_modes`` at ``w_modes`` in relative
    terms: a gain and up to three shelves (a gain alone for one mode, one shelf for two,
    two for three to six, three for more).
    Start: for small losses each shelf adds (nearly) a fixed shape times its depth, so
    every pair of shelf poles from ``SHELF_POLES`` gives a linear least-squares problem;
    the best is refined by Levenberg-Marquardt on the exact losses."""
    count = 0 if w_modes.size == 1 else 1 if w_modes.size == 2 else 2 if w_modes.size < 7 else 3
    if count == 0:
        return Loss(math.exp(-float(loss_modes[0])))

    def make(x):  # x = [sqrt(DC nepers), (sqrt(Nyquist nepers), atanh(c)) per shelf]
        shelves = tuple(_shelf(0.999 * math.tanh(x[2 + 2 * k]), min(x[1 + 2 * k] ** 2, MAX_SHELF_NEPERS))
                        for k in range(count))
        return Loss(math.exp(-min(x[0] ** 2, MAX_SHELF_NEPERS)), shelves)

    cos_w = np.cos(w_modes)

    def residuals(xs):  # each row's make(x).nepers(w_modes) / loss_modes - 1, all rows at once
        return _nepers_rows(xs.tolist(), count, cos_w) / loss_modes - 1.0

    shapes = {c: Loss(1.0, (_shelf(c, 1e-6),)).nepers(w_modes) / 1e-6 for c in SHELF_POLES}
    best = None
    for poles in itertools.combinations(SHELF_POLES, count):
        basis = np.column_stack([np.ones(w_modes.size)] + [shapes[c] for c in poles]) / loss_modes[:, None]
        coef = np.maximum(np.linalg.lstsq(basis, np.ones(w_modes.size), rcond=None)[0], 1e-12)
        cost = float(np.sum((basis @ coef - 1.0) ** 2))
        if best is None or cost < best[0]:
            best = (cost, coef, poles)
    _, coef, poles = best
    x0 = [math.sqrt(coef[0])]
    for depth, c in zip(coef[1:], poles):
        x0 += [math.sqrt(depth), math.atanh(c / 0.999)]
    return make(levenberg_marquardt(numeric_jacobian_rows(residuals), np.array(x0), iterations=60))


def _nepers_rows(points: list[list[float]], count: int, cos_w: np.ndarray) -> np.ndarray:
    """``make(x).nepers(w)`` of :func:`design_loss` for every point ``x`` (one row each;
    ``cos_w = cos(w)``), with the very arithmetic of ``make`` and :meth:`Loss.nepers` (the
    scalars in plain floats, each array operation on all rows at once): the loss fit's
    Jacobian asks for a point and its steps together."""
    out = np.array([-math.log(math.exp(-min(x[0] ** 2, MAX_SHELF_NEPERS))) for x in points])[:, None]
    for k in range(count):
        shelves = [_shelf(0.999 * math.tanh(x[2 + 2 * k]), min(x[1 + 2 * k] ** 2, MAX_SHELF_NEPERS)) for x in points]
        b = np.array([shelf[0] for shelf in shelves])[:, None]
        c = np.array([shelf[1] for shelf in shelves])[:, None]
        dc = np.array([math.log((1.0 + c_k) / (1.0 + b_k)) for b_k, c_k in shelves])[:, None]
        out = out + 0.5 * (np.log1p(c * c + 2.0 * c * cos_w) - np.log1p(b * b + 2.0 * b * cos_w)) - dc
    return out


def filter_losses(w_modes: np.ndarray, round_trip: np.ndarray, a: float, b: float) -> dict:
    """Each distinct filter's :class:`Loss`, its share of the round trip's being its length."""
    shares = {"end0": a, "middle": 0.5 * (b - a), "endL": 1.0 - b}
    losses = {name: design_loss(w_modes, share * round_trip) if share > 1e-9 else None
              for name, share in shares.items()}
    losses["ends"] = losses["end0"]  # the same share: the same fit
    return losses
