"""Hearing barsynth in a notebook: :func:`audio` plays samples, :func:`hear` a model's note.

Both return an ``IPython.display.Audio`` object (Jupyter shows it as a player). They need
IPython: ``pip install 'barsynth[notebook]'``. (Not ``listen``, which names the listening
tests.)

>>> from barsynth.notebook import hear            # doctest: +SKIP
>>> hear("twang", "steel-30cm", duration_s=1.5)   # doctest: +SKIP
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import ParameterError
from .extras import require
from .models.rendering import check_sample_rate

MAX_CHANNELS = 8

__all__ = ["audio", "hear"]


def audio(samples: Any, sample_rate: float, *, normalize: bool = True) -> Any:
    """``samples`` as a player: mono (1-D) or several channels (channels x samples), any real
    dtype, finite; ``sample_rate`` in Hz (8 kHz to 192 kHz). With ``normalize`` (the default)
    the peak is played at full scale; without it the samples must lie within -1 to 1 (as they
    would be written to a file) and are played as they are."""
    require("notebook", "barsynth.notebook")
    from IPython.display import Audio

    rate = check_sample_rate(sample_rate)
    data = _checked(samples, normalize)
    return Audio(data, rate=int(round(rate)), normalize=normalize)


def hear(model: str, preset: str | None = None, *, duration_s: float = 2.0, sample_rate: float = 48000.0,
         seed: int | None = 0, **parameters: Any) -> Any:
    """One note of ``model`` (its ``preset``, then ``parameters`` on top) rendered offline for
    ``duration_s`` seconds and returned as a player (:func:`audio`, normalised)."""
    from .models import get_model
    from .presets import preset_parameters

    chosen = get_model(model)
    settings = {**(preset_parameters(model, preset) if preset is not None else {}), **parameters}
    samples = chosen.render(settings, duration_s=duration_s, sample_rate=sample_rate, seed=seed, dtype=np.float64)
    return audio(samples, sample_rate)


def _checked(samples: Any, normalize: bool) -> np.ndarray:
    """The samples as a float64 array IPython takes, or one line saying what is wrong."""
    try:
        data = np.asarray(samples, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"parameter samples = {type(samples).__name__} is not allowed; allowed: an array of "
                             "real numbers, mono (1-D) or channels x samples (2-D)") from None
    if data.ndim not in (1, 2) or data.size == 0 or (data.ndim == 2 and not 1 <= data.shape[0] <= MAX_CHANNELS):
        raise ParameterError(f"parameter samples of shape {data.shape} is not allowed; allowed: mono (1-D) or "
                             f"1 to {MAX_CHANNELS} channels x samples (2-D), at least one sample")
    if not np.all(np.isfinite(data)):
        raise ParameterError("parameter samples holds NaN or infinite values; allowed: finite samples")
    peak = float(np.max(np.abs(data)))
    if not normalize and peak > 1.0:
        raise ParameterError(f"parameter samples peaks at {peak:.4g} with normalize=False; allowed: -1 to 1 "
                             "(or normalize=True)")
    return data
