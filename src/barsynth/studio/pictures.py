"""The studio's pictures of a sound, as numbers the page paints: waveform, spectrogram, modes.

One strike of the settings is rendered offline (peak at -1 dBFS) and measured with
:func:`barsynth.analysis.spectrogram`, the same analysis the tests and the CLI use;
the page only draws what it is sent.
"""

from __future__ import annotations

import base64
from typing import Any

import numpy as np

from ..jsonout import json_number

SPECTROGRAM_ROWS = 256
MAX_COLUMNS = 1200
FLOOR_DB = -100.0
CEILING_DB = 0.0
WINDOW_S = 0.0853  # 4096 samples at 48 kHz: 12 Hz bins, for the low modes
LOWEST_HZ = 20.0


def waveform_columns(samples: np.ndarray, width: int) -> tuple[list[float], list[float]]:
    """The least and greatest sample in each of ``width`` equal runs of ``samples``."""
    edges = np.linspace(0, samples.size, width + 1).astype(np.int64)
    starts = np.minimum(edges[:-1], samples.size - 1)
    low = np.minimum.reduceat(samples, starts)
    high = np.maximum.reduceat(samples, starts)
    return [round(float(v), 5) for v in low], [round(float(v), 5) for v in high]


def log_rows(power_db: np.ndarray, freqs_hz: np.ndarray, edges_hz: np.ndarray) -> np.ndarray:
    """Pool FFT bins (rows of ``power_db``) into bands between ``edges_hz``: the loudest bin whose
    centre lies in a band, or the bin nearest its centre where the band is narrower than a bin."""
    step = freqs_hz[1] - freqs_hz[0]
    rows = np.empty((edges_hz.size - 1, power_db.shape[1]))
    for k, (low, high) in enumerate(zip(edges_hz[:-1], edges_hz[1:])):
        first, last = int(np.ceil(low / step)), min(int(np.floor(high / step)), freqs_hz.size - 1)
        if last >= first:
            rows[k] = power_db[first:last + 1].max(axis=0)
        else:
            rows[k] = power_db[min(freqs_hz.size - 1, int(round(np.sqrt(low * high) / step)))]
    return rows


def spectrogram_levels(samples: np.ndarray, sample_rate: float, width: int) -> dict[str, Any]:
    """The spectrogram in ``SPECTROGRAM_ROWS`` log-spaced frequency bands from ``LOWEST_HZ`` to half
    the sample rate (the lowest first) and at most ``width`` time columns (the loudest bin of each
    cell), as bytes: 0 is ``FLOOR_DB``, 255 is ``CEILING_DB``."""
    from ..analysis import spectrogram

    window_s = min(WINDOW_S, 2.0 * samples.size / sample_rate)
    times, freqs, power_db = spectrogram(samples, sample_rate, window_s=window_s,
                                         hop_s=max(1.0 / sample_rate, samples.size / sample_rate / width))
    whole = max(1, int(np.searchsorted(times, samples.size / sample_rate - window_s / 2.0, side="right")))
    times, power_db = times[:whole], power_db[:, :whole]  # frames whose window runs past the end smear
    edges = np.geomspace(LOWEST_HZ, freqs[-1], SPECTROGRAM_ROWS + 1)
    pooled = log_rows(power_db, freqs, edges)
    if pooled.shape[1] > width:
        columns = np.linspace(0, pooled.shape[1], width + 1).astype(np.int64)[:-1]
        pooled = np.maximum.reduceat(pooled, columns, axis=1)
        times = times[columns]
    scaled = np.clip((pooled - FLOOR_DB) / (CEILING_DB - FLOOR_DB), 0.0, 1.0)
    levels = np.round(scaled * 255.0).astype(np.uint8)
    return {"times_s": [round(float(t), 5) for t in times], "scale": "log", "min_frequency_hz": LOWEST_HZ,
            "max_frequency_hz": float(freqs[-1]), "bins": int(levels.shape[0]), "floor_db": FLOOR_DB,
            "ceiling_db": CEILING_DB, "levels": base64.b64encode(np.ascontiguousarray(levels).tobytes()).decode("ascii")}


def mode_rows(model: Any, resolved: Any, sample_rate: float) -> list[dict[str, Any]]:
    """The modes the model synthesises, as JSON rows (``error_cents`` for the reference models)."""
    modes = model.describe(resolved, sample_rate=sample_rate)
    errors = model.errors_cents(resolved, sample_rate=sample_rate) if model.reports_reference_errors else None
    rows = []
    for k, mode in enumerate(modes):
        row = {key: (json_number(v) if isinstance(v, float) else v) for key, v in mode.to_json().items()}
        if errors is not None and k < len(errors):
            row["error_cents"] = json_number(float(errors[k]))
        rows.append(row)
    return rows


def picture(model: Any, resolved: Any, *, sample_rate: float, duration_s: float, width: int) -> dict[str, Any]:
    """Everything the page draws for these settings (see ``docs/studio.md``)."""
    samples = model.render(resolved, duration_s=duration_s, sample_rate=sample_rate, dtype=np.float64)
    width = max(16, min(MAX_COLUMNS, int(width), samples.size))
    low, high = waveform_columns(samples, width)
    return {"model": model.name, "sample_rate": sample_rate, "duration_s": duration_s,
            "waveform": {"min": low, "max": high},
            "spectrogram": spectrogram_levels(samples, sample_rate, width),
            "modes": mode_rows(model, resolved, sample_rate)}
