"""Measuring sounds: partials, their ratios and decays, spectrograms and plots.

Shared by barsynth's tests and its users (spec 3.4). Importing this package is
cheap: SciPy loads on first use and matplotlib only when a plot is drawn.

>>> from barsynth.analysis import find_partials, partial_ratios   # doctest: +SKIP
>>> partials = find_partials(samples, sample_rate)                # doctest: +SKIP
>>> partial_ratios(partials)                                      # doctest: +SKIP
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..audio_io import load_audio
from .decay import band_decay_t60
from .partial import Partial, partial_ratios
from .plots import spectrogram
from .search import find_partials, measure_partial

__all__ = [
    "Partial",
    "band_decay_t60",
    "find_partials",
    "load_audio",
    "measure_partial",
    "partial_ratios",
    "plot_sound",
    "spectrogram",
]


def plot_sound(
    samples: Any,
    sample_rate: float,
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
    partials: Any = None,
    max_frequency_hz: float | None = None,
) -> Path:
    """Write a PNG of a sound's waveform and spectrogram; returns its path.

    See :func:`barsynth.analysis.plots.plot_sound` (loaded, with matplotlib, on
    the first call).
    """
    from .plots import plot_sound as _plot_sound

    return _plot_sound(
        samples,
        sample_rate,
        path,
        title=title,
        partials=partials,
        max_frequency_hz=max_frequency_hz,
    )
