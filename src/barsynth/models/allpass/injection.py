"""The all-pass waveguide's strike and pick-up filters, and what the built loop does between
them: its resonances, their decays and gains.

* Strike: the force enters both directions through ``1 / (4 rho A v(w))`` (the travelling
  waves' share of a point force on an infinite bar; K. F. Graff, *Wave Motion in Elastic
  Solids*, 1975, ch. 3), real poles every two octaves with zeros placed by least squares
  (within 0.15 dB over the band), times a fourth-order Butterworth high-pass at half the first
  mode.
* Pick-up: the sum of the two travelling waves, through the same high-pass. The two
  high-passes keep DC out (the loop has a pole there when its signs multiply to +1) and any of
  the loop's resonances below the first mode far down.
* The loop: its resonances lie where the round trip's lag is a multiple of ``2 pi``; each
  one's T60 follows from the loop's loss and group delay there, its gain from the two rails
  (strike point to pick-up point, both ways round).

Filters are cascades of biquad rows ``b0 b1 b2 a1 a2`` (``a0 = 1``); frequencies ``w`` in
rad/sample.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ...numerics import levenberg_marquardt, numeric_jacobian
from .plan import BAND_BOTTOM
from .targets import Bar

if TYPE_CHECKING:
    from .design import Filter

HIGH_PASS_FRACTION = 0.5  # strike and pick-up high-passes: this fraction of the first mode
PINK_SPACING = 4.0  # frequency ratio between the -3 dB/octave filter's poles


def response(sections: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Complex frequency response of a cascade of biquad rows ``b0 b1 b2 a1 a2`` at ``w``."""
    z1 = np.exp(-1j * np.asarray(w, dtype=float))
    h = np.ones(z1.shape, dtype=complex)
    for b0, b1, b2, a1, a2 in np.asarray(sections, dtype=float).reshape(-1, 5):
        h *= (b0 + z1 * (b1 + z1 * b2)) / (1.0 + z1 * (a1 + z1 * a2))
    return h


def high_pass(w_c: float) -> np.ndarray:
    """Fourth-order Butterworth high-pass at ``w_c`` (rad/sample), bilinear with prewarping."""
    rows = []
    cw, sw = math.cos(w_c), math.sin(w_c)
    for q in (0.5411961001461969, 1.3065629648763766):
        alpha = sw / (2.0 * q)
        a0 = 1.0 + alpha
        b0 = 0.5 * (1.0 + cw) / a0
        rows.append([b0, -2.0 * b0, b0, -2.0 * cw / a0, (1.0 - alpha) / a0])
    return np.array(rows)


def pink(w_from: float, w_to: float) -> np.ndarray:
    """Magnitude ``w^-1/2`` (-3 dB per octave) from ``w_from`` to ``w_to`` (rad/sample):
    real poles every ``PINK_SPACING`` in frequency (matched z: radius ``exp(-w_pole)``),
    a real zero after each, placed by least squares on the log magnitude (the bilinear
    or matched-z zeros alone bend away near Nyquist); unit gain at ``w_from``."""
    poles = [w_from / PINK_SPACING]
    while poles[-1] < w_to:
        poles.append(poles[-1] * PINK_SPACING)
    p = np.exp(-np.array(poles))
    w = np.geomspace(w_from, w_to, 8 * len(poles) + 8)
    z1 = np.exp(-1j * w)
    want = -0.5 * np.log(w)

    def log_gain(zeros):
        return (np.log(np.abs(1.0 - np.outer(z1, zeros))).sum(axis=1)
                - np.log(np.abs(1.0 - np.outer(z1, p))).sum(axis=1))

    def residual(x):
        err = log_gain(np.tanh(x)) - want
        return err - err.mean()

    x0 = np.arctanh(np.exp(-np.array(poles) * math.sqrt(PINK_SPACING)))
    zeros = np.tanh(levenberg_marquardt(numeric_jacobian(residual), x0, iterations=40))
    rows = np.column_stack([np.ones(p.size), -zeros, np.zeros(p.size), -p, np.zeros(p.size)])
    rows[0, :3] /= abs(complex(response(rows, np.array([w_from]))[0]))
    return rows


def injection_filter(bar: Bar, w_1: float, w_top: float, w_modes: np.ndarray) -> np.ndarray:
    """Force (N per sample) to travelling-wave velocity (m/s): ``1 / (4 rho A v(w))``
    from just below the first mode to ``w_top``, scaled to match at the fitted modes (least
    squares in dB), then high-passed."""
    rows = pink(BAND_BOTTOM * w_1, w_top)
    wanted = bar.length_m / (4.0 * bar.mass_kg * np.sqrt(bar.bending * w_modes * bar.sample_rate))
    scale = math.exp(float(np.mean(np.log(wanted / np.abs(response(rows, w_modes))))))
    rows[0, :3] *= scale
    return np.vstack([rows, high_pass(HIGH_PASS_FRACTION * w_1)])


def _filter_lag(f: Filter, w: np.ndarray) -> np.ndarray:
    """Lag (rad) of one loop filter, continuous in ``w`` (sign, delay, sections, loss)."""
    w = np.asarray(w, dtype=float)
    lag = (math.pi if f.sign < 0 else 0.0) + f.delay * w
    e1, e2 = np.exp(-1j * w), np.exp(-2j * w)
    for _, _, b2, a1, a2 in f.sections[:len(f.sections) - (0 if f.loss is None else len(f.loss.rows()))]:
        if b2 == 1.0:  # second-order all-pass
            lag = lag + 2.0 * w + 2.0 * np.angle(1.0 + a1 * e1 + a2 * e2)
        else:  # first-order all-pass
            lag = lag + w + 2.0 * np.angle(1.0 + a1 * e1)
    if f.loss is not None:
        lag = lag + f.loss.lag(w)
    return lag


def loop_lag(filters, w: np.ndarray) -> np.ndarray:
    return sum(_filter_lag(f, w) for f in filters)


def _loop_loss(filters, w: np.ndarray) -> np.ndarray:
    """``-ln |T(w)|`` of the round trip (nepers): the shelves'."""
    return sum(f.loss.nepers(w) for f in filters if f.loss is not None)


def group_delay(filters, w: np.ndarray) -> np.ndarray:
    """The loop's group delay (samples) at ``w``."""
    h = 1e-6 * w
    return (loop_lag(filters, w + h) - loop_lag(filters, w - h)) / (2.0 * h)


def _crossings(filters, w_from: float) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (rad/sample) above ``w_from`` where the loop's lag is a multiple of
    2 pi, and those multiples."""
    w = np.linspace(math.sqrt(w_from), math.sqrt(math.pi), 20000) ** 2
    lag = loop_lag(filters, w)
    turns = np.arange(math.floor(lag[0] / (2 * math.pi)) + 1, math.floor(lag[-1] / (2 * math.pi)) + 1)
    found = np.interp(2 * math.pi * turns, lag, w)
    for _ in range(3):  # secant refinement on the exact lag
        h = 1e-7 * np.maximum(found, 1e-6)
        lag_at = loop_lag(filters, found)
        slope = (loop_lag(filters, found + h) - lag_at) / h
        found = np.clip(found - (lag_at - 2 * math.pi * turns) / slope, w_from, math.pi)
    return found, turns


def _rails(design_filters, strike_at_a: bool, pickup_at_a: bool, w: np.ndarray):
    """Pick-up sum of the waves per unit wave injected at the strike point (complex, at
    ``w``), and the round trip ``T``."""
    s = [f.sign * np.exp(-1j * f.delay * w) * response(f.sections, w) for f in design_filters]
    ia, ib = (1.0, 0.0) if strike_at_a else (0.0, 1.0)
    pa, pb = (1.0, 0.0) if pickup_at_a else (0.0, 1.0)
    loop = s[0] * s[1] * s[2] * s[3]
    x3 = (s[2] * s[1] * s[0] * ia + s[2] * s[1] * ia + s[2] * ib + ib) / (1.0 - loop)
    x0 = s[3] * x3 + ia
    x1 = s[0] * x0 + ia
    x2 = s[1] * x1 + ib
    y0, y1, y2, y3 = s[0] * x0, s[1] * x1, s[2] * x2, s[3] * x3
    return pa * (y0 + y3 + ia) + pb * (y1 + y2 + ib), loop


def resonances(design_filters, injection, pickup, strike_at_a, pickup_at_a, w_from, bar):
    """Each resonance of the loop above ``w_from``: (w, turns, T60 in s, gain), where the
    gain is the velocity amplitude per unit impulse times the bar's mass (for a real bar:
    the product of the two mode shapes)."""
    w, turns = _crossings(design_filters, w_from)
    h = 1e-6 * w
    group = (loop_lag(design_filters, w + h) - loop_lag(design_filters, w - h)) / (2 * h)
    loss = _loop_loss(design_filters, w)
    t60 = math.log(1000.0) * group / (np.maximum(loss, 1e-300) * bar.sample_rate)
    path, loop = _rails(design_filters, strike_at_a, pickup_at_a, w)
    numerator = path * (1.0 - loop)
    size = np.abs(numerator * response(injection, w) * response(pickup, w))
    gain = 2.0 * bar.mass_kg * bar.sample_rate * size / group * np.sign(numerator.real)
    return w, turns, t60, gain
