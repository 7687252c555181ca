"""Live audio's plumbing: a ring buffer between a synthesis thread and an audio callback (spec 10.4).

The audio callback (PortAudio's, through ``sounddevice``; or JACK's) must never allocate, lock
or wait: it only copies what the synthesis thread has rendered ahead out of a
:class:`RingBuffer`, and plays zeros (an underrun, counted) when nothing is ready. The
:class:`Renderer` thread keeps the ring ``lead_blocks`` blocks ahead, taking note events from a
queue (MIDI input, the keyboard) and rendering them into an :class:`~.instrument.Instrument`.
The kernels release the GIL, so the callback's thread gets its turn.

Timing: :meth:`Renderer.schedule` stamps an event, when it arrives, with the sample the
consumer has reached plus the lead and one block (the most the renderer keeps ahead), and the
instrument plays it at that sample. Every note then sounds the same time after it arrived
(one block of jitter: the consumer moves a block at a time), whether the synthesis thread was
ahead or, on a loaded machine, behind; an event put straight on :attr:`Renderer.events` plays
at the next block rendered instead.
"""

from __future__ import annotations

import heapq
import queue
import threading
from typing import Any

import numpy as np

from ..checks import check_whole
from ..errors import BarsynthError

__all__ = ["RingBuffer", "Renderer"]

POLL_S = 0.001
"""How often the synthesis thread looks for room in the ring when it is full (s)."""


class RingBuffer:
    """A single-producer, single-consumer ring of float32 samples (``capacity`` a power of two).

    ``written`` and ``read`` only grow (Python ints: each assignment is atomic under the GIL),
    and each side only moves its own; the producer writes only into free space, the consumer
    reads only what was written, so neither needs a lock. ``read`` counts every sample the
    consumer played, the zeros of an underrun too, so it is the audio clock: a producer that
    fell behind it skips to it (:meth:`catch_up`), and what it renders next plays at the sample
    it was meant for.
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
        return self.capacity - self.available()

    def available(self) -> int:
        return max(0, self.written - self.read)

    def catch_up(self) -> int:
        """(Producer) After an underrun the consumer is past what was written: continue from where
        it is. Returns the samples skipped (they were played as zeros)."""
        read = self.read
        skipped = max(0, read - self.written)
        if skipped:
            self.written = read
        return skipped

    def write(self, samples: np.ndarray) -> None:
        """Append ``samples`` (the caller checked :meth:`free` and called :meth:`catch_up`)."""
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
        ready = min(n, max(0, self.written - self.read))
        start = self.read & self._mask
        first = min(ready, self.capacity - start)
        out[:first] = self._data[start:start + first]
        out[first:ready] = self._data[:ready - first]
        if ready < n:
            out[ready:] = 0.0
            self.underruns += n - ready
        self.read += n
        return ready


class Renderer(threading.Thread):
    """The synthesis thread: keeps ``ring`` filled ``lead_blocks`` blocks of ``block`` samples
    ahead from ``instrument``, applying the events put on :attr:`events`: ``(method, args,
    kwargs)``, e.g. ``("note_on", (60, 100), {})``, at the next block it renders, or
    ``(method, args, kwargs, sample)`` (from :meth:`schedule`) at that sample of the ring."""

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
        self._stopping = threading.Event()
        self.blocks = 0
        self.late = 0
        """Scheduled events that came after their sample was rendered (played at the next block)."""
        self.refusals: queue.SimpleQueue = queue.SimpleQueue()
        """The one-line messages of events the instrument refused (e.g. a note out of the model's range)."""

    @property
    def latency_samples(self) -> int:
        """How long after it arrives a scheduled event sounds, in samples at the ring's output
        (up to one block more, by when in the consumer's block it arrives)."""
        return self.lead + self.block

    def schedule(self, method: str, *args: Any, delay_samples: int = 0) -> int:
        """Queue ``instrument.method(*args)`` to sound :attr:`latency_samples` (plus
        ``delay_samples``) after the sample the consumer has reached; returns that sample.
        Safe from any thread (MIDI callbacks, the keyboard)."""
        sample = self.ring.read + self.latency_samples + delay_samples
        self.events.put((method, args, {}, sample))
        return sample

    def run(self) -> None:
        pending: list[tuple[int, int, str, tuple]] = []  # scheduled events: (sample, order, method, args)
        order = 0
        while not self._stopping.is_set():
            self.ring.catch_up()  # (after an underrun: the next block plays at ring.written)
            while True:
                try:
                    event = self.events.get_nowait()
                except queue.Empty:
                    break
                if len(event) == 4:
                    heapq.heappush(pending, (event[3], order, event[0], event[1]))
                    order += 1
                else:
                    self._call(event[0], event[1], event[2])
            if self.ring.available() < self.lead and self.ring.free() >= self.block:
                written = self.ring.written
                while pending and pending[0][0] < written + self.block:  # (the instrument's next block is here)
                    sample, _, method, args = heapq.heappop(pending)
                    if sample < written:
                        self.late += 1
                    self._call(method, args, {"at": max(0, sample - written)})
                self._render()
                self.ring.write(self._buffer)
                self.blocks += 1
            else:
                # Poll: the callback's next read makes room. (It is not woken by the callback: setting
                # a threading.Event takes a lock, which an audio callback must never do.)
                self._stopping.wait(POLL_S)

    def _render(self) -> None:
        """The next block into the buffer. A note the model cannot reach is refused when its sample
        comes (one line on :attr:`refusals`); the rest of the block is rendered after it."""
        start = self.instrument.rendered
        while (done := self.instrument.rendered - start) < self.block:
            try:
                self.instrument.process(self.block - done, out=self._buffer[done:])
            except BarsynthError as error:
                self.refusals.put(str(error))

    def _call(self, method: str, args: tuple, kwargs: dict) -> None:
        try:
            getattr(self.instrument, method)(*args, **kwargs)
        except BarsynthError as error:  # a note the model cannot reach: refused, the thread plays on
            self.refusals.put(str(error))

    def stop(self) -> None:
        self._stopping.set()
        self.join(timeout=5.0)
