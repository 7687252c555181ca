"""Notes on every model (barsynth.playing.notes, Voice.note_on): the pitch lands on the note,
velocity drives the level, a note out of reach is one line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from barsynth.errors import ParameterError
from barsynth.models import get_model, model_names
from barsynth.playing.notes import control_settings, note_hz, note_map, pitch_of, velocity_fraction

RATE = 48000
FAST = {"fd": {"points": 40}}
NOTES = {"twang": 40, "farnell": 60, "banded": 69, "allpass": 72, "fd": 69, "ruler": 30, "kalimba": 72}
"""A note each model reaches from its defaults (the twang and the ruler ring low)."""


@pytest.mark.parametrize("name", model_names())
def test_every_model_declares_note_maps_on_its_own_table(name):
    model = get_model(name)
    assert model.note_maps, name
    for mapping in model.note_maps:
        named = [mapping.pitch, *mapping.when, *(c.parameter for c in mapping.velocity.values()),
                 *(c.per for c in mapping.velocity.values() if c.per),
                 *(c.parameter for c in mapping.controls.values())]
        assert all(n in model.table for n in named), (name, named)
        excitations = model.table["excitation"].choices if "excitation" in model.table else (None,)
        assert set(mapping.velocity) <= set(excitations)


def test_the_modulation_wheel_moves_what_each_model_declares():
    banded = get_model("banded")
    vibraphone = banded.preset("vibraphone-bar")
    assert control_settings(banded, vibraphone, 1, 127) == {"motor_rate_hz": 12.0}
    assert control_settings(banded, vibraphone, 1, 0) == {"motor_rate_hz": 0.0}
    assert control_settings(banded, banded.preset("marimba"), 1, 64) == {}  # no tube: no motor
    assert control_settings(banded, vibraphone, 7, 64) == {}  # a control it has not
    twang, farnell = get_model("twang"), get_model("farnell")
    assert control_settings(twang, twang.resolve(None), 1, 127) == {"vibrato_rate_hz": 8.0}
    assert control_settings(farnell, farnell.resolve(None), 1, 0) == {"vibrato_depth_hz": 1.0}
    for name in ("fd", "allpass", "ruler", "kalimba"):
        assert control_settings(get_model(name), get_model(name).resolve(None), 1, 64) == {}


@pytest.mark.parametrize("name", model_names())
def test_the_described_pitch_lands_on_the_note(name):
    model = get_model(name)
    voice = model.voice(FAST.get(name, {}), sample_rate=RATE)
    voice.note_on(NOTES[name], 100)
    mapping = note_map(model, voice.parameters)
    found = pitch_of(model, voice.parameters, mapping.group, RATE)
    assert abs(1200 * math.log2(found / note_hz(NOTES[name]))) < 0.02


@pytest.mark.parametrize("name", ["fd", "banded", "kalimba"])  # (Farnell's patch is noise-driven: its describe test covers it)
def test_the_sound_rings_at_the_note(name):
    voice = get_model(name).voice(FAST.get(name, {}), sample_rate=RATE)
    voice.note_on(frequency_hz=523.25, velocity=1.0)
    x = voice.process(RATE, dtype=np.float64)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    f = np.fft.rfftfreq(x.size, 1 / RATE)
    band = (f > 400) & (f < 700)
    peak = f[band][np.argmax(spectrum[band])]
    assert abs(peak - 523.25) < 2.0


@pytest.mark.parametrize("name", model_names())
def test_a_harder_note_is_louder(name):
    levels = []
    for velocity in (20, 120):
        voice = get_model(name).voice(FAST.get(name, {}), sample_rate=RATE, seed=0)
        voice.note_on(NOTES[name], velocity)
        levels.append(float(np.sqrt(np.mean(voice.process(RATE // 4, dtype=np.float64) ** 2))))
    assert levels[1] > 1.2 * levels[0], levels


@pytest.mark.parametrize("name,pitch", [("fd", -20), ("farnell", 120), ("kalimba", 0), ("fd", 140), ("banded", 140)])
def test_a_note_out_of_reach_is_one_line_and_changes_nothing(name, pitch):
    voice = get_model(name).voice(FAST.get(name, {}), sample_rate=RATE)
    before = voice.parameters
    with pytest.raises(ParameterError) as info:
        voice.note_on(pitch, 100)
    assert "allowed" in str(info.value) and "\n" not in str(info.value)
    assert "Nyquist" in str(info.value) if pitch == 140 else "needs" in str(info.value)
    assert voice.parameters == before


def test_pitch_and_velocity_in_their_units():
    assert note_hz(69) == 440.0 and note_hz(81) == 880.0 and note_hz(60.5) == pytest.approx(269.29, abs=0.01)
    assert note_hz(frequency_hz=100.0) == 100.0 and note_hz(69, tuning_hz=442.0) == 442.0
    assert velocity_fraction(127) == 1.0 and velocity_fraction(0) == 0.0 and velocity_fraction(0.5) == 0.5
    for bad in (128, -1, 1.5, True, "loud"):
        with pytest.raises(ParameterError):
            velocity_fraction(bad)
    with pytest.raises(ParameterError):
        note_hz(69, frequency_hz=440.0)


def test_the_note_map_table_in_the_docs_is_generated_from_the_models():
    from pathlib import Path

    from barsynth.playing.notes import note_maps_markdown

    doc = (Path(__file__).parents[1] / "docs" / "playing.md").read_text(encoding="utf-8")
    inside = doc.split("<!-- note-maps:begin -->\n", 1)[1].split("<!-- note-maps:end -->", 1)[0]
    assert inside == note_maps_markdown([get_model(n) for n in model_names()])


def test_a_voice_goes_from_a_loud_low_note_to_a_higher_one_whose_velocity_scales_with_it():
    """The ruler's tip is bent by a fraction of its overhang: after a full-velocity low note, a
    higher note (a shorter overhang) is checked with its own tip, not the last note's."""
    voice = get_model("ruler").voice(sample_rate=RATE)
    voice.note_on(40, 127)
    for note in (48, 60, 72):
        voice.note_on(note, 127)
        p = voice.parameters
        assert p.tip_displacement_mm == pytest.approx(0.25 * p.overhang_m * 1000.0)


def test_numpy_integers_are_midi_velocities():
    assert velocity_fraction(np.int64(127)) == 1.0 and velocity_fraction(np.uint8(0)) == 0.0
    with pytest.raises(ParameterError):
        velocity_fraction(np.int64(128))
