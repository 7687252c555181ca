"""Decay time (T60) of the energy in a band, for noise-excited or otherwise rough decays.

The band comes from the same demodulation as the partials' (:mod:`.demodulation`);
a line is fitted in dB to its smoothed energy down to a margin above the noise
floor.

Reference: A. Lundeby et al., "Uncertainties of measurements in room acoustics",
Acustica 81 (1995) (noise-floor aware decay fits).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..checks import check_number
from .demodulation import MIN_FIT_POINTS, SG_6DB, Engine, Mode
from .inputs import as_signal, below_nyquist

__all__ = ["band_decay_t60"]

_FLOOR_MARGIN_DB = 10.0  # the fit ends this far above the noise floor


def _wls_line(t: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[Any, Any, float]:
    """Weighted least-squares line y ~ a + b (t - tm); returns (a, b, tm). y may be complex."""
    sw = float(w.sum())
    tm = float((w * t).sum()) / sw
    tc = t - tm
    stt = float((w * tc * tc).sum())
    a = (w * y).sum() / sw
    b = (w * tc * (y - a)).sum() / stt if stt > 0 else 0.0 * a
    return a, b, tm


def band_decay_t60(
    samples: Any,
    sample_rate: float,
    centre_hz: float,
    bandwidth_hz: float,
) -> float:
    """T60 (s) of the energy in a band, for noise-excited or otherwise rough decays.

    The sound is band-passed (zero phase, -3 dB at ``centre_hz +- bandwidth_hz/2``)
    and its squared magnitude taken (of the analytic band signal, so free of ripple
    at twice the frequency). A first line is fitted in dB to that energy smoothed
    over about 4/bandwidth_hz, from its maximum down to 10 dB above the noise
    floor (estimated from the last tenth, Lundeby-style) or 100 dB below the
    maximum. Returns ``math.inf`` if the energy does not decay and ``nan`` if there
    is too little to fit.
    """
    from scipy.ndimage import uniform_filter1d

    x, fs = as_signal(samples, sample_rate)
    fc = below_nyquist("centre_hz", centre_hz, fs)
    bw = check_number(
        "bandwidth_hz", bandwidth_hz, "Hz", minimum=0.0, maximum=fs, minimum_exclusive=True
    )
    engine = Engine(x, fs)
    if engine.peak == 0.0:
        return math.nan
    # -3 dB at +-bw/2 for exp(-0.5 (f/f1)^4)
    half = 0.5 * bw
    f1 = half / (2.0 * math.log(math.sqrt(2.0))) ** 0.25
    cutoff = f1 * SG_6DB
    engine.prepare([Mode(frequency_hz=fc, centre_hz=fc, cutoff_hz=cutoff)])
    band = engine.band(fc, cutoff)
    t = band.t
    z = engine.envelope(band, engine.band_values(engine.spectrum(x), band))
    energy = z.real**2 + z.imag**2
    dt = t[1] - t[0] if t.size > 1 else 1.0 / fs
    width = max(1, int(round(min(4.0 / bw, 0.05 * engine.duration) / dt)))
    smooth = np.maximum(uniform_filter1d(energy, width, mode="nearest"), 1e-300)
    # leave out the filter's edge smear
    margin = min(2.0 / f1, 0.1 * engine.duration) + 0.5 * width * dt
    sel = (t >= engine.t0 + margin) & (t <= engine.duration - margin)
    if np.count_nonzero(sel) < MIN_FIT_POINTS:
        return math.nan
    tt = t[sel]
    level = smooth[sel]
    top = float(level.max())
    if not top > 0:
        return math.nan
    db = 10.0 * np.log10(level / top + 1e-300)
    i0 = int(np.argmax(db >= -1.0))  # (a steady sound's maximum may be anywhere)
    below = np.flatnonzero(db[i0:] < -100.0)
    i1 = i0 + int(below[0]) if below.size else tt.size
    tail = max(MIN_FIT_POINTS, tt.size // 10)
    floor_db = float(10.0 * np.log10(np.mean(level[-tail:]) / top + 1e-300))
    slope = 0.0
    for _ in range(5):
        if i1 - i0 < MIN_FIT_POINTS:
            return math.nan
        a, slope, tm = _wls_line(tt[i0:i1], db[i0:i1], np.ones(i1 - i0))
        t_tail = float(np.mean(tt[-tail:]))
        if not (slope < 0 and floor_db > a + slope * (t_tail - tm) + 6.0):
            break
        t_cross = tm + (floor_db + _FLOOR_MARGIN_DB - a) / slope
        new_i1 = int(np.searchsorted(tt, t_cross))
        new_i1 = max(i0 + MIN_FIT_POINTS, min(new_i1, i1))
        if new_i1 >= i1:
            break
        i1 = new_i1
    if slope >= 0:
        return math.inf
    return float(-60.0 / slope)
