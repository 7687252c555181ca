"""A listening test's configuration (TOML): its clips, MUSHRA pages and A/B pairs.

Everything is checked and every clip is loaded or rendered when the file is read,
so a malformed config, a missing or unreadable audio file, an unsupported WAV or a
bad model parameter is one clear error at start-up, never a failure mid-test.

    [test]
    title = "How real is this ruler?"
    sample_rate = 48000            # every clip is rendered or resampled to this rate (Hz)

    [[clips]]
    id = "real1"
    file = "recordings/ruler1.wav" # relative to this file

    [[clips]]
    id = "proposed1"
    model = "twang"
    preset = "plastic-30cm"
    parameters = { q = 120 }
    duration_s = 2.0
    seed = 1

    [[mushra]]                     # one page; clips shown in random order
    clips = ["real1", "proposed1"]

    [[ab]]                         # which one is real?
    real = "real1"
    synthetic = "proposed1"
    label = "proposed"             # how the report names it (default: the clip id)
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..checks import show_text
from ..errors import BarsynthError

MIN_CLIP_RATE_HZ = 8000     # what every browser plays
MAX_CLIP_RATE_HZ = 192000
MAX_CLIP_S = 120.0          # a listening-test clip, not an album
_ID = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
_TOP_KEYS = {"test", "clips", "mushra", "ab"}
_TEST_KEYS = {"title", "sample_rate"}
_CLIP_KEYS = {"id", "file", "model", "preset", "parameters", "duration_s", "seed"}
_PAGE_KEYS = {"clips"}
_AB_KEYS = {"real", "synthetic", "label"}


class ConfigError(BarsynthError, ValueError):
    """A listening-test config that cannot be run."""


@dataclass(frozen=True)
class Clip:
    """One clip, loaded or rendered: mono float32 samples at ``sample_rate`` Hz."""

    id: str
    samples: np.ndarray
    sample_rate: float
    source: str


@dataclass(frozen=True)
class ABPair:
    real: str
    synthetic: str
    label: str


@dataclass(frozen=True)
class ListeningTest:
    title: str
    clips: dict[str, Clip]
    pages: tuple[tuple[str, ...], ...]
    ab_pairs: tuple[ABPair, ...]


def _keys(where: str, table: Any, allowed: set[str], path: Path) -> dict:
    if not isinstance(table, dict):
        raise ConfigError(f"config {show_text(path)}: {where} must be a table")
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise ConfigError(f"config {show_text(path)}: {where} has unknown key {show_text(repr(unknown[0]))}; "
                          f"allowed: {', '.join(sorted(allowed))}")
    return table


def load_test(path: str | Path) -> ListeningTest:
    """Read, check and prepare a listening test (loads and renders every clip)."""
    from ..models.rendering import check_sample_rate

    from ..checks import check_input_file

    path = Path(path)
    try:
        check_input_file(path, "config")  # a FIFO would hang the read, a device never end
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except BarsynthError as exc:
        raise ConfigError(str(exc)) from None
    except FileNotFoundError:
        raise ConfigError(f"config {show_text(path)}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"config {show_text(path)}: cannot be read ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"config {show_text(path)}: not valid TOML ({exc})") from None
    _keys("the file", doc, _TOP_KEYS, path)
    head = _keys("[test]", doc.get("test", {}), _TEST_KEYS, path)
    title = str(head.get("title", "Listening test"))
    try:
        rate = check_sample_rate(head.get("sample_rate", 48000))
    except BarsynthError as exc:
        raise ConfigError(f"config {show_text(path)}: [test] {exc}") from None
    if rate > MAX_CLIP_RATE_HZ:
        raise ConfigError(f"config {show_text(path)}: [test] sample_rate = {rate:g} Hz is more than browsers play; "
                          f"allowed: up to {MAX_CLIP_RATE_HZ} Hz")

    clips: dict[str, Clip] = {}
    entries = doc.get("clips", [])
    if not isinstance(entries, list) or not entries:
        raise ConfigError(f"config {show_text(path)}: needs at least one [[clips]] entry")
    for number, entry in enumerate(entries, start=1):
        entry = _keys(f"[[clips]] #{number}", entry, _CLIP_KEYS, path)
        clip_id = entry.get("id")
        where = f"[[clips]] #{number}"
        if not isinstance(clip_id, str) or not _ID.match(clip_id):
            raise ConfigError(f"config {show_text(path)}: {where} needs an id of 1-64 letters, digits, '-' or '_'")
        if clip_id in clips:
            raise ConfigError(f"config {show_text(path)}: {where}: id {clip_id!r} is used twice")
        clips[clip_id] = _clip(path, f"{where} ({clip_id})", clip_id, entry, rate)

    pages = []
    for number, page in enumerate(doc.get("mushra", []), start=1):
        page = _keys(f"[[mushra]] #{number}", page, _PAGE_KEYS, path)
        ids = page.get("clips")
        if not isinstance(ids, list) or len(ids) < 2:
            raise ConfigError(f"config {show_text(path)}: [[mushra]] #{number} needs clips = [at least 2 ids]")
        _known(path, f"[[mushra]] #{number}", ids, clips)
        if len(set(ids)) != len(ids):
            raise ConfigError(f"config {show_text(path)}: [[mushra]] #{number} lists a clip twice")
        pages.append(tuple(ids))
    pairs = []
    for number, pair in enumerate(doc.get("ab", []), start=1):
        pair = _keys(f"[[ab]] #{number}", pair, _AB_KEYS, path)
        real, synthetic = pair.get("real"), pair.get("synthetic")
        _known(path, f"[[ab]] #{number}", [real, synthetic], clips)
        if real == synthetic:
            raise ConfigError(f"config {show_text(path)}: [[ab]] #{number} compares {real!r} with itself")
        if any(p.real == real and p.synthetic == synthetic for p in pairs):
            raise ConfigError(f"config {show_text(path)}: [[ab]] #{number} repeats the pair {real!r} / {synthetic!r}")
        pairs.append(ABPair(real, synthetic, str(pair.get("label", synthetic))))
    if not pages and not pairs:
        raise ConfigError(f"config {show_text(path)}: needs at least one [[mushra]] page or [[ab]] pair")
    return ListeningTest(title, clips, tuple(pages), tuple(pairs))


def _known(path: Path, where: str, ids: list, clips: dict) -> None:
    for clip_id in ids:
        if clip_id not in clips:
            raise ConfigError(f"config {show_text(path)}: {where} names unknown clip {show_text(repr(clip_id))}; "
                              f"known: {', '.join(clips)}")


def _playable(path: Path, where: str, audio: Path, samples: np.ndarray, rate: float) -> None:
    """Refuse a recording a browser cannot play faithfully (checked at start-up)."""
    problem = None
    if not MIN_CLIP_RATE_HZ <= rate <= MAX_CLIP_RATE_HZ:
        problem = (f"sample rate {rate:g} Hz is not supported; allowed: {MIN_CLIP_RATE_HZ} to "
                   f"{MAX_CLIP_RATE_HZ} Hz")
    elif samples.size / rate > MAX_CLIP_S:
        problem = f"lasts {samples.size / rate:.1f} s; allowed: up to {MAX_CLIP_S:g} s"
    else:
        peak = float(np.max(np.abs(samples)))
        if peak == 0.0:
            problem = "is silent"
        elif peak > 1.0:
            problem = (f"peaks at {20 * np.log10(peak):+.1f} dBFS, above full scale; allowed: peaks up to "
                       "0 dBFS (it would clip when served)")
    if problem:
        raise ConfigError(f"config {show_text(path)}: {where}: audio file {show_text(audio)} {problem}")


def _clip(path: Path, where: str, clip_id: str, entry: dict, rate: float) -> Clip:
    has_file, has_model = "file" in entry, "model" in entry
    if has_file == has_model:
        raise ConfigError(f"config {show_text(path)}: {where} needs exactly one of file = ... or model = ...")
    if has_file:
        if set(entry) - {"id", "file"}:
            raise ConfigError(f"config {show_text(path)}: {where}: a file clip takes only id and file")
        from ..audio_io import load_audio

        audio = (path.parent / str(entry["file"])).resolve()
        try:
            samples, file_rate = load_audio(audio)
        except BarsynthError as exc:
            raise ConfigError(f"config {show_text(path)}: {where}: {exc}") from None
        _playable(path, where, audio, samples, file_rate)
        source = f"file {audio}"
        if file_rate != rate:  # every clip is served at one rate, so no header tells them apart
            from math import gcd

            from scipy.signal import resample_poly

            common = gcd(int(file_rate), int(rate))
            samples = resample_poly(samples, int(rate) // common, int(file_rate) // common)
            source += f" (resampled from {file_rate:g} Hz)"
        return Clip(clip_id, samples.astype(np.float32), rate, source)
    from ..models import get_model
    from ..presets import preset_parameters

    try:
        model = get_model(str(entry["model"]))
        layers = [preset_parameters(model.name, str(entry["preset"]))] if "preset" in entry else []
        parameters = entry.get("parameters", {})
        if not isinstance(parameters, dict):
            raise ConfigError("parameters must be a table of NAME = VALUE")
        resolved = model.table.resolve(*layers, parameters)
        samples = model.render(resolved, duration_s=entry.get("duration_s", 2.0), sample_rate=rate,
                               seed=entry.get("seed", 0))
    except BarsynthError as exc:
        raise ConfigError(f"config {show_text(path)}: {where}: {exc}") from None
    label = f"model {model.name}" + (f" preset {entry['preset']}" if "preset" in entry else "")
    return Clip(clip_id, samples, rate, label)
