"""Damped cosines of known frequency and decay: their amplitudes in a sound, and their sum.

When the frequencies and T60s of a sound's modes are known (a model's own design, or a
recording's analysis), each mode's amplitude and phase follow by linear least squares: the
sound is a sum of ``exp(-t/tau) cos(w t)`` and ``exp(-t/tau) sin(w t)`` columns, one pair a
mode. A fit uses it to calibrate a model's output (the level each mode comes out at, for a
gain of 0 dB) and to take a recording's partials away from it (what remains is the attack).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["damped_sum", "mode_amplitudes"]

LN1000 = math.log(1000.0)


def _rates(t60s: Any) -> np.ndarray:
    """Decay rates (1/s) of T60s (s; None, inf or <= 0: a mode that holds)."""
    return np.array([LN1000 / t if t is not None and math.isfinite(t) and t > 0.0 else 0.0 for t in t60s])


def mode_amplitudes(samples: np.ndarray, sample_rate: float, frequencies_hz: Any, t60s_s: Any, *,
                    start: int = 0, fit_from: int | None = None, fit_to: int | None = None) -> np.ndarray:
    """Each mode's complex amplitude at sample ``start``: ``samples[n]`` is fitted, over
    ``fit_from`` to ``fit_to`` (default: from ``start`` to the end), by ``Re sum c_k exp((-s_k +
    j w_k) (n - start) / fs)``; ``|c_k|`` is the amplitude, ``arg c_k`` the phase (cosine)."""
    freqs = np.asarray(frequencies_hz, dtype=float)
    rates = _rates(t60s_s)
    lo = start if fit_from is None else fit_from
    hi = samples.size if fit_to is None else min(fit_to, samples.size)
    if freqs.size == 0 or hi - lo < 2 * freqs.size + 1:
        return np.zeros(freqs.size, dtype=complex)
    t = (np.arange(lo, hi) - start) / sample_rate
    envelope = np.exp(-np.outer(t, rates))
    phase = 2.0 * np.pi * np.outer(t, freqs)
    columns = np.concatenate([envelope * np.cos(phase), -envelope * np.sin(phase)], axis=1)
    solution, *_ = np.linalg.lstsq(columns, samples[lo:hi], rcond=None)
    return solution[:freqs.size] + 1j * solution[freqs.size:]


def damped_sum(num_samples: int, sample_rate: float, frequencies_hz: Any, t60s_s: Any, amplitudes: Any, *,
               start: int = 0) -> np.ndarray:
    """``Re sum c_k exp((-s_k + j w_k) (n - start) / fs)`` for ``n`` from 0 (0 before ``start``)."""
    out = np.zeros(num_samples)
    if start >= num_samples:
        return out
    t = np.arange(num_samples - start) / sample_rate
    for f, rate, c in zip(np.asarray(frequencies_hz, dtype=float), _rates(t60s_s), np.asarray(amplitudes)):
        out[start:] += np.real(c * np.exp((-rate + 2j * np.pi * f) * t))
    return out
