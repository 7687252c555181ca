"""The voice contract (models/base.py), measured on the sounds of every registered model.

Every test is parametrised over ``model_names()``, so a new model is covered the day it
is registered; what only some models have (a bow, a retired waveguide, oversampling, a
vibrato) is tried through per-model scenario tables (SCENARIOS, EVENT_SCENARIOS,
RANDOM_RENDERS, MEASURED_SCENARIOS, LEVEL_GLIDES, CLICK_CHANGES, REFUSED_COMBINATIONS) that
a new model adds its rows to. What is checked is what ``Voice`` and ``Model`` declare:

- blocks of any size (and random splits, and timed events) give the offline render's
  samples exactly, for the default settings, every excitation the table offers and every
  scenario (at several rates where a model's scenario asks for them);
- ``process(n, out=buf)`` writes the very samples of ``process(n)`` into a caller's float64
  or float32 buffer, returns it, refuses a wrong one (naming ``out``) and allocates nothing:
  no Python or NumPy memory held or passing through a call of 4096 samples beyond
  ALLOCATION_SLACK_BYTES (tracemalloc), for every excitation, every scenario and through
  ``CrossfadingVoice``'s fades; numba's own per-call allocations (one wrapper per array
  argument it unboxes) are counted (NRT statistics), bounded per model and do not grow with
  the block (docs/contract.md says what "allocates nothing" means);
- ``prepare(sample_rate, max_block)`` from 8 kHz to 192 kHz: a voice prepared again is a
  voice made at that rate, the modes below a quarter of the lowest rate stay where they
  are (where the model is rate-independent) and the sound agrees; a refused rate, block
  size or seed changes nothing and is refused by ``render`` too, naming it;
- seeds: the same seed, the same samples; another seed (or none) changes the sound exactly
  where the voice class declares ``uses_seed``;
- the declared capabilities: ``restarts_on_trigger`` (a restart is a fresh note; otherwise
  the strike adds to what rings), ``can_release`` (a bow stroke stops; otherwise release()
  changes nothing), ``reports_reference_errors`` (finite errors_cents, or NotImplementedError);
- changes while sounding (set_parameters, trigger, release): finite, bounded and, where the
  voice glides the change, without a click (tests/clicks.py's measures, shown to fail on a
  cut); the level glides along the model's declared ramp; a refused change leaves the
  parameters and the sound as they were and says the model's reason;
- random settings in range (Hypothesis, derandomized): a one-line ParameterError giving one
  of the model's reasons, or finite samples below the model's bound; every case ever found
  stays as an ``@example``.

``FAST`` keeps the finite-difference bar on a coarse grid. Model physics (frequencies
against the beam equation, decays, mallet and pluck levels, bowing regions) stays in each
model's own test file.
"""

from __future__ import annotations

import copy
import functools
import math
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from barsynth.dsp.smoothing import LEVEL_GLIDE_S, ramp_steps
from barsynth.errors import BarsynthError, ParameterError
from barsynth.exciters import EXCITERS, Bow
from barsynth.models import get_model, model_names
from barsynth.models.crossfade import CrossfadingVoice
from barsynth.models.rendering import MAX_RAW_PEAK
from barsynth.parameters import BOOL, CHOICE, FLOATS
from barsynth.presets import preset_parameters
from clicks import MAX_HIGHPASS_SPIKE, MAX_STEP_RATIO, highpass_spike, largest_step, step_ratio
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

RANDOM_RANGES = {"fd": {"points": (8, 80)}, "kalimba": {"points": (20, 120)}}
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

DESCRIBE_CENTS = {"allpass": 0.5, "fd": None, "kalimba": None}
"""How far (cents) describe()'s modes below a quarter of the lowest rate may move between rates.
0 (to rounding) for a model whose modes do not depend on the rate; the all-pass bar fits its
dispersion filters anew at each rate (within 0.1 cent measured); the finite-difference scheme's
time step warps its frequencies (None: rate-dependent; at 8 kHz with 2 steps a sample its
second mode rings 51 cents flat; the kalimba's "tine on bridge" modes are the scheme's at the
rate, its step unrefined), which the measured test below follows instead."""

COUPLED = {("fd", "strike")}
"""(model, excitation) pairs whose exciter is solved with the bar (the fd mallet's contact
force depends on how the bar moves), besides every bow: two notes are not exactly the sum of
each alone. Every other strike and pluck is an uncoupled force (or a static shape) on a
linear resonator."""

BOWL = preset_parameters("banded", "bowl")  # twelve modes on a ring
MARIMBA = preset_parameters("banded", "marimba")


@dataclass(frozen=True)
class Scenario:
    """Settings (on top of FAST) a model's own tests used to render with, and for how long at
    which rates the block test renders them."""

    settings: dict
    seconds: float = 0.3
    rates: tuple = (RATE,)


SCENARIOS = {
    "twang": {"vibrato-slide": Scenario({"vibrato_rate_hz": 5.0, "slide": True, "slide_time_s": 0.2}, 0.4,
                                        (22050, 44100, 48000, 96000))},
    "farnell": {"anchor": Scenario({"anchor": True}, 0.3)},
    "banded": {"bowl": Scenario(BOWL, 0.5),
               "bowl-bowed": Scenario({**BOWL, "excitation": "bow", "bow_duration_s": 0.05}, 0.8)},  # lifted at 0.7 s
    "allpass": {"clamped-free": Scenario({"bc": "clamped-free", "allpass_order": 12}, 0.3)},
    "fd": {"oversampling-1": Scenario({"points": 40, "oversampling": 1}, 0.3),
           "oversampling-4": Scenario({"points": 40, "oversampling": 4}, 0.3)},
}
"""Per model, the settings that reach what only that model has: the twang's vibrato and slide,
Farnell's anchor (a cosine drive), the banded bowl (a ring of twelve modes, struck at its
rim; bowed, its bow lifted), the all-pass bar clamped at one end, the finite-difference bar at
one and four steps a sample. The block, glide, allocation and numba-allocation tests run
each."""

SCENARIO_CASES = [pytest.param(name, label, id=f"{name}-{label}")
                  for name, table in SCENARIOS.items() if name in MODELS for label in table]

FD_EVENTS = {0: ("trigger", {}), 5000: ("set", {"excitation": "bow", "bow_force_n": 2.0}), 5001: ("trigger", {}),
             12000: ("set", {"bow_velocity_m_s": 0.2}), 13000: ("set", {"excitation": "strike"}),
             13001: ("trigger", {}), 20000: ("release", {})}
EVENT_SCENARIOS = {  # model -> {scenario: (settings, {sample: event}, samples, rate, block sizes)}
    "banded": {"bowed-marimba": ({**MARIMBA, "excitation": "bow"},
                                 {0: ("trigger", {}), 9000: ("set", {"bow_force_n": 5.0}),
                                  20000: ("set", {"excitation": "strike"}), 20001: ("trigger", {}),
                                  30000: ("release", {})}, 50000, 44100, (1, 31, 512, 5000))},
    "fd": {f"oversampling-{steps}": ({"points": 40, "oversampling": steps}, FD_EVENTS, 25000, 44100, (1, 7, 37, 1000))
           for steps in (1, 3, 4)},
}
"""Timed events a model's own tests played (a stroke, a strike on the bowed bar, a glide of the
bow, a change of excitation, an early stop), besides the events every model plays."""


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


def scenario_settings(name: str, label: str) -> dict:
    return model_settings(name, **SCENARIOS[name][label].settings)


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


def duration_for(excitation: str | None) -> float:
    return 0.55 if excitation == "bow" else 0.3


@functools.lru_cache(maxsize=None)
def offline(name: str, excitation: str | None) -> np.ndarray:
    p = excited(name, excitation)
    return raw(name, p, duration_for(excitation), seed=3)


def in_blocks(voice, sizes) -> np.ndarray:
    voice.trigger()
    return np.concatenate([voice.process(n, dtype=np.float64) for n in sizes])


def splits(total: int, block: int) -> list[int]:
    return [block] * (total // block) + ([total % block] if total % block else [])


# -- blocks ------------------------------------------------------------------------------------
BLOCKS = (1, 5, 7, 17, 64, 256, 1000, 3001, 4097)


@pytest.mark.parametrize("block", BLOCKS)
@pytest.mark.parametrize("name,excitation", CASES)
def test_blocks_of_any_size_equal_the_offline_render(name, excitation, block):
    whole = offline(name, excitation)
    assert np.max(np.abs(whole)) > 0.0
    voice = fresh(name, excited(name, excitation), seed=3)
    assert np.array_equal(in_blocks(voice, splits(whole.size, block)), whole)


@pytest.mark.parametrize("name,label", SCENARIO_CASES)
def test_blocks_of_any_size_equal_the_offline_render_in_every_scenario(name, label):
    scenario = SCENARIOS[name][label]
    p = scenario_settings(name, label)
    for rate in scenario.rates:
        whole = raw(name, p, scenario.seconds, rate=rate, seed=3)
        assert np.max(np.abs(whole)) > 0.0
        for block in BLOCKS:
            voice = fresh(name, p, rate=rate, seed=3)
            assert np.array_equal(in_blocks(voice, splits(whole.size, block)), whole), (rate, block)


@pytest.mark.parametrize("name,excitation", CASES)
@settings(max_examples=8)
@given(st.lists(st.integers(min_value=0, max_value=3000), min_size=1, max_size=30))
def test_random_block_splits_equal_the_offline_render(name, excitation, sizes):
    whole = offline(name, excitation)
    cuts = sorted(min(int(c), whole.size) for c in np.cumsum(sizes))
    sizes = np.diff([0, *cuts, whole.size]).tolist()  # random splits (empty blocks too), ending with the rest
    assert np.array_equal(in_blocks(fresh(name, excited(name, excitation), seed=3), sizes), whole)


@pytest.mark.parametrize("block", [1, 7, 64, 1000])
@pytest.mark.parametrize("name", MODELS)
def test_blocks_with_events_equal_one_long_block(name, block):
    """A trigger, a change, a second trigger and a release, each at its sample whatever the blocks."""
    events = {0: ("trigger", {}), 1000: ("set", {"level_db": -6.0}), 2500: ("trigger", {}), 4000: ("release", {})}
    whole = play(fresh(name, model_settings(name)), events, 6000, 6000)
    assert np.max(np.abs(whole)) > 0.0
    assert np.array_equal(play(fresh(name, model_settings(name)), events, 6000, block), whole)


@pytest.mark.parametrize("name,label", [pytest.param(name, label, id=f"{name}-{label}")
                                        for name, table in EVENT_SCENARIOS.items() if name in MODELS
                                        for label in table])
def test_blocks_with_a_models_own_events_equal_one_long_block(name, label):
    p, events, total, rate, blocks = EVENT_SCENARIOS[name][label]
    whole = play(fresh(name, model_settings(name, **p), rate=rate), events, total, total)
    assert np.max(np.abs(whole)) > 0.01
    for block in blocks:
        voice = fresh(name, model_settings(name, **p), rate=rate)
        assert np.array_equal(play(voice, events, total, block), whole), block


# -- process into a caller's buffer ----------------------------------------------------------------
def _twins(name: str, parameters: dict | None = None, *, max_block: int | None = None):
    kw = {} if max_block is None else {"max_block": max_block}
    voices = [fresh(name, model_settings(name) if parameters is None else parameters, **kw) for _ in range(2)]
    for voice in voices:
        voice.trigger()
    return voices


@pytest.mark.parametrize("kind", [np.float64, np.float32])
@pytest.mark.parametrize("name,excitation", CASES)
def test_process_into_a_buffer_gives_the_samples_of_process(name, excitation, kind):
    """Blocks below, at and above ``max_block`` (a float32 buffer is filled in pieces of it), on
    through a bow's stop."""
    mine, reference = _twins(name, excited(name, excitation), max_block=64)
    for n in (0, 1, 63, 64, 65, 1000, *[256] * 40):
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
    "big-endian": lambda n: np.empty(n, dtype=">f8"),
    "list": lambda n: [0.0] * n,
}


@pytest.mark.parametrize("bad", BAD_BUFFERS)
@pytest.mark.parametrize("name", MODELS)
def test_a_wrong_buffer_is_refused_and_changes_nothing(name, bad):
    mine, reference = _twins(name)
    with pytest.raises(ParameterError, match="out"):
        mine.process(64, out=BAD_BUFFERS[bad](64))
    assert np.array_equal(mine.process(500, dtype=np.float64), reference.process(500, dtype=np.float64))


@pytest.mark.parametrize("count", [64.0, np.float64(64), True, -1, "64"])
def test_a_wrong_block_size_with_a_good_buffer_is_refused(count):
    """The block size is checked even when the buffer is one process takes without checks."""
    mine, reference = _twins("banded")
    buf = np.empty(1 if count is True else 64)
    with pytest.raises(ParameterError, match="num_samples"):
        mine.process(count, out=buf)
    assert np.array_equal(mine.process(500, dtype=np.float64), reference.process(500, dtype=np.float64))


def test_a_buffer_changed_in_place_after_a_block_is_refused():
    """A buffer that was fine for one block is checked again at the next (nothing is trusted for
    having passed once): made read-only, or given another shape, in place."""
    mine, _ = _twins("banded")
    buf = np.empty(64)
    mine.process(64, out=buf)
    buf.flags.writeable = False
    with pytest.raises(ParameterError, match="out"):
        mine.process(64, out=buf)
    buf.flags.writeable = True
    buf.shape = (8, 8)
    with pytest.raises(ParameterError, match="out"):
        mine.process(64, out=buf)


# -- allocations -----------------------------------------------------------------------------------
ALLOCATION_BLOCK = 4096
ALLOCATION_SLACK_BYTES = 4096
"""What one call of process(ALLOCATION_BLOCK, out=buf) may allocate in passing (the peak of
tracemalloc's traced memory above what was allocated before the calls): a quarter of the
16 KiB of a float32 block of 4096 samples, an eighth of a float64 one, so any temporary the
size of a block (or a quarter of one) fails. Measured: 0.4 to 2.4 KiB (the Python objects of
a call: numba's dispatch, views of the buffers, the float32 path's pieces)."""

KEPT_SLACK_BYTES = 512
"""What ALLOCATION_CALLS calls may leave allocated: under 26 bytes a call, so one float kept a
call (24 bytes and its slot in a list) fails."""

ALLOCATION_CALLS = 20  # 1.7 s at 48 kHz: a bow's lift, a retired waveguide's end and fades fall inside
WARM_UP_CALLS = 300
"""One-sample calls under tracemalloc before measuring: a voice's first calls fill numba's and
Python's caches (Farnell's kernel, typed by numba's dispatcher at each call: some KiB at the
first), and a block allocated before tracemalloc started and freed during the measured calls
would offset a new one. Blocks of one sample leave what a block of ALLOCATION_BLOCK needs
unprepared: a buffer grown at the first large block is caught."""


@dataclass(frozen=True)
class Measured:
    """A voice to measure: its settings (on top of FAST), the block (and max_block), an event
    done after the warm-up (what the voice does once, at the event, is not measured) and a check
    that the measured blocks saw what the scenario is for: ``reached(voice, first, end)`` with
    the samples the measured calls began and ended at."""

    settings: dict
    block: int = ALLOCATION_BLOCK
    event: Callable[[Any], None] | None = None
    reached: Callable[[Any, int, int], bool] | None = None
    wrap: bool = False  # measured through a CrossfadingVoice (a 100 ms fade: longer than a block)


def _lifted_inside(voice, first: int, end: int) -> bool:
    return first < voice.driven_until <= end


def _retired_one(voice) -> None:
    voice.set_parameters(pickup_position=0.3)  # a new waveguide; the old one rings on beside it...
    voice.trigger()
    assert len(voice._retired) == 1


def _retired_gone(voice, first: int, end: int) -> bool:
    return not voice._retired  # ...rings out, fades over FADE_S and is dropped while measured


def _attack_heard_inside(voice, first: int, end: int) -> bool:
    from barsynth.exciters import Sample

    return voice._exciters.of(Sample).attack.size > first + ALLOCATION_BLOCK  # heard across a block's end


LONG_ATTACK = tuple(float(v) for v in 0.5 * np.sin(0.05 * np.arange(4800)))  # 0.1 s at 48 kHz

MEASURED_SCENARIOS = {
    "banded": {"bowl-bowed": Measured({**BOWL, "excitation": "bow", "bow_duration_s": 0.05}, reached=_lifted_inside),
               "bowl-plucked": Measured({**BOWL, "excitation": "pluck"}),
               "long-attack": Measured({"excitation": "sample", "attack_samples": LONG_ATTACK},
                                       reached=_attack_heard_inside)},
    "allpass": {"retired-waveguide": Measured({"allpass_order": 12, "q": 50.0}, event=_retired_one,
                                              reached=_retired_gone)},
    "fd": {f"large-block-{ex}": Measured({"points": 20, "oversampling": 1, "excitation": ex, "bow_duration_s": 10.0},
                                         block=16384) for ex in ("strike", "bow", "pluck")},
}
"""Beyond every excitation (with a bow that keeps bowing) and every SCENARIOS entry: the banded
bowl bowed, its bow lifted while measured, and plucked, and a recorded attack of 0.1 s heard
while measured; an all-pass bar with a replaced
waveguide that rings out, fades and is dropped while measured; the finite-difference bar in
blocks of 16384 samples. Besides these, every model through a CrossfadingVoice fading (a
change of level, a trigger)."""


def _fade_change(voice) -> None:
    voice.set_parameters(level_db=voice.parameters.level_db - 10.0)


def _fade_restart(voice) -> None:
    voice.trigger()


def _faded(voice, first: int, end: int) -> bool:
    return not voice.fading


def _measured_cases():
    for name in MODELS:
        for ex in excitations(name):
            yield name, f"{ex or 'default'}", Measured(excited(name, ex, long_bow=True))
        for label in SCENARIOS.get(name, {}):
            yield name, label, Measured(scenario_settings(name, label))
        for label, measured in MEASURED_SCENARIOS.get(name, {}).items():
            yield name, label, measured
        yield name, "crossfade-change", Measured(excited(name, excitations(name)[0], long_bow=True), wrap=True,
                                                 event=_fade_change, reached=_faded)
        yield name, "crossfade-trigger", Measured(excited(name, excitations(name)[0], long_bow=True), wrap=True,
                                                  event=_fade_restart,
                                                  reached=_faded if voice_class(name).restarts_on_trigger else None)


MEASURED = {(name, label): measured for name, label, measured in _measured_cases()}
MEASURED_CASES = [pytest.param(name, label, id=f"{name}-{label}") for name, label in MEASURED]


def measured_voice(name: str, measured: Measured, voice_type: type | None = None):
    kind = voice_type or get_model(name).voice_class
    voice = kind(model_settings(name, **measured.settings), sample_rate=RATE, seed=1,
                 max_block=max(measured.block, 4096))
    voice.trigger()  # (before wrapping: a first trigger of a restarting voice would start a fade)
    return CrossfadingVoice(voice, fade_s=0.1) if measured.wrap else voice


def allocations(voice, measured: Measured, kind) -> tuple[int, int, str, int, int]:
    """(bytes kept by ALLOCATION_CALLS calls of process(block, out=buf), the largest extra in
    passing, the largest allocation sites traced, the samples the measured calls began and ended
    at), after WARM_UP_CALLS one-sample calls and the scenario's event, under tracemalloc.

    Kept and passing bytes are tracemalloc's traced memory before, after and at its peak during
    the calls. (No snapshot is held while they run: with one alive, numba's dispatcher keeps
    blocks of ~57 bytes at each call of a kernel it types (Farnell's), up to 14 KiB over 40
    calls, that it does not keep otherwise (measured); gc.collect() does not free them. The sites are
    read from a snapshot taken after the calls, for the failure message.)"""
    small, buf = np.empty(1, dtype=kind), np.empty(measured.block, dtype=kind)
    first = WARM_UP_CALLS
    tracemalloc.start()
    try:
        for _ in range(WARM_UP_CALLS):
            voice.process(1, out=small)
        if measured.event is not None:
            measured.event(voice)
            voice.process(1, out=small)  # what the event leaves to the next call (a kernel resolved anew)
            first += 1
        tracemalloc.reset_peak()
        start = tracemalloc.get_traced_memory()[0]
        for _ in range(ALLOCATION_CALLS):
            voice.process(measured.block, out=buf)
        end, peak = tracemalloc.get_traced_memory()
        sites = tracemalloc.take_snapshot().filter_traces([tracemalloc.Filter(False, tracemalloc.__file__)])
    finally:
        tracemalloc.stop()
    where = "; ".join(str(stat) for stat in sites.statistics("lineno")[:3])
    assert np.all(np.isfinite(buf))
    return end - start, peak - start, where, first, first + ALLOCATION_CALLS * measured.block


def check_allocates_nothing(voice, measured: Measured, kind) -> None:
    kept, passing, where, first, end = allocations(voice, measured, kind)
    assert kept < KEPT_SLACK_BYTES, f"{kept} bytes kept over {ALLOCATION_CALLS} calls (largest sites: {where})"
    assert passing < ALLOCATION_SLACK_BYTES, f"{passing} bytes allocated within a call (largest sites: {where})"
    if measured.reached is not None:
        assert measured.reached(voice, first, end), "the measured blocks missed what the scenario is for"


@pytest.mark.parametrize("kind", [np.float64, np.float32])
@pytest.mark.parametrize("name,label", MEASURED_CASES)
def test_process_into_a_buffer_allocates_nothing(name, label, kind):
    measured = MEASURED[name, label]
    check_allocates_nothing(measured_voice(name, measured), measured, kind)


class _Temporary:
    """What an injected _render adds to the voice's own (a voice subclass per kind of leak)."""

    @staticmethod
    def block_copy(voice, out):  # a float64 block: 32 KiB
        return out.copy()

    @staticmethod
    def float32_block(voice, out):  # the float32 cast of a block: 16 KiB
        return out.astype(np.float32)

    @staticmethod
    def quarter_block_float32(voice, out):  # 4 KiB: a quarter of a float32 block
        return np.empty(out.size // 4, dtype=np.float32)

    @staticmethod
    def kept_float(voice, out):  # one float kept a call: 24 bytes and a list slot
        voice.__dict__.setdefault("log", []).append(float(out.size) + 0.5)


@pytest.mark.parametrize("leak", [n for n in vars(_Temporary) if not n.startswith("_")])
@pytest.mark.parametrize("kind", [np.float64, np.float32])
def test_the_allocation_check_fails_on_an_injected_temporary(leak, kind):
    """The check can fail: a voice whose _render makes one temporary (or keeps one float) a call."""
    name = MODELS[0]
    base = get_model(name).voice_class
    add = getattr(_Temporary, leak)

    class Leaky(base):
        def _render(self, out):
            super()._render(out)
            add(self, out)

    measured = Measured(model_settings(name, **NOISE_FREE.get(name, {})))
    check_allocates_nothing(measured_voice(name, measured), measured, kind)  # the model itself passes
    with pytest.raises(AssertionError, match="bytes"):
        check_allocates_nothing(measured_voice(name, measured, Leaky), measured, kind)


# -- numba's own allocations -------------------------------------------------------------------
NUMBA_ARRAYS_PER_CALL = {"twang": 27, "farnell": 8, "banded": 19, "allpass": 66, "fd": 18}
"""The most NRT allocations (numba's runtime: malloc'd, not seen by tracemalloc) one
process(n, out=buf) call of each model's voice may make, for blocks up to max_block; each
is freed before the call returns. Measured: each is the wrapper (an NRT MemInfo) numba makes
for one NumPy array argument it unboxes into a compiled call; no kernel allocates (one more
array in a call, or an array made inside a kernel, adds one: the test below shows both).
twang 23 arrays in its records for a note that holds still (its static kernel) and 27 for
one that moves, Farnell 8, banded 9 struck or plucked (one is the drive of a resonator tube, empty
without one), 11 while a recorded attack is heard (the level applied to it) and 10 bowed (19 in the
block its bow is lifted in: both kernels), all-pass 18 and 16 more for each replaced
waveguide still ringing (at most MAX_RETIRED = 3), fd 18. A CrossfadingVoice adds its old
voice's during a fade."""


def numba_allocations(voice, block: int, calls: int) -> list[tuple[int, int]]:
    """(NRT allocations, NRT frees) in each of ``calls`` calls of process(block, out=buf)."""
    from numba.core.runtime import rtsys

    buf, counts = np.empty(block), []
    for _ in range(calls):
        a = rtsys.get_allocation_stats()
        voice.process(block, out=buf)
        b = rtsys.get_allocation_stats()
        counts.append((b.alloc - a.alloc, b.free - a.free))
    return counts


@pytest.fixture
def nrt_statistics():
    """numba's NRT allocation statistics on (as NUMBA_NRT_STATS=1 sets them at start-up), then
    as they were. (The runtime must be running first: it zeroes them when it starts.)"""
    from numba.core.runtime import _nrt_python as nrt

    voice = fresh(MODELS[0], model_settings(MODELS[0]))
    voice.trigger()
    voice.process(1)  # a kernel has run: the runtime is up
    was_on = nrt.memsys_stats_enabled()
    nrt.memsys_enable_stats()
    yield
    if not was_on:
        nrt.memsys_disable_stats()


@pytest.mark.parametrize("name,label", MEASURED_CASES)
def test_numbas_per_call_allocations_are_bounded_and_do_not_grow_with_the_block(name, label, nrt_statistics):
    measured = MEASURED[name, label]
    voice = measured_voice(name, measured)
    voice.process(3000)
    if measured.event is not None:
        measured.event(voice)
    pinned = NUMBA_ARRAYS_PER_CALL.get(name)  # a model not pinned yet: nothing kept, nothing grows
    by_block = {block: numba_allocations(voice, block, 20) for block in (1, 64, measured.block)}
    for block, counts in by_block.items():
        assert all(made == freed for made, freed in counts), (block, counts)  # nothing kept
        if pinned is not None:  # a fade's end: old, new, then new alone
            assert max(made for made, _ in counts) <= pinned * (3 if measured.wrap else 1), (block, counts)
    if measured.event is None and measured.reached is None:  # one path throughout: the same count whatever the block
        assert len({made for counts in by_block.values() for made, _ in counts}) == 1, by_block


def test_the_numba_count_sees_each_array_unboxed_and_each_made_in_a_kernel(nrt_statistics):
    """The count can fail: a voice whose _render also passes its block to a compiled function
    makes one more NRT allocation a call; one whose compiled function makes an array, two."""
    from numba import njit

    @njit
    def passed(x):
        return x.size

    @njit
    def made(x):
        return np.empty(x.size).size

    name = MODELS[0]
    base = get_model(name).voice_class
    counts = {}
    for extra in (None, passed, made):
        class Probed(base):
            def _render(self, out, extra=extra):
                super()._render(out)
                if extra is not None:
                    extra(out)

        voice = Probed(model_settings(name), sample_rate=RATE)
        voice.trigger()
        voice.process(64)  # compiles the probe
        counts[extra] = {c for c, _ in numba_allocations(voice, 64, 5)}
    (plain,) = counts[None]
    assert plain <= NUMBA_ARRAYS_PER_CALL.get(name, plain)
    assert counts[passed] == {plain + 1}
    assert counts[made] == {plain + 2}


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


REFUSED_SEEDS = [-1, 1.5, "x", True, float("nan")]


@pytest.mark.parametrize("name", MODELS)
def test_render_and_voice_refuse_a_bad_rate_or_seed_naming_it(name):
    model = get_model(name)
    for rate in REFUSED_RATES:
        with pytest.raises(ParameterError, match="sample_rate"):
            model.render(model_settings(name), duration_s=0.01, sample_rate=rate)
        with pytest.raises(ParameterError, match="sample_rate"):
            model.voice(model_settings(name), sample_rate=rate)
    for seed in REFUSED_SEEDS:
        with pytest.raises(ParameterError, match="seed"):
            model.render(model_settings(name), duration_s=0.01, seed=seed)
        with pytest.raises(ParameterError, match="seed"):
            model.voice(model_settings(name), seed=seed)


REFUSED_AT_RATE = {"banded": ({"tuning": "ratios", "frequency_hz": 3000.0, "mode_ratios": (1.0,)}, 8000,
                              "no mode of this object")}
"""A setting and a valid rate the model itself refuses (its _prepare raises: the only mode above
a quarter of 8 kHz), so the base must keep the old rate and design; and the refusal's reason."""


@pytest.mark.parametrize("name", [name for name in REFUSED_AT_RATE if name in MODELS])
def test_a_rate_the_model_refuses_leaves_the_voice_playing_at_its_old_rate(name):
    p, rate, reason = REFUSED_AT_RATE[name]
    mine, reference = (fresh(name, model_settings(name, **p)) for _ in range(2))
    for voice in (mine, reference):
        voice.trigger()
        voice.process(300)
    with pytest.raises(ParameterError) as info:
        mine.prepare(rate)
    assert reason in str(info.value) and "\n" not in str(info.value) and mine.sample_rate == RATE
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
    """The same seed, the same samples; another seed, or none (fresh noise each time), another
    sound exactly where the voice uses its seed."""
    p = excited(name, excitation)
    a, b, other = raw(name, p, 0.1, seed=5), raw(name, p, 0.1, seed=5), raw(name, p, 0.1, seed=6)
    unseeded = raw(name, p, 0.1, seed=None), raw(name, p, 0.1, seed=None)
    assert np.array_equal(a, b)
    if voice_class(name).uses_seed:
        assert not np.array_equal(a, other)
        assert not np.array_equal(*unseeded)
    else:
        assert np.array_equal(a, other)
        assert np.array_equal(a, unseeded[0]) and np.array_equal(a, unseeded[1])


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
        assert np.max(np.abs(again - ringing - new)) <= 1e-12 * np.max(np.abs(again))
    else:  # coupled: not a sum, but the old note is still there
        assert rms(again - new) > 0.5 * rms(ringing)
        if excitation != "bow":  # and a second strike adds to it
            assert rms(again[:2000]) > rms(ringing[:2000])


@pytest.mark.parametrize("name,excitation", CASES)
def test_a_second_trigger_is_no_sharper_than_a_note_and_what_rings(name, excitation):
    """No click: the largest step after a second trigger is at most the largest steps of a fresh
    note's start plus those of the note ringing on without it (exactly so where the two add;
    MAX_STEP_RATIO times where the exciter is coupled to the bar or a bow); a coupled strike's
    first five samples step less than three times the ringing did. A voice that restarts cuts
    what rings: through the CrossfadingVoice made for it the old note fades out, and what is
    left of it after taking the new note away steps no more than it did."""
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
    adds = excitation != "bow" and (name, excitation) not in COUPLED
    factor = 1.0 + 1e-9 if adds else MAX_STEP_RATIO
    assert largest_step(after) <= factor * (largest_step(note) + largest_step(ringing_on))
    if (name, excitation) in COUPLED:
        onset = np.concatenate([before[-5:], after[1:6]])
        assert largest_step(onset) < 3.0 * largest_step(before[-2000:-4])


@pytest.mark.parametrize("name", MODELS)
def test_warm_up_changes_no_sample(name):
    """warm_up() (called by live players before they play) compiles ahead: the samples of a
    warmed voice, through a change while sounding, are those of one that was not warmed."""
    runs = []
    for warm in (False, True):
        voice = fresh(name, model_settings(name))
        if warm:
            voice.warm_up()
        voice.trigger()
        head = voice.process(50 * MS, dtype=np.float64)
        voice.set_parameters(level_db=-12.0)
        runs.append(np.concatenate([head, voice.process(50 * MS, dtype=np.float64)]))
    assert np.array_equal(runs[0], runs[1])


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
            assert step_ratio(x, first[1].size, RATE) <= MAX_STEP_RATIO  # without a click
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

MAX_SWEEP_RATIO = 2.0  # a change that sweeps the modes by octaves (steel for acrylic: x7.8 in pitch)
SWEEP_FACTOR = 4.0

REFUSAL_REASONS = {
    "twang": ("Nyquist",),
    "farnell": (),
    "banded": ("no mode of this object", "too short", "values for", "no free-free bar", "tube_mode",
               "tube_radius_m"),
    "allpass": ("first mode",),
    "fd": ("unstable",),
    "ruler": ("shorter than the ruler", "beyond the ruler's back end", "grid cells", "too far", "no rest on these"),
    "kalimba": ("grid cells", "bends the tine too far", "no rest"),
}
"""Why each model may refuse settings that are each in range (words its one-line message must
contain): a ruler with no audible mode; an object with no mode between 30 Hz and a quarter of
the rate, a T60 shorter than its mode allows, more T60s or gains than modes, ratios no bar has
with shape = bar (a doublet), a tube on a mode the object lacks (or that does not sound) or too
wide for its frequency; a bar whose first mode
lies outside the band the all-pass filters are fitted in; an unstable finite-difference step; a ruler whose overhang is not shorter than it, whose finger
lies beyond its back end, whose vibrating part spans too few grid cells, whose tip is bent down
too far for small deflections, or whose finger cannot hold it; a kalimba tine whose vibrating
part or back span is too short for its grid, or pushed down too far.
Farnell's patch refuses nothing. Random settings and changes while sounding are refused only
for these: a model not listed may refuse nothing (a new model adds its reasons here).
LEVEL_GLIDES and NUMBA_ARRAYS_PER_CALL hold defaults for a new model too (the shared output-level
glide; a count not pinned but checked never to grow), so the suite covers it at once."""


def _glides(name: str, p) -> bool:
    return (name in GLIDES_EVERYTHING or p.name in GLIDED_BY_EVERY_MODEL
            or "excitation" in p.reads)


def assert_refused_for_a_reason(name: str, exc: Exception) -> None:
    message = str(exc)
    assert "\n" not in message, message
    assert any(reason in message for reason in REFUSAL_REASONS.get(name, ())), message


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
    """Finite, bounded, taken (or refused in one line for one of the model's reasons, changing
    nothing) and, where the voice glides it, without a click (the step measure needs a tone:
    NOISE_FREE)."""
    p = excited(name, excitation, long_bow=True, **NOISE_FREE.get(name, {}))
    voice = fresh(name, p, seed=1)
    voice.trigger()
    before = voice.process(200 * MS, dtype=np.float64)
    twin = copy.deepcopy(voice)
    try:
        voice.set_parameters(**{parameter: value})
    except BarsynthError as exc:  # a combination the model refuses (an unstable step...)
        assert "allowed" in str(exc)
        assert_refused_for_a_reason(name, exc)
        assert voice.parameters == twin.parameters
        assert np.array_equal(voice.process(2000, dtype=np.float64), twin.process(2000, dtype=np.float64))
        return
    assert getattr(voice.parameters, parameter) == value
    x = np.concatenate([before, voice.process(100 * MS, dtype=np.float64)])
    assert np.all(np.isfinite(x)) and np.max(np.abs(x)) <= MAX_RAW_PEAK
    if _glides(name, get_model(name).table[parameter]):
        moved = {n: (getattr(twin.parameters, n), getattr(voice.parameters, n)) for n in get_model(name).table.names}
        assert step_ratio(x, before.size, RATE) <= (MAX_SWEEP_RATIO if _sweeps(moved) else MAX_STEP_RATIO)


def _sweeps(moved: dict) -> bool:
    """Whether a change moves a stiffness, density or length by more than SWEEP_FACTOR: the voice's
    modes then sweep octaves within its 5 ms glide, and the steps of that sweep are the sound's own."""
    return any(isinstance(old, float) and old > 0 and new > 0 and max(new / old, old / new) > SWEEP_FACTOR
               for name, (old, new) in moved.items()
               if name in ("youngs_modulus_pa", "density_kg_m3", "length_m", "thickness_m"))


CLICK_CHANGES = {
    "twang": ({"free_bar_gain": 0.0, "q": 800.0}, [
        ("level_db", -30.0), ("level_db", 0.0), ("length_m", 0.2), ("length_m", 0.5), ("thickness_m", 0.005),
        ("youngs_modulus_pa", 6e9), ("density_kg_m3", 2500.0), ("q", 50.0), ("q", 800.0), ("shape", 6.0),
        ("shape", 0.5), ("gain_mapping", "log"), ("short_length_ratio", 0.4), ("full_cantilever_gain", 0.0),
        ("short_cantilever_gain", 1.0), ("slide", True), ("vibrato_rate_hz", 8.0), ("vibrato_depth_hz", 50.0),
        ("slide_time_s", 0.05)]),
}
"""Per model, settings of a clear tone (long decays, no noise) and changes made 0.3 s into it
that must pass both click measures: the step ratio over a wider window (5 ms before to 25 ms
after) and the 12 kHz high-pass spike (every mode of this ruler lies far below 12 kHz)."""


def test_the_click_measures_catch_an_unsmoothed_change():
    """A 700 Hz sine whose level jumps (x0.1, x0.5, x2) fails the step ratio or the high-pass
    spike, and the spike by five times its bound."""
    t = np.arange(RATE) / RATE
    for gain_after in (0.1, 0.5, 2.0):
        x = np.sin(2 * np.pi * 700 * t + 0.3) * np.where(t < 0.5, 1.0, gain_after)
        ratio, spike = step_ratio(x, RATE // 2, RATE, around_ms=(5, 25)), highpass_spike(x, RATE // 2, RATE)
        assert ratio > MAX_STEP_RATIO or spike > MAX_HIGHPASS_SPIKE
        assert spike > 5 * MAX_HIGHPASS_SPIKE


@pytest.mark.parametrize("name,parameter,value", [pytest.param(name, parameter, value, id=f"{name}-{parameter}-{value}")
                                                  for name, (_, changes) in CLICK_CHANGES.items() if name in MODELS
                                                  for parameter, value in changes])
def test_a_change_of_a_clear_tone_passes_both_click_measures(name, parameter, value):
    voice = fresh(name, model_settings(name, **CLICK_CHANGES[name][0]))
    voice.trigger()
    before = voice.process(300 * MS, dtype=np.float64)
    voice.set_parameters(**{parameter: value})
    x = np.concatenate([before, voice.process(100 * MS, dtype=np.float64)])
    assert np.all(np.isfinite(x))
    assert step_ratio(x, before.size, RATE, around_ms=(5, 25)) <= MAX_STEP_RATIO
    assert highpass_spike(x, before.size, RATE) <= MAX_HIGHPASS_SPIKE


def _twang_level_glide(rate: float) -> tuple[int, str]:
    from barsynth.models.twang import CONTROL_FRAME_S, SMOOTHING_TIME_S

    frame = max(1, int(round(rate * CONTROL_FRAME_S)))  # from the next control frame, in whole frames
    return (ramp_steps(SMOOTHING_TIME_S, rate / frame) + 1) * frame, "within"


def _farnell_level_glide(rate: float) -> tuple[int, str]:
    from barsynth.models.farnell import SMOOTHING_TIME_S

    return ramp_steps(SMOOTHING_TIME_S, rate), "linear"


def _bar_level_glide(rate: float) -> tuple[int, str]:
    return ramp_steps(LEVEL_GLIDE_S, rate), "db"


LEVEL_GLIDES = {"twang": _twang_level_glide, "farnell": _farnell_level_glide, "banded": _bar_level_glide,
                "allpass": _bar_level_glide, "fd": _bar_level_glide}
"""How each model glides a new level_db, at a rate: (samples, shape). "db": an output gain in
equal steps of dB, a step a sample from the first sample on (dsp.smoothing.LEVEL_GLIDE_S);
"linear": a gain in equal steps, a step a sample (Farnell's 5 ms); "within": its controls'
ramp, which starts at the next control frame and lasts whole frames (the twang's 5 ms), so
only falling all the way and being there within the samples is checked."""

GLIDE_ALONGSIDE = {"fd": {"sigma0_per_s": 1.0}}
"""A change made together with the level (and to the twin without it): the fd bar redesigns its
step for it, and the level must glide through that too."""

LEVEL_CHANGE_DB = -20.0


def _glide_cases():
    for name in MODELS:
        for ex in excitations(name):
            yield pytest.param(name, excited(name, ex, long_bow=True), id=f"{name}-{ex or 'default'}")
        for label in SCENARIOS.get(name, {}):
            yield pytest.param(name, scenario_settings(name, label), id=f"{name}-{label}")


@pytest.mark.parametrize("name,parameters", list(_glide_cases()))
def test_a_new_level_glides_there_along_the_models_ramp(name, parameters):
    """The sound with a level change is the sound without it times the model's ramp (from just
    below 1: no jump), then held at the new level; nothing else changes (not the loops, the
    grid or the noise)."""
    voice, twin = fresh(name, parameters, seed=5), fresh(name, parameters, seed=5)
    heads = []
    for v in (voice, twin):
        v.trigger()
        heads.append(v.process(100 * MS, dtype=np.float64))
    alongside = GLIDE_ALONGSIDE.get(name, {})
    voice.set_parameters(level_db=voice.parameters.level_db + LEVEL_CHANGE_DB, **alongside)
    if alongside:
        twin.set_parameters(**alongside)
    assert np.array_equal(*heads)
    changed, kept = voice.process(100 * MS, dtype=np.float64), twin.process(100 * MS, dtype=np.float64)
    heard = np.abs(kept) > 1e-3 * np.max(np.abs(kept))
    at = np.flatnonzero(heard)
    assert at.size > 0.5 * kept.size
    gain, target = changed[heard] / kept[heard], 10.0 ** (LEVEL_CHANGE_DB / 20.0)
    steps, shape = LEVEL_GLIDES.get(name, _bar_level_glide)(RATE)
    done = np.minimum(at + 1, steps) / steps
    if shape == "db":
        assert np.allclose(gain, 10.0 ** (LEVEL_CHANGE_DB / 20.0 * done), rtol=1e-12, atol=0.0)
    elif shape == "linear":
        assert np.allclose(gain, 1.0 + (target - 1.0) * done, rtol=1e-12, atol=0.0)
    else:
        assert np.all(np.diff(gain) <= 1e-12)  # falls, never back
    assert gain[0] > 0.98  # no jump at the change
    assert np.allclose(gain[at >= steps], target, rtol=1e-9, atol=0.0) and np.any(at >= steps)


REFUSED_COMBINATIONS = {
    "banded": [({}, {"length_m": 3.0, "thickness_m": 0.0003}, "no mode of this object"),  # no mode above 30 Hz
               ({"tuning": "ratios", "frequency_hz": 440.0}, {"frequency_hz": 5000.0, "mode_ratios": (4.0,)},
                "no mode of this object")],  # its one mode above a quarter of the rate
    "allpass": [({}, {"length_m": 3.0, "thickness_m": 0.0003}, "first mode")],  # the first mode below 1 Hz
    "fd": [({}, {"theta": 1.0}, "unstable")],  # unstable at this grid and step
}
"""Values each in range that a model refuses together (on top of some settings), and the reason
it gives: set_parameters must roll back."""


def _refusals(name: str):
    table = get_model(name).table
    numeric = [p for p in table if p.kind not in (CHOICE, BOOL, FLOATS)]
    yield {}, {"no_such_parameter": 1.0}, "no_such_parameter"
    yield {}, {numeric[0].name: numeric[0].maximum + (numeric[0].maximum - numeric[0].minimum)}, numeric[0].name
    yield {}, {numeric[-1].name: float("nan")}, numeric[-1].name
    # one good value with a bad one: neither is taken
    yield {}, {numeric[0].name: numeric[0].from_unit_interval(0.3), numeric[-1].name: numeric[-1].minimum - 1.0}, \
        numeric[-1].name
    yield from REFUSED_COMBINATIONS.get(name, [])


@pytest.mark.parametrize("name", MODELS)
def test_a_refused_change_leaves_the_voice_as_it_was(name):
    for base, bad, reason in _refusals(name):
        voice = fresh(name, model_settings(name, **base))
        voice.trigger()
        voice.process(1000)
        twin = copy.deepcopy(voice)
        with pytest.raises(ParameterError) as info:
            voice.set_parameters(**bad)
        assert "\n" not in str(info.value) and reason in str(info.value), (bad, str(info.value))
        assert voice.parameters == twin.parameters, bad
        assert np.array_equal(voice.process(3000, dtype=np.float64), twin.process(3000, dtype=np.float64)), bad


# -- random settings -------------------------------------------------------------------------------
def _draw_settings(data, name: str) -> dict:
    """Every parameter drawn along its scale (table.settings_at); lists as tuples of one drawn
    length (so ratios and their T60s can agree), or left at their defaults (given whenever the
    drawn choices ask for them and their default is empty); RANDOM_RANGES narrowed for speed."""
    table = get_model(name).table
    narrowed = RANDOM_RANGES.get(name, {})
    values = table.settings_at({p.name: data.draw(st.floats(0.0, 1.0), label=p.name)
                                for p in table if p.kind != FLOATS and p.name not in narrowed})
    length = data.draw(st.integers(2, 6), label="list length")
    resolved = table.resolve(values)
    for p in table:
        # a list the drawn choices ask for and whose default is empty (fd's profile = samples
        # asks for its profile_samples) is always given: else such a choice is only ever refused
        asked_for = bool(p.when) and not p.default and p.acts_under(resolved)
        if p.kind == FLOATS and (asked_for or data.draw(st.booleans(), label=f"{p.name} given")):
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


def _twang_has_no_audible_mode(values: dict, rate: int) -> bool:
    from barsynth.models.twang import AUDIBLE_MIN_HZ

    return not any(m.frequency_hz >= AUDIBLE_MIN_HZ for m in get_model("twang").describe(values, sample_rate=rate))


@dataclass(frozen=True)
class RandomRenders:
    """How a model's random settings are rendered and judged: ``seconds`` at one of ``rates``,
    ``examples`` of them; the raw peak below ``max_raw_peak``; a refusal only for one of
    REFUSAL_REASONS, and (where ``refused_exactly_when`` is given) exactly when it says;
    described modes with ``positive_gains`` where the model's gains are levels."""

    seconds: float = 0.1
    examples: int = 25
    rates: tuple = (22050, 44100, 96000)
    max_raw_peak: float = MAX_RAW_PEAK
    refused_exactly_when: Callable[[dict, int], bool] | None = None
    positive_gains: bool = False


RANDOM_RENDERS = {
    "twang": RandomRenders(0.3, 60, (8000, 44100, 96000), max_raw_peak=4.0,
                           refused_exactly_when=_twang_has_no_audible_mode, positive_gains=True),
    "farnell": RandomRenders(0.2, 30, (8000, 44100, 96000), max_raw_peak=100.0),
    "banded": RandomRenders(0.2, 25),
    "allpass": RandomRenders(0.05, 8),
    "fd": RandomRenders(0.1, 25),
    "kalimba": RandomRenders(0.1, 15),
}
"""Per model, as its own tests rendered random settings. The raw peak is bounded where the model
says what its output is: the twang's is the level (at most 0 dB) times a mix of unit-gain
modes (cantilever sum 1.14, free bar up to 4 with noise crests): below 4; Farnell's patch
(+12 dB at most) peaks near 5: below 100. The bar models' output is a velocity (m/s) times
a level up to +40 dB, whose extreme corners (a heavy mallet at a clamped end) are far from
any bound a bar would keep: MAX_RAW_PEAK (a blow-up), and FOUND_BOUND for the cases found.
The all-pass bar fits its dispersion filters for every new setting (0.1 to 0.4 s each): 8."""


@pytest.mark.parametrize("name", MODELS)
def test_random_settings_in_range_give_a_one_line_refusal_or_finite_bounded_samples(name):
    """Random settings (RANDOM_RENDERS) and every FOUND case of the model: a one-line ParameterError
    for one of the model's REFUSAL_REASONS, or finite samples within its bound (FOUND_BOUND for a
    found one) and described modes below Nyquist with positive T60s."""
    spec = RANDOM_RENDERS.get(name, RandomRenders())

    @settings(max_examples=spec.examples)
    @given(data=st.data(), found=st.just(None))
    def check(data, found):
        if found is None:
            values = _draw_settings(data, name)
            rate = data.draw(st.sampled_from(spec.rates), label="sample_rate")
        else:
            values, rate = found
        refuses = spec.refused_exactly_when is not None and spec.refused_exactly_when(values, rate)
        try:
            x = raw(name, values, spec.seconds, rate=rate)
        except ParameterError as exc:
            assert_refused_for_a_reason(name, exc)
            assert refuses or spec.refused_exactly_when is None, str(exc)
            return
        assert not refuses, "rendered settings the model says it refuses"
        assert np.all(np.isfinite(x)) and np.max(np.abs(x)) < spec.max_raw_peak
        if found is not None:
            assert np.max(np.abs(x)) < FOUND_BOUND
        for m in get_model(name).describe(values, sample_rate=rate):
            assert 0.0 < m.frequency_hz < rate / 2 and m.t60_s > 0.0 and math.isfinite(m.gain), m
            assert m.gain > 0.0 or not spec.positive_gains, m

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
    assert np.abs(x[:lifted]).max() > 0.0  # it was bowed (a stopping bow may damp it to exactly 0)
    assert np.all(frames[1:] <= 1.05 * frames[:-1])  # nothing drives it: it only rings out
