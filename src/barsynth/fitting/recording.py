"""Reading the recording a fit is given: bounded, mono, and what about it a user should know.

:func:`read_recording` reads a WAV, FLAC or OGG file as :func:`barsynth.audio_io.load_audio`
does (the same one-line errors for a missing, unreadable, empty or non-finite file), but

* reads at most ``max_seconds`` of it (a note has rung out long before; a huge file is neither
  read whole nor refused: the first seconds are fitted, and a warning says so);
* averages the channels only when that keeps the sound: channels that cancel (a mix more than
  20 dB below the loudest channel, say one channel the other's negative) are refused in one line;
* warns of a clipped recording (a run of samples at its full-scale peak), whose levels and
  decays near the peak are not the instrument's.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ..audio_io import _check_finite, _check_rate, check_sound_path, decode_errors, unreadable
from ..checks import show_text
from ..errors import AudioFileError

__all__ = ["MAX_RECORDING_S", "Recording", "read_recording"]

MAX_RECORDING_S = 10.0  # seconds of a file a fit reads
CANCEL_DB = 20.0  # channels whose average is this far below the loudest channel cancel
CLIP_PEAK = 0.98  # a clip is at full scale: a peak at least this high (full scale 1.0)...
CLIP_STEP = 2.0 ** -16  # ...with samples flat at it, within half a 16-bit step...
CLIP_RUN = 4  # ...for this many samples in a row


@dataclass(frozen=True)
class Recording:
    """A recording read for a fit: mono float64 samples, the rate (Hz), and warnings (one line each)."""

    samples: np.ndarray
    sample_rate: float
    duration_s: float  # of the whole file
    warnings: tuple[str, ...] = field(default=())


def _clip_count(x: np.ndarray) -> int:
    """Samples in runs of CLIP_RUN or more flat at a peak near full scale (a clipped recording)."""
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if peak < CLIP_PEAK:
        return 0
    rail = np.abs(x) >= peak - CLIP_STEP
    if not rail.any():
        return 0
    edges = np.diff(np.concatenate([[0], rail.view(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    runs = ends - starts
    return int(runs[runs >= CLIP_RUN].sum())


def read_recording(path: str | os.PathLike[str], *, max_seconds: float = MAX_RECORDING_S) -> Recording:
    """The first ``max_seconds`` of the sound file at ``path`` (see the module docstring). Raises
    :class:`~barsynth.errors.AudioFileError` (one line, naming the file) for a file that cannot be
    fitted at all."""
    import soundfile

    name = os.fspath(path)
    shown = show_text(name)
    check_sound_path(name, allow_empty=False)
    try:
        sound = soundfile.SoundFile(name)
    except decode_errors() as exc:
        raise unreadable(name, exc) from None
    warnings = []
    with sound:
        rate = float(sound.samplerate)
        _check_rate(name, rate)
        most = max(1, int(max_seconds * rate))
        try:
            data = sound.read(most, dtype="float64", always_2d=True)
            more = sound.read(1, dtype="float64", always_2d=True).shape[0] > 0 if data.shape[0] == most else False
        except decode_errors() as exc:
            raise unreadable(name, exc) from None
        frames = sound.frames if sound.seekable() and sound.frames > 0 else data.shape[0] + int(more)
    if data.shape[0] == 0:
        raise AudioFileError(f"audio file {shown}: contains no samples")
    _check_finite(name, data)
    if more:
        warnings.append(f"{shown} is {frames / rate:.4g} s long; the fit reads its first {max_seconds:g} s")
    if data.shape[1] > 1:
        mono = data.mean(axis=1)
        loudest = float(np.sqrt(np.max(np.mean(data ** 2, axis=0))))
        mixed = float(np.sqrt(np.mean(mono ** 2)))
        if loudest > 0.0 and mixed < loudest * 10.0 ** (-CANCEL_DB / 20.0):
            below = "all" if mixed == 0.0 else f"{20.0 * np.log10(loudest / mixed):.0f} dB"
            raise AudioFileError(
                f"audio file {shown}: its {data.shape[1]} channels cancel when averaged to mono (the mix is {below} "
                f"below the loudest channel); allowed: a mono file or channels in phase (keep one channel first)")
    else:
        mono = data[:, 0].copy()
    clipped = _clip_count(mono)
    if clipped:
        warnings.append(f"{shown} looks clipped ({clipped} samples flat at its peak, "
                        f"{20.0 * np.log10(float(np.max(np.abs(mono)))):.1f} dBFS): levels and decays near the "
                        "peak are not the instrument's")
    return Recording(mono, rate, frames / rate, tuple(warnings))

