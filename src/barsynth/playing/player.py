"""`barsynth play`: an Instrument through the computer's audio, played from MIDI (spec 10.4).

The synthesis thread (:class:`~.live.Renderer`) keeps a ring buffer ahead; PortAudio's callback
(through ``sounddevice``; JACK is one of its host APIs) only copies out of it. MIDI comes in
through ``python-rtmidi`` (its callback puts the notes on the renderer's queue). The MIDI port
is opened before the audio stream: with JACK, an rtmidi port opened while a Python audio
callback runs stalls the server (docs/jack-notes.md).
"""

from __future__ import annotations

import threading
import time
from typing import Any, Callable

import numpy as np

from .live import Renderer, RingBuffer

MIDI_APIS = ("default", "jack", "alsa")


def midi_events(message: list[int]) -> tuple[str, tuple, dict] | None:
    """The instrument call for a MIDI message (status and data bytes), or None to ignore it."""
    if not message:
        return None
    status, kind = message[0], message[0] & 0xF0
    if kind == 0x90 and len(message) >= 3:
        return ("note_on", (message[1], message[2]), {}) if message[2] > 0 else ("note_off", (message[1],), {})
    if kind == 0x80 and len(message) >= 2:
        return ("note_off", (message[1],), {})
    if kind == 0xB0 and len(message) >= 3:
        return ("control", (message[1], message[2]), {})
    del status
    return None


def open_midi_in(name: str, api: str) -> Any:
    """A python-rtmidi input with a virtual port ``name:in`` (JACK) or ``name`` (ALSA)."""
    import rtmidi

    apis = {"default": rtmidi.API_UNSPECIFIED, "jack": rtmidi.API_UNIX_JACK, "alsa": rtmidi.API_LINUX_ALSA}
    midi_in = rtmidi.MidiIn(apis[api], name=name)
    midi_in.open_virtual_port("in")
    midi_in.ignore_types(sysex=True, timing=True, active_sense=True)
    return midi_in


def play(instrument: Any, *, sample_rate: float, device: Any = None, block: int = 256, lead_blocks: int = 4,
         midi_in: Any = None, seconds: float | None = None, echo: Callable[[str], None] = print,
         stop: threading.Event | None = None) -> dict[str, Any]:
    """Play until ``seconds`` have passed (None: until ``stop`` is set or Ctrl-C). Returns the
    counts: blocks rendered, samples the callback found missing."""
    import sounddevice

    ring = RingBuffer(1 << max(12, int(np.ceil(np.log2(block * (lead_blocks + 2))))))
    renderer = Renderer(instrument, ring, block=block, lead_blocks=lead_blocks)
    if midi_in is not None:
        midi_in.set_callback(lambda event, _: _put(renderer, event[0]))

    def callback(outdata, frames, time_info, status):  # PortAudio's thread: copy out, nothing else
        ring.read_into(outdata[:, 0])
        renderer.consumed()

    renderer.start()
    stop = stop or threading.Event()
    try:
        with sounddevice.OutputStream(samplerate=sample_rate, blocksize=block, device=device, channels=1,
                                      dtype="float32", callback=callback) as stream:
            echo(f"ready: {stream.latency * 1000:.1f} ms output latency + {lead_blocks} blocks of {block} samples "
                 f"ahead ({lead_blocks * block / sample_rate * 1000:.1f} ms)")
            began = time.monotonic()
            while not stop.is_set() and (seconds is None or time.monotonic() - began < seconds):
                stop.wait(0.05)
    finally:
        renderer.stop()
        if midi_in is not None:
            midi_in.cancel_callback()
            midi_in.close_port()
    return {"blocks": renderer.blocks, "underruns": ring.underruns}


def _put(renderer: Renderer, message: list[int]) -> None:
    event = midi_events(message)
    if event is not None:
        renderer.events.put(event)
