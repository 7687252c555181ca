"""The polyphonic instrument (barsynth.playing.Instrument): several notes at once, each event at
its sample whatever the blocks, voices stolen without a click, the sustain pedal."""

from __future__ import annotations

import numpy as np
import pytest

from barsynth.errors import ParameterError
from barsynth.playing.instrument import Instrument

RATE = 48000


def song(instrument, events, total, block):
    """Play timed events ((sample, kind, args)) in blocks of ``block``."""
    out, now = [], 0
    pending = sorted(events)
    while now < total:
        n = min(block, total - now)
        for at, kind, args in [e for e in pending if now <= e[0] < now + n]:
            getattr(instrument, kind)(*args[0], **{**args[1], "at": at - now})
        pending = [e for e in pending if e[0] >= now + n]
        out.append(instrument.process(n))
        now += n
    return np.concatenate(out)


EVENTS = [(0, "note_on", ((60, 100), {})), (700, "note_on", ((64, 90), {})), (1500, "note_on", ((67, 80), {})),
          (3000, "note_off", ((60,), {})), (4000, "control", ((64, 127), {})), (4500, "note_off", ((64,), {})),
          (6000, "control", ((64, 0), {})), (7000, "note_on", ((72, 120), {}))]


@pytest.mark.parametrize("block", [1, 37, 256, 1000, 10000])
def test_blocks_of_any_size_give_the_same_samples(block):
    whole = song(Instrument("banded", voices=4, preset="marimba"), EVENTS, 10000, 10000)
    assert np.max(np.abs(whole)) > 0
    assert np.array_equal(song(Instrument("banded", voices=4, preset="marimba"), EVENTS, 10000, block), whole)


def test_a_chord_sounds_every_note():
    piano = Instrument("banded", voices=4, preset="marimba")
    for note in (60, 64, 67):
        piano.note_on(note, 100)
    x = piano.process(RATE)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    f = np.fft.rfftfreq(x.size, 1 / RATE)
    for hz in (261.63, 329.63, 392.0):
        near = (f > hz - 3) & (f < hz + 3)
        far = (f > hz + 20) & (f < hz + 40)
        assert np.max(spectrum[near]) > 30 * np.max(spectrum[far])


def test_a_stolen_voice_fades_without_a_click():
    two = Instrument("banded", voices=2, preset="marimba")
    two.note_on(60, 127)
    two.note_on(64, 127, at=10)
    x1 = two.process(4800)
    two.note_on(67, 127)  # a third note: the oldest is stolen
    x2 = two.process(4800)
    x = np.concatenate([x1, x2])
    steps = np.abs(np.diff(x))
    assert np.max(steps[4790:4900]) < 3.0 * np.max(steps[3800:4790])


def test_sustain_holds_note_offs_until_the_pedal_comes_up():
    held = Instrument("banded", voices=2, parameters={"excitation": "bow", "bow_duration_s": 60.0})
    free = Instrument("banded", voices=2, parameters={"excitation": "bow", "bow_duration_s": 60.0})
    for inst, pedal in ((held, True), (free, False)):
        inst.note_on(60, 100)
        inst.process(4800)
        if pedal:
            inst.control(64, 127)
        inst.note_off(60)
    late_held = held.process(48000)[-4800:]
    late_free = free.process(48000)[-4800:]
    assert np.sqrt(np.mean(late_held ** 2)) > 3 * np.sqrt(np.mean(late_free ** 2))


def _rms(x):
    return float(np.sqrt(np.mean(x ** 2)))


@pytest.mark.parametrize("preset", ["vibraphone", "vibraphone-bar"])
def test_the_vibraphone_damper_pedal_holds_or_damps_its_notes(preset):
    """Pedal up: a released note is damped (the preset's damper = release); pedal down: it rings
    on until the pedal comes up, which damps it then. A marimba rings on whatever the pedal."""
    tails = {}
    for case in ("up", "down", "lifted"):
        inst = Instrument("banded", voices=2, preset=preset)
        if case != "up":
            inst.control(64, 127)
        inst.note_on(69, 100)
        inst.process(RATE // 4)
        inst.note_off(69)
        inst.process(RATE // 4)
        if case == "lifted":
            inst.control(64, 0)
        tails[case] = _rms(inst.process(RATE // 2)[-RATE // 10:])
    assert tails["down"] > 30 * tails["up"], tails  # a damper T60 of 80 ms against seconds
    assert tails["down"] > 30 * tails["lifted"], tails
    marimba = Instrument("banded", voices=2, preset="marimba")
    marimba.note_on(69, 100)
    marimba.process(RATE // 4)
    marimba.note_off(69)
    ring = marimba.process(RATE // 4)
    assert _rms(ring[-RATE // 10:]) > 0.3 * _rms(ring[:RATE // 10])


def test_the_modulation_wheel_sets_the_motor_rate_of_every_voice():
    """CC 1 on a vibraphone bar: its motor's tremolo rate follows the wheel (the tube's sound is
    modulated at that rate: the envelope's spectrum peaks there)."""
    rates = {}
    for value, expected_hz in ((32, 12.0 * 32 / 127), (110, 12.0 * 110 / 127)):
        inst = Instrument("banded", voices=2, preset="vibraphone-bar")
        inst.control(1, value)
        inst.control(64, 127)
        inst.note_on(57, 100)
        x = inst.process(2 * RATE)[RATE // 2:]
        assert all(s.voice.parameters.motor_rate_hz == pytest.approx(expected_hz) for s in inst._slots)
        envelope = np.log(np.abs(x).reshape(-1, 480).max(axis=1))  # 10 ms frames, in nepers
        frames = np.arange(envelope.size)
        envelope = envelope - np.polyval(np.polyfit(frames, envelope, 1), frames)  # the decay taken away
        spectrum = np.abs(np.fft.rfft(envelope * np.hanning(envelope.size), 8 * envelope.size))
        f = np.fft.rfftfreq(8 * envelope.size, 0.01)
        band = f > 1.5
        rates[value] = f[band][np.argmax(spectrum[band])]
        assert abs(rates[value] - expected_hz) < 0.35, (value, rates[value], expected_hz)


def test_the_modulation_wheel_starts_a_twangs_vibrato_while_it_sounds():
    """CC 1 on the twang sets its vibrato rate at the control's sample: the sound is unchanged
    before it and differs after it (the loudest mode swings)."""
    def play(wheel):
        inst = Instrument("twang", voices=1)
        inst.note_on(40, 110)
        if wheel:
            inst.control(1, 80, at=RATE // 10)
        return inst.process(RATE // 2), inst._slots[0].voice.parameters.vibrato_rate_hz
    (plain, off), (swung, on) = play(False), play(True)
    assert off == 0.0 and on == pytest.approx(8.0 * 80 / 127)
    assert np.array_equal(plain[:RATE // 10], swung[:RATE // 10])
    assert _rms(swung[RATE // 4:] - plain[RATE // 4:]) > 0.05 * _rms(plain[RATE // 4:])


def test_a_note_out_of_reach_is_refused_when_played_and_nothing_is_queued():
    inst = Instrument("fd", voices=2, parameters={"points": 40})
    with pytest.raises(ParameterError) as info:
        inst.note_on(-20, 100)
    assert "length_m" in str(info.value) and "allowed" in str(info.value)
    with pytest.raises(ParameterError):
        inst.note_on(60, 300)
    assert not np.any(inst.process(2048))  # nothing was queued
    inst.note_on(69, 100)
    assert np.max(np.abs(inst.process(2048))) > 0


def test_length_tuned_notes_give_the_same_samples_whatever_the_blocks():
    """A bar built from physics: each note's length is found from the instrument's settings, not
    from whichever note a voice played last, so blocks of any size agree to the sample."""
    events = [(0, "note_on", ((60, 100), {})), (300, "note_on", ((67, 90), {})), (900, "note_off", ((60,), {})),
              (1200, "note_on", ((72, 80), {})), (1500, "note_on", ((60, 70), {}))]
    whole = song(Instrument("fd", voices=2, parameters={"points": 40}), events, 3000, 3000)
    assert np.max(np.abs(whole)) > 0
    assert np.array_equal(song(Instrument("fd", voices=2, parameters={"points": 40}), events, 3000, 1), whole)


STEALS = [(0, "note_on", ((60, 127), {})), (3000, "note_on", ((84, 40), {})), (9000, "note_on", ((72, 100), {})),
          (20000, "note_off", ((60,), {})), (20000, "note_off", ((84,), {})), (26000, "note_on", ((67, 90), {})),
          (30000, "note_on", ((65, 90), {})), (34000, "note_on", ((62, 90), {}))]


@pytest.mark.parametrize("block", [64, 100, 4801])
def test_which_voice_is_stolen_does_not_depend_on_the_blocks(block):
    """Two voices, more notes: the quietest voice is judged by whole windows of the instrument's
    own samples, so the same voices are stolen (and the same samples come out) in any blocks."""
    whole = song(Instrument("banded", voices=2, preset="marimba"), STEALS, 40000, 40000)
    parts = Instrument("banded", voices=2, preset="marimba")
    assert np.array_equal(song(parts, STEALS, 40000, block), whole)


def test_a_note_off_releases_the_oldest_note_of_its_pitch():
    inst = Instrument("banded", voices=2, parameters={"excitation": "bow", "bow_duration_s": 60.0})
    inst.note_on(64, 100)
    inst.note_on(60, 100, at=10)
    inst.note_off(64, at=100)
    inst.note_on(60, 100, at=200)  # takes the first voice (the oldest released): slot order is not age
    inst.process(1000)
    inst.note_off(60)
    inst.process(10)
    first, second = sorted(inst._slots, key=lambda s: s.started)
    assert (first.started, second.started) == (10, 200)
    assert first.released is not None and second.released is None


def test_a_rung_out_voice_is_freed_and_no_longer_rendered():
    inst = Instrument("banded", voices=4, preset="xylophone")
    for k, note in enumerate((60, 64, 67, 72)):
        inst.note_on(note, 100, at=k)
    inst.process(RATE // 10)
    for note in (60, 64, 67, 72):
        inst.note_off(note)
    tail = inst.process(30 * RATE)
    assert all(slot.note is None for slot in inst._slots)
    freed_at = np.flatnonzero(tail)[-1]
    assert freed_at < 29 * RATE and np.max(np.abs(tail[freed_at - 4800:freed_at])) < 1e-5 * np.max(np.abs(tail))
    inst.note_on(60, 100)  # a freed voice plays again
    assert np.max(np.abs(inst.process(4800))) > 0.1 * np.max(np.abs(tail))


def test_a_soft_note_after_a_loud_one_starts_soft():
    """Farnell's level (and pitch) start at the note's own settings, not the last note's: a
    velocity-10 note's first 5 ms are as soft as the rest of it, against a velocity-127 note."""
    inst = Instrument("farnell", voices=1)
    inst.note_on(60, 127)
    loud = inst.process(RATE // 10)
    inst.note_off(60)
    inst.process(5 * RATE)
    assert inst._slots[0].note is None  # rung out: the next note takes the voice as it is (no fading copy)
    inst.note_on(60, 10)
    soft = inst.process(RATE // 10)
    assert np.max(np.abs(soft[:240])) < 0.1 * np.max(np.abs(loud[:240]))
