"""`barsynth play` through a real JACK server (its dummy back end): notes sent over JACK MIDI
come back as sound at their pitches, one onset each (tests/jack_server.py)."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import sounddevice  # noqa: F401  (before the fixture starts jackd: it re-initialises PortAudio)
from jack_server import SAMPLE_RATE
from test_jack_infrastructure import PORTAUDIO_OUT, onsets, peak_frequency_hz

NOTES = (69, 76)  # A4, E5


def test_notes_over_jack_midi_sound_at_their_pitches(jack_server):
    sender = jack_server.midi_out("tester")  # (rtmidi ports before any Python audio callback)
    player = subprocess.Popen(
        [sys.executable, "-m", "barsynth", "play", "banded", "--preset", "marimba", "--midi-in", "barsynth",
         "--midi-api", "jack", "--device", "jack", "--seconds", "5"],
        env=jack_server.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = player.stdout.readline()
        assert line.startswith("ready"), (line, player.stderr.read() if player.poll() is not None else "")
        (source,) = jack_server.wait_for_ports(PORTAUDIO_OUT, is_audio=True, is_output=True)
        (midi_port,) = jack_server.wait_for_ports("barsynth", is_midi=True, is_input=True)
        (sender_port,) = jack_server.wait_for_ports("tester", is_midi=True, is_output=True)
        jack_server.connect(sender_port, midi_port)
        recorder = jack_server.recorder(channels=1, max_duration_s=6.0, name="play-recorder")
        jack_server.connect(source, recorder.port_names[0])
        recorder.start()
        for note in NOTES:
            sender.send_message([0x90, note, 110])
            time.sleep(1.0)  # (not asserted: the recording is measured in its own frames)
            sender.send_message([0x80, note, 0])
        recorder.wait_frames(int(2.5 * SAMPLE_RATE))
        recorder.stop()
        jack_server.disconnect(sender_port, midi_port)  # before the player leaves: a connection to a
        jack_server.disconnect(source, recorder.port_names[0])  # client that went away stalls the server
    finally:
        try:
            player.wait(60)  # its --seconds run out: it closes its clients (a killed one stalls the server)
        except subprocess.TimeoutExpired:
            player.kill()
            player.wait()
    x = recorder.audio[:, 0]
    found = onsets(x, threshold=0.2 * np.max(np.abs(x)), quiet_frames=4800)
    assert len(found) >= 2, found
    for start, note in zip(found[:2], NOTES):
        segment = x[start + 480:start + 480 + SAMPLE_RATE // 4]
        hz = 440.0 * 2 ** ((note - 69) / 12)
        assert abs(peak_frequency_hz(segment) - hz) < 0.02 * hz, (note, peak_frequency_hz(segment))
