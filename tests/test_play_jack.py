"""`barsynth play` through a real JACK server (its dummy back end, tests/jack_server.py): notes sent
over JACK MIDI, or typed as keys, come back as sound at their pitches, the MIDI notes at their
spacing; the player leaves no client behind (a dead client stalls a synchronous jackd).

Everything is measured in the recorder's JACK frames (the MIDI events are recorded on the same
time line as the sound), never in wall-clock time: with ``jackd --sync`` a loaded machine makes the
dummy clock run late, not the notes. The note-to-sound latency is printed (``pytest -s``), not
asserted.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import termios

import numpy as np
import pytest
import sounddevice  # noqa: F401  (before the fixture starts jackd: it re-initialises PortAudio)
from jack_server import BLOCK_FRAMES, SAMPLE_RATE, stop_process
from test_jack_infrastructure import PORTAUDIO_OUT, peak_frequency_hz

NOTES = (69, 76, 64)  # A4, E5, E4
PAUSES_S = (0.7, 0.45)  # between the note ons: uneven, so a constant shift cannot pass for the spacing
SPACING_TOLERANCE = 2 * BLOCK_FRAMES + 48
"""A note is stamped with the audio clock (the ring's read position) when its MIDI event reaches the
player, which moves a block at a time, and JACK may run the player's MIDI and audio clients in
either order within a cycle: two blocks, plus a millisecond for the onset's detection."""
KEYS = "zeny"  # barsynth.playing.keyboard: C4, E5, A4, A5 (none two octaves above another:
KEY_NOTES = (60, 76, 69, 81)  # the marimba's second mode sits there)
LEAD = ("--lead", "32")
"""171 ms ahead (4 blocks by default): the tests run niced beside other work, and a synthesis thread
kept off the CPU for longer than its lead leaves a gap (counted, played as zeros); a gap over a
note's attack would move its onset (with 16 blocks one run of about twenty, on the busy shared
machine, heard a note 46 ms late)."""
GUARD_S = 60.0
"""Hang guards only."""


def hz(note: int) -> float:
    return 440.0 * 2 ** ((note - 69) / 12)


def start_player(jack_server, *args: str, stdin=subprocess.DEVNULL) -> tuple[subprocess.Popen, str]:
    """`barsynth play banded --preset marimba --device jack ARGS`, once it has said "ready" (on stderr)."""
    player = subprocess.Popen([sys.executable, "-m", "barsynth", "play", "banded", "--preset", "marimba",
                               "--device", "jack", *LEAD, *args],
                              env=jack_server.env, stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
    lines = []
    while not (line := player.stderr.readline()).startswith("ready"):
        lines.append(line)
        if not line and player.poll() is not None:
            pytest.fail(f"barsynth play exited with {player.returncode}: {''.join(lines)}")
    return player, line


def finish(player: subprocess.Popen, jack_server, audio_client: str, *, terminate: bool) -> str:
    """Stop the player (SIGTERM, as a service manager would) or wait for it; check that it left
    nothing on the server (its MIDI client ``barsynth``, its PortAudio client ``audio_client``).
    Returns the rest of its stderr."""
    if terminate:
        player.send_signal(signal.SIGTERM)
    try:
        _, rest = player.communicate(timeout=GUARD_S)
    except subprocess.TimeoutExpired:
        stop(player)
        pytest.fail("barsynth play did not stop")
    assert player.returncode == 0, rest
    assert "played" in rest, rest
    for client in ("barsynth", audio_client):
        assert not jack_server.has_client(client), f"{client} left its JACK client open"
    assert jack_server.log_problems() == [], jack_server.log_problems()
    return rest


def stop(player: subprocess.Popen) -> None:
    """After a failure: SIGTERM, so that the player closes its clients (a killed one leaves a dead
    client, which stalls the synchronous server for ten times its client timeout); SIGKILL only
    if that does not work."""
    stop_process(player, GUARD_S)


def rise(x: np.ndarray, frame: int, until: int) -> int:
    """The first frame after ``frame`` where the sound reaches half the peak that follows (up to
    ``until`` and at most a quarter second): the note's attack, louder than any earlier note's
    tail, and unmoved by a gap an underrun may have left before it."""
    window = np.abs(x[frame:min(until, frame + SAMPLE_RATE // 4)])
    assert window.size and window.max() > 1e-3, f"no note after frame {frame}"
    return frame + int(np.argmax(window >= 0.5 * window.max()))


def promised_frames(ready: str) -> int:
    """The note-to-sound latency `barsynth play` printed, in frames."""
    return round(float(re.search(r"latency ([0-9.]+) ms", ready).group(1)) * SAMPLE_RATE / 1000)


def notes_heard(x: np.ndarray, hop: int = 256) -> list[int]:
    """The notes heard, in order, without MIDI to go by: at each hop (longer than a period of C4)
    whose peak is 1.5x the larger of the two hops before the one before it and above 5 % of the
    recording's peak, the MIDI note nearest the spectral peak of the 0.1 s after it; a note heard
    twice in a row (a gap left by an underrun, or a beat, looks like an attack) counts once."""
    peaks = np.abs(x[: len(x) // hop * hop]).reshape(-1, hop).max(axis=1)
    heard: list[int] = []
    for k in range(3, len(peaks)):
        if peaks[k] > 0.05 * peaks.max() and peaks[k] > 1.5 * peaks[k - 3:k - 1].max():
            segment = x[k * hop + 480:k * hop + 480 + SAMPLE_RATE // 10]
            if segment.size == SAMPLE_RATE // 10:
                note = round(69 + 12 * np.log2(peak_frequency_hz(segment) / 440.0))
                if not heard or heard[-1] != note:
                    heard.append(note)
    return heard


def assert_pitch(x: np.ndarray, onset: int, until: int, note: int) -> None:
    segment = x[onset + 480:min(until, onset + 480 + SAMPLE_RATE // 5)]
    found = peak_frequency_hz(segment)
    assert abs(found - hz(note)) < 0.02 * hz(note), (note, found)


@pytest.mark.parametrize("how", ["--midi-in", "--midi-virtual"])
def test_notes_over_jack_midi_sound_at_their_pitches_and_spacing(jack_server, how):
    sender = jack_server.midi_out("tester")  # (rtmidi ports before any Python audio callback)
    (sender_port,) = jack_server.wait_for_ports("tester", is_midi=True, is_output=True)
    port_args = ["--midi-in", "tester"] if how == "--midi-in" else ["--midi-virtual", "barsynth"]
    player, ready = start_player(jack_server, *port_args, "--midi-api", "jack")
    try:
        (source,) = jack_server.wait_for_ports(PORTAUDIO_OUT, is_audio=True, is_output=True)
        (midi_port,) = jack_server.wait_for_ports("barsynth:in", is_midi=True, is_input=True)
        if how == "--midi-in":  # the player connected itself to the named port
            assert sender_port in jack_server.connections(midi_port)
        else:
            jack_server.connect(sender_port, midi_port)
        recorder = jack_server.recorder(channels=1, midi_inputs=1, max_duration_s=8.0, name="play-recorder")
        jack_server.connect(source, recorder.port_names[0])
        jack_server.connect(sender_port, recorder.midi_port_names[0])
        recorder.start()
        recorder.wait_frames(8 * BLOCK_FRAMES)
        for note, pause_s in zip(NOTES, (*PAUSES_S, 0.0)):
            sender.send_message([0x90, note, 110])
            recorder.wait_frames(recorder.frames + int(pause_s * SAMPLE_RATE))  # (the server's time: a loaded
            sender.send_message([0x80, note, 0])  # machine slows its clock; the spacing is measured, not assumed)
        recorder.wait_frames(recorder.frames + SAMPLE_RATE // 2)
        recorder.stop()
        rest = finish(player, jack_server, source.split(":")[0], terminate=True)
    finally:
        stop(player)
    x = recorder.audio[:, 0]
    sent = [frame for frame, _, data in recorder.midi_events if data[0] == 0x90]
    assert len(sent) == len(NOTES), recorder.midi_events
    early = promised_frames(ready) - 2 * BLOCK_FRAMES  # (where to look: not what is checked)
    starts = [frame + early for frame in sent]
    until = [*starts[1:], len(x)]
    heard = [rise(x, start, end) for start, end in zip(starts, until)]
    summary = rest.strip().splitlines()[-1]
    for onset, end, note in zip(heard, until, NOTES):
        assert_pitch(x, onset, end, note)
    np.testing.assert_allclose(np.diff(heard), np.diff(sent), atol=SPACING_TOLERANCE,
                               err_msg=f"note ons at {sent}, heard at {heard}; {summary}")
    latency_ms = (np.array(heard) - np.array(sent)) / SAMPLE_RATE * 1000
    print(f"\n{how}: note to sound {latency_ms.round(1).tolist()} ms in JACK frames "
          f"(barsynth play expected {promised_frames(ready) / SAMPLE_RATE * 1000:.1f} ms; the sender's wait "
          f"for its next cycle not included); {summary}")


@pytest.mark.parametrize("stdin", ["pipe", "terminal"])
def test_keys_play_their_notes(jack_server, stdin):
    """Keys from a pipe (its end stops the player) or a terminal (a pty: cbreak mode while playing,
    Escape quits, the settings restored) come back at their pitches, in order."""
    if stdin == "pipe":
        player, ready = start_player(jack_server, "--hold", "0.2", stdin=subprocess.PIPE)
        write = lambda key: (player.stdin.write(key), player.stdin.flush())
    else:
        master, slave = os.openpty()
        before = termios.tcgetattr(slave)
        player, ready = start_player(jack_server, "--hold", "0.2", stdin=slave)
        write = lambda key: os.write(master, key.encode())
    assert "z s x d c v g b h n j m" in ready
    try:
        (source,) = jack_server.wait_for_ports(PORTAUDIO_OUT, is_audio=True, is_output=True)
        recorder = jack_server.recorder(channels=1, max_duration_s=8.0, name="keys-recorder")
        jack_server.connect(source, recorder.port_names[0])
        recorder.start()
        recorder.wait_frames(8 * BLOCK_FRAMES)
        if stdin == "terminal":
            assert not termios.tcgetattr(slave)[3] & termios.ICANON  # the player's cbreak mode
        for key in KEYS:
            write(key)
            write("p")  # (not a note key: ignored)
            recorder.wait_frames(recorder.frames + SAMPLE_RATE // 2)
        if stdin == "pipe":
            player.stdin.close()  # the end of the input: the player stops after the last note
            player.stdin = None
        else:
            write("\x1b")  # Escape
        rest = finish(player, jack_server, source.split(":")[0], terminate=False)
        recorder.stop()
    finally:
        stop(player)
        if stdin == "terminal":
            after = termios.tcgetattr(slave)
            os.close(master)
            os.close(slave)
    if stdin == "terminal":
        assert after == before  # restored
    assert notes_heard(recorder.audio[:, 0]) == list(KEY_NOTES), rest


def test_an_unknown_midi_port_is_refused_in_one_line_listing_the_ports(jack_server):
    jack_server.midi_out("tester")
    result = subprocess.run([sys.executable, "-m", "barsynth", "play", "banded", "--midi-in", "nosuch", "--midi-api",
                             "jack", "--device", "jack"], env=jack_server.env, capture_output=True, text=True,
                            timeout=GUARD_S, check=False)
    assert result.returncode == 2 and result.stdout == "", result.stderr
    (line,) = result.stderr.splitlines()
    assert line.startswith("barsynth: error: --midi-in 'nosuch' names no MIDI input port") and "tester:out" in line
    assert not jack_server.has_client("barsynth")


def test_an_unknown_audio_device_is_refused_in_one_line_listing_the_devices(jack_server):
    result = subprocess.run([sys.executable, "-m", "barsynth", "play", "banded", "--device", "nosuch"],
                            env=jack_server.env, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                            timeout=GUARD_S, check=False)
    assert result.returncode == 2 and result.stdout == "", result.stderr
    (line,) = result.stderr.splitlines()
    assert line.startswith("barsynth: error: could not open --device 'nosuch'") and "system" in line, line
