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
            done += 128
        else:
            time.sleep(0.0005)
    renderer.stop()
    assert done == got.size
    np.testing.assert_array_equal(got, expected.astype(np.float32))
    assert not renderer.is_alive() and isinstance(renderer, threading.Thread)


def _consume(ring: RingBuffer, renderer: Renderer, got: np.ndarray, start: int, stop: int, piece: int = 128) -> int:
    """Read ``got[start:stop]`` as a callback would, ``piece`` samples when they are ready."""
    done = start
    deadline = time.monotonic() + 60.0  # (a bound so a broken thread fails, not a timing assertion)
    while done < stop and time.monotonic() < deadline:
        if ring.available() >= piece:
            ring.read_into(got[done:done + piece])
            done += piece
        else:
            time.sleep(0.0005)
    assert done == stop
    return done


def test_a_scheduled_note_sounds_a_fixed_lead_after_it_came_even_after_an_underrun():
    """The consumer plays zeros before the synthesis thread starts (an underrun: counted, and the
    ring's clock moves on); a note scheduled later sounds exactly ``latency_samples`` after the
    consumer's position when it came, sample for sample as an offline render with the note there."""
    live = Instrument("banded", voices=2, preset="marimba")
    ring = RingBuffer(4096)
    renderer = Renderer(live, ring, block=256, lead_blocks=4)
    got = np.zeros(256 * 48, dtype=np.float32)
    assert ring.read_into(got[:1024]) == 0  # nothing rendered yet
    renderer.start()
    _consume(ring, renderer, got, 1024, 3072)
    came = ring.read
    sample = renderer.schedule("note_on", 60, 100)
    _consume(ring, renderer, got, 3072, got.size)
    renderer.stop()
    assert sample == came + 5 * 256 == came + renderer.latency_samples
    offline = Instrument("banded", voices=2, preset="marimba")
    offline.note_on(60, 100, at=sample)
    np.testing.assert_array_equal(got, offline.process(got.size).astype(np.float32))
    assert ring.underruns == 1024 and renderer.late == 0


def test_a_note_the_model_cannot_reach_is_refused_and_the_thread_plays_on():
    live = Instrument("banded", voices=2, preset="marimba")
    ring = RingBuffer(4096)
    renderer = Renderer(live, ring, block=256, lead_blocks=4)
    renderer.start()
    got = np.zeros(256 * 24, dtype=np.float32)
    renderer.schedule("note_on", 0, 100)  # 8.2 Hz: below the model's 20 Hz
    sample = renderer.schedule("note_on", 69, 100, delay_samples=100)
    _consume(ring, renderer, got, 0, got.size)
    renderer.stop()
    refusals = []
    while not renderer.refusals.empty():
        refusals.append(renderer.refusals.get())
    assert len(refusals) == 1 and "8.1758 Hz" in refusals[0] and "allowed: 20 to 5000 Hz" in refusals[0]
    assert np.all(got[:sample] == 0.0) and np.max(np.abs(got[sample:])) > 0.1
