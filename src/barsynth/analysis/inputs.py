"""Checks of the arguments the analysis functions share: the sound, its sample rate, frequencies."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..checks import check_array, check_number
from ..errors import ParameterError


def as_signal(samples: Any, sample_rate: Any) -> tuple[np.ndarray, float]:
    fs = positive("sample_rate", sample_rate, "Hz")
    x = check_array("samples", samples, "")
    if x.ndim != 1:
        raise ParameterError(
            f"parameter samples has shape {x.shape}; allowed: a 1-D array "
            "(mono; average the channels first)"
        )
    if x.size == 0:
        raise ParameterError("parameter samples is empty; allowed: at least 1 sample")
    return x, fs


def positive(name: str, value: Any, unit: str) -> float:
    """``value`` as a finite float > 0."""
    return check_number(name, value, unit, minimum=0.0, minimum_exclusive=True)


def below_nyquist(name: str, value: Any, sample_rate: float) -> float:
    """``value`` as a frequency strictly between 0 and half the sample rate, Hz."""
    return check_number(
        name, value, "Hz (below half the sample rate)", minimum=0.0, maximum=0.5 * sample_rate,
        minimum_exclusive=True, maximum_exclusive=True,
    )
