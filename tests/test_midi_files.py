"""MIDI files read into timed events (barsynth.midi.events) and the channel/program map (barsynth.midi.mapping).

Files are written here, with mido or byte by byte, and every time is checked against seconds
computed by hand from ticks and tempi.
"""

from __future__ import annotations

import struct
from fractions import Fraction

import mido
import pytest

from barsynth.errors import BarsynthError, MidiFileError, MidiMapError, ParameterError
from barsynth.midi import (
    ControlChange,
    NoteOff,
    NoteOn,
    PitchBend,
    ProgramChange,
    load_map,
    parse_map,
    read_midi,
    sample_index,
)


def smf(tracks: list[bytes], *, fmt: int = 1, division: int = 480, count: int | None = None) -> bytes:
    """A standard MIDI file from raw track bodies (header division as a signed 16-bit number)."""
    head = b"MThd" + struct.pack(">LhhH" if division >= 0 else ">Lhhh", 6, fmt,
                                 len(tracks) if count is None else count, division)
    return head + b"".join(b"MTrk" + struct.pack(">L", len(body)) + body for body in tracks)


END = b"\x00\xff\x2f\x00"


def write(tmp_path, name: str, data: bytes):
    path = tmp_path / name
    path.write_bytes(data)
    return path


@pytest.fixture
def song_path(tmp_path):
    """Three tracks at 480 ticks per beat: a tempo track with two changes mid-song, channel 0 with a
    program change, sustain and a note-on of velocity 0, channel 1 with a note and a pitch bend.

    Tempo: 500000 µs/beat from tick 0, 250000 from tick 960 (t = 1 s), 1000000 from tick 1440
    (t = 1 + 480/480 * 0.25 = 1.25 s); so t(tick) = 1.25 + (tick - 1440) / 480 s after that.
    """
    midi = mido.MidiFile(type=1, ticks_per_beat=480)
    tempo, piano, strings = midi.add_track(), midi.add_track(), midi.add_track()
    tempo.extend([mido.MetaMessage("set_tempo", tempo=500000, time=0),
                  mido.MetaMessage("set_tempo", tempo=250000, time=960),
                  mido.MetaMessage("set_tempo", tempo=1000000, time=480),
                  mido.MetaMessage("end_of_track", time=960)])                      # ends at tick 2400
    piano.extend([mido.Message("program_change", channel=0, program=12, time=0),
                  mido.Message("note_on", channel=0, note=60, velocity=100, time=0),
                  mido.Message("note_off", channel=0, note=60, velocity=40, time=480),   # tick 480
                  mido.Message("note_on", channel=0, note=64, velocity=90, time=480),    # tick 960
                  mido.Message("control_change", channel=0, control=64, value=127, time=0),
                  mido.Message("note_on", channel=0, note=64, velocity=0, time=240),     # tick 1200
                  mido.Message("control_change", channel=0, control=64, value=0, time=720)])  # tick 1920
    strings.extend([mido.Message("note_on", channel=1, note=67, velocity=127, time=1000),  # tick 1000
                    mido.Message("pitchwheel", channel=1, pitch=-4096, time=0),
                    mido.Message("control_change", channel=1, control=1, value=33, time=440),  # tick 1440
                    mido.Message("note_off", channel=1, note=67, velocity=0, time=560)])      # tick 2000
    path = tmp_path / "song.mid"
    midi.save(path)
    return path


def test_times_through_tempo_changes_are_exact(song_path):
    song = read_midi(song_path)
    got = [(type(e).__name__, e.channel, e.time_s) for e in song.events]
    want = [("ProgramChange", 0, 0.0), ("NoteOn", 0, 0.0),
            ("NoteOff", 0, 0.5),                          # 480 ticks at 0.5 s/beat
            ("NoteOn", 0, 1.0), ("ControlChange", 0, 1.0),
            ("NoteOn", 1, 1.0 + 40 / 480 * 0.25),          # tick 1000 in the 0.25 s/beat stretch
            ("PitchBend", 1, 1.0 + 40 / 480 * 0.25),
            ("NoteOff", 0, 1.0 + 240 / 480 * 0.25),        # tick 1200: the note-on of velocity 0
            ("ControlChange", 1, 1.25),                   # tick 1440, where the tempo changes again
            ("ControlChange", 0, 1.25 + 480 / 480),       # tick 1920
            ("NoteOff", 1, 1.25 + 560 / 480)]             # tick 2000
    assert [g[:2] for g in got] == [w[:2] for w in want]
    for (_, _, time_s), (_, _, expected) in zip(got, want):
        assert abs(time_s - expected) < 1e-9
    assert song.events[7].time == Fraction(9, 8) and song.events[-1].time == Fraction(29, 12)
    assert abs(song.length_s - 3.25) < 1e-9 and song.length == Fraction(13, 4)   # the tempo track ends at tick 2400
    assert [(float(t), us) for t, us in song.tempo_changes] == [(0.0, 500000), (1.0, 250000), (1.25, 1000000)]
    assert song.midi_type == 1 and song.ticks_per_beat == 480 and song.dropped_note_offs == 0


def test_velocities_programs_controls_and_sample_indices(song_path):
    song = read_midi(song_path)
    ons = [e for e in song.events if isinstance(e, NoteOn)]
    offs = [e for e in song.events if isinstance(e, NoteOff)]
    assert [(e.channel, e.key, e.velocity, e.program) for e in ons] == [(0, 60, 100, 12), (0, 64, 90, 12),
                                                                       (1, 67, 127, 0)]
    assert [(e.key, e.velocity, e.cause) for e in offs] == [(60, 40, "note_off"), (64, 64, "note_on_0"),
                                                            (67, 0, "note_off")]
    pedal = [e for e in song.events if isinstance(e, ControlChange) and e.control == 64]
    assert [(e.value, e.pedal_down) for e in pedal] == [(127, True), (0, False)]
    assert [(e.control, e.value) for e in song.events if isinstance(e, ControlChange) and e.channel == 1] == [(1, 33)]
    assert [e.program for e in song.events if isinstance(e, ProgramChange)] == [12]
    assert [e.value for e in song.events if isinstance(e, PitchBend)] == [-4096]
    # 1 + 1/48 s at 48 kHz is sample 49000 exactly; at 44.1 kHz 45018.75 rounds to 45019
    assert ons[2].sample_index(48000) == 49000 and ons[2].sample_index(44100) == 45019
    assert song.length_samples(48000) == 156000
    assert song.sample_indices(44100) == [e.sample_index(44100) for e in song.events]
    assert song.sample_indices(44100)[-1] == round((1.25 + 560 / 480) * 44100)   # 106575.0 exactly
    assert sample_index(Fraction(1, 96000), 48000) == 1 and sample_index(Fraction(1, 96001), 48000) == 0
    notes = song.notes()
    assert [(n.on.key, round(n.duration_s, 12)) for n in notes] == [(60, 0.5), (64, 0.125), (67, round(17 / 12 - 1 / 48, 12))]
    assert song.channels() == (0, 1)


def test_running_status_bytes_and_smpte_time(tmp_path):
    # note on, then 3 running-status data pairs (a note-on 0 is a note-off), deltas in variable-length form
    body = b"\x00\x90\x3c\x64" + b"\x83\x60\x3c\x00" + b"\x00\x40\x50" + b"\x81\x70\x40\x00" + END
    song = read_midi(write(tmp_path, "running.mid", smf([body], fmt=0, division=96)))
    assert [(type(e).__name__, e.key, e.time) for e in song.events] == [
        ("NoteOn", 60, 0), ("NoteOff", 60, Fraction(480, 96) / 2), ("NoteOn", 64, Fraction(5, 2)),
        ("NoteOff", 64, Fraction(5, 2) + Fraction(240, 96) / 2)]
    # SMPTE: 25 frames/s x 40 ticks/frame = 1000 ticks/s; a tempo change does not move time
    smpte = b"\x00\xff\x51\x03\x0f\x42\x40" + b"\x00\x91\x45\x50" + b"\x8b\x5c\x45\x00" + END   # 1500 ticks
    song = read_midi(write(tmp_path, "smpte.mid", smf([smpte], fmt=0, division=-25 * 256 + 40)))
    assert song.ticks_per_beat is None and song.ticks_per_second == 1000
    assert [e.time_s for e in song.events] == [0.0, 1.5] and song.events[0].channel == 1
    drop = b"\x00\x90\x3c\x64" + b"\x81\x70\x3c\x00" + END   # 29.97 frames/s x 2 ticks/frame, 240 ticks
    song = read_midi(write(tmp_path, "drop.mid", smf([drop], fmt=0, division=-29 * 256 + 2)))
    assert song.events[1].time == Fraction(240 * 1001, 30000 * 2)


def test_overlapping_notes_of_one_key_restrike_and_end_together(tmp_path):
    midi = mido.MidiFile(ticks_per_beat=100)   # 500000 µs/beat: 1 tick = 5 ms
    track = midi.add_track()
    track.extend([mido.Message("note_off", note=50, time=0),               # ends nothing: dropped
                  mido.Message("note_on", note=60, velocity=80, time=0),
                  mido.Message("note_on", note=60, velocity=70, time=100),  # 0.5 s: restrike
                  mido.Message("note_off", note=60, time=10),               # 0.55 s: absorbed
                  mido.Message("note_off", note=60, time=90),               # 1.0 s: ends the key
                  mido.Message("note_on", note=62, velocity=10, time=0),
                  mido.Message("note_on", note=64, velocity=20, time=0),
                  mido.Message("control_change", control=123, value=0, time=100),   # 1.5 s: all notes off
                  mido.Message("note_on", note=65, velocity=30, time=20),           # 1.6 s, never released
                  mido.MetaMessage("end_of_track", time=80)])                       # 2.0 s
    midi.save(tmp_path / "overlap.mid")
    song = read_midi(tmp_path / "overlap.mid")
    got = [(type(e).__name__, getattr(e, "key", None), getattr(e, "cause", None), e.time_s) for e in song.events]
    assert got == [("NoteOn", 60, None, 0.0), ("NoteOff", 60, "restrike", 0.5), ("NoteOn", 60, None, 0.5),
                   ("NoteOff", 60, "note_off", 1.0), ("NoteOn", 62, None, 1.0), ("NoteOn", 64, None, 1.0),
                   ("ControlChange", None, None, 1.5), ("NoteOff", 62, "all_notes_off", 1.5),
                   ("NoteOff", 64, "all_notes_off", 1.5), ("NoteOn", 65, None, 1.6), ("NoteOff", 65, "end", 2.0)]
    assert song.dropped_note_offs == 2
    # every note-on is matched by exactly one later note-off of its channel and key
    assert len(song.notes()) == sum(isinstance(e, NoteOn) for e in song.events) == 5


def test_same_tick_events_keep_track_order(tmp_path):
    midi = mido.MidiFile(ticks_per_beat=480)
    first, second = midi.add_track(), midi.add_track()
    first.extend([mido.Message("note_on", note=60, velocity=1, time=0),
                  mido.Message("note_off", note=60, velocity=10, time=480)])
    second.extend([mido.Message("note_on", note=60, velocity=2, time=480), mido.Message("note_off", note=60, time=480)])
    midi.save(tmp_path / "ties.mid")
    events = read_midi(tmp_path / "ties.mid").events
    assert [(type(e).__name__, e.velocity, getattr(e, "cause", None)) for e in events] == [
        ("NoteOn", 1, None), ("NoteOff", 10, "note_off"), ("NoteOn", 2, None),
        ("NoteOff", 64, "note_off")]   # track 1's note-off first, so no restrike (mido's note_off velocity is 64)
    assert [e.time_s for e in events] == [0.0, 0.5, 0.5, 1.0]


GOOD = b"\x00\x90\x3c\x64\x83\x60\x3c\x00" + END


@pytest.mark.parametrize("name, data, words", [
    ("empty.mid", b"", "is empty (0 bytes)"),
    ("text.mid", b"hello, I am not music\n", "is not a MIDI file"),
    ("wave.mid", b"RIFF\x24\x00\x00\x00WAVEfmt ", "is not a MIDI file"),
    ("cut.mid", smf([GOOD])[:-5], "truncated"),
    ("header.mid", b"MThd\x00\x00", "truncated"),
    ("missing-track.mid", smf([GOOD], count=2), "truncated"),
    ("byte.mid", smf([b"\x00\x90\x3c\xe4" + END]), "is corrupt (data byte must be in range 0..127)"),
    ("status.mid", smf([b"\x00\x3c\x64" + END]), "is corrupt (running status without last_status)"),
    ("chunk.mid", smf([GOOD])[:14] + b"XXXX" + smf([GOOD])[18:], "is corrupt (no MTrk header"),
    ("key.mid", smf([b"\x00\xff\x59\x02\x00\xab" + GOOD]), "is corrupt (Could not decode key"),   # mido's own error
    ("type2.mid", smf([GOOD, GOOD], fmt=2), "is type 2 (independent sequences); allowed: a standard MIDI file of type 0 or 1"),
    ("type7.mid", smf([GOOD], fmt=7), "is of unknown type 7"),
    ("notracks.mid", smf([]), "has no tracks"),
    ("division.mid", smf([GOOD], division=0), "time division of 0 ticks per beat"),
    ("smpte.mid", smf([GOOD], division=-23 * 256 + 4), "SMPTE time division of 23 frames per second"),
    ("silent.mid", smf([b"\x00\xff\x51\x03\x07\xa1\x20" + END]), "contains no notes"),
    ("silent0.mid", smf([b"\x00\x90\x3c\x00" + END]), "contains no notes"),
])
def test_bad_files_give_one_line_naming_the_file(tmp_path, name, data, words):
    path = write(tmp_path, name, data)
    with pytest.raises(MidiFileError) as caught:
        read_midi(path)
    message = str(caught.value)
    assert "\n" not in message and message.startswith(f"MIDI file {path}: ") and words in message, message


def test_missing_folder_and_too_long(tmp_path):
    for path, words in [(tmp_path / "nope.mid", "no such file"), (tmp_path, "is a folder")]:
        with pytest.raises(MidiFileError, match=words) as caught:
            read_midi(path)
        assert isinstance(caught.value, BarsynthError) and "\n" not in str(caught.value)
    long = write(tmp_path, "long.mid", smf([b"\x00\x90\x3c\x64\x8f\xff\xff\x7f\x3c\x00" + END], division=1))
    with pytest.raises(MidiFileError, match=r"is 1\.67772e\+07 s long; allowed: up to 3600 s"):
        read_midi(long, max_length_s=3600)
    assert read_midi(long).length == Fraction(2 ** 25 - 1, 2)


MAP = """
[[channel]]
channel = 2
model = "banded"
preset = "marimba"
parameters = { excitation = "strike" }

[[channel]]
channel = 4
ignore = true

[[program]]
program = 13
model = "banded"
preset = "vibraphone"

[[channel]]
channel = 10
model = "farnell"
"""


def test_map_lookup_order_and_drums(tmp_path, song_path):
    (tmp_path / "map.toml").write_text(MAP)
    table = load_map(tmp_path / "map.toml", model="twang", preset="steel-30cm")
    assert (table.assignment(1).model, table.assignment(1).preset) == ("banded", "marimba")
    assert table.assignment(1, 12).preset == "marimba"            # the channel entry wins over the program
    assert table.assignment(3) is None                              # ignored
    assert table.assignment(0, 12).preset == "vibraphone"           # GM program 13 (12 on the wire)
    assert (table.assignment(0, 0).model, table.assignment(0, 0).preset) == ("twang", "steel-30cm")
    assert table.assignment(9, 12).model == "farnell"               # drums only through their channel entry
    assert table.assignment(1).overrides == (("excitation", "strike"),)
    assert table.assignment(1).parameters.excitation == "strike"
    plain = load_map(None, model="banded", preset="xylophone")
    assert plain.assignment(9) is None and plain.assignment(0, 99).preset == "xylophone"
    # the program a note-on carries selects its player
    ons = [e for e in read_midi(song_path).events if isinstance(e, NoteOn)]
    assert [table.assignment(e.channel, e.program).preset for e in ons] == ["vibraphone", "vibraphone", "marimba"]


@pytest.mark.parametrize("text, words", [
    ('[[channel]]\nchannel = 17\nmodel = "banded"', "[[channel]] #1: channel = 17 is not allowed; allowed: a whole number from 1 to 16"),
    ('[[channel]]\nchannel = 0\nmodel = "banded"', "channel = 0 is not allowed"),
    ('[[channel]]\nchannel = "2"\nmodel = "banded"', "channel = '2' is not allowed"),
    ('[[program]]\nprogram = 129\nmodel = "banded"', "program = 129 is not allowed; allowed: a whole number from 1 to 128"),
    ('[[channel]]\nchannel = 2\nmodel = "piano"', "model = 'piano' is not a known model; allowed: one of twang"),
    ('[[channel]]\nchannel = 2\nmodel = "banded"\npreset = "tuba"', "preset = 'tuba' is not a preset of model banded; allowed: one of bowl"),
    ('[[channel]]\nchannel = 2\nmodel = "banded"\nparameters = { colour = 1 }', "unknown parameter 'colour' for model banded"),
    ('[[channel]]\nchannel = 2\nmodel = "banded"\nparameters = { excitation = "kick" }', "excitation"),
    ('[[channel]]\nchannel = 2\nmodel = "banded"\nparameters = 3', "parameters = 3 is not a table"),
    ('[[channel]]\nchannel = 2\nmodel = "banded"\n[[channel]]\nchannel = 2\nmodel = "fd"', "[[channel]] #2: channel = 2 is mapped twice"),
    ('[[channel]]\nchannel = 2\nmodel = "banded"\nvolume = 3', "unknown key 'volume'; allowed: channel, ignore, model"),
    ('[[channel]]\nchannel = 2', "model is missing"),
    ('[[channel]]\nmodel = "banded"', "channel is missing"),
    ('[[channel]]\nchannel = 2\nignore = true\nmodel = "banded"', "ignore = true with model"),
    ('[[channel]]\nchannel = 2\nignore = "yes"', "ignore = 'yes' is not allowed; allowed: true or false"),
    ('[default]\nmodel = "banded"', "unknown key 'default'; allowed: [[channel]] and [[program]] entries"),
    ('channel = 3', "channel is not a list of [[channel]] entries"),
    ('[[channel]\nchannel = 2', "is not valid TOML"),
])
def test_bad_maps_give_one_line(text, words):
    with pytest.raises(MidiMapError) as caught:
        parse_map(text, model="banded", name="m.toml")
    message = str(caught.value)
    assert "\n" not in message and message.startswith("map m.toml: "), message
    assert words in message, message


def test_bad_default_and_map_files(tmp_path):
    with pytest.raises(MidiMapError, match="default: model = 'organ' is not a known model"):
        load_map(None, model="organ")
    with pytest.raises(MidiMapError, match="default: preset = 'marimba' is not a preset of model twang"):
        load_map(None, model="twang", preset="marimba")
    with pytest.raises(MidiMapError, match="no such file"):
        load_map(tmp_path / "none.toml", model="banded")
    (tmp_path / "latin.toml").write_bytes(b"# caf\xe9\n")
    with pytest.raises(MidiMapError, match="cannot be read"):
        load_map(tmp_path / "latin.toml", model="banded")


def test_the_docs_map_example_reads_as_it_says():
    """docs/midi-notes.md's map parses, and plays what its comments say."""
    import re
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "midi-notes.md").read_text(encoding="utf-8")
    (text,) = re.findall(r"```toml\n(.*?)```", doc, flags=re.DOTALL)
    table = parse_map(text, model="twang", name="song-map.toml")
    assert table.assignment(1).preset == "marimba" and table.assignment(3) is None
    assert table.assignment(0, 11).preset == "vibraphone" and table.assignment(9).preset == "glockenspiel-bar"
    assert table.assignment(0, 12).model == "twang"


def test_docstring_examples():
    import doctest

    from barsynth.midi import events

    assert doctest.testmod(events).attempted >= 1 and doctest.testmod(events).failed == 0


def test_max_length_is_checked(song_path):
    with pytest.raises(ParameterError, match=r"parameter max_length_s = nan is not a finite number"):
        read_midi(song_path, max_length_s=float("nan"))
    with pytest.raises(ParameterError, match=r"max_length_s = 0"):
        read_midi(song_path, max_length_s=0)
    assert read_midi(song_path, max_length_s=3.25).length_s == 3.25


def test_mangled_files_never_escape_as_other_errors(song_path, tmp_path):
    """Bytes flipped, cut out and put in at random (seeded): each file reads, or gives one MidiFileError line."""
    import random

    base, rng, outcomes = song_path.read_bytes(), random.Random(17), {"read": 0, "refused": 0}
    for trial in range(400):
        data = bytearray(base)
        for _ in range(rng.randint(1, 4)):
            at, op = rng.randrange(len(data)), rng.random()
            if op < 0.6:
                data[at] = rng.randrange(256)
            elif op < 0.8:
                del data[at:at + rng.randint(1, 8)]
            else:
                data[at:at] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 4)))
        path = write(tmp_path, f"mangled{trial}.mid", bytes(data))
        try:
            song = read_midi(path)
        except MidiFileError as exc:
            assert "\n" not in str(exc) and str(exc).startswith(f"MIDI file {path}: ")
            outcomes["refused"] += 1
        else:
            assert len(song.notes()) == sum(isinstance(e, NoteOn) for e in song.events)
            outcomes["read"] += 1
    assert outcomes["read"] > 20 and outcomes["refused"] > 200, outcomes


def test_the_mapping_modules_example_map_reads():
    from barsynth.midi import mapping

    text = mapping.__doc__.split("::\n", 1)[1].split("\nA note's", 1)[0]
    table = parse_map(text, model="banded")
    assert table.assignment(1).preset == "marimba" and table.assignment(3) is None
    assert table.assignment(0, 11).preset == "vibraphone" and table.assignment(9) is None
