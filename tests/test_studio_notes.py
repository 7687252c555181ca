"""Notes in the studio's live stream (studio.stream with studio.notes): chords at the model's
note frequencies, note offs, refusals, the same samples as an offline Instrument, sets during
notes, the limiter and sleep over notes, and the WebSocket path."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fastapi.testclient import TestClient
from test_studio_stream import RATE, decode, play, started

from barsynth.errors import BarsynthError
from barsynth.models import get_model
from barsynth.playing.instrument import Instrument
from barsynth.playing.notes import note_hz, pitch_of
from barsynth.studio.notes import MAX_RINGING, VOICES
from barsynth.studio.server import create_app
from barsynth.studio.stream import BLOCK, LIMIT, parse_message

RATIOS = {"tuning": "ratios", "frequency_hz": 440.0}
BOWED = {**RATIOS, "excitation": "bow", "bow_duration_s": 60.0}


def peak_hz(x: np.ndarray, near_hz: float, width_hz: float = 10.0) -> tuple[float, float]:
    """The strongest spectral peak within ``width_hz`` of ``near_hz`` (parabolic interpolation; Hz)
    and its height over the spectrum's median (a ratio)."""
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    f = np.fft.rfftfreq(x.size, 1 / RATE)
    band = np.flatnonzero(np.abs(f - near_hz) <= width_hz)
    k = band[np.argmax(spectrum[band])]
    a, b, c = np.log(spectrum[k - 1:k + 2] + 1e-300)
    shift = 0.5 * (a - c) / (a - 2 * b + c)
    return float(f[k] + shift * RATE / x.size), float(spectrum[k] / np.median(spectrum))


def cents(a: float, b: float) -> float:
    return 1200.0 * abs(np.log2(a / b))


def rms(x: np.ndarray) -> float:
    return max(1e-30, float(np.sqrt(np.mean(np.asarray(x, float) ** 2))))


@pytest.mark.parametrize("model_name, parameters", [("banded", RATIOS), ("kalimba", {})])
def test_a_chord_of_two_notes_sounds_both_at_the_models_note_frequencies(model_name, parameters):
    """banded tuned by ratios moves frequency_hz; the kalimba moves its tine's length: the pitch
    each note has is the model's own (describe) at the note's settings."""
    stream = started(model_name, parameters)
    stream.handle({"type": "note_on", "pitch": 60, "velocity": 100})
    stream.handle({"type": "note_on", "pitch": 67, "velocity": 100})
    x, _ = play(stream, 1.0)
    model = get_model(model_name)
    settings = model.table.resolve(parameters)
    for pitch in (60, 67):
        expected = note_hz(pitch)
        found, height = peak_hz(x, expected)
        assert cents(found, expected) < 3.0, (pitch, found, expected)
        assert height > 1000, (pitch, height)
    # and the model's own pitch of the note's settings is that note (the pitch search of spec 10.1)
    from barsynth.playing.notes import note_map, note_settings

    changes = note_settings(model, settings, note_hz(67), 0.8, sample_rate=RATE)
    assert cents(pitch_of(model, model.table.changed(settings, changes), note_map(model, settings).group, RATE),
                 note_hz(67)) < 0.05
    assert np.max(np.abs(x)) <= LIMIT + 1e-6


def test_the_streamed_notes_are_an_offline_instrument_render_times_the_gains():
    """Events at block boundaries: the stream's samples are the Instrument's (same voices, seed,
    settings), times the notes' gain and the stream's gain, cast to float32: equal to the bit."""
    stream = started("banded", BOWED)
    events = {0: ("note_on", 60, 40), 10: ("note_on", 64, 30), 20: ("control", 64, 127), 30: ("note_off", 60),
              40: ("note_off", 64), 60: ("control", 64, 0), 70: ("note_on", 67, 50), 90: ("note_off", 67)}
    blocks = []
    for k in range(140):
        event = events.get(k)
        if event and event[0] == "note_on":
            stream.handle({"type": "note_on", "pitch": event[1], "velocity": event[2]})
        elif event and event[0] == "note_off":
            stream.handle({"type": "note_off", "pitch": event[1]})
        elif event:
            stream.handle({"type": "control", "cc": event[1], "value": event[2]})
        blocks.append(decode(stream.next_block())[2])
        stream.handle({"type": "played", "samples": stream.samples_sent})
    streamed = np.concatenate(blocks)
    offline = Instrument("banded", voices=VOICES, parameters=BOWED, sample_rate=RATE, seed=0)
    out = []
    for k in range(140):
        event = events.get(k)
        if event and event[0] == "note_on":
            offline.note_on(event[1], event[2])
        elif event and event[0] == "note_off":
            offline.note_off(event[1])
        elif event:
            offline.control(event[1], event[2])
        out.append(offline.process(BLOCK))
    x = np.concatenate(out)
    playing = stream._playing
    expected = ((x * playing.notes.gain) * playing.base_gain).astype(np.float32)
    assert 0.3 < np.max(np.abs(expected)) < LIMIT  # loud, and the limiter has nothing to do
    assert np.array_equal(streamed, expected)


def test_a_note_off_lets_a_bowed_note_decay_and_a_held_one_sound_on():
    held, let_go = started("banded", BOWED), started("banded", BOWED)
    for stream in (held, let_go):
        stream.handle({"type": "note_on", "pitch": 69, "velocity": 100})
    before = [play(stream, 0.5)[0] for stream in (held, let_go)]
    let_go.handle({"type": "note_off", "pitch": 69})
    after_held, after_free = play(held, 1.5)[0], play(let_go, 1.5)[0]
    level_before = rms(before[1][-4800:])
    assert 20 * np.log10(rms(after_free[-4800:]) / level_before) < -30  # lifted: it rings down
    assert 20 * np.log10(rms(after_held[-4800:]) / rms(before[0][-4800:])) > -3  # still bowed


def test_the_sustain_pedal_holds_note_offs_until_it_comes_up_for_later_settings_too():
    stream = started("banded", BOWED)
    stream.handle({"type": "note_on", "pitch": 69, "velocity": 100})
    play(stream, 0.3)
    stream.handle({"type": "control", "cc": 64, "value": 127})
    stream.handle({"type": "set", "id": 1, "parameters": {"level_db": -1.0}})  # the next note: new voices
    stream.handle({"type": "note_on", "pitch": 72, "velocity": 100})
    play(stream, 0.3)
    assert stream._playing.notes._ringing  # the first note rings on with the settings it began with
    for pitch in (69, 72):
        stream.handle({"type": "note_off", "pitch": pitch})
    held, _ = play(stream, 1.0)
    stream.handle({"type": "control", "cc": 64, "value": 0})
    freed, _ = play(stream, 1.5)
    for pitch in (69, 72):  # both held by the pedal, both let go when it comes up
        assert peak_level(held[-9600:], note_hz(pitch)) - peak_level(held[:9600], note_hz(pitch)) > -3, pitch
        assert peak_level(freed[-9600:], note_hz(pitch)) - peak_level(held[-9600:], note_hz(pitch)) < -30, pitch


def test_bad_notes_are_refused_in_one_line_and_the_stream_plays_on():
    stream = started("twang")
    stream.handle({"type": "note_on", "pitch": 45, "velocity": 100})
    for message, words in [({"type": "note_on", "pitch": 200, "velocity": 100}, "pitch = 200 is out of range"),
                           ({"type": "note_on", "pitch": 60, "velocity": "x"}, "velocity = 'x' is out of range"),
                           ({"type": "note_on", "pitch": 60, "velocity": 0}, "velocity = 0 is out of range"),
                           ({"type": "note_on", "pitch": 60, "velocity": 64.5}, "whole numbers from 1 to 127"),
                           ({"type": "note_on", "pitch": True}, "pitch = True is out of range"),
                           ({"type": "note_off", "pitch": -1}, "pitch = -1 is out of range"),
                           ({"type": "control", "cc": 200, "value": 1}, "cc = 200 is out of range"),
                           ({"type": "note_on", "pitch": 83, "velocity": 100},
                            "the note at 987.767 Hz needs length_m = 0.04")]:
        with pytest.raises(BarsynthError, match=words) as caught:
            stream.handle(message)
        assert "\n" not in str(caught.value) and len(str(caught.value)) < 200
    for text, words in [('{"type": "note_on"}', "needs pitch"), ('{"type": "note_on", "pitch": 60, "colour": 1}',
                                                                  "unknown field 'colour'")]:
        with pytest.raises(BarsynthError, match=words):
            parse_message(text)
    with pytest.raises(BarsynthError, match="needs a started stream"):
        type(stream)().handle({"type": "note_on", "pitch": 60})
    stream.handle({"type": "note_off", "pitch": 50})  # a note not held: nothing to do, no error
    x, _ = play(stream, 0.5)  # the good note plays on, at its pitch
    found, _ = peak_hz(x, note_hz(45), 6.0)
    assert cents(found, note_hz(45)) < 5 and np.max(np.abs(x)) > 0.05
    assert stream.refused() == []


def test_a_set_while_notes_sound_changes_the_next_notes_only():
    """The note that sounds rings on exactly as it would have (no click, nothing redesigned);
    the next note has the new settings (here 20 dB quieter)."""
    changed, same = started("banded", RATIOS), started("banded", RATIOS)
    for stream in (changed, same):
        stream.handle({"type": "note_on", "pitch": 60, "velocity": 100})
    first = [play(stream, 0.2)[0] for stream in (changed, same)]
    changed.handle({"type": "set", "id": 1, "parameters": {"level_db": -20.0}})
    ringing = [play(stream, 0.2)[0] for stream in (changed, same)]
    assert np.array_equal(first[0], first[1]) and np.array_equal(ringing[0], ringing[1])
    for stream in (changed, same):
        stream.handle({"type": "note_on", "pitch": 67, "velocity": 100})
    later = [play(stream, 1.0)[0] for stream in (changed, same)]
    level_changed, level_same = (peak_level(x, note_hz(67)) for x in later)
    assert level_changed - level_same == pytest.approx(-20.0, abs=0.5)
    assert peak_level(later[0], note_hz(60)) == pytest.approx(peak_level(later[1], note_hz(60)), abs=0.2)


def peak_level(x: np.ndarray, hz: float) -> float:
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    f = np.fft.rfftfreq(x.size, 1 / RATE)
    return float(20 * np.log10(np.max(spectrum[np.abs(f - hz) < 4]) + 1e-30))


def test_older_settings_ringing_on_are_bounded_and_a_loud_chord_is_limited():
    stream = started("banded", RATIOS)
    for k in range(10):  # a slider dragged between notes: each note has settings of its own
        stream.handle({"type": "set", "id": k + 1, "parameters": {"level_db": -k * 0.5}})
        play(stream, 0.02)
        stream.handle({"type": "note_on", "pitch": 48 + k, "velocity": 127})
    assert len(stream._playing.notes._ringing) <= MAX_RINGING + 1
    for pitch in range(60, 60 + VOICES):  # eight notes at full velocity at once
        stream.handle({"type": "note_on", "pitch": pitch, "velocity": 127})
    x, _ = play(stream, 0.5)
    assert np.all(np.isfinite(x)) and np.max(np.abs(x)) <= LIMIT + 1e-6 and np.max(np.abs(x)) > 0.5
    assert len(stream._playing.notes._ringing) <= MAX_RINGING


def test_a_note_wakes_a_sleeping_stream_and_a_stop_silences_the_notes():
    stream = started("banded", {**RATIOS, "mode_t60s_s": (0.05,)})
    stream.handle({"type": "note_on", "pitch": 72, "velocity": 100})
    x, _ = play(stream, 10.0)
    assert not stream.running and 3.0 <= x.size / RATE <= 3.1  # asleep three seconds after the note
    stream.handle({"type": "note_on", "pitch": 72, "velocity": 100})
    assert stream.running
    again, _ = play(stream, 0.1)
    assert np.max(np.abs(again)) > 0.05
    stream.handle({"type": "stop"})
    play(stream, 0.1)
    assert not stream.running and not stream._playing.notes.playing
    stream.handle({"type": "note_on", "pitch": 74, "velocity": 100})
    after, _ = play(stream, 0.1)
    assert stream.running and np.max(np.abs(after)) > 0.05
    # a note planned before a stop's fade and played during it: the fade goes on beside the new note
    planned = stream.plan_note({"type": "note_on", "pitch": 76, "velocity": 100})
    stream.handle({"type": "stop"})
    play(stream, BLOCK / RATE)  # one block of the fade
    stream.play_note(planned)
    late, _ = play(stream, 0.2)
    assert stream.running and len(stream._leaving) == 0
    found, _ = peak_hz(late, note_hz(76))
    assert cents(found, note_hz(76)) < 5 and np.max(np.abs(late)) > 0.05


def test_notes_over_the_websocket_and_a_refused_one_gets_one_line():
    with TestClient(create_app(), base_url="http://127.0.0.1:8000") as client, \
            client.websocket_connect("/api/stream", headers={"host": "127.0.0.1:8000"}) as socket:
        socket.send_json({"type": "start", "model": "banded", "sample_rate": RATE, "parameters": RATIOS})
        assert socket.receive_json()["type"] == "started"
        socket.send_json({"type": "note_on", "pitch": 200, "velocity": 100})
        socket.send_json({"type": "note_on", "pitch": 64, "velocity": 100})
        socket.send_json({"type": "note_on", "pitch": 71, "velocity": 100})
        samples, errors, played = [], [], 0
        while len(samples) < 160:
            message = socket.receive()
            if message.get("text"):
                errors.append(json.loads(message["text"]))
            elif message.get("bytes"):
                samples.append(decode(message["bytes"])[2])
                played += BLOCK
                socket.send_json({"type": "played", "samples": played})
        assert errors == [{"type": "error", "error": "parameter pitch = 200 is out of range; allowed: MIDI note "
                                                     "numbers from 0 to 127"}]
        x = np.concatenate(samples)[2048:]
        for pitch in (64, 71):
            found, height = peak_hz(x, note_hz(pitch))
            assert cents(found, note_hz(pitch)) < 5 and height > 100


def test_a_full_velocity_note_at_the_settings_own_pitch_peaks_at_the_notes_headroom():
    """The notes' gain comes from one note at the settings' pitch (440 Hz here) and velocity 127:
    that note peaks at NOTE_HEADROOM_DBFS (-12 dBFS), whatever the strike's own level."""
    from barsynth.studio.notes import NOTE_HEADROOM_DBFS

    for level_db in (0.0, -30.0):
        stream = started("banded", {**RATIOS, "level_db": level_db})
        stream.handle({"type": "note_on", "pitch": 69, "velocity": 127})
        x, _ = play(stream, 1.0)
        assert 20 * np.log10(np.max(np.abs(x))) == pytest.approx(NOTE_HEADROOM_DBFS, abs=0.01), level_db
