"""Measuring sounds: partials, their ratios and decays, spectrograms and plots.

Shared by barsynth's tests and its users (spec 3.4). Importing this package is
cheap: SciPy loads on first use and matplotlib only when a plot is drawn.

- :func:`analyze_note`: a recorded note as a fit needs it (spec 7.1): f0, the
  sustained partials with their decays and how they were measured, the attack, a loop.
- :func:`find_partials` / :func:`measure_partial`: every partial (or one) of a sound to
  sub-cent precision, by a slower SAGE-like refinement.

>>> from barsynth.analysis import analyze_note, find_partials     # doctest: +SKIP
>>> note = analyze_note(samples, sample_rate)                     # doctest: +SKIP
>>> note.f0_hz, [p.ratio for p in note.partials]                  # doctest: +SKIP
>>> partials = find_partials(samples, sample_rate)                # doctest: +SKIP
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..audio_io import load_audio
from .decay import band_decay_t60
from .note import analyze_note
from .partial import Partial, partial_ratios
from .records import Attack, Damped, Decay, NoteAnalysis, NotePartial
from .plots import spectrogram
from .search import find_partials, measure_partial

__all__ = [
    "Attack",
    "Damped",
    "Decay",
    "NoteAnalysis",
    "NotePartial",
    "Partial",
    "analyze_note",
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
