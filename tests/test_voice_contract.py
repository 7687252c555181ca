"""The voice contract (models/base.py), measured on the sounds of every registered model.

Every test is parametrised over ``model_names()``, so a new model is covered the day it
is registered. What is checked is what ``Voice`` and ``Model`` declare:

- blocks of any size (and random splits, and timed events) give the offline render's
  samples exactly, for the default settings and every excitation the table offers;
- ``process(n, out=buf)`` writes the very samples of ``process(n)`` into a caller's float64
  or float32 buffer, returns it, refuses a wrong one (naming ``out``) and allocates nothing;
- ``prepare(sample_rate, max_block)`` from 8 kHz to 192 kHz: a voice prepared again is a
  voice made at that rate, the modes below a quarter of the lowest rate stay where they
  are (where the model is rate-independent) and the sound agrees; a refused rate or block
  size changes nothing;
- seeds: the same seed, the same samples; another seed changes the sound exactly where
  the voice class declares ``uses_seed``;
- the declared capabilities: ``restarts_on_trigger`` (a restart is a fresh note; otherwise
  the strike adds to what rings), ``can_release`` (a bow stroke stops; otherwise release()
  changes nothing), ``reports_reference_errors`` (finite errors_cents, or NotImplementedError);
- changes while sounding (set_parameters, trigger, release): finite, bounded and, where the
  voice glides the change, without a click (the crossfade tests' step ratio); a refused
  change leaves the parameters and the sound as they were;
- random settings in range (Hypothesis, derandomized): a one-line ParameterError or finite
  samples below ``MAX_RAW_PEAK``; every case ever found stays as an ``@example``.

The renders are short (0.05 to 0.3 s); ``FAST`` keeps the finite-difference bar on a
coarse grid. Model physics (frequencies against the beam equation, decays, mallet and
pluck levels, bowing regions) stays in each model's own test file.
"""

from __future__ import annotations

import copy
import functools
import math
import tracemalloc

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from barsynth.errors import BarsynthError, ParameterError
from barsynth.exciters import EXCITERS, Bow
from barsynth.models import get_model, model_names
from barsynth.models.rendering import MAX_RAW_PEAK
from barsynth.parameters import BOOL, CHOICE, FLOATS
from streaming import play

MODELS = model_names()
RATE = 48000
MS = RATE // 1000
RATES = (8000, 22050, 44100, 48000, 96000, 192000)

FAST = {"fd": {"points": 30, "oversampling": 2}}
"""Settings under which each model renders quickly, used by every test here (the rest of each
model's table at its defaults). The finite-difference bar costs points x oversampling per
sample: 30 points at 2 steps a sample instead of 100 at 4 (its modes move a few cents; nothing
here depends on where they are)."""

RANDOM_RANGES = {"fd": {"points": (8, 80)}}
"""Narrower ranges for the random-settings test (whole numbers, inclusive), only for speed: the
finite-difference bar's cost grows with its grid."""

NOISE_FREE = {"twang": {"free_bar_gain": 0.0}}
"""Settings that silence a seeded voice's noise (the twang's free-bar bands), where the model
has them, so a restarted note can be compared with a fresh one sample for sample. Farnell's
twang has none: its noise always sounds."""

NOISY_GROUPS = {"twang": {"free-bar"}, "farnell": {"free-bar"}}
"""describe() groups that are filtered noise: no steady partial to measure (a new model whose
modes include noise bands names them here, or its measured-partial test measures noise)."""

SPURIOUS_GROUPS = {"spurious"}
"""describe() groups that are a model's own artefacts far below its modes (the all-pass loop's)."""

DESCRIBE_CENTS = {"allpass": 0.5, "fd": None}
"""How far (cents) describe()'s modes below a quarter of the lowest rate may move between rates.
0 (to rounding) for a model whose modes do not depend on the rate; the all-pass bar fits its
dispersion filters anew at each rate (within 0.1 cent measured); the finite-difference scheme's
time step warps its frequencies (None: rate-dependent; at 8 kHz with 2 steps a sample its
second mode rings 51 cents flat), which the measured test below follows instead."""

COUPLED = {("fd", "strike")}
"""(model, excitation) pairs whose exciter is solved with the bar (the fd mallet's contact
force depends on how the bar moves), besides every bow: two notes are not exactly the sum of
each alone. Every other strike and pluck is an uncoupled force (or a static shape) on a
linear resonator."""

REFUSED_COMBINATIONS = {
    "banded": {"length_m": 3.0, "thickness_m": 0.0003},  # each in range; no mode above 30 Hz
    "allpass": {"length_m": 3.0, "thickness_m": 0.0003},  # the first mode below 1 Hz
    "fd": {"theta": 1.0},  # unstable at this grid and step
}
"""Values each in range that a model refuses together (set_parameters must roll back)."""

MAX_STEP_RATIO = 1.5  # as tests/test_crossfade.py
MAX_SWEEP_RATIO = 2.0  # a change that sweeps the modes by octaves (steel for acrylic: x7.8 in pitch)
SWEEP_FACTOR = 4.0


def model_settings(name: str, **extra) -> dict:
    return {**FAST.get(name, {}), **extra}


def excitations(name: str) -> tuple:
    """The ``excitation`` of each exciter the model declares (None: a model that is its own excitation)."""
    return tuple(e.name for e in get_model(name).exciters) or (None,)


def excited(name: str, excitation: str | None, *, long_bow: bool = False, **extra) -> dict:
    """The fast settings with ``excitation``. A bow stroke short enough that its stop (and, in
    the longer renders, the bow's lift 0.5 s later) falls inside the render; or, with
    ``long_bow``, one that lasts 10 s (longer than any render here)."""
    p = model_settings(name)
    if excitation is not None:
        p["excitation"] = excitation
    if excitation == "bow":
        p.update({"bow_duration_s": 10.0} if long_bow else {"bow_duration_s": 0.02, "bow_ramp_ms": 5.0})
    return {**p, **extra}


CASES = [pytest.param(name, ex, id=f"{name}-{ex}" if ex else name) for name in MODELS for ex in excitations(name)]
BOWED = [name for name in MODELS if Bow in get_model(name).exciters]


def voice_class(name: str) -> type:
    return type(get_model(name).voice(model_settings(name)))


def fresh(name: str, parameters: dict, *, rate: int = RATE, seed: int = 0, **kw):
    return get_model(name).voice(parameters, sample_rate=rate, seed=seed, **kw)


def raw(name: str, parameters: dict, seconds: float, *, rate: int = RATE, seed: int = 0) -> np.ndarray:
    return get_model(name).render(parameters, duration_s=seconds, sample_rate=rate, seed=seed, normalize=False,
                                  dtype=np.float64)


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x ** 2)))


def largest_step(x: np.ndarray) -> float:
    return float(np.max(np.abs(np.diff(x)))) if x.size > 1 else 0.0


def step_ratio(x: np.ndarray, change: int) -> float:
    """tests/test_crossfade.py's click measure: the largest sample-to-sample step from 2 ms
    before to 15 ms after ``change``, over the larger of the largest steps in the 20 ms
    before it and in the 20 ms after that."""
    before = largest_step(x[change - 20 * MS:change])
    across = largest_step(x[change - 2 * MS:change + 15 * MS])
    after = largest_step(x[change + 15 * MS:change + 35 * MS])
    return across / max(before, after, 1e-300)


def duration_for(excitation: str | None) -> float:
    return 0.55 if excitation == "bow" else 0.1


@functools.lru_cache(maxsize=None)
def offline(name: str, excitation: str | None) -> np.ndarray:
    p = excited(name, excitation)
    return raw(name, p, duration_for(excitation), seed=3)


def in_blocks(name: str, excitation: str | None, sizes) -> np.ndarray:
    voice = fresh(name, excited(name, excitation), seed=3)
    voice.trigger()
    return np.concatenate([voice.process(n, dtype=np.float64) for n in sizes])


# -- blocks ------------------------------------------------------------------------------------
@pytest.mark.parametrize("block", [1, 7, 64, 256, 1000])
@pytest.mark.parametrize("name,excitation", CASES)
def test_blocks_of_any_size_equal_the_offline_render(name, excitation, block):
    whole = offline(name, excitation)
    assert np.max(np.abs(whole)) > 0.0
    sizes = [block] * (whole.size // block) + ([whole.size % block] if whole.size % block else [])
    assert np.array_equal(in_blocks(name, excitation, sizes), whole)


@pytest.mark.parametrize("name,excitation", CASES)
@settings(max_examples=8)
@given(st.lists(st.integers(min_value=0, max_value=3000), min_size=1, max_size=30))
def test_random_block_splits_equal_the_offline_render(name, excitation, sizes):
    whole = offline(name, excitation)
    cuts = sorted(min(int(c), whole.size) for c in np.cumsum(sizes))
    sizes = np.diff([0, *cuts, whole.size]).tolist()  # random splits (empty blocks too), ending with the rest
    assert np.array_equal(in_blocks(name, excitation, sizes), whole)


@pytest.mark.parametrize("block", [1, 7, 64, 1000])
@pytest.mark.parametrize("name", MODELS)
def test_blocks_with_events_equal_one_long_block(name, block):
    """A trigger, a change, a second trigger and a release, each at its sample whatever the blocks."""
    events = {0: ("trigger", {}), 1000: ("set", {"level_db": -6.0}), 2500: ("trigger", {}), 4000: ("release", {})}
    whole = play(fresh(name, model_settings(name)), events, 6000, 6000)
    assert np.max(np.abs(whole)) > 0.0
    assert np.array_equal(play(fresh(name, model_settings(name)), events, 6000, block), whole)


# -- process into a caller's buffer ----------------------------------------------------------------
def _twins(name: str, *, max_block: int | None = None):
    kw = {} if max_block is None else {"max_block": max_block}
    voices = [fresh(name, model_settings(name), **kw) for _ in range(2)]
    for voice in voices:
        voice.trigger()
    return voices


@pytest.mark.parametrize("kind", [np.float64, np.float32])
@pytest.mark.parametrize("name", MODELS)
def test_process_into_a_buffer_gives_the_samples_of_process(name, kind):
    """Blocks below, at and above ``max_block`` (a float32 buffer is filled in pieces of it)."""
    mine, reference = _twins(name, max_block=64)
    for n in (0, 1, 63, 64, 65, 1000):
        expected = reference.process(n, dtype=np.float64).astype(kind)
        buf = np.full(n, np.nan, dtype=kind)
        assert mine.process(n, out=buf) is buf
        assert np.array_equal(buf, expected), n


BAD_BUFFERS = {
    "too short": lambda n: np.empty(n - 1),
    "too long": lambda n: np.empty(n + 1),
    "2-D": lambda n: np.empty((1, n)),
    "int": lambda n: np.empty(n, dtype=np.int32),
    "float16": lambda n: np.empty(n, dtype=np.float16),
    "complex": lambda n: np.empty(n, dtype=np.complex128),
    "read-only": lambda n: np.lib.stride_tricks.as_strided(np.empty(n), writeable=False),
    "strided": lambda n: np.empty(2 * n)[::2],
    "list": lambda n: [0.0] * n,
}


@pytest.mark.parametrize("bad", BAD_BUFFERS)
@pytest.mark.parametrize("name", MODELS)
def test_a_wrong_buffer_is_refused_and_changes_nothing(name, bad):
    mine, reference = _twins(name)
    with pytest.raises(ParameterError, match="out"):
        mine.process(64, out=BAD_BUFFERS[bad](64))
    assert np.array_equal(mine.process(500, dtype=np.float64), reference.process(500, dtype=np.float64))


ALLOCATION_SLACK_BYTES = 2048
"""What 200 calls of process(256, out=buf) may leave allocated, or allocate at their peak,
beyond what was allocated before them: less than the 2 KiB of one 256-sample float64 block.
(tracemalloc sees Python and NumPy allocations; memory numba's kernels allocate themselves
is not traced.)"""


@pytest.mark.parametrize("kind", [np.float64, np.float32])
@pytest.mark.parametrize("name,excitation", CASES)
def test_process_into_a_buffer_allocates_nothing(name, excitation, kind):
    voice = fresh(name, excited(name, excitation, long_bow=True), max_block=256)
    voice.trigger()
    buf = np.empty(256, dtype=kind)
    tracemalloc.start()
    try:
        # warm-up under tracemalloc (lazy allocations, numba's dispatch caches, the bow's start:
        # blocks allocated before it started and freed after would hide new ones)
        for _ in range(2000):
            voice.process(256, out=buf)
        before, _ = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        for _ in range(500):
            voice.process(256, out=buf)
        after, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert after - before < ALLOCATION_SLACK_BYTES, f"{after - before} bytes kept over 500 calls"
    assert peak - before < ALLOCATION_SLACK_BYTES, f"{peak - before} bytes allocated within a call"
    assert np.all(np.isfinite(buf))


# -- sample rates ----------------------------------------------------------------------------------
@pytest.mark.parametrize("rate", RATES)
@pytest.mark.parametrize("name", MODELS)
def test_a_voice_prepared_at_any_rate_is_a_voice_made_at_it(name, rate):
    voice = fresh(name, model_settings(name))
    voice.prepare(rate, 512)
    assert voice.sample_rate == rate
    voice.trigger()
    x = voice.process(int(0.05 * rate), dtype=np.float64)
    assert np.all(np.isfinite(x)) and np.max(np.abs(x)) > 0.0
    made = fresh(name, model_settings(name), rate=rate)
    made.trigger()
    assert np.array_equal(x, made.process(x.size, dtype=np.float64))


def _tonal_modes(name: str, rate: int, top_hz: float) -> list:
    skip = NOISY_GROUPS.get(name, set()) | SPURIOUS_GROUPS
    return [m for m in get_model(name).describe(model_settings(name, **NOISE_FREE.get(name, {})), sample_rate=rate)
            if m.group not in skip and m.frequency_hz < top_hz]


@pytest.mark.parametrize("name", MODELS)
def test_the_modes_below_a_quarter_of_the_lowest_rate_stay_put(name):
    tolerance = DESCRIBE_CENTS.get(name, 1e-6)
    if tolerance is None:
        pytest.skip(f"{name}'s modes depend on the rate (DESCRIBE_CENTS); the measured test follows them")
    top = min(RATES) / 4
    reference = _tonal_modes(name, RATE, top)
    assert reference
    for rate in RATES:
        modes = _tonal_modes(name, rate, top)
        assert [m.group for m in modes] == [m.group for m in reference], rate
        for m, r in zip(modes, reference):
            assert abs(1200 * math.log2(m.frequency_hz / r.frequency_hz)) <= tolerance, (rate, m, r)


def _peak_hz(x: np.ndarray, rate: int, low: float, high: float) -> float:
    """The strongest spectral peak between ``low`` and ``high`` Hz (Hann window, zero-padded,
    parabolic interpolation on the log magnitude)."""
    pad = 1 << 18
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size), pad))
    freqs = np.fft.rfftfreq(pad, 1 / rate)
    i = int(np.argmax(np.where((freqs > low) & (freqs < high), spectrum, 0.0)))
    a, b, c = np.log(spectrum[i - 1:i + 2])
    return (i + 0.5 * (a - c) / (a - 2 * b + c)) * rate / pad


MEASURED_CENTS = 2.0


@pytest.mark.parametrize("name", MODELS)
def test_the_strongest_partial_sounds_alike_at_every_rate(name):
    """The loudest steady mode (between 50 Hz and a quarter of 8 kHz, no other within 10 %)
    measured at each rate moves from 48 kHz's by what describe() says it moves (nothing for a
    rate-independent model), within MEASURED_CENTS."""
    p = model_settings(name, **NOISE_FREE.get(name, {}))
    everything = get_model(name).describe(p, sample_rate=RATE)

    def isolated(m) -> bool:
        return not any(o.frequency_hz != m.frequency_hz and abs(o.gain) > 0
                       and abs(o.frequency_hz / m.frequency_hz - 1) < 0.1 for o in everything)

    candidates = [m for m in _tonal_modes(name, RATE, min(RATES) / 4) if m.frequency_hz > 50.0 and isolated(m)]
    assert candidates, "no isolated steady mode to measure"
    target = max(candidates, key=lambda m: abs(m.gain))
    found = {}
    for rate in RATES:
        voice = fresh(name, p, rate=rate)
        voice.trigger()
        x = voice.process(int(0.3 * rate), dtype=np.float64)
        assert np.all(np.isfinite(x))
        described = min(_tonal_modes(name, rate, rate / 2), key=lambda m: abs(m.frequency_hz - target.frequency_hz))
        found[rate] = (_peak_hz(x, rate, 0.92 * described.frequency_hz, 1.08 * described.frequency_hz),
                       described.frequency_hz)
    measured_48, described_48 = found[RATE]
    for rate, (measured, described) in found.items():
        moved = 1200 * math.log2(measured / measured_48)
        expected = 1200 * math.log2(described / described_48)
        assert abs(moved - expected) <= MEASURED_CENTS, (rate, moved, expected)


REFUSED_RATES = [7999, 0, -48000, "abc", float("nan"), 44100.5, 1e6, None]


@pytest.mark.parametrize("rate", REFUSED_RATES, ids=str)
@pytest.mark.parametrize("name", MODELS)
def test_a_refused_rate_leaves_the_voice_playing_at_its_old_rate(name, rate):
    mine, reference = _twins(name)
    for voice in (mine, reference):
        voice.process(300)
    with pytest.raises(ParameterError, match="sample_rate"):
        mine.prepare(rate)
    assert mine.sample_rate == RATE
    assert np.array_equal(mine.process(1000, dtype=np.float64), reference.process(1000, dtype=np.float64))


REFUSED_AT_RATE = {"banded": ({"tuning": "ratios", "frequency_hz": 3000.0, "mode_ratios": (1.0,)}, 8000)}
"""A setting and a valid rate the model itself refuses (its _prepare raises: the only mode above
a quarter of 8 kHz), so the base must keep the old rate and design."""


@pytest.mark.parametrize("name", list(REFUSED_AT_RATE))
def test_a_rate_the_model_refuses_leaves_the_voice_playing_at_its_old_rate(name):
    p, rate = REFUSED_AT_RATE[name]
    mine, reference = (fresh(name, model_settings(name, **p)) for _ in range(2))
    for voice in (mine, reference):
        voice.trigger()
        voice.process(300)
    with pytest.raises(ParameterError) as info:
        mine.prepare(rate)
    assert "\n" not in str(info.value) and mine.sample_rate == RATE
    assert np.array_equal(mine.process(1000, dtype=np.float64), reference.process(1000, dtype=np.float64))


@pytest.mark.parametrize("max_block", [0, -1, 2.5, "x", 10 ** 12])
@pytest.mark.parametrize("name", MODELS)
def test_a_refused_block_size_changes_nothing(name, max_block):
    mine, reference = _twins(name)
    with pytest.raises(ParameterError, match="max_block"):
        mine.prepare(RATE, max_block)
    assert mine.sample_rate == RATE
    assert np.array_equal(mine.process(1000, dtype=np.float64), reference.process(1000, dtype=np.float64))


@pytest.mark.parametrize("name,excitation", CASES)
def test_silence_before_the_first_trigger_and_after_reset(name, excitation):
    voice = fresh(name, excited(name, excitation))
    assert not np.any(voice.process(1000, dtype=np.float64))
    voice.trigger()
    assert np.any(voice.process(1000, dtype=np.float64))
    voice.reset()
    assert not np.any(voice.process(1000, dtype=np.float64))


# -- seeds -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("name,excitation", CASES)
def test_seeds(name, excitation):
    p = excited(name, excitation)
    a, b, other = raw(name, p, 0.1, seed=5), raw(name, p, 0.1, seed=5), raw(name, p, 0.1, seed=6)
    assert np.array_equal(a, b)
    if voice_class(name).uses_seed:
        assert not np.array_equal(a, other)
    else:
        assert np.array_equal(a, other)
        assert np.array_equal(a, raw(name, p, 0.1, seed=None))


# -- declared capabilities -------------------------------------------------------------------------
@pytest.mark.parametrize("name", MODELS)
def test_capabilities_are_declared_on_the_classes(name):
    from barsynth.models.base import Model, Voice

    model = get_model(name)
    assert isinstance(model, Model) and issubclass(model.voice_class, Voice)
    assert model.voice_class.model is model and type(model.voice()) is model.voice_class
    for flag in ("restarts_on_trigger", "can_release", "uses_seed"):
        assert isinstance(getattr(model.voice_class, flag), bool), flag
    assert isinstance(model.reports_reference_errors, bool)
    if Bow in model.exciters:
        assert model.voice_class.can_release, "a bow stroke must be able to stop"


@pytest.mark.parametrize("name", MODELS)
def test_the_declared_exciters_are_the_tables_excitations(name):
    """``Model.exciters`` names the table's ``excitation`` choices, each one of barsynth's exciters
    with its rows in the table; a model that declares other exciters than its table is refused."""
    model = get_model(name)
    names = tuple(e.name for e in model.exciters)
    assert names == (model.table["excitation"].choices if "excitation" in model.table else ())
    for exciter in model.exciters:
        assert EXCITERS[exciter.name] is exciter
        assert exciter.parameters()[0].name in model.table  # (a pluck's release row is optional)
    mismatched = type("Mismatched", (type(model),), {"exciters": model.exciters[::-1] or (Bow,)})
    with pytest.raises(TypeError, match="excitation"):
        mismatched()


def _second_trigger(name: str, parameters: dict, at: int = 50 * MS, length: int = 50 * MS):
    """(after the second trigger, the first note ringing on without it, a fresh note, a note
    triggered after ``at`` silent samples)."""
    voice = fresh(name, parameters, seed=3)
    voice.trigger()
    voice.process(at, dtype=np.float64)
    ringing = copy.deepcopy(voice)
    voice.trigger()
    new = fresh(name, parameters, seed=3)
    new.trigger()
    late = fresh(name, parameters, seed=3)
    late.process(at, dtype=np.float64)
    late.trigger()
    return tuple(v.process(length, dtype=np.float64) for v in (voice, ringing, new, late))


@pytest.mark.parametrize("name,excitation", CASES)
def test_a_second_trigger_restarts_or_adds_as_declared(name, excitation):
    p = excited(name, excitation, long_bow=True, **NOISE_FREE.get(name, {}))
    again, ringing, new, late = _second_trigger(name, p)
    assert rms(ringing) > 0.0
    cls = voice_class(name)
    if cls.restarts_on_trigger:
        if name in NOISE_FREE or not cls.uses_seed:
            assert np.array_equal(again, new)  # a fresh note, sample for sample
        else:  # noise keeps running: the restart is nearer a fresh note than the old one plus it
            assert rms(again - late) < 0.5 * rms(again - late - ringing)
    elif excitation != "bow" and (name, excitation) not in COUPLED:
        # strikes and plucks add to what rings: exactly the sum (the resonator is linear)
        assert np.max(np.abs(again - ringing - new)) <= 1e-9 * np.max(np.abs(again))
    else:  # coupled: not a sum, but the old note is still there
        assert rms(again - new) > 0.5 * rms(ringing)


@pytest.mark.parametrize("name,excitation", CASES)
def test_a_second_trigger_is_no_sharper_than_a_note_and_what_rings(name, excitation):
    """No click: the largest step after a second trigger is at most MAX_STEP_RATIO times a fresh
    note's first steps plus those of the note ringing on without it. A voice that restarts cuts what rings: through the
    CrossfadingVoice made for it the old note fades out, and what is left of it after taking
    the new note away steps no more than it did."""
    from barsynth.models.crossfade import CrossfadingVoice

    p = excited(name, excitation, long_bow=True)
    cls = voice_class(name)
    voice = fresh(name, p, seed=4)
    voice.trigger()
    before = voice.process(150 * MS, dtype=np.float64)
    if cls.restarts_on_trigger:
        reference = copy.deepcopy(voice)
        reference.trigger()
        new_note = reference.process(30 * MS, dtype=np.float64)
        faded = CrossfadingVoice(voice)
        faded.trigger()
        left = np.concatenate([before, faded.process(30 * MS, dtype=np.float64) - new_note])
        assert np.all(np.isfinite(left))
        assert largest_step(left[before.size - 2 * MS:]) <= 1.2 * largest_step(before[-20 * MS:])
        return
    ringing = copy.deepcopy(voice)
    voice.trigger()
    after = np.concatenate([before[-1:], voice.process(30 * MS, dtype=np.float64)])
    ringing_on = np.concatenate([before[-1:], ringing.process(30 * MS, dtype=np.float64)])
    alone = fresh(name, p, seed=4)
    alone.trigger()
    note = np.concatenate([[0.0], alone.process(30 * MS, dtype=np.float64)])
    assert np.all(np.isfinite(after))
    assert largest_step(after) <= MAX_STEP_RATIO * (largest_step(note) + largest_step(ringing_on))


@pytest.mark.parametrize("name", MODELS)
def test_release_stops_a_bow_stroke_or_changes_nothing(name):
    cls = voice_class(name)
    for excitation in excitations(name):
        p = excited(name, excitation, long_bow=True)
        plain, released = fresh(name, p), fresh(name, p)
        for voice in (plain, released):
            voice.trigger()
        first = [v.process(300 * MS, dtype=np.float64) for v in (plain, released)]
        released.release()
        rest = [v.process(400 * MS, dtype=np.float64) for v in (plain, released)]
        if excitation == "bow" and cls.can_release:
            x = np.concatenate([first[1], rest[1]])
            assert np.all(np.isfinite(x))
            assert rms(rest[1][-100 * MS:]) < 1e-3 * rms(first[1][-100 * MS:])  # the stroke has stopped
            assert rms(rest[0][-100 * MS:]) > 0.5 * rms(first[0][-100 * MS:])  # and would have gone on
            assert step_ratio(x, first[1].size) <= MAX_STEP_RATIO  # without a click
        else:
            assert np.array_equal(rest[0], rest[1]), excitation


@pytest.mark.parametrize("name", MODELS)
def test_reference_errors_as_declared(name):
    model = get_model(name)
    if model.reports_reference_errors:
        for p in ({}, model_settings(name)):
            errors = model.errors_cents(p, sample_rate=RATE)
            assert len(errors) == len(model.describe(p, sample_rate=RATE)) > 0
            assert all(math.isfinite(e) for e in errors)
    else:
        with pytest.raises(NotImplementedError):
            model.errors_cents({}, sample_rate=RATE)


# -- changes while sounding ------------------------------------------------------------------------
GLIDES_EVERYTHING = {"twang", "farnell"}
"""Voices whose every control glides (their docstrings: 5 ms smoothing). Every other voice
glides the settings of an excitation (they shape the next strike or pluck, or the bow while it
moves) and the parameters of GLIDED_BY_EVERY_MODEL; a change of what rings (bar, loops, grid)
is CrossfadingVoice's to fade (tests/test_crossfade.py)."""

GLIDED_BY_EVERY_MODEL = {"level_db"}
"""Parameters every model must glide: the output level (the bar models ramp their output gain
over dsp.smoothing.LEVEL_GLIDE_S, the twang and Farnell's twang over their 5 ms)."""


def _glides(name: str, p) -> bool:
    return (name in GLIDES_EVERYTHING or p.name in GLIDED_BY_EVERY_MODEL
            or "excitation" in p.reads)


@pytest.mark.parametrize("name", MODELS)
def test_every_model_has_the_level_it_must_glide(name):
    """GLIDED_BY_EVERY_MODEL is not empty words: every model has those parameters."""
    assert GLIDED_BY_EVERY_MODEL <= set(get_model(name).table.names)


def _changes():
    """Every parameter with a slider or a switch, of every model, to two other values (as
    tests/test_crossfade.py); lists are left out. A bow's own settings are changed while it bows."""
    for name in MODELS:
        for p in get_model(name).table:
            if p.kind == FLOATS:
                continue
            if p.kind == CHOICE:
                values = [c for c in p.choices if c != p.default][:2]
            elif p.kind == BOOL:
                values = [not p.default]
            else:
                values = [p.from_unit_interval(0.25), p.from_unit_interval(0.75)]
            bowing = p.when == ((("excitation", ("bow",)),),)
            for value in values:
                yield pytest.param(name, p.name, value, "bow" if bowing else None,
                                   id=f"{name}-{p.name}-{value!s:.8}" + ("-bowing" if bowing else ""))


@pytest.mark.parametrize("name,parameter,value,excitation", list(_changes()))
def test_a_change_while_sounding(name, parameter, value, excitation):
    """Finite, bounded, taken (or refused in one line, changing nothing) and, where the voice
    glides it, without a click (the step measure needs a tone: NOISE_FREE)."""
    p = excited(name, excitation, long_bow=True, **NOISE_FREE.get(name, {}))
    voice = fresh(name, p, seed=1)
    voice.trigger()
    before = voice.process(200 * MS, dtype=np.float64)
    twin = copy.deepcopy(voice)
    try:
        voice.set_parameters(**{parameter: value})
    except BarsynthError as exc:  # a combination the model refuses (a material with E and rho given...)
        assert "allowed" in str(exc) and "\n" not in str(exc)
        assert voice.parameters == twin.parameters
        assert np.array_equal(voice.process(2000, dtype=np.float64), twin.process(2000, dtype=np.float64))
        return
    assert getattr(voice.parameters, parameter) == value
    x = np.concatenate([before, voice.process(100 * MS, dtype=np.float64)])
    assert np.all(np.isfinite(x)) and np.max(np.abs(x)) <= MAX_RAW_PEAK
    if _glides(name, get_model(name).table[parameter]):
        moved = {n: (getattr(twin.parameters, n), getattr(voice.parameters, n)) for n in get_model(name).table.names}
        assert step_ratio(x, before.size) <= (MAX_SWEEP_RATIO if _sweeps(moved) else MAX_STEP_RATIO)


def _sweeps(moved: dict) -> bool:
    """Whether a change moves a stiffness, density or length by more than SWEEP_FACTOR: the voice's
    modes then sweep octaves within its 5 ms glide, and the steps of that sweep are the sound's own."""
    return any(isinstance(old, float) and old > 0 and new > 0 and max(new / old, old / new) > SWEEP_FACTOR
               for name, (old, new) in moved.items()
               if name in ("youngs_modulus_pa", "density_kg_m3", "length_m", "thickness_m"))


def _refusals(name: str):
    table = get_model(name).table
    numeric = [p for p in table if p.kind not in (CHOICE, BOOL, FLOATS)]
    yield {"no_such_parameter": 1.0}
    yield {numeric[0].name: numeric[0].maximum + (numeric[0].maximum - numeric[0].minimum)}
    yield {numeric[-1].name: float("nan")}
    # one good value with a bad one: neither is taken
    yield {numeric[0].name: numeric[0].from_unit_interval(0.3), numeric[-1].name: numeric[-1].minimum - 1.0}
    if name in REFUSED_COMBINATIONS:
        yield REFUSED_COMBINATIONS[name]


@pytest.mark.parametrize("name", MODELS)
def test_a_refused_change_leaves_the_voice_as_it_was(name):
    for bad in _refusals(name):
        voice = fresh(name, model_settings(name))
        voice.trigger()
        voice.process(1000)
        twin = copy.deepcopy(voice)
        with pytest.raises(ParameterError) as info:
            voice.set_parameters(**bad)
        assert "\n" not in str(info.value)
        assert voice.parameters == twin.parameters, bad
        assert np.array_equal(voice.process(3000, dtype=np.float64), twin.process(3000, dtype=np.float64)), bad


# -- random settings -------------------------------------------------------------------------------
def _draw_settings(data, name: str) -> dict:
    """Every parameter drawn along its scale (table.settings_at); lists as tuples of one drawn
    length (so ratios and their T60s can agree), or empty; RANDOM_RANGES narrowed for speed."""
    table = get_model(name).table
    narrowed = RANDOM_RANGES.get(name, {})
    values = table.settings_at({p.name: data.draw(st.floats(0.0, 1.0), label=p.name)
                                for p in table if p.kind != FLOATS and p.name not in narrowed})
    length = data.draw(st.integers(2, 6), label="list length")
    for p in table:
        if p.kind == FLOATS and data.draw(st.booleans(), label=f"{p.name} given"):
            values[p.name] = tuple(data.draw(st.lists(st.floats(p.minimum, p.maximum), min_size=length,
                                                      max_size=length), label=p.name))
    for parameter, (low, high) in narrowed.items():
        values[parameter] = data.draw(st.integers(low, high), label=parameter)
    return values


FOUND = {  # model -> (settings, sample rate) that a random test once found wrong; each stays tried
    "allpass": [  # a pluck at a clamped end took a force growing as 1 / x^4 (1e30 at 0, 3e9 at 0.001)
        ({"bc": "clamped-free", "excitation": "pluck", "strike_position": 0.0}, 44100),
        ({"bc": "clamped-free", "excitation": "pluck", "strike_position": 0.001}, 44100),
        ({"bc": "clamped-pinned", "excitation": "pluck", "strike_position": 1.0 - 1e-9, "pickup_position": 0.37},
         22050),
        ({"bc": "clamped-clamped", "excitation": "pluck", "strike_position": 1e-300}, 22050),
    ],
    "banded": [  # a pluck at a node of every kept mode took a force without bound (3e16 on a one-mode ring)
        ({"tuning": "ratios", "shape": "ring", "mode_ratios": (1.0,), "excitation": "pluck",
          "strike_position": 0.125}, 22050),
        ({"tuning": "physics", "mode_count": 1, "excitation": "pluck", "strike_position": 0.2242}, 22050),
    ],
    "fd": [  # a pluck by a clamped or pinned end held it out with a force growing as 1 / x (NaN at 1e-155)
        ({"bc": "clamped-free", "excitation": "pluck", "strike_position": 1e-155, "points": 20}, 22050),
        ({"bc": "pinned-pinned", "excitation": "pluck", "strike_position": 1e-155, "points": 20}, 22050),
        ({"bc": "clamped-pinned", "excitation": "pluck", "strike_position": 1e-300, "points": 20}, 22050),
        ({"bc": "clamped-clamped", "excitation": "pluck", "strike_position": 1.0 - 1e-9, "points": 20}, 22050),
    ],
}
FOUND_BOUND = 1e3
"""A found case must be more than finite: a bar moving at 1 km/s is no bar."""

RANDOM_EXAMPLES = {"allpass": 8}
"""Random examples per model (25 unless named): the all-pass bar fits its dispersion filters
for every new setting (0.1 to 0.4 s each)."""


@pytest.mark.parametrize("name", MODELS)
def test_random_settings_in_range_give_a_one_line_refusal_or_finite_bounded_samples(name):
    """Random settings (RANDOM_EXAMPLES of them) and every FOUND case of the model: a
    one-line ParameterError, or finite samples within MAX_RAW_PEAK (FOUND_BOUND for a found one)."""

    @settings(max_examples=RANDOM_EXAMPLES.get(name, 25))
    @given(data=st.data(), found=st.just(None))
    def check(data, found):
        if found is None:
            values = _draw_settings(data, name)
            rate = data.draw(st.sampled_from([22050, 44100, 96000]), label="sample_rate")
        else:
            values, rate = found
        try:
            x = raw(name, values, 0.05, rate=rate)
        except ParameterError as exc:
            assert "\n" not in str(exc), str(exc)
            return
        assert np.all(np.isfinite(x)) and np.max(np.abs(x)) <= MAX_RAW_PEAK
        if found is not None:
            assert np.max(np.abs(x)) < FOUND_BOUND

    for found in FOUND.get(name, []):
        check = example(data=None, found=found)(check)
    check()


@pytest.mark.parametrize("name", MODELS)
def test_driven_until_says_when_a_bow_lets_go(name):
    """A voice that only rings out says 0; a bowed one the sample its bow is lifted at, after which
    its sound decays (render duration auto waits for it)."""
    if Bow not in get_model(name).exciters:
        voice = fresh(name, model_settings(name))
        voice.trigger()
        voice.process(1000)
        assert voice.driven_until == 0
        return
    voice = fresh(name, excited(name, "bow"))
    assert voice.driven_until == 0  # never bowed
    voice.trigger()
    lifted = voice.driven_until
    assert lifted > 0
    x = voice.process(lifted + int(0.3 * RATE), dtype=np.float64)
    frames = np.sqrt(np.mean(x[lifted:lifted + 15 * 20 * MS].reshape(15, 20 * MS) ** 2, axis=1))
    assert frames[0] > 0 and np.all(frames[1:] <= 1.05 * frames[:-1])  # nothing drives it: it only rings out
