"""Live audio's plumbing (barsynth.playing.live): the ring buffer and the synthesis thread give
the callback the instrument's samples in order, and count what was missing."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from barsynth.playing.instrument import Instrument
from barsynth.playing.live import Renderer, RingBuffer


def test_the_ring_gives_back_what_was_written_across_its_end():
    ring2 = RingBuffer(8)
    seen = []
    for k in range(20):
        ring2.write(np.arange(3, dtype=np.float32) + 3 * k)
        out2 = np.empty(3, dtype=np.float32)
        assert ring2.read_into(out2) == 3
        seen.extend(out2.tolist())
    assert seen == list(range(60))
    assert ring2.underruns == 0


def test_an_empty_ring_plays_zeros_and_counts_them():
    ring = RingBuffer(16)
    ring.write(np.ones(5, dtype=np.float32))
    out = np.full(8, 7.0, dtype=np.float32)
    assert ring.read_into(out) == 5
    assert out.tolist() == [1.0] * 5 + [0.0] * 3 and ring.underruns == 3
    with pytest.raises(ValueError):
        ring.write(np.zeros(17, dtype=np.float32))


def test_the_renderer_feeds_a_slow_callback_the_instruments_samples_in_order():
    """A consumer reading 128 samples at a time, as a callback would, from another thread, gets
    exactly the instrument's offline samples (the events land at the block they were put before)."""
    live = Instrument("banded", voices=2, preset="marimba")
    offline = Instrument("banded", voices=2, preset="marimba")
    offline.note_on(60, 100)
    expected = offline.process(256 * 40)
    ring = RingBuffer(4096)
    renderer = Renderer(live, ring, block=256, lead_blocks=4)
    renderer.events.put(("note_on", (60, 100), {}))
    renderer.start()
    got = np.empty(256 * 40, dtype=np.float32)
    done = 0
    deadline = time.monotonic() + 60.0  # (not a timing assertion: a bound so a broken thread fails)
    while done < got.size and time.monotonic() < deadline:
        if ring.available() >= 128:
            ring.read_into(got[done:done + 128])
            renderer.consumed()
            done += 128
        else:
            time.sleep(0.0005)
    renderer.stop()
    assert done == got.size
    np.testing.assert_array_equal(got, expected.astype(np.float32))
    assert not renderer.is_alive() and isinstance(renderer, threading.Thread)
