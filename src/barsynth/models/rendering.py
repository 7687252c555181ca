"""Shared checks and helpers for rendering any model offline."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..checks import check_number, check_whole
from ..errors import ParameterError

MIN_SAMPLE_RATE = 8_000.0
MAX_SAMPLE_RATE = 384_000.0
MAX_DURATION_S = 600.0
NORMALIZE_PEAK_DBFS = -1.0
MAX_BLOCK_SAMPLES = int(MAX_DURATION_S * MAX_SAMPLE_RATE)  # the longest render at the highest rate


def check_sample_rate(sample_rate: Any) -> float:
    """Validate a sample rate: a whole number of Hz from 8 kHz to 384 kHz (audio files
    store whole rates); text such as "48000" is parsed."""
    rate = check_number(
        "sample_rate", sample_rate, "Hz",
        minimum=MIN_SAMPLE_RATE, maximum=MAX_SAMPLE_RATE, parse_text=True,
    )
    if not rate.is_integer():
        raise ParameterError(
            f"parameter sample_rate = {sample_rate!r} is not a whole number; "
            f"allowed: whole numbers from {MIN_SAMPLE_RATE:g} to {MAX_SAMPLE_RATE:g} Hz"
        )
    return rate


def check_seed(seed: Any) -> int | None:
    """Validate a noise seed: None (fresh entropy each time) or a whole number >= 0."""
    if seed is None:
        return None
    return check_whole("seed", seed, "", 0)


def check_duration(duration_s: Any) -> float:
    """Validate a render duration in seconds (more than 0, at most 600 s); text is parsed."""
    return check_number(
        "duration_s", duration_s, "s",
        minimum=0.0, maximum=MAX_DURATION_S, minimum_exclusive=True, parse_text=True,
    )


def check_block_size(num_samples: Any) -> int:
    """Validate a block length in samples (a whole number, 0 or more)."""
    return check_whole("num_samples", num_samples, "samples", 0, MAX_BLOCK_SAMPLES)


def check_dtype(dtype: Any) -> np.dtype:
    """Validate an output sample type: float32 or float64."""
    try:
        kind = None if dtype is None else np.dtype(dtype)
    except TypeError:
        kind = None
    # (``kind is None`` first: NumPy compares None equal to the float64 dtype)
    if kind is None or kind not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ParameterError(f"parameter dtype = {dtype!r} is not allowed; allowed: float32 or float64")
    return kind


def render_voice(voice: Any, duration_s: float, *, normalize: bool = True,
                 dtype: Any = np.float32) -> np.ndarray:
    """Trigger ``voice`` once and render ``duration_s`` seconds, as every model's
    ``render`` does: peak-normalised to -1 dBFS, or exactly the voice's samples when
    ``normalize`` is false; float32 or float64 (``dtype``)."""
    dtype = check_dtype(dtype)
    duration = check_duration(duration_s)
    count = int(round(duration * voice.sample_rate))
    if count < 1:
        raise ParameterError(
            f"parameter duration_s = {duration_s!r} is shorter than one sample; allowed: at "
            f"least {1.0 / voice.sample_rate:.3g} s at {voice.sample_rate:g} Hz"
        )
    voice.trigger()
    samples = voice.process(count, dtype=np.float64)
    if normalize:
        return normalize_peak(samples, dtype=dtype)
    return samples.astype(dtype, copy=False)


def normalize_peak(samples: np.ndarray, peak_dbfs: float = NORMALIZE_PEAK_DBFS,
                   *, dtype: Any = None) -> np.ndarray:
    """``samples`` scaled so the largest magnitude is ``peak_dbfs`` dBFS, as ``dtype``
    (the input's by default); silence stays silence. One pass, no temporaries."""
    out = np.empty(samples.shape, dtype=dtype or samples.dtype)
    peak = max(float(samples.max()), -float(samples.min())) if samples.size else 0.0
    scale = 10.0 ** (peak_dbfs / 20.0) / peak if peak > 0.0 else 1.0
    np.multiply(samples, scale, out=out, casting="same_kind")
    return out
