"""Benchmark of the studio's live stream (run by hand, never as a timed test).

    python benchmarks/bench_stream.py [--seconds S]

For each model's default settings (the finite-difference bar also at its cheaper
one step per sample), the time the server spends on one 256-sample block at 48 kHz
(the block's samples, the cross-fade, gain and limiter, the float32 message),
both steady and while a parameter changes every 20 ms (the page's fastest rate,
so a cross-fade is nearly always under way), and how many such streams one core
could keep in real time (5.33 ms of sound per block / time per block).

A block must take well under 5.33 ms; the studio plays at most 4 streams at once.
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
         ("fd (1 step)", {"oversampling": 1}, "level_db", (0.0, -6.0)))


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


if __name__ == "__main__":
    main()
