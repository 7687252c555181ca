"""`barsynth play`: an Instrument through the computer's audio, played from MIDI or the keyboard (spec 10.4).

The synthesis thread (:class:`~.live.Renderer`) keeps a ring buffer ahead; PortAudio's callback
(through ``sounddevice``; JACK is one of its host APIs) only copies out of it. MIDI comes in
through ``python-rtmidi`` (its callback schedules the notes on the renderer), or keys from
the terminal (:mod:`.keyboard`). Each note sounds a fixed time after it arrives: PortAudio's
output latency plus the ring's lead (:attr:`~.live.Renderer.latency_samples`); ``play``
prints that figure when it starts.

Order matters with JACK (docs/jack-notes.md): python-rtmidi holds the GIL while it talks to the
server, and the server waits for every client's process callback, so the MIDI client is opened
before the audio stream and closed after it (:func:`midi_input`), never while a Python audio
callback runs. And it is closed explicitly: an rtmidi object refers to itself (a reference
cycle), so dropping it does not close its JACK client, and a process that exits with the
client open leaves a dead client in the server's graph, which a synchronous server then waits
for (``jackd -t`` times ten) at its next graph change.
"""

from __future__ import annotations

import contextlib
import copy
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from ..errors import BarsynthError
from .live import Renderer, RingBuffer

CLIENT_NAME = "barsynth"
"""The MIDI client's name when it connects to an existing port."""
END_TAIL_S = 0.5
"""After the input ends (a pipe closed), how long the last note rings after its release before ``play`` returns."""


def midi_events(message: list[int]) -> tuple[str, tuple] | None:
    """The instrument call for a MIDI message (status and data bytes), or None to ignore it."""
    if not message:
        return None
    kind = message[0] & 0xF0
    if kind == 0x90 and len(message) >= 3:
        return ("note_on", (message[1], message[2])) if message[2] > 0 else ("note_off", (message[1],))
    if kind == 0x80 and len(message) >= 2:
        return ("note_off", (message[1],))
    if kind == 0xB0 and len(message) >= 3:
        return ("control", (message[1], message[2]))
    return None


def _rtmidi_api(api: str) -> int:
    import rtmidi

    return {"default": rtmidi.API_UNSPECIFIED, "jack": rtmidi.API_UNIX_JACK, "alsa": rtmidi.API_LINUX_ALSA}[api]


def find_port(wanted: str, ports: list[str]) -> int:
    """The index of the port ``wanted`` names: its number, its full name, or the one port whose
    name contains it (case-insensitive). Refuses in one line listing the ports."""
    available = ", ".join(f"{i}: {name}" for i, name in enumerate(ports)) or "none"
    if wanted.isdigit() and int(wanted) < len(ports):
        return int(wanted)
    if wanted in ports:
        return ports.index(wanted)
    matches = [i for i, name in enumerate(ports) if wanted.lower() in name.lower()]
    if len(matches) == 1:
        return matches[0]
    what = "names more than one" if matches else "names no"
    raise BarsynthError(f"--midi-in {wanted!r} {what} MIDI input port; available: {available}")


@contextlib.contextmanager
def midi_input(port: str | None = None, *, virtual: str | None = None, api: str = "default") -> Iterator[Any]:
    """A python-rtmidi ``MidiIn`` reading ``port`` (an existing port: see :func:`find_port`) or a
    new port ``virtual:in`` others connect to; closed (port, then client) when the block ends.

    Open it before the audio stream and let the stream close first (the module's note).
    """
    import rtmidi

    if (port is None) == (virtual is None):
        raise ValueError("give port or virtual")
    try:
        with _quiet_stderr():  # libasound and libjack print their own complaints
            midi_in = rtmidi.MidiIn(_rtmidi_api(api), name=virtual or CLIENT_NAME)
            ports = midi_in.get_ports()
    except rtmidi.RtMidiError as error:
        raise BarsynthError(f"could not open MIDI input ({api}): {' '.join(str(error).split())}") from None
    try:
        with _quiet_stderr():
            if virtual is not None:
                midi_in.open_virtual_port("in")
            else:
                midi_in.open_port(find_port(port, ports), "in")
        midi_in.ignore_types(sysex=True, timing=True, active_sense=True)
    except rtmidi.RtMidiError as error:
        midi_in.delete()
        raise BarsynthError(f"could not open MIDI input ({api}): {' '.join(str(error).split())}") from None
    except BaseException:
        midi_in.delete()
        raise
    try:
        yield midi_in
    finally:
        midi_in.cancel_callback()
        midi_in.close_port()
        midi_in.delete()  # closes the client now (see the module's note); the object is dead after this


@contextlib.contextmanager
def _quiet_stderr() -> Iterator[None]:
    """Standard error (the file descriptor, where C libraries write) to /dev/null for a while."""
    import os
    import sys

    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def open_stream(callback: Callable, *, sample_rate: float, block: int, device: Any) -> Any:
    """A ``sounddevice.OutputStream`` (mono float32, not started), or a one-line refusal naming
    the device and the output devices there are."""
    import sounddevice

    try:
        return sounddevice.OutputStream(samplerate=sample_rate, blocksize=block, device=device, channels=1,
                                        dtype="float32", callback=callback)
    except (sounddevice.PortAudioError, ValueError) as error:
        outputs = [f"{i}: {d['name']}" for i, d in enumerate(sounddevice.query_devices())
                   if d["max_output_channels"] > 0]
        which = f"--device {device!r}" if device is not None else "the default audio output"
        reason = " ".join(str(error).split())
        listed = "; ".join(outputs) if outputs else "none (no audio output device found)"
        raise BarsynthError(f"could not open {which}: {reason}; output devices: {listed}") from None


def play(instrument: Any, *, sample_rate: float, device: Any = None, block: int = 256, lead_blocks: int = 4,
         midi_in: Any = None, keyboard: Any = None, seconds: float | None = None,
         echo: Callable[[str], None] = print, stop: threading.Event | None = None,
         source: str = "") -> dict[str, Any]:
    """Play until ``seconds`` have passed, ``stop`` is set, the keyboard quits (or its input
    ends) or Ctrl-C. Returns the counts: blocks rendered, samples the callback found missing,
    events that came too late for their sample, and the expected latency in ms.

    Parameters
    ----------
    midi_in : rtmidi.MidiIn, optional
        Open (see :func:`midi_input`); its callback is set here and cancelled before the stream closes.
    keyboard : .keyboard.KeyboardInput, optional
        Polled on this thread; each key it reads becomes a note.
    """
    warm_up(instrument, block)
    ring = RingBuffer(1 << max(12, int(np.ceil(np.log2(block * (lead_blocks + 2))))))
    renderer = Renderer(instrument, ring, block=block, lead_blocks=lead_blocks)

    def callback(outdata, frames, time_info, status):  # PortAudio's thread: copy out, nothing else
        ring.read_into(outdata[:, 0])

    stream = open_stream(callback, sample_rate=sample_rate, block=block, device=device)
    if midi_in is not None:
        midi_in.set_callback(lambda event, _: _put(renderer, event[0]))
    if keyboard is not None:
        keyboard.bind(renderer, sample_rate)
    stop = stop or threading.Event()
    counts: dict[str, Any] = {}
    renderer.start()
    try:
        with stream:
            lead_ms = renderer.latency_samples / sample_rate * 1000.0
            counts["latency_ms"] = stream.latency * 1000.0 + lead_ms
            echo(f"ready: note-to-sound latency {counts['latency_ms']:.1f} ms = output {stream.latency * 1000:.1f} ms "
                 f"(as PortAudio reports it) + ring lead {lead_ms:.1f} ms ({lead_blocks} + 1 blocks of {block} "
                 f"samples at {sample_rate:g} Hz){'; ' + source if source else ''}")
            began = time.monotonic()
            end_at: int | None = None  # the sample after which a finished input stops the player
            try:
                while not stop.is_set() and (seconds is None or time.monotonic() - began < seconds):
                    if keyboard is not None and end_at is None:
                        state = keyboard.poll(0.05)
                        if state == "quit":
                            break
                        if state == "end":
                            end_at = keyboard.last_sample + int(END_TAIL_S * sample_rate)
                    else:
                        stop.wait(0.05)
                    if end_at is not None and ring.read >= end_at:
                        break
                    while not renderer.refusals.empty():
                        echo(f"refused: {renderer.refusals.get()}")
            except KeyboardInterrupt:  # Ctrl-C: a way to stop, like Escape
                pass
            finally:
                if midi_in is not None:
                    midi_in.cancel_callback()  # no new events while the stream closes
    finally:
        renderer.stop()
    counts.update(blocks=renderer.blocks, underruns=ring.underruns, late=renderer.late)
    return counts


WARM_UP_NOTES = (69, 60, 81, 48, 93, 36, 105)


def warm_up(instrument: Any, block: int) -> None:
    """Play a note on a copy of ``instrument`` (the first note of a process loads and compiles what
    it needs: about 0.2 s for banded here, which would come late on the first key played)."""
    trial = copy.deepcopy(instrument)
    for note in WARM_UP_NOTES:  # the first the model can play
        try:
            trial.note_on(note, 100)
            trial.process(block)
        except BarsynthError:
            continue
        return


def _put(renderer: Renderer, message: list[int]) -> None:
    event = midi_events(message)
    if event is not None:
        renderer.schedule(event[0], *event[1])
