"""Damping of bar modes: quality factor, decay rate and T60.

Mode n decays as ``exp(-alpha_n t)``; with quality factor ``Q_n`` (spec 1.3;
Fletcher & Rossing, *The Physics of Musical Instruments*, 2nd ed., Springer 1998,
ch. 1):

    alpha_n = π f_n / Q_n          (1/s)
    T60_n   = ln(1000) / alpha_n   (s, the time to fall by 60 dB)

Every function accepts scalars or arrays (broadcast together), returns a float for
scalar input and a float64 array otherwise, and raises ParameterError for values
that are not finite and positive.
"""

from __future__ import annotations

import math

import numpy as np

from ..checks import check_array

__all__ = [
    "alpha_from_q",
    "alpha_from_t60",
    "damped_frequency",
    "q_from_t60",
    "t60_from_alpha",
    "t60_from_q",
]

LN_1000 = math.log(1000.0)


def _positive(name: str, value, unit: str, minimum: float = 0.0) -> np.ndarray:
    """``value`` as a float64 array, every element finite and > ``minimum``."""
    return check_array(name, value, unit, minimum=minimum, minimum_exclusive=True)


def _result(out: np.ndarray):
    out = np.asarray(out, dtype=np.float64)
    return float(out) if out.ndim == 0 else out


def alpha_from_q(frequency_hz, q):
    """Decay rate ``alpha = π f / Q``.

    Parameters
    ----------
    frequency_hz : float or array_like
        Mode frequency in Hz, > 0.
    q : float or array_like
        Quality factor (dimensionless), > 0.

    Returns
    -------
    float or numpy.ndarray
        ``alpha`` in 1/s.
    """
    f = _positive("frequency_hz", frequency_hz, "Hz")
    qq = _positive("q", q, "dimensionless")
    return _result(math.pi * f / qq)


def t60_from_alpha(alpha):
    """Time to decay by 60 dB, ``T60 = ln(1000) / alpha``.

    Parameters
    ----------
    alpha : float or array_like
        Decay rate in 1/s, > 0.

    Returns
    -------
    float or numpy.ndarray
        T60 in s.
    """
    return _result(LN_1000 / _positive("alpha", alpha, "1/s"))


def alpha_from_t60(t60_s):
    """Decay rate ``alpha = ln(1000) / T60``.

    Parameters
    ----------
    t60_s : float or array_like
        Time to decay by 60 dB in s, > 0.

    Returns
    -------
    float or numpy.ndarray
        ``alpha`` in 1/s.
    """
    return _result(LN_1000 / _positive("t60_s", t60_s, "s"))


def t60_from_q(frequency_hz, q):
    """T60 of a mode of frequency ``f`` and quality ``Q``: ``ln(1000) Q / (π f)``.

    Parameters
    ----------
    frequency_hz : float or array_like
        Mode frequency in Hz, > 0.
    q : float or array_like
        Quality factor (dimensionless), > 0.

    Returns
    -------
    float or numpy.ndarray
        T60 in s.
    """
    f = _positive("frequency_hz", frequency_hz, "Hz")
    qq = _positive("q", q, "dimensionless")
    return _result(LN_1000 * qq / (math.pi * f))


def q_from_t60(frequency_hz, t60_s):
    """Quality factor of a mode that decays 60 dB in ``T60``: ``π f T60 / ln(1000)``.

    Parameters
    ----------
    frequency_hz : float or array_like
        Mode frequency in Hz, > 0.
    t60_s : float or array_like
        Time to decay by 60 dB in s, > 0.

    Returns
    -------
    float or numpy.ndarray
        Q (dimensionless).
    """
    f = _positive("frequency_hz", frequency_hz, "Hz")
    t60 = _positive("t60_s", t60_s, "s")
    return _result(math.pi * f * t60 / LN_1000)


def damped_frequency(frequency_hz, q):
    """Frequency of a damped mode, ``f sqrt(1 − 1/(4 Q²))``.

    This is ``w_d = w sqrt(1 − ε²)`` with ``ε = 1/(2Q)`` (spec 1.3).

    For Q >= 50 the shift is below 0.01 % (``1/(8 Q²)`` = 0.005 % at Q = 50), so
    barsynth's models ignore it and use the undamped frequency.

    Parameters
    ----------
    frequency_hz : float or array_like
        Undamped frequency in Hz, > 0.
    q : float or array_like
        Quality factor (dimensionless), > 0.5 (at or below 0.5 the mode is not
        oscillatory).

    Returns
    -------
    float or numpy.ndarray
        Damped frequency in Hz.
    """
    f = _positive("frequency_hz", frequency_hz, "Hz")
    qq = _positive("q", q, "dimensionless", minimum=0.5)
    return _result(f * np.sqrt(1.0 - 1.0 / (4.0 * qq * qq)))
