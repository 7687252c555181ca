"""Benchmark of the studio's live stream (run by hand, never as a timed test).

    python benchmarks/bench_stream.py [--seconds S]

For each model's default settings (the finite-difference bar also at its cheaper
one step per sample), the time the server spends on one 256-sample block at 48 kHz
(the block's samples, the cross-fade, gain and limiter, the float32 message),
both steady and while a parameter changes every 20 ms (the page's fastest rate,
so a cross-fade is nearly always under way), and how many such streams one core
could keep in real time (5.33 ms of sound per block / time per block).

A block must take well under 5.33 ms; the studio plays at most 4 streams at once.

Then, per model, the time the server takes to land one change that needs a new design
(a new value each time): trying it on a fresh voice and applying it. A change is heard
after this on top of the stream's lead.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from barsynth.studio.stream import BLOCK, Stream

RATE = 48000
CASES = (("twang", {}, "length_m", (0.25, 0.3)),
         ("farnell", {}, "frequency_hz", (300.0, 420.0)),
         ("banded (marimba)", {"tuning": "ratios", "mode_ratios": (1.0, 4.0, 10.0)}, "frequency_hz", (220.0, 260.0)),
         ("banded (bowed)", {"excitation": "bow", "bow_duration_s": 600.0}, "bow_force_n", (3.0, 4.0)),
         ("allpass", {}, "level_db", (0.0, -6.0)),
         ("fd (4 steps)", {}, "level_db", (0.0, -6.0)),
         ("fd (1 step)", {"oversampling": 1}, "level_db", (0.0, -6.0)),
         ("ruler", {}, "finger_force_n", (20.0, 25.0)),
         ("kalimba", {}, "q", (2000.0, 2500.0)))


def measure(model: str, parameters: dict, name: str, values: tuple, seconds: float, changing: bool) -> np.ndarray:
    stream = Stream()
    found = stream.prepare_start({"model": model.split()[0], "parameters": parameters, "sample_rate": RATE})
    stream.start(found[0], *Stream.build_voice(*found), found[2])
    stream.handle({"type": "trigger"})
    every = max(1, round(0.020 * RATE / BLOCK))
    times = []
    for k in range(int(seconds * RATE / BLOCK)):
        start = time.perf_counter()
        if changing and k % every == 0:
            stream.handle({"type": "set", "id": k, "parameters": {name: values[(k // every) % 2]}})
        stream.next_block()
        times.append(time.perf_counter() - start)
        stream.handle({"type": "played", "samples": stream.samples_sent})
    return np.array(times[10:]) * 1e3  # ms, after the first blocks


REDESIGNS = (("twang", {}, "length_m", 0.25), ("farnell", {}, "frequency_hz", 300.0),
             ("banded", {"tuning": "ratios"}, "frequency_hz", 220.0), ("allpass", {}, "length_m", 0.25),
             ("fd", {}, "points", 120), ("fd", {"points": 300}, "points", 320))


def change_time(model: str, parameters: dict, name: str, first: float, count: int = 8) -> np.ndarray:
    """What the server does for one ``set`` that needs a new design (a new value each time, so no
    design cache helps): the rehearsal on a fresh voice, then the change itself (ms)."""
    from barsynth.studio.live import _rehearse

    stream = Stream()
    found = stream.prepare_start({"model": model, "parameters": parameters, "sample_rate": RATE})
    stream.start(found[0], *Stream.build_voice(*found), found[2])
    stream.handle({"type": "trigger"})
    times = []
    for k in range(count):
        value = type(first)(first * (1.0 + 0.01 * (k + 1)))
        start = time.perf_counter()
        _rehearse(stream, {name: value})
        stream.handle({"type": "set", "id": k + 1, "parameters": {name: value}})
        times.append(time.perf_counter() - start)
        stream.next_block()
    return np.array(times) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    args = parser.parse_args()
    budget = BLOCK / RATE * 1e3
    print(f"{'model':<18} {'steady ms/block':>16} {'p99':>6} {'changing ms/block':>18} {'p99':>6} "
          f"{'streams/core':>13}")
    for label, parameters, name, values in CASES:
        steady = measure(label, parameters, name, values, args.seconds, False)
        moving = measure(label, parameters, name, values, args.seconds, True)
        print(f"{label:<18} {np.median(steady):16.3f} {np.percentile(steady, 99):6.3f} "
              f"{np.median(moving):18.3f} {np.percentile(moving, 99):6.3f} "
              f"{budget / np.mean(moving):13.0f}")
    print()
    print(f"{'a change that needs a new design':<40} {'median ms':>10} {'max ms':>8}")
    for model, parameters, name, first in REDESIGNS:
        spent = change_time(model, parameters, name, first)
        label = f"{model} {name}, from {first:g}"
        print(f"{label:<40} {np.median(spent):10.1f} {np.max(spent):8.1f}")


if __name__ == "__main__":
    main()
