"""Shared checks and helpers for rendering any model offline."""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

import numpy as np

from ..checks import check_number, check_whole, show_value
from ..errors import ParameterError, SamplesError
from ..parameters import table_of

MIN_SAMPLE_RATE = 8_000.0
MAX_SAMPLE_RATE = 384_000.0
MAX_DURATION_S = 600.0
NORMALIZE_PEAK_DBFS = -1.0
MAX_BLOCK_SAMPLES = int(MAX_DURATION_S * MAX_SAMPLE_RATE)  # the longest render at the highest rate

# duration_s="auto": render until the sound has fallen AUTO_QUIET_DB below its peak (the largest
# magnitude in the last AUTO_WINDOW_S against the largest so far, tested every AUTO_HOP_S), after
# any bow stroke is over, at most AUTO_MAX_S; then end with an AUTO_FADE_S raised-cosine fade.
# Both are measured on what can be heard: the samples high-passed at 20 Hz (dsp.biquad). A ruler's
# sway at a few hertz (the steel ruler's whole-length mode: 9 Hz, T60 97 s) is not heard, and
# waiting for it would take every such render to the cap.
AUTO = "auto"
AUTO_QUIET_DB = 90.0
AUTO_WINDOW_S = 0.05
AUTO_MAX_S = 60.0
AUTO_FADE_S = 0.02
AUTO_SILENT_S = 1.0  # a voice that gives only zeros this long (after any bow) is done
AUTO_HOP_S = 0.01  # the test is made every 10 ms of sound, so the length is a whole number of hops
# Renders run in blocks so a render can be interrupted (Ctrl-C) and watched: each block aims at
# BLOCK_WALL_S of computing time, between MIN_BLOCK_SAMPLES and MAX_BLOCK_S of sound. The voices
# give the same samples for any split into blocks (each model's tests), so the sound does not
# depend on the sizes.
BLOCK_WALL_S = 0.05
MIN_BLOCK_SAMPLES = 64
MAX_BLOCK_S = 0.25

# The largest raw sample (before any normalisation or gain) a model may give; beyond it the
# output is a numerical blow-up, not a sound. Raw output is the pick-up velocity in m/s times
# the level gain (level_db, at most +40 dB). Measured (0.3-0.5 s renders at 48 kHz, level_db
# at each model's maximum): every preset and 160 random in-range settings peak below 2.5e2 (fd),
# 5 (farnell), 2.1 (twang), 1.2e4 (banded) and 6e5 (allpass, heavy mallet near a clamped end);
# the worst corner found that is not a blow-up, banded struck at its end with the heaviest
# mallet, 1.7e8. Blow-ups grow exponentially and pass 1e30 within milliseconds (allpass plucked
# at a support: 6e34; fd plucked at the clamp: NaN from the first sample). 1e10 is 34 dB above
# that corner and 84 dB above any interior setting, and far below float overflow.
MAX_RAW_PEAK = 1e10
_MAX_SETTINGS_SHOWN = 6  # non-default parameters named in a samples error
_MAX_VALUE_CHARS = 24  # longest value shown in a samples error


def check_sample_rate(sample_rate: Any) -> float:
    """Validate a sample rate: a whole number of Hz from 8 kHz to 384 kHz (audio files
    store whole rates); text such as "48000" is parsed."""
    rate = check_number(
        "sample_rate", sample_rate, "Hz",
        minimum=MIN_SAMPLE_RATE, maximum=MAX_SAMPLE_RATE, parse_text=True,
    )
    if not rate.is_integer():
        raise ParameterError(
            f"parameter sample_rate = {show_value(sample_rate)} is not a whole number; "
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


def check_render_duration(duration_s: Any) -> float | str:
    """A render duration: ``"auto"`` (any case, see :func:`render_voice`) or a number of seconds
    as :func:`check_duration` takes."""
    if isinstance(duration_s, str) and duration_s.strip().lower() == AUTO:
        return AUTO
    try:
        return check_duration(duration_s)
    except ParameterError as exc:
        raise ParameterError(str(exc).replace("allowed: ", "allowed: auto, or ", 1)) from None


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
        raise ParameterError(f"parameter dtype = {show_value(dtype)} is not allowed; allowed: float32 or float64")
    return kind


class NeverQuietWarning(UserWarning):
    """A ``duration_s="auto"`` render reached :data:`AUTO_MAX_S` before the sound fell
    :data:`AUTO_QUIET_DB` below its peak (a voice that sustains, or a bow still moving)."""


_watcher: ContextVar[Callable[[float, float | None, float | None], None] | None] = ContextVar(
    "barsynth_render_watcher", default=None)


@contextmanager
def watching(callback: Callable[[float, float | None, float | None], None]) -> Iterator[None]:
    """Within the block, every render calls ``callback(done_s, total_s, below_peak_db)`` after
    each block of samples: the seconds rendered, the seconds asked for (None for ``"auto"``), and
    for ``"auto"`` how far the last 50 ms lie below the peak so far (dB; None while silent).
    The command line's progress line uses it; an exception it raises (or a Ctrl-C) ends the
    render between blocks."""
    token = _watcher.set(callback)
    try:
        yield
    finally:
        _watcher.reset(token)


def render_voice(voice: Any, duration_s: float | str, *, normalize: bool = True,
                 dtype: Any = np.float32) -> np.ndarray:
    """Trigger ``voice`` once and render ``duration_s`` seconds, as every model's
    ``render`` does: peak-normalised to -1 dBFS, or exactly the voice's samples when
    ``normalize`` is false; float32 or float64 (``dtype``).

    ``duration_s="auto"`` renders until the sound has fallen :data:`AUTO_QUIET_DB` (90 dB)
    below its peak, and not before a bow stroke is over (the bow lifted), at most
    :data:`AUTO_MAX_S` (60 s, then with a :class:`NeverQuietWarning`); the last
    :data:`AUTO_FADE_S` (20 ms) are faded out with a raised cosine so the sound ends at 0.
    A number of seconds gives exactly the voice's samples (no fade).
    """
    dtype = check_dtype(dtype)
    duration = check_render_duration(duration_s)
    if duration == AUTO:
        samples = _render_until_quiet(voice)
    else:
        count = int(round(duration * voice.sample_rate))
        if count < 1:
            raise ParameterError(
                f"parameter duration_s = {show_value(duration_s)} is shorter than one sample; allowed: at "
                f"least {1.0 / voice.sample_rate:.3g} s at {voice.sample_rate:g} Hz"
            )
        samples = np.empty(count)
        voice.trigger()
        for start, block in _blocks(voice, count):
            samples[start:start + block.size] = block
            _report(start + block.size, count, voice.sample_rate)
    if normalize:
        return normalize_peak(samples, dtype=dtype)
    return samples.astype(dtype, copy=False)


def _report(done: int, total: int | None, sample_rate: float, below_peak_db: float | None = None) -> None:
    watcher = _watcher.get()
    if watcher is not None:
        watcher(done / sample_rate, None if total is None else total / sample_rate, below_peak_db)


def _blocks(voice: Any, limit: int) -> Iterator[tuple[int, np.ndarray]]:
    """``(start, samples)``: the voice's raw samples, checked, block after block up to ``limit``
    samples (the caller may stop sooner), each block sized to take about BLOCK_WALL_S to compute."""
    rate = voice.sample_rate
    parameters = voice.parameters
    largest = max(MIN_BLOCK_SAMPLES, int(MAX_BLOCK_S * rate))
    size = min(largest, int(0.01 * rate))
    done = 0
    while done < limit:
        n = min(size, limit - done)
        started = time.perf_counter()
        block = voice.process(n, dtype=np.float64)
        spent = time.perf_counter() - started
        check_samples(block, parameters, rate, start=done)
        yield done, block
        done += n
        # the next block: about BLOCK_WALL_S of computing, at most 4 times this one
        wanted = n * BLOCK_WALL_S / spent if spent > 0.0 else 4 * n
        size = int(min(largest, 4 * n, max(MIN_BLOCK_SAMPLES, wanted)))


def _render_until_quiet(voice: Any) -> np.ndarray:
    """The raw samples of ``duration_s="auto"`` (see :func:`render_voice`), faded out."""
    from ..dsp.biquad import AUDIBLE_FROM_HZ, high_pass, run_biquad

    rate = voice.sample_rate
    cap = int(round(AUTO_MAX_S * rate))
    window = max(1, int(round(AUTO_WINDOW_S * rate)))
    quiet = 10.0 ** (-AUTO_QUIET_DB / 20.0)
    samples = np.empty(cap)  # pages never written are never touched
    voice.trigger()
    # a bowed voice sustains while its bow touches the bar: wait until it is lifted
    lifted_at = int(voice.driven_until)
    hop = max(1, int(round(AUTO_HOP_S * rate)))
    heard = np.empty(cap)  # the samples as heard: high-passed at AUDIBLE_FROM_HZ
    audible, state = high_pass(AUDIBLE_FROM_HZ, rate), np.zeros(2)
    peak, level, checked, done, stop = 0.0, 0.0, 0, 0, None
    for start, block in _blocks(voice, cap):
        done = start + block.size
        samples[start:done] = block
        run_biquad(block, audible, state, heard[start:done])
        # the test at every hop from the start, in order: where the sound ends does not depend
        # on the sizes of the blocks (which follow the computer's speed)
        while stop is None and checked + hop <= done:
            new = heard[checked:checked + hop]
            peak = max(peak, float(np.max(new)), -float(np.min(new)))
            checked += hop
            last = heard[max(0, checked - window):checked]
            level = max(float(np.max(last)), -float(np.min(last)))
            if checked >= lifted_at + window and ((peak > 0.0 and level <= quiet * peak) or (
                    peak == 0.0 and checked >= lifted_at + AUTO_SILENT_S * rate)):
                stop = checked
        _report(done, None, rate, 20.0 * np.log10(level / peak) if level > 0.0 and peak > 0.0 else None)
        if stop is not None:
            done = stop
            break
    else:
        still_bowed = done < lifted_at
        below = -20.0 * np.log10(level / peak) if level > 0.0 and peak > 0.0 else 0.0
        why = ("the bow is still on the bar" if still_bowed else
               f"the sound is only {below:.0f} dB below its peak, not {AUTO_QUIET_DB:g}")
        warnings.warn(f"duration auto stopped at its cap of {AUTO_MAX_S:g} s: {why}; ended with a "
                      f"{AUTO_FADE_S * 1000:g} ms fade (give a number of seconds for a longer sound)",
                      NeverQuietWarning, stacklevel=3)
    samples = samples[:done].copy()
    return fade_out(samples, int(round(AUTO_FADE_S * rate)))


def fade_out(samples: np.ndarray, length: int) -> np.ndarray:
    """``samples`` with the last ``length`` samples (or all, when fewer) multiplied, in place, by a
    raised-cosine fade that ends at exactly 0: ``0.5 (1 + cos(pi k / length))``, k = 1 ... length.

    >>> fade_out(np.ones(4), 2)
    array([1. , 1. , 0.5, 0. ])
    """
    n = min(length, samples.size)
    if n > 0:
        k = np.arange(1, n + 1)
        samples[samples.size - n:] *= 0.5 * (1.0 + np.cos(np.pi * k / n))
    return samples


def normalize_peak(samples: np.ndarray, peak_dbfs: float = NORMALIZE_PEAK_DBFS,
                   *, dtype: Any = None) -> np.ndarray:
    """``samples`` scaled so the largest magnitude is ``peak_dbfs`` dBFS, as ``dtype``
    (the input's by default); silence stays silence. One pass, no temporaries."""
    out = np.empty(samples.shape, dtype=dtype or samples.dtype)
    peak = max(float(samples.max()), -float(samples.min())) if samples.size else 0.0
    scale = 10.0 ** (peak_dbfs / 20.0) / peak if peak > 0.0 else 1.0
    np.multiply(samples, scale, out=out, casting="same_kind")
    return out


def _short(value: Any) -> str:
    if isinstance(value, tuple):
        text = ",".join(_short(x) for x in value) or "-"
    elif isinstance(value, float):
        text = f"{value:g}"
    else:
        text = str(value)
    text = " ".join(text.split())
    return text if len(text) <= _MAX_VALUE_CHARS else text[:_MAX_VALUE_CHARS - 3] + "..."


def settings_text(parameters: Any) -> str:
    """``model fd with bc=clamped-free, excitation=pluck, ...``: a model's resolved parameters as one
    short line (the values that differ from the defaults, each shortened; at most a few of them)."""
    table = table_of(parameters)
    if table is None:
        return "the model"
    changed = [(p.name, getattr(parameters, p.name)) for p in table
               if getattr(parameters, p.name) != p.default]
    if not changed:
        return f"model {table.model} with its default parameters"
    shown = ", ".join(f"{name}={_short(value)}" for name, value in changed[:_MAX_SETTINGS_SHOWN])
    more = len(changed) - _MAX_SETTINGS_SHOWN
    return f"model {table.model} with {shown}" + (f" and {more} more" if more > 0 else "")


def check_samples(samples: np.ndarray, parameters: Any, sample_rate: float, *, start: int = 0) -> np.ndarray:
    """``samples`` (a model's raw output) if every one is finite and at most ``MAX_RAW_PEAK`` in
    magnitude; else :class:`~barsynth.errors.SamplesError`, one line naming the model, its settings
    (``parameters``, the resolved dataclass) and when the trouble begins (``start``: the index of
    the first sample in the whole sound). Every path that computes samples calls it: renders (CLI,
    studio, listening tests), the studio's pictures and its live stream.

    >>> check_samples(np.zeros(4), None, 48000.0)
    array([0., 0., 0., 0.])
    """
    if samples.size == 0:
        return samples
    with np.errstate(invalid="ignore"):
        peak = max(float(np.max(samples)), -float(np.min(samples)))
    if peak <= MAX_RAW_PEAK:  # False for NaN
        return samples
    flat = samples.reshape(-1)
    finite = np.isfinite(flat)
    if not finite.all():
        first = int(np.argmax(~finite))
        kind = "NaN" if np.isnan(flat[first]) else "infinite"
        what = f"non-finite samples ({kind} from {(start + first) / sample_rate:.3g} s)"
    else:
        first = int(np.argmax(np.abs(flat) > MAX_RAW_PEAK))
        what = (f"exploding samples (peak {peak:.2g}, beyond {MAX_RAW_PEAK:g}, from "
                f"{(start + first) / sample_rate:.3g} s)")
    raise SamplesError(f"{settings_text(parameters)} gives {what}; nothing is played or written "
                       "(a numerical blow-up: change these settings)")
