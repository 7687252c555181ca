"""Live audio's plumbing: a ring buffer between a synthesis thread and an audio callback (spec 10.4).

The audio callback (PortAudio's, through ``sounddevice``; or JACK's) must never allocate, lock
or wait: it only copies what the synthesis thread has rendered ahead out of a
:class:`RingBuffer`, and plays zeros (an underrun, counted) when nothing is ready. The
:class:`Renderer` thread keeps the ring ``lead_blocks`` blocks ahead, taking note events from a
queue (MIDI input, the keyboard) and rendering them into an :class:`~.instrument.Instrument`
at the next block. The kernels release the GIL, so the callback's thread gets its turn.
"""

from __future__ import annotations

import queue
import threading
from typing import Any

import numpy as np

from ..checks import check_whole

__all__ = ["RingBuffer", "Renderer"]


class RingBuffer:
    """A single-producer, single-consumer ring of float32 samples (``capacity`` a power of two).

    ``written`` and ``read`` only grow (Python ints: each assignment is atomic under the GIL),
    and each side only moves its own; the producer writes only into free space, the consumer
    reads only what was written, so neither needs a lock.
    """

    def __init__(self, capacity: int):
        capacity = check_whole("capacity", capacity, "samples", 2, 1 << 24)
        if capacity & (capacity - 1):
            raise ValueError("capacity must be a power of two")
        self._data = np.zeros(capacity, dtype=np.float32)
        self._mask = capacity - 1
        self.written = 0
        self.read = 0
        self.underruns = 0
        """Samples the consumer asked for and found missing (played as zeros)."""

    @property
    def capacity(self) -> int:
        return self._data.size

    def free(self) -> int:
        return self.capacity - (self.written - self.read)

    def available(self) -> int:
        return self.written - self.read

    def write(self, samples: np.ndarray) -> None:
        """Append ``samples`` (the caller checked :meth:`free`)."""
        n = samples.size
        if n > self.free():
            raise ValueError("ring buffer overflow")
        start = self.written & self._mask
        first = min(n, self.capacity - start)
        self._data[start:start + first] = samples[:first]
        self._data[:n - first] = samples[first:]
        self.written += n

    def read_into(self, out: np.ndarray) -> int:
        """Fill ``out`` (a float32 view the callback owns) with the next samples, zeros where none
        are ready; returns how many were real. Allocates nothing."""
        n = out.size
        ready = min(n, self.written - self.read)
        start = self.read & self._mask
        first = min(ready, self.capacity - start)
        out[:first] = self._data[start:start + first]
        out[first:ready] = self._data[:ready - first]
        if ready < n:
            out[ready:] = 0.0
            self.underruns += n - ready
        self.read += ready
        return ready


class Renderer(threading.Thread):
    """The synthesis thread: keeps ``ring`` filled ``lead_blocks`` blocks of ``block`` samples
    ahead from ``instrument``, applying the events put on :attr:`events` (``(method, args,
    kwargs)``, e.g. ``("note_on", (60, 100), {})``) at the next block it renders."""

    def __init__(self, instrument: Any, ring: RingBuffer, *, block: int = 256, lead_blocks: int = 4):
        super().__init__(name="barsynth-renderer", daemon=True)
        self.instrument = instrument
        self.ring = ring
        self.block = check_whole("block", block, "samples", 16, 8192)
        self.lead = check_whole("lead_blocks", lead_blocks, "blocks", 1, 64) * self.block
        if self.lead + self.block > ring.capacity:
            raise ValueError("the ring buffer is smaller than the lead")
        self.events: queue.SimpleQueue = queue.SimpleQueue()
        self._buffer = np.empty(self.block)
        self._wake = threading.Event()
        self._stopping = threading.Event()
        self.blocks = 0

    def run(self) -> None:
        while not self._stopping.is_set():
            while True:
                try:
                    method, args, kwargs = self.events.get_nowait()
                except queue.Empty:
                    break
                getattr(self.instrument, method)(*args, **kwargs)
            if self.ring.available() < self.lead and self.ring.free() >= self.block:
                self.instrument.process(self.block, out=self._buffer)
                self.ring.write(self._buffer)
                self.blocks += 1
            else:
                self._wake.wait(timeout=0.001)  # the callback's next read makes room
                self._wake.clear()

    def consumed(self) -> None:
        """Called by the audio callback after a read: room was made (a cheap, lock-free set)."""
        self._wake.set()

    def stop(self) -> None:
        self._stopping.set()
        self._wake.set()
        self.join(timeout=5.0)
