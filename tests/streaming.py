"""A helper for the streaming tests: play a voice through timed events in blocks of a size."""

from __future__ import annotations

import numpy as np


def play(voice, events: dict, total: int, block: int) -> np.ndarray:
    """Run ``voice`` for ``total`` samples in blocks of at most ``block``, doing each event
    ``{sample: ("trigger" | "release" | "set", {parameters})}`` exactly at its sample."""
    out, now = [], 0
    while now < total:
        if now in events:
            action, values = events[now]
            if action == "trigger":
                voice.trigger()
            elif action == "set":
                voice.set_parameters(**values)
            else:
                voice.release()
        count = min(block, min([t for t in events if t > now] + [total]) - now)
        out.append(voice.process(count, dtype=np.float64))
        now += count
    return np.concatenate(out)
