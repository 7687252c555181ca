"""Reading and writing sound files (WAV, FLAC, OGG) through soundfile (libsndfile).

Importing this module is cheap: numpy and soundfile load on first use.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

from .checks import check_extension, show_text
from .errors import AudioFileError, AudioFormatError, ParameterError

__all__ = [
    "AUDIO_FORMATS",
    "MAX_OGG_RATE",
    "MIN_AUDIO_RATE_HZ",
    "SUBTYPES",
    "audio_from_bytes",
    "load_audio",
    "output_format",
    "output_subtype",
    "wav_bytes",
    "write_audio",
]

AUDIO_FORMATS = {".wav": "WAV", ".flac": "FLAC", ".ogg": "OGG"}
MAX_OGG_RATE = 192_000.0  # libvorbis refuses (and older builds crash) above this
SUBTYPES = ("PCM_16", "PCM_24", "FLOAT")
MIN_AUDIO_RATE_HZ = 100.0


def load_audio(path: str | os.PathLike[str]) -> tuple[Any, float]:
    """Read a WAV, FLAC or OGG file as mono float64 samples (a numpy array) and its sample rate (Hz).

    Channels are averaged. Raises :class:`~barsynth.errors.AudioFileError` (one line,
    naming the file) when the file is missing, unreadable, empty or of a kind
    libsndfile does not know (that last: :class:`~barsynth.errors.AudioFormatError`).
    """
    import soundfile

    name = os.fspath(path)
    check_sound_path(name)
    try:
        data, rate = soundfile.read(name, dtype="float64", always_2d=True)
    except decode_errors() as exc:
        raise unreadable(name, exc) from None
    if data.shape[0] == 0:
        raise AudioFileError(f"audio file {show_text(name)}: contains no samples")
    _check_rate(name, rate)
    mono = data.mean(axis=1) if data.shape[1] > 1 else data[:, 0].copy()
    _check_finite(name, mono)
    return mono, float(rate)


def check_sound_path(name: str, *, allow_empty: bool = True) -> None:
    """Refuse, in one line naming the file, a path that is missing, a directory, not a regular
    file (a FIFO or device would block or never end) or, unless ``allow_empty``, empty."""
    if not os.path.exists(name):
        raise AudioFileError(f"audio file {show_text(name)}: no such file")
    if os.path.isdir(name):
        raise AudioFileError(f"audio file {show_text(name)}: is a directory, not a sound file")
    if not stat.S_ISREG(os.stat(name).st_mode):
        raise AudioFileError(f"audio file {show_text(name)}: is not a regular file")
    if not allow_empty and os.path.getsize(name) == 0:
        raise AudioFileError(f"audio file {show_text(name)}: is empty (0 bytes)")


def decode_errors() -> tuple[type[BaseException], ...]:
    """What libsndfile's reader raises for a file it cannot decode (soundfile is imported only
    when a file is read: it costs start-up time)."""
    import soundfile

    return (RuntimeError, soundfile.SoundFileError, OSError, ValueError)


def unreadable(name: str, exc: BaseException) -> AudioFormatError:
    """The one-line error for a file libsndfile cannot decode, with its reason."""
    reason = " ".join(str(getattr(exc, "error_string", None) or exc).split()) or type(exc).__name__
    return AudioFormatError(f"audio file {show_text(name)}: cannot be read as WAV, FLAC or OGG ({reason})")


READ_BLOCK_VALUES = 1 << 20  # samples (all channels) decoded at a time by audio_from_bytes


def audio_from_bytes(data: bytes, *, name: str = "upload", max_duration_s: float | None = None,
                     max_rate_hz: float | None = None) -> tuple[Any, float]:
    """Read a WAV, FLAC or OGG file held in memory (``data``, its bytes) as :func:`load_audio` reads
    a file: mono float64 samples (channels averaged) and the sample rate (Hz), with the same one-line
    :class:`~barsynth.errors.AudioFileError` naming ``name`` (an upload's file name, say).

    Bytes that are not such a file raise :class:`~barsynth.errors.AudioFormatError` (an
    AudioFileError). ``max_duration_s`` and ``max_rate_hz`` bound what is decoded: both are checked
    from the file's header before any sample is, and the length again while decoding (a header that
    lies), so a small compressed file cannot unpack into more than that. Nothing is written to disk.
    """
    import io

    import numpy as np
    import soundfile

    if not data:
        raise AudioFileError(f"audio file {show_text(name)}: is empty (0 bytes)")
    try:
        sound = soundfile.SoundFile(io.BytesIO(data))
    except (RuntimeError, soundfile.SoundFileError, OSError, ValueError) as exc:
        raise AudioFormatError(f"audio file {show_text(name)}: cannot be read as WAV, FLAC or OGG "
                               f"({_reason(exc)})") from None
    with sound:
        rate, channels = float(sound.samplerate), int(sound.channels)
        _check_rate(name, rate)
        if max_rate_hz is not None and rate > max_rate_hz:
            raise AudioFileError(f"audio file {show_text(name)}: sample rate {rate:g} Hz is too high; allowed: up to "
                                 f"{max_rate_hz:g} Hz")
        most = None if max_duration_s is None else int(np.floor(max_duration_s * rate))
        if most is not None and sound.frames > most:
            raise _too_long(name, sound.frames / rate, max_duration_s)
        block = max(1, READ_BLOCK_VALUES // max(1, channels))
        parts, frames = [], 0
        try:
            while True:
                chunk = sound.read(block, dtype="float64", always_2d=True)
                if chunk.shape[0] == 0:
                    break
                frames += chunk.shape[0]
                if most is not None and frames > most:
                    raise _too_long(name, frames / rate, max_duration_s, "at least ")
                parts.append(chunk.mean(axis=1) if channels > 1 else chunk[:, 0].copy())
        except (RuntimeError, soundfile.SoundFileError, ValueError) as exc:
            raise AudioFormatError(f"audio file {show_text(name)}: cannot be read as WAV, FLAC or OGG "
                                   f"({_reason(exc)})") from None
    if frames == 0:
        raise AudioFileError(f"audio file {show_text(name)}: contains no samples")
    mono = np.concatenate(parts)
    _check_finite(name, mono)
    return mono, rate


def _reason(exc: BaseException) -> str:
    """libsndfile's own words for an error (not the repr of the buffer it read from), on one line."""
    text = getattr(exc, "error_string", None) or str(exc)
    return " ".join(str(text).split()) or type(exc).__name__


def _too_long(name: str, seconds: float, max_duration_s: float | None, what: str = "") -> AudioFileError:
    return AudioFileError(f"audio file {show_text(name)}: is {what}{seconds:.4g} s long; allowed: up to "
                          f"{max_duration_s:g} s")


def _check_rate(name: str, rate: float) -> None:
    if rate < MIN_AUDIO_RATE_HZ:
        raise AudioFileError(
            f"audio file {show_text(name)}: sample rate {rate} Hz is too low; allowed: at least "
            f"{MIN_AUDIO_RATE_HZ:g} Hz"
        )


def _check_finite(name: str, mono: Any) -> None:
    import numpy as np

    if not np.all(np.isfinite(mono)):
        raise AudioFileError(f"audio file {show_text(name)}: contains non-finite samples")


def output_format(path: Path) -> str:
    """The file format (``"WAV"``, ``"FLAC"`` or ``"OGG"``) an output path's extension asks for."""
    return AUDIO_FORMATS[check_extension(path, "parameter output =", tuple(AUDIO_FORMATS))]


def output_subtype(fmt: str, subtype: str, sample_rate: float, suffix: str) -> str:
    """The libsndfile subtype to write ``fmt`` with, given the sample format asked for.

    OGG files are Vorbis: they take only the default ``subtype`` (PCM_24, which then
    means nothing) and rates up to :data:`MAX_OGG_RATE`. ``suffix`` is the output
    file's extension, for the message when the format cannot hold the subtype.
    """
    import soundfile

    if fmt == "OGG" and subtype != "PCM_24":
        raise ParameterError(f"parameter subtype = {subtype!r} does not apply to .ogg files")
    if fmt == "OGG" and sample_rate > MAX_OGG_RATE:
        raise ParameterError(f"parameter sample_rate = {sample_rate:g} is too high for .ogg files; "
                             f"allowed: up to {MAX_OGG_RATE:g} Hz")
    file_subtype = "VORBIS" if fmt == "OGG" else subtype
    if not soundfile.check_format(fmt, file_subtype):
        raise ParameterError(f"parameter subtype = {subtype!r} cannot be written to "
                             f"{suffix} files; allowed: PCM_16 or PCM_24")
    return file_subtype


def write_audio(path: str | os.PathLike[str], samples: Any, sample_rate: float, *, fmt: str,
                subtype: str) -> None:
    """Write ``samples`` to ``path`` as ``fmt`` (see :func:`output_format`) and libsndfile ``subtype``."""
    import soundfile

    soundfile.write(path, samples, int(sample_rate), format=fmt, subtype=subtype)


def wav_bytes(samples: Any, sample_rate: float) -> bytes:
    """A mono 16-bit PCM WAV file of ``samples``, which every browser plays."""
    import io

    import soundfile

    buffer = io.BytesIO()
    soundfile.write(buffer, samples, int(round(sample_rate)), format="WAV", subtype="PCM_16")
    return buffer.getvalue()
