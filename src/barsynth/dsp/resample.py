"""Band-limited resampling of a short recording to another sample rate (at design time).

SciPy's polyphase resampler (``scipy.signal.resample_poly``: a Kaiser-windowed low-pass FIR at
the lower of the two Nyquist frequencies, applied without delay), at the rational ratio of the
two rates. Rates are whole numbers of Hz; a ratio whose terms exceed :data:`MOST_TERMS` (44101
Hz to 48000 Hz, say) is taken as the nearest one whose terms do not, which moves the duration by
less than 0.1 % (the usual rates, 8 to 192 kHz, are exact).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

MOST_TERMS = 1000
"""The largest up or down factor of a ratio of rates (the FIR grows with it)."""


def resample(samples: np.ndarray, from_hz: float, to_hz: float) -> np.ndarray:
    """``samples`` recorded at ``from_hz`` as heard at ``to_hz`` (both whole numbers of Hz): the
    same duration, ``ceil(n to_hz / from_hz)`` samples, the spectrum above the lower Nyquist
    frequency removed. Returns a new float64 array.

    Examples
    --------
    >>> click = np.zeros(441); click[100] = 1.0
    >>> at_48k = resample(click, 44100, 48000)
    >>> at_48k.size, int(np.argmax(at_48k))  # 10 ms in both; the click at 100 / 44100 s
    (480, 109)
    """
    x = np.asarray(samples, dtype=np.float64)
    ratio = Fraction(int(round(to_hz)), int(round(from_hz)))
    if max(ratio.numerator, ratio.denominator) > MOST_TERMS:  # the larger term limited (then the other is)
        small = ratio if ratio < 1 else 1 / ratio
        small = max(small.limit_denominator(MOST_TERMS), Fraction(1, MOST_TERMS))  # (not 0 below 1 / 2000)
        ratio = small if ratio < 1 else 1 / small
    if ratio == 1 or x.size == 0:
        return x.copy()
    from scipy.signal import resample_poly

    return np.asarray(resample_poly(x, ratio.numerator, ratio.denominator), dtype=np.float64)
