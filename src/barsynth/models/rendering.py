"""Shared checks and helpers for rendering any model offline."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ParameterError

MIN_SAMPLE_RATE = 8_000.0
MAX_SAMPLE_RATE = 384_000.0
MAX_DURATION_S = 600.0
NORMALIZE_PEAK_DBFS = -1.0


def _as_float(value: Any) -> float:
    if isinstance(value, bool):
        return float("nan")
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def check_sample_rate(sample_rate: Any) -> float:
    """Validate a sample rate in Hz (8 kHz to 384 kHz)."""
    rate = _as_float(sample_rate)
    if not (math.isfinite(rate) and MIN_SAMPLE_RATE <= rate <= MAX_SAMPLE_RATE):
        raise ParameterError(
            f"parameter sample_rate = {sample_rate!r} is out of range; "
            f"allowed: {MIN_SAMPLE_RATE:g} to {MAX_SAMPLE_RATE:g} Hz"
        )
    return rate


def check_duration(duration_s: Any) -> float:
    """Validate a render duration in seconds (more than 0, at most 600 s)."""
    duration = _as_float(duration_s)
    if not (math.isfinite(duration) and 0.0 < duration <= MAX_DURATION_S):
        raise ParameterError(
            f"parameter duration_s = {duration_s!r} is out of range; "
            f"allowed: more than 0 up to {MAX_DURATION_S:g} s"
        )
    return duration


def check_block_size(num_samples: Any) -> int:
    """Validate a block length in samples (a whole number, 0 or more)."""
    if isinstance(num_samples, bool) or not isinstance(num_samples, (int, np.integer)) or num_samples < 0:
        raise ParameterError(
            f"parameter num_samples = {num_samples!r} is out of range; "
            "allowed: a whole number of samples, 0 or more"
        )
    return int(num_samples)


def render_voice(voice: Any, duration_s: float) -> np.ndarray:
    """Trigger ``voice`` once and return ``duration_s`` seconds of float64 samples."""
    duration = check_duration(duration_s)
    voice.trigger()
    return voice.process(int(round(duration * voice.sample_rate)), dtype=np.float64)


def normalize_peak(samples: np.ndarray, peak_dbfs: float = NORMALIZE_PEAK_DBFS) -> np.ndarray:
    """Scale so the largest magnitude is ``peak_dbfs`` dBFS; silence stays silence."""
    peak = float(np.max(np.abs(samples))) if samples.size else 0.0
    if peak == 0.0:
        return samples
    return samples * (10.0 ** (peak_dbfs / 20.0) / peak)
