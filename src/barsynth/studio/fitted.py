"""A recording dropped on the studio's page, fitted: what the page shows and plays (issue 14).

The upload's bytes are read in memory (:func:`barsynth.audio_io.audio_from_bytes`; nothing is
written to disk), bounded in length (``MAX_UPLOAD_S``) and rate, fitted
(:func:`barsynth.fitting.fit_recording`) and answered as JSON (:func:`fit_answer`):

- ``parameters``: every value of the fitted model's table, resolved as a preset's are (banded's
  recorded attack, ``attack_samples``, among them: a data row the page keeps for the stream);
- ``fit``: the fit's own report (:meth:`barsynth.fitting.Fit.to_json`: each partial of the
  recording against the resynthesis, the spectral distance and the one-sine baseline);
- ``recording`` and ``resynthesis``: each a WAV file (16-bit, base64) and its spectrogram. Both
  start at the recording's onset and are as long as the resynthesis (at most 10 s); the
  resynthesis is :meth:`~barsynth.fitting.Fit.heard` (the recording's rate and peak), and both get
  the same gain (the louder peak at -1 dBFS), so the two sound and show at the same level. The
  spectrograms are :func:`barsynth.studio.pictures.spectrogram_levels` of the two: the same
  times, frequency bands and level range (-100 to 0 dBFS).

It runs in the studio's worker processes (:func:`barsynth.studio.work.fit_json`).
"""

from __future__ import annotations

import base64
from typing import Any

import numpy as np

__all__ = ["MAX_UPLOAD_BYTES", "MAX_UPLOAD_RATE_HZ", "MAX_UPLOAD_S", "MIN_UPLOAD_RATE_HZ", "fit_answer"]

MAX_UPLOAD_BYTES = 20 * 1024 * 1024
"""The largest upload (bytes): 30 s of 96 kHz stereo 24-bit WAV is 17.3 MB."""
MAX_UPLOAD_S = 30.0
"""The longest recording (s) at its own rate."""
MIN_UPLOAD_RATE_HZ = 8000.0
MAX_UPLOAD_RATE_HZ = 192000.0
"""The rates a recording may have (Hz): those a recorded attack may have (``attack_rate_hz``)."""
PEAK_DBFS = -1.0


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def fit_answer(data: bytes, name: str, model: str, max_modes: int, nominal_hz: float | None,
               width: int) -> dict[str, Any]:
    """Read ``data`` (a WAV, FLAC or OGG file's bytes, called ``name`` in messages), fit ``model`` to
    it and answer what the page shows (see the module's docstring); ``width``: the spectrograms'
    most time columns. Raises :class:`~barsynth.errors.AudioFormatError` for bytes that are no
    sound file, :class:`~barsynth.errors.AudioFileError` for an empty, too long or oddly sampled
    one and :class:`~barsynth.errors.ParameterError` for a recording with no note to fit."""
    from ..audio_io import audio_from_bytes, wav_bytes
    from ..checks import show_text
    from ..errors import AudioFileError
    from ..fitting import fit_recording
    from ..jsonout import json_ready
    from ..models import get_model
    from .pictures import spectrogram_levels

    samples, rate = audio_from_bytes(data, name=name, max_duration_s=MAX_UPLOAD_S, max_rate_hz=MAX_UPLOAD_RATE_HZ)
    if rate < MIN_UPLOAD_RATE_HZ:
        raise AudioFileError(f"audio file {show_text(name)}: sample rate {rate:g} Hz is too low; allowed: "
                             f"{MIN_UPLOAD_RATE_HZ:g} to {MAX_UPLOAD_RATE_HZ:g} Hz")
    fit = fit_recording(samples, rate, model=model, max_modes=max_modes, nominal_hz=nominal_hz)
    table = get_model(fit.model).table
    values = json_ready(table.as_dict(table.resolve(fit.parameters)))

    heard = np.asarray(fit.heard(), dtype=np.float64)
    onset = int(round(fit.analysis.onset_s * rate))
    recording = np.zeros(heard.size)
    part = fit.recording[onset:onset + heard.size]
    recording[:part.size] = part
    peak = max(float(np.max(np.abs(recording))), float(np.max(np.abs(heard))) if heard.size else 0.0)
    gain = 10.0 ** (PEAK_DBFS / 20.0) / peak if peak > 0.0 else 1.0
    sounds = {}
    for key, x in (("recording", recording * gain), ("resynthesis", heard * gain)):
        sounds[key] = {"wav": _b64(wav_bytes(x, rate)), "spectrogram": spectrogram_levels(x, rate, width)}
    report = fit.to_json()
    description = (f"fitted to {show_text(name)[:80]}: f0 {fit.analysis.f0_hz:.2f} Hz, {len(fit.comparison)} partials, "
                   f"spectral distance {fit.distance_db:.2f} dB (one sine: {fit.baseline_db:.2f} dB)")
    return {"model": fit.model, "file": show_text(name), "description": description[:200], "sample_rate": rate,
            "onset_s": float(fit.analysis.onset_s), "duration_s": heard.size / rate, "parameters": values,
            "fit": report, **sounds}
