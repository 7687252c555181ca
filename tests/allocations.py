"""How much a voice's ``process(n, out=buf)`` allocates, measured with tracemalloc."""

from __future__ import annotations

import tracemalloc

import numpy as np


def process_allocations(voice, block: int = 256, calls: int = 1000, warm_up: int = 3000) -> tuple[int, int]:
    """(bytes still held, largest passing extra) over ``calls`` blocks into float64 and float32
    buffers, after ``warm_up`` blocks under tracemalloc (blocks allocated before it started and
    freed after would hide new ones). The int that holds the first reading is 32 bytes."""
    buffers = (np.empty(block), np.empty(block, dtype=np.float32))
    tracemalloc.start()
    try:
        for _ in range(warm_up):
            for buf in buffers:
                voice.process(block, out=buf)
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        for _ in range(calls):
            for buf in buffers:
                voice.process(block, out=buf)
        now, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return now - before, peak - before
