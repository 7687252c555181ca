"""A MIDI song rendered (barsynth.playing.song): each note at its time and pitch, on the model
its channel is mapped to."""

from __future__ import annotations

import mido
import numpy as np

from barsynth.midi import load_map, read_midi
from barsynth.playing.song import render_song

RATE = 48000


def write_song(path, notes, *, bpm=120, program_channel=None):
    """``notes``: (channel, key, start_beats, length_beats) on one track at ``bpm``."""
    midi = mido.MidiFile(ticks_per_beat=480)
    track = mido.MidiTrack()
    midi.tracks.append(track)
    track.append(mido.MetaMessage("set_tempo", tempo=mido.bpm2tempo(bpm), time=0))
    timeline = []
    for channel, key, start, length in notes:
        timeline.append((int(start * 480), 1, mido.Message("note_on", channel=channel, note=key, velocity=100)))
        timeline.append((int((start + length) * 480), 0, mido.Message("note_off", channel=channel, note=key)))
    last = 0
    for tick, _, message in sorted(timeline, key=lambda e: (e[0], e[1])):
        track.append(message.copy(time=tick - last))
        last = tick
    midi.save(path)


def peak_hz(x, low, high):
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size), 4 * x.size))
    f = np.fft.rfftfreq(4 * x.size, 1 / RATE)
    band = (f > low) & (f < high)
    return f[band][np.argmax(spectrum[band])]


def test_each_note_sounds_at_its_time_and_pitch(tmp_path):
    path = tmp_path / "song.mid"
    write_song(path, [(0, 69, 0, 1), (0, 76, 2, 1)])  # A4 at 0 s, E5 at 1 s (120 bpm)
    x = render_song(read_midi(path), load_map(None, model="banded", preset="marimba"), sample_rate=RATE)
    assert x.size > RATE
    first, second = x[:RATE // 2], x[RATE + 2400:RATE + 2400 + RATE // 2]
    assert abs(peak_hz(first, 400, 480) - 440.0) < 1.0
    assert abs(peak_hz(second, 620, 700) - 659.26) < 1.5
    onset = np.flatnonzero(np.abs(x[RATE - 2400:]) > 0.5 * np.max(np.abs(x[RATE:RATE + 4800])))[0] + RATE - 2400
    assert abs(onset - RATE) < 200  # the second note starts at 1.000 s


def test_channels_play_the_models_the_map_names(tmp_path):
    path = tmp_path / "two.mid"
    write_song(path, [(0, 69, 0, 2), (1, 45, 0, 2)])
    mapping = tmp_path / "map.toml"
    mapping.write_text('[[channel]]\nchannel = 2\nmodel = "kalimba"\n')
    song = read_midi(path)
    both = render_song(song, load_map(mapping, model="banded", preset="marimba"), sample_rate=RATE)
    alone = render_song(song, load_map(None, model="banded", preset="marimba"), sample_rate=RATE)
    assert not np.allclose(both[:RATE], alone[:RATE])
    assert abs(peak_hz(both[:RATE], 100, 120) - 110.0) < 1.0  # A2 on the kalimba


def test_the_cli_renders_a_song_and_refuses_a_corrupt_file_in_one_line(tmp_path):
    import soundfile
    from click.testing import CliRunner

    from barsynth.cli import main

    path = tmp_path / "song.mid"
    write_song(path, [(0, 60, 0, 1), (0, 64, 1, 1)])
    out = tmp_path / "song.wav"
    result = CliRunner().invoke(main, ["midi", str(path), "--preset", "marimba", "-o", str(out)],
                                catch_exceptions=False)
    assert result.exit_code == 0, result.output
    info = soundfile.info(str(out))
    assert info.samplerate == RATE and info.frames > RATE
    bad = tmp_path / "bad.mid"
    bad.write_bytes(b"MThd\x00\x00\x00\x06\x00\x01\x00\x02")  # cut short
    out2 = tmp_path / "bad.wav"
    result = CliRunner().invoke(main, ["midi", str(bad), "-o", str(out2)], catch_exceptions=False)
    assert result.exit_code == 2
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "bad.mid" in lines[0]
    assert not out2.exists()


def test_a_pedal_put_down_before_the_first_note_holds_the_notes(tmp_path):
    """CC 64 = 127 at the start, then a short struck note on a vibraphone (damper =
    release): held by the pedal it rings on; without the pedal event it is damped."""
    def render(pedal):
        midi = mido.MidiFile(ticks_per_beat=480)
        track = mido.MidiTrack()
        midi.tracks.append(track)
        if pedal:
            track.append(mido.Message("control_change", control=64, value=127, time=0))
        track.append(mido.Message("note_on", note=69, velocity=100, time=0))
        track.append(mido.Message("note_off", note=69, time=240))  # a quarter of a second at 120 bpm
        track.append(mido.MetaMessage("end_of_track", time=960))
        path = tmp_path / f"pedal-{pedal}.mid"
        midi.save(path)
        song = read_midi(path)
        return render_song(song, load_map(None, model="banded", preset="vibraphone"), sample_rate=48000)
    held, damped = render(True), render(False)
    window = slice(int(0.6 * 48000), int(0.7 * 48000))
    rms = lambda x: float(np.sqrt(np.mean(x[window] ** 2)))  # noqa: E731
    assert rms(held) > 30 * rms(damped)


def test_notes_a_model_cannot_reach_are_left_out_with_one_warning(tmp_path):
    """The twang reaches keys up to about 75: a song with two higher keys renders the others (at
    their pitches) and says in one line what it left out."""
    import soundfile
    from click.testing import CliRunner

    from barsynth.cli import main

    path = tmp_path / "high.mid"
    write_song(path, [(0, 40, 0, 1), (0, 90, 1, 1), (0, 100, 2, 1), (0, 45, 3, 1)])
    out = tmp_path / "high.wav"
    result = CliRunner().invoke(main, ["midi", str(path), "--model", "twang", "-o", str(out)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    warnings = [line for line in result.stderr.splitlines() if "warning" in line]
    assert len(warnings) == 1 and "2 notes left out (keys 90-100, channel 1)" in warnings[0]
    assert "length_m" in warnings[0] and "2 notes)" in result.stdout
    x, rate = soundfile.read(str(out))
    assert abs(peak_hz(x[int(1.5 * rate):int(2.0 * rate)], 60, 120) - 110.0) < 3.0  # key 45 at 1.5 s (A2)


def test_one_channels_pedal_does_not_hold_another_channels_notes(tmp_path):
    """Both channels on the default map (the same model and preset): channel 1 holds its pedal
    down over its A3, channel 2's released A4 on the vibraphone (1 : 4 modes, so A3 has nothing
    at 440 Hz) is still damped."""
    midi = mido.MidiFile(ticks_per_beat=480)
    track = mido.MidiTrack()
    midi.tracks.append(track)
    track.append(mido.Message("control_change", channel=0, control=64, value=127, time=0))
    track.append(mido.Message("note_on", channel=0, note=57, velocity=100, time=0))
    track.append(mido.Message("note_on", channel=1, note=69, velocity=100, time=0))
    track.append(mido.Message("note_off", channel=1, note=69, time=240))
    track.append(mido.Message("note_off", channel=0, note=57, time=0))
    track.append(mido.MetaMessage("end_of_track", time=960))
    path = tmp_path / "two.mid"
    midi.save(path)
    x = render_song(read_midi(path), load_map(None, model="banded", preset="vibraphone"), sample_rate=48000)

    def at_440(start_s):
        part = x[int(start_s * 48000):int((start_s + 0.1) * 48000)]
        spectrum = np.abs(np.fft.rfft(part * np.hanning(part.size)))
        f = np.fft.rfftfreq(part.size, 1 / 48000)
        return spectrum[np.argmin(np.abs(f - 440.0))]
    assert at_440(0.6) < 0.01 * at_440(0.1)
