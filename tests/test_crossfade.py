"""Cross-faded voices (models.crossfade): no parameter change of any model and no re-trigger clicks.

The click measure is tests/clicks.py's step ratio: the largest sample-to-sample step from
2 ms before to 15 ms after the change, over the larger of the largest steps in the 20 ms
before it and in the 20 ms after that. A bare voice fails it for many changes, and a bare
twang's restart cuts its note (the tests below show the measures can fail); the cross-faded
voice passes it for every one.

A CrossfadingVoice keeps the voice contract's ``process(n, out=buf)``: the samples of
``process(n)`` into the caller's buffer, allocating nothing (tests/test_voice_contract.py
measures that through its fades).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from barsynth.errors import BarsynthError, ParameterError
from barsynth.models import get_model, model_names
from barsynth.models.crossfade import CrossfadingVoice
from barsynth.parameters import BOOL, CHOICE, FLOATS
from clicks import MAX_STEP_RATIO, largest_step, step_ratio

RATE = 48000
MS = RATE // 1000
BASE = {"twang": {"free_bar_gain": 0.0, "q": 800.0}, "farnell": {}, "banded": {}, "allpass": {},
        "fd": {"points": 60, "oversampling": 2}, "ruler": {}, "kalimba": {}}


def changed(model_name: str, name: str, value, *, crossfade: bool) -> tuple[np.ndarray, int]:
    model = get_model(model_name)
    voice = model.voice(BASE[model_name], sample_rate=RATE, seed=1)
    if crossfade:
        voice = CrossfadingVoice(voice, table=model.table)
    voice.trigger()
    before = voice.process(int(0.2 * RATE), dtype=np.float64)
    voice.set_parameters(**{name: value})
    after = voice.process(int(0.1 * RATE), dtype=np.float64)
    return np.concatenate([before, after]), before.size


def changes():
    """Every parameter that has a slider or a switch, of every model, to two other values."""
    for model_name in model_names():
        for p in get_model(model_name).table:
            if p.kind == FLOATS:
                continue
            if p.kind == CHOICE:
                values = [c for c in p.choices if c != p.default][:2]
            elif p.kind == BOOL:
                values = [not p.default]
            else:
                values = [p.from_unit_interval(0.25), p.from_unit_interval(0.75)]
            for value in values:
                yield pytest.param(model_name, p.name, value, id=f"{model_name}-{p.name}-{value!s:.8}")


@pytest.mark.parametrize("model_name,name,value", [("banded", "length_m", 0.2), ("banded", "density_kg_m3", 385.0),
                                                    ("fd", "bc", "clamped-free"), ("fd", "points", 106)])
def test_a_bare_voice_clicks_on_these_changes(model_name, name, value):
    """Changes no voice can glide: a new set of banded loops (another length or density moves
    every mode), a new finite-difference grid (another boundary or number of points). (The
    level glides in every model now; a bare all-pass voice has no change left that fails the
    measure: a rebuilt waveguide rings on beside the new one.)"""
    x, at = changed(model_name, name, value, crossfade=False)
    assert step_ratio(x, at, RATE) > 2.0


@pytest.mark.parametrize("model_name,name,value", list(changes()))
def test_no_change_of_any_parameter_clicks(model_name, name, value):
    try:
        x, at = changed(model_name, name, value, crossfade=True)
    except BarsynthError as exc:  # a combination the model refuses (the message says why)
        assert "allowed" in str(exc)
        return
    assert np.all(np.isfinite(x))
    assert step_ratio(x, at, RATE) <= MAX_STEP_RATIO


def test_without_events_the_output_is_the_voices_own():
    model = get_model("banded")
    bare, wrapped = model.voice(sample_rate=RATE), CrossfadingVoice(model.voice(sample_rate=RATE))
    bare.trigger()
    wrapped.trigger()
    assert np.array_equal(bare.process(5000), wrapped.process(5000))


def test_a_change_lands_after_the_fade_and_equals_the_changed_voice():
    """After the 10 ms fade the output is exactly the changed voice's."""
    model = get_model("banded")
    bare, wrapped = model.voice(sample_rate=RATE), CrossfadingVoice(model.voice(sample_rate=RATE))
    for voice in (bare, wrapped):
        voice.trigger()
        voice.process(2000)
        voice.set_parameters(level_db=-20.0)
    assert np.array_equal(bare.process(4000)[10 * MS:], wrapped.process(4000)[10 * MS:])


@pytest.mark.parametrize("model_name", ["twang", "farnell"])
def test_a_bare_restart_clicks_and_the_cross_faded_one_does_not(model_name):
    """These voices restart on a trigger; the ringing note fades out over 10 ms instead of
    stopping dead. Taking the new note away (the same voice triggered bare, same noise)
    leaves the old note ending: no larger a step than it had before. The bare twang cuts
    it: a step more than three times larger, and more than three times the cross-faded one's
    (the measure sees a click). (Farnell's note at 150 ms is mostly noise, whose own steps are
    as large as the cut.)"""
    model = get_model(model_name)
    ringing_voice = model.voice(BASE[model_name], sample_rate=RATE, seed=4)
    ringing_voice.trigger()
    ringing = ringing_voice.process(int(0.15 * RATE), dtype=np.float64)
    reference = copy.deepcopy(ringing_voice)
    reference.trigger()
    new_note = reference.process(30 * MS, dtype=np.float64)
    results = {}
    for crossfade in (False, True):
        voice = copy.deepcopy(ringing_voice)
        if crossfade:
            voice = CrossfadingVoice(voice)
        voice.trigger()
        left = np.concatenate([ringing, voice.process(30 * MS, dtype=np.float64) - new_note])  # the old note
        results[crossfade] = largest_step(left[ringing.size - 2 * MS:]) / largest_step(ringing[-20 * MS:])
    if model_name == "twang":
        assert results[False] > 3.0 and results[False] > 3.0 * results[True], results
    assert results[True] <= 1.2, results


def _events(voice, sizes, *, out_kind=None) -> np.ndarray:
    """A change, a restart with a change waiting behind it and another change, between blocks of
    ``sizes``; the samples as process() gives them, or through a buffer of ``out_kind``."""
    parts = []
    for i, n in enumerate(sizes):
        if i == 2:
            voice.set_parameters(level_db=-12.0)
        if i == 3:
            voice.trigger()
            voice.set_parameters(level_db=-6.0)
        if i == 5:
            voice.set_parameters(level_db=-3.0)
        if out_kind is None:
            parts.append(voice.process(n, dtype=np.float64))
        else:
            buf = np.full(n, np.nan, dtype=out_kind)
            assert voice.process(n, out=buf) is buf
            parts.append(buf.astype(np.float64))
    return np.concatenate(parts)


@pytest.mark.parametrize("max_block", [None, 64, 100])
@pytest.mark.parametrize("kind", [np.float64, np.float32])
@pytest.mark.parametrize("model_name", ["twang", "banded"])
def test_process_into_a_buffer_gives_the_samples_of_process(model_name, kind, max_block):
    """Through fades, restarts and waiting changes, with blocks below, at and above the
    largest block (pieces of it for a float32 buffer, and for a fade's work space)."""
    model = get_model(model_name)
    sizes = [1, 7, 480, 1000, 3000, 64, 5000, 100]

    def voice():
        v = CrossfadingVoice(model.voice(BASE[model_name], sample_rate=RATE, seed=2, max_block=max_block))
        v.trigger()
        return v

    expected = _events(voice(), sizes).astype(kind).astype(np.float64)
    assert np.array_equal(_events(voice(), sizes, out_kind=kind), expected)
    assert np.array_equal(voice().process(5000, dtype=kind), voice().process(5000, dtype=np.float64).astype(kind))


def test_a_wrong_buffer_or_type_is_refused_naming_it_and_changes_nothing():
    model = get_model("banded")
    mine, reference = (CrossfadingVoice(model.voice(sample_rate=RATE)) for _ in range(2))
    for voice in (mine, reference):
        voice.trigger()
        voice.set_parameters(level_db=-10.0)
    for bad in (np.empty(63), np.empty(64, dtype=np.int16), np.empty(128)[::2], [0.0] * 64):
        with pytest.raises(ParameterError, match="out"):
            mine.process(64, out=bad)
    with pytest.raises(ParameterError, match="dtype"):
        mine.process(64, dtype=np.int16)
    with pytest.raises(ParameterError, match="num_samples"):
        mine.process(-1)
    assert np.array_equal(mine.process(2000, dtype=np.float64), reference.process(2000, dtype=np.float64))


def test_prepare_sets_the_rate_and_block_ends_the_fade_and_makes_the_waiting_change():
    model = get_model("twang")
    voice = CrossfadingVoice(model.voice(BASE["twang"], sample_rate=RATE), table=model.table)
    voice.trigger()
    voice.process(100)
    voice.set_parameters(q=300.0)  # waits for the restart's fade
    assert voice.fading and voice.parameters.q == 800.0
    voice.prepare(22050, 128)
    assert not voice.fading and voice.sample_rate == 22050 and voice.max_block == 128
    assert voice.parameters.q == 300.0
    fresh = model.voice({**BASE["twang"], "q": 300.0}, sample_rate=22050, max_block=128)
    for v in (voice, fresh):
        v.trigger()
    assert np.array_equal(voice.process(3000, out=np.empty(3000, dtype=np.float32)),
                          fresh.process(3000, dtype=np.float32))
    with pytest.raises(ParameterError, match="sample_rate"):
        voice.prepare(7999)
    assert voice.sample_rate == 22050


def test_bad_values_are_refused_at_once_even_during_a_fade():
    model = get_model("twang")
    voice = CrossfadingVoice(model.voice(sample_rate=RATE), table=model.table)
    voice.trigger()
    voice.process(100)
    voice.set_parameters(q=300.0)
    assert voice.fading
    with pytest.raises(ParameterError, match="q = 5000"):
        voice.set_parameters(q=5000)
    voice.set_parameters(q=200.0)  # waits for the fade, then fades again
    voice.process(20 * MS)
    assert voice.parameters.q == 200.0


def test_a_combination_refused_after_the_fade_is_dropped_and_reported():
    model = get_model("banded")
    voice = CrossfadingVoice(model.voice(sample_rate=RATE), table=model.table)
    voice.trigger()
    voice.set_parameters(level_db=-10.0)
    voice.set_parameters(length_m=3.0, thickness_m=0.0003)  # each in range; no mode above 30 Hz
    x = voice.process(30 * MS)
    assert np.all(np.isfinite(x)) and voice.parameters.length_m == 0.3
    assert voice.refused and "no mode" in voice.refused[0]


def test_triggers_during_a_restart_fade_make_one_restart_after_it():
    model = get_model("twang")
    voice = CrossfadingVoice(model.voice(BASE["twang"], sample_rate=RATE))
    voice.trigger()
    voice.process(100)
    voice.trigger()  # a restart: a 10 ms fade begins
    for _ in range(20000):
        voice.trigger()
    voice.set_parameters(q=300.0)
    assert len(voice._waiting) == 2
    voice.process(30 * MS)
    assert voice.parameters.q == 300.0 and not voice._waiting
