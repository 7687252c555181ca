"""Decay slopes of an envelope in dB: the range fitted, one line or two (a knee), the quality.

The envelope's power, less the band's noise power and smoothed over about ``1/f1``, is
taken in dB. The fit starts where the envelope is clean (after the attack and the
band filter's settling; at its maximum if it still rises by more than 3 dB after that)
and ends where it falls (for good: for at least three smoothing widths) to
:data:`FLOOR_MARGIN_DB` above the noise floor, or :data:`MAX_RANGE_DB` below its start -- the
range of a noise-floor-aware decay fit (Lundeby et al. 1995), the noise power being
known from the recording's tail (:mod:`.noise`) and also subtracted (Chu's
noise compensation), so the floor does not bend the line.

A straight line is fitted by least squares; then a continuous two-segment line (a knee
at the best of a grid of times). The two-stage fit is kept when it fits clearly better
(at most half the RMS deviation, slopes that differ by more than a third, and a knee
at least 10 dB above the range's end, so that the noise floor is no second stage): common in
real bars (two polarisations, a doublet with different decays) and in looped samples.

References: A. Lundeby, T. E. Vigran, H. Bietz and M. Vorlaender, "Uncertainties of
measurements in room acoustics", Acustica 81 (1995); W. T. Chu, "Comparison of
reverberation measurements using Schroeder's impulse method and decay-curve averaging
method", JASA 63 (1978).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["FLOOR_MARGIN_DB", "MIN_POINTS", "Slopes", "fit_slopes", "smoothed_db", "with_slope"]

FLOOR_MARGIN_DB = 10.0  # the fit ends this far above the noise floor
MIN_POINTS = 8  # the fewest envelope samples a line is fitted to
MAX_RANGE_DB = 100.0  # nor does it go further than this below its start
RISE_DB = 3.0  # a later maximum this much above the clean start starts the fit there
_KNEE_GAIN = 0.5  # a knee must at least halve the RMS deviation ...
_KNEE_SLOPES = 1.0 / 3.0  # ... with slopes that differ by more than a third of the steeper
_KNEE_MIN_RMS_DB = 0.25  # ... of a line that misses by more than this
_KNEE_ABOVE_END_DB = 10.0  # ... at least this far above where the range ends (not the floor)
_KNEE_GRID = 64


@dataclass(frozen=True)
class Slopes:
    """A decay fit in dB (times in s from the sound's first sample).

    Attributes
    ----------
    t_start, t_end
        The range fitted, s.
    slope_db_s
        Slope of the line, or of the first stage when there is a knee, dB/s.
    intercept_db
        The line (first stage) at ``t = 0``, dB of envelope power.
    rms_db
        RMS deviation of the envelope from the fit over the range, dB.
    r2
        Coefficient of determination of the fit (1 for a perfect one).
    points
        Envelope samples in the range.
    knee_s
        Time of the knee, s (None for one line).
    second_slope_db_s
        Slope after the knee, dB/s (None for one line).
    line_rms_db
        RMS deviation of the single line (the same as ``rms_db`` without a knee), dB.
    """

    t_start: float
    t_end: float
    slope_db_s: float
    intercept_db: float
    rms_db: float
    r2: float
    points: int
    knee_s: float | None = None
    second_slope_db_s: float | None = None
    line_rms_db: float = 0.0

    def at(self, t: float) -> float:
        """The fitted curve (both stages) at time ``t``, dB."""
        y = self.intercept_db + self.slope_db_s * t
        if self.knee_s is not None and t > self.knee_s:
            y += (self.second_slope_db_s - self.slope_db_s) * (t - self.knee_s)
        return y


def smoothed_db(power: np.ndarray, noise_power: float, width: int) -> np.ndarray:
    """Envelope power less the noise power, smoothed over ``width`` samples, in dB.

    Where the compensated power is not above a hundredth of the noise power, the result
    is that hundredth (far below any range end).
    """
    from scipy.ndimage import uniform_filter1d

    smooth = uniform_filter1d(power, max(1, width), mode="nearest") if width > 1 else power
    floor = max(0.01 * noise_power, 1e-300)
    return 10.0 * np.log10(np.maximum(smooth - noise_power, floor))


def _line(t: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least-squares line y ~ c + b t: (c, b, sum of squared residuals)."""
    tm = float(t.mean())
    tc = t - tm
    stt = float(tc @ tc)
    ym = float(y.mean())
    b = float(tc @ (y - ym)) / stt if stt > 0 else 0.0
    r = y - ym - b * tc
    return ym - b * tm, b, float(r @ r)


def _hinge(t: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float, float] | None:
    """The best continuous two-segment line over a grid of knees: (knee, c, b1, b2, sse).

    ``y ~ c + b1 t + (b2 - b1) max(t - knee, 0)``; each segment keeps at least a fiftieth of
    the points (and four).
    """
    n = t.size
    margin = max(4, n // 50)
    if n - 2 * margin < 1:
        return None
    knees = np.unique(np.linspace(margin, n - margin - 1, min(_KNEE_GRID, n - 2 * margin)).astype(int))
    tk = t[knees]
    # design columns per knee: 1, t, max(t - tk, 0); normal equations batched
    ramp = np.maximum(t[None, :] - tk[:, None], 0.0)  # (K, n)
    one = np.ones(n)
    s11 = float(n)
    s1t = float(t.sum())
    stt = float(t @ t)
    s1r = ramp.sum(axis=1)
    str_ = ramp @ t
    srr = np.einsum("kn,kn->k", ramp, ramp)
    gram = np.empty((knees.size, 3, 3))
    gram[:, 0, 0] = s11
    gram[:, 0, 1] = gram[:, 1, 0] = s1t
    gram[:, 1, 1] = stt
    gram[:, 0, 2] = gram[:, 2, 0] = s1r
    gram[:, 1, 2] = gram[:, 2, 1] = str_
    gram[:, 2, 2] = srr
    rhs = np.stack([np.full(knees.size, float(one @ y)), np.full(knees.size, float(t @ y)), ramp @ y], axis=1)
    ok = np.abs(np.linalg.det(gram)) > 0
    if not ok.any():
        return None
    coef = np.zeros((knees.size, 3))
    coef[ok] = np.linalg.solve(gram[ok], rhs[ok][..., None])[..., 0]
    fit = coef[:, 0:1] + coef[:, 1:2] * t[None, :] + coef[:, 2:3] * ramp
    sse = np.sum((y[None, :] - fit) ** 2, axis=1)
    sse[~ok] = np.inf
    best = int(np.argmin(sse))
    c, b1, d = coef[best]
    return float(tk[best]), float(c), float(b1), float(b1 + d), float(sse[best])


def with_slope(slopes: Slopes, t: np.ndarray, db: np.ndarray, slope_db_s: float) -> Slopes:
    """A one-line fit over the same range with a given slope (dB/s; e.g. a maximum-likelihood
    decay from the complex envelope): the intercept by least squares, the quality anew.

    ``t`` and ``db`` are the whole envelope's times (s) and :func:`smoothed_db`.
    """
    sel = (t >= slopes.t_start - 1e-12) & (t <= slopes.t_end + 1e-12)
    tt, yy = t[sel], db[sel]
    c = float(np.mean(yy - slope_db_s * tt))
    r = yy - c - slope_db_s * tt
    sse = float(r @ r)
    sst = float(((yy - yy.mean()) ** 2).sum())
    rms = math.sqrt(sse / max(tt.size, 1))
    return Slopes(
        t_start=slopes.t_start, t_end=slopes.t_end, slope_db_s=slope_db_s, intercept_db=c, rms_db=rms,
        r2=1.0 - sse / sst if sst > 0 else 1.0, points=int(tt.size), line_rms_db=rms,
    )


def fit_slopes(
    t: np.ndarray,
    db: np.ndarray,
    *,
    noise_power: float,
    t_clean: float,
    t_last: float,
    width: int,
) -> Slopes | None:
    """Fit the decay of an envelope (``db``: :func:`smoothed_db` at times ``t``, s).

    Parameters
    ----------
    noise_power
        The band's noise power in envelope power units (0 for none).
    t_clean, t_last
        The earliest and latest times the envelope is usable (after the attack and the
        filter's settling; before the filter feels the end of the file), s.
    width
        The smoothing of ``db``, envelope samples.

    Returns None when fewer than :data:`MIN_POINTS` samples are usable.
    """
    usable = np.flatnonzero((t >= t_clean) & (t <= t_last))
    if usable.size < MIN_POINTS:
        return None
    a, last = int(usable[0]), int(usable[-1])
    peak = a + int(np.argmax(db[a : last + 1]))
    if db[peak] > db[a] + RISE_DB:
        a = peak
    threshold = db[a] - MAX_RANGE_DB
    if noise_power > 0:
        threshold = max(threshold, 10.0 * math.log10(noise_power) + FLOOR_MARGIN_DB)
    below = db[a : last + 1] < threshold
    # the first time it falls below the threshold and stays there for a while (a
    # beating pair's short dips do not end the range)
    stay = max(3 * width, 3)
    m = below.size
    counts = np.concatenate(([0], np.cumsum(below)))
    i = np.arange(m)
    reach = np.minimum(i + stay, m)
    ends = np.flatnonzero(below & (counts[reach] - counts[i] == reach - i))
    b = a + int(ends[0]) - 1 if ends.size else last
    if b - a + 1 < MIN_POINTS:
        return None
    tt, yy = t[a : b + 1], db[a : b + 1]
    c, slope, sse = _line(tt, yy)
    n = tt.size
    sst = float(((yy - yy.mean()) ** 2).sum())
    line_rms = math.sqrt(sse / n)
    result = Slopes(
        t_start=float(tt[0]), t_end=float(tt[-1]), slope_db_s=slope, intercept_db=c,
        rms_db=line_rms, r2=1.0 - sse / sst if sst > 0 else 1.0, points=n, line_rms_db=line_rms,
    )
    if line_rms <= _KNEE_MIN_RMS_DB:
        return result
    hinge = _hinge(tt, yy)
    if hinge is None:
        return result
    knee, c2, b1, b2, sse2 = hinge
    rms2 = math.sqrt(sse2 / n)
    steeper = max(abs(b1), abs(b2))
    knee_db = c2 + b1 * knee
    if (
        rms2 <= _KNEE_GAIN * line_rms
        and abs(b1 - b2) > _KNEE_SLOPES * steeper
        and knee_db >= threshold + _KNEE_ABOVE_END_DB
    ):
        return Slopes(
            t_start=result.t_start, t_end=result.t_end, slope_db_s=b1, intercept_db=c2,
            rms_db=rms2, r2=1.0 - sse2 / sst if sst > 0 else 1.0, points=n, knee_s=knee,
            second_slope_db_s=b2, line_rms_db=line_rms,
        )
    return result
