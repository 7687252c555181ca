"""The live-audio test rig works: a real JACK server (dummy back end), sound through
sounddevice's JACK device into a recording client, and notes over JACK MIDI with
python-rtmidi. These tests measure the rig, not barsynth; barsynth's ``play`` tests build on it.
The ``jack_server`` fixture comes from tests/jack_server.py through conftest.py.
"""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest
import sounddevice  # imported before the fixture starts jackd: the fixture re-initialises PortAudio
from jack_server import BLOCK_FRAMES, SAMPLE_RATE

FREQUENCY_HZ = 440.0
AMPLITUDE = 0.5
BURST_S = 0.25
GAP_S = 0.25
BURSTS = 3
ONSET_THRESHOLD = 0.1
PORTAUDIO_OUT = r"^PortAudio[^:]*:out_"


def bursts(frequency_hz: float = FREQUENCY_HZ, count: int = BURSTS, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """``count`` sine bursts of BURST_S seconds, each followed by GAP_S of silence (float32)."""
    burst = int(BURST_S * sample_rate)
    t_s = np.arange(burst) / sample_rate
    tone = (AMPLITUDE * np.sin(2 * np.pi * frequency_hz * t_s)).astype(np.float32)
    period = np.concatenate([tone, np.zeros(int(GAP_S * sample_rate), np.float32)])
    return np.tile(period, count)


def onsets(x: np.ndarray, threshold: float = ONSET_THRESHOLD, quiet_frames: int = 2400) -> np.ndarray:
    """Frames where |x| first exceeds ``threshold`` after at least ``quiet_frames`` below it."""
    loud = np.flatnonzero(np.abs(x) > threshold)
    if len(loud) == 0:
        return loud
    starts = np.concatenate([[0], np.flatnonzero(np.diff(loud) > quiet_frames) + 1])
    return loud[starts]


def peak_frequency_hz(x: np.ndarray, sample_rate: int = SAMPLE_RATE) -> float:
    """The frequency of the largest Hann-windowed spectral peak (zero-padded to 2**20 points)."""
    n_fft = 1 << 20
    spectrum = np.abs(np.fft.rfft(x * np.hanning(len(x)), n_fft))
    return float(np.argmax(spectrum) * sample_rate / n_fft)


def jack_output_device() -> int:
    """sounddevice's default output device on the JACK host API."""
    for hostapi in sounddevice.query_hostapis():
        if "JACK" in hostapi["name"]:
            return hostapi["default_output_device"]
    pytest.fail(f"sounddevice lists no JACK host API: {[h['name'] for h in sounddevice.query_hostapis()]}")


class Player:
    """A sounddevice OutputStream on JACK whose callback copies from a preallocated buffer
    once ``go`` is set (silence before and after)."""

    def __init__(self, signal: np.ndarray):
        self.signal = signal
        self.position = 0
        self.go = False
        self.stream = sounddevice.OutputStream(device=jack_output_device(), samplerate=SAMPLE_RATE, channels=1,
                                               dtype="float32", blocksize=BLOCK_FRAMES, callback=self._callback)

    def _callback(self, outdata, frames, time_info, status):
        if not self.go:
            outdata.fill(0.0)
            return
        chunk = self.signal[self.position: self.position + frames]
        outdata[: len(chunk), 0] = chunk
        outdata[len(chunk):] = 0.0
        self.position += len(chunk)

    def __enter__(self):
        self.stream.start()
        return self

    def __exit__(self, *exc):
        self.stream.close()


def test_sounddevice_plays_a_sine_into_the_recorder(jack_server):
    signal = bursts()
    recorder = jack_server.recorder(channels=1, max_duration_s=len(signal) / SAMPLE_RATE + 2.0)
    with Player(signal) as player:
        (source,) = jack_server.wait_for_ports(PORTAUDIO_OUT, is_audio=True, is_output=True)
        jack_server.connect(source, recorder.port_names[0])
        recorder.start()
        player.go = True
        recorder.wait_frames(len(signal) + SAMPLE_RATE // 2)
        recorder.stop()
    x = recorder.audio[:, 0]
    found = onsets(x)
    assert len(found) == BURSTS, f"onsets at frames {found}"
    period = int((BURST_S + GAP_S) * SAMPLE_RATE)
    np.testing.assert_allclose(np.diff(found), period, atol=4 * BLOCK_FRAMES)
    burst = int(BURST_S * SAMPLE_RATE)
    for start in found:
        segment = x[start + 64: start + burst - 64]
        assert abs(peak_frequency_hz(segment) - FREQUENCY_HZ) < 1.0
        assert np.max(np.abs(segment)) == pytest.approx(AMPLITUDE, rel=0.01)  # unscaled (robust to a dropped block)
    print(f"\nrecorded {len(x)} frames, onsets {found.tolist()}, missed frames {recorder.missed_frames}")


def wait_message(midi_in, timeout_s: float = 60.0):
    """The next message on a python-rtmidi MidiIn (fails the test on a hang)."""
    deadline = time.monotonic() + timeout_s
    while (message := midi_in.get_message()) is None:
        if time.monotonic() > deadline:
            pytest.fail(f"no MIDI message within {timeout_s:g} s")
        time.sleep(0.005)
    return message[0]


def test_rtmidi_sends_notes_over_jack_midi(jack_server):
    sender = jack_server.midi_out("sender")
    listener = jack_server.midi_in("listener")
    recorder = jack_server.recorder(channels=1, midi_inputs=1, max_duration_s=5.0, name="midi-recorder")
    jack_server.connect("sender:out", "listener:in")
    jack_server.connect("sender:out", recorder.midi_port_names[0])
    recorder.start()
    recorder.wait_frames(BLOCK_FRAMES)
    sender.send_message([0x90, 64, 97])  # note on, channel 1, E4, velocity 97
    sender.send_message([0x80, 64, 40])  # note off, release velocity 40
    assert wait_message(listener) == [0x90, 64, 97]
    assert wait_message(listener) == [0x80, 64, 40]
    deadline = time.monotonic() + 60.0
    while len(recorder.midi_events) < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    recorder.stop()
    messages = [data for _, _, data in recorder.midi_events]
    assert messages == [bytes([0x90, 64, 97]), bytes([0x80, 64, 40])]
    frames = [frame for frame, _, _ in recorder.midi_events]
    assert 0 <= frames[0] <= frames[1]


def test_note_to_sound_latency(jack_server):
    """A tiny responder: an rtmidi MidiIn on JACK starts a sounddevice burst on note-on. The
    recorder hears the MIDI and the sound on one time line; the latency is printed, not asserted."""
    signal = bursts(count=1)
    sender = jack_server.midi_out("latency-sender")  # rtmidi first: see jack_server.JackServer.midi_out
    responder = jack_server.midi_in("responder")
    recorder = jack_server.recorder(channels=1, midi_inputs=1, max_duration_s=5.0, name="latency-recorder")
    with Player(signal) as player:
        def on_message(event, data=None):
            message, _ = event
            if message[0] & 0xF0 == 0x90 and message[2] > 0:
                player.go = True

        responder.set_callback(on_message)
        (source,) = jack_server.wait_for_ports(PORTAUDIO_OUT, is_audio=True, is_output=True)
        jack_server.connect(source, recorder.port_names[0])
        jack_server.connect("latency-sender:out", "responder:in")
        jack_server.connect("latency-sender:out", recorder.midi_port_names[0])
        recorder.start()
        recorder.wait_frames(4 * BLOCK_FRAMES)
        sender.send_message([0x90, 69, 100])
        recorder.wait_frames(recorder.frames + len(signal) + SAMPLE_RATE // 4)
        recorder.stop()
    (note_frame, _, data), = recorder.midi_events
    assert data == bytes([0x90, 69, 100])
    x = recorder.audio[:, 0]
    found = onsets(x)
    assert len(found) == 1, f"onsets at frames {found}"
    latency = int(found[0] - onsets(signal)[0] - note_frame)  # the burst crosses the threshold a few frames in
    assert latency >= 0, "the sound began before the note reached JACK"
    segment = x[found[0] + 64: found[0] + int(BURST_S * SAMPLE_RATE) - 64]
    assert abs(peak_frequency_hz(segment) - FREQUENCY_HZ) < 1.0
    print(f"\nnote to sound: {latency} frames = {1000 * latency / SAMPLE_RATE:.1f} ms "
          f"({latency / BLOCK_FRAMES:.1f} blocks of {BLOCK_FRAMES}); recorder missed {recorder.missed_frames} frames")


PLAYER_SCRIPT = """
import sys
import numpy as np
import sounddevice
rate, frequency_hz, seconds = 48000, float(sys.argv[1]), float(sys.argv[2])
signal = (0.5 * np.sin(2 * np.pi * frequency_hz * np.arange(int(seconds * rate)) / rate)).astype(np.float32)
state = {"go": False, "position": 0}
def callback(outdata, frames, time_info, status):
    outdata.fill(0.0)
    if state["go"]:
        chunk = signal[state["position"]: state["position"] + frames]
        outdata[: len(chunk), 0] = chunk
        state["position"] += len(chunk)
jack = next(h for h in sounddevice.query_hostapis() if "JACK" in h["name"])
with sounddevice.OutputStream(device=jack["default_output_device"], samplerate=rate, channels=1, dtype="float32",
                              callback=callback):
    print("ready", flush=True)
    sys.stdin.readline()
    state["go"] = True
    sys.stdin.readline()
"""


def test_a_subprocess_plays_into_the_recorder(jack_server, tmp_path):
    """What ``barsynth play`` tests will do: another process (given ``jack_server.env``) plays through
    its own PortAudio JACK client, and the recorder hears it."""
    frequency_hz, seconds = 660.0, 0.5
    script = tmp_path / "player.py"
    script.write_text(PLAYER_SCRIPT)
    recorder = jack_server.recorder(channels=1, max_duration_s=3.0, name="subprocess-recorder")
    player = subprocess.Popen([sys.executable, str(script), str(frequency_hz), str(seconds)], env=jack_server.env,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert player.stdout.readline().strip() == "ready"
        (source,) = jack_server.wait_for_ports(PORTAUDIO_OUT, is_audio=True, is_output=True)
        jack_server.connect(source, recorder.port_names[0])
        recorder.start()
        player.stdin.write("go\n")
        player.stdin.flush()
        recorder.wait_frames(int((seconds + 0.5) * SAMPLE_RATE))
        recorder.stop()
        player.stdin.write("stop\n")
        player.stdin.flush()
        assert player.wait(60) == 0
    finally:
        if player.poll() is None:
            player.kill()
            player.wait()
    x = recorder.audio[:, 0]
    (start,) = onsets(x)
    segment = x[start + 64: start + int(seconds * SAMPLE_RATE) - 64]
    assert abs(peak_frequency_hz(segment) - frequency_hz) < 1.0
    assert np.max(np.abs(segment)) == pytest.approx(0.5, rel=0.01)
