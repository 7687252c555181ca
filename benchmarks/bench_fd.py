"""Benchmark of the finite-difference bar (run by hand, never as a timed test).

    taskset -c 1 python benchmarks/bench_fd.py [--repeat N]

Prints x real-time of 2 s at 44.1 kHz rendered offline by a 100-point grid (the
default aluminium bar, free-free), one scheme step per output sample, when
  * struck (the Hertzian mallet coupled to the bar),
  * bowed (Newton's method on the friction every step, bowed for the whole 2 s),
  * bowed with the explicit (forced-oscillation) friction,
and struck at the model's default of 4 steps per sample (the accurate setting),
each the whole render() call (grid, stability check, factorisation, kernel,
normalisation), best and median of N.

Target on one core (issue 5): struck >= 20x real-time (one step per sample).
"""

from __future__ import annotations

import argparse

from real_time import real_time

SAMPLE_RATE = 44_100
DURATION_S = 2.0
BOWED = {"excitation": "bow", "bow_duration_s": DURATION_S}
ONE_STEP = {"oversampling": 1}
CASES = (("struck, 100 points", ONE_STEP, 20.0),
         ("bowed (Newton), 100 points", {**ONE_STEP, **BOWED}, None),
         ("bowed (explicit), 100 points", {**ONE_STEP, **BOWED, "bow_solver": "explicit"}, None),
         ("struck, 100 points, 4 steps", {"oversampling": 4}, None))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args()
    for label, changes, target in CASES:
        best, median = real_time("fd", {"points": 100, **changes}, duration_s=DURATION_S,
                                 sample_rate=SAMPLE_RATE, repeat=args.repeat)
        verdict = "" if target is None else f" (target {target:.0f}x: {'meets' if best >= target else 'MISSES'})"
        print(f"{label:<30} {best:6.1f}x real-time best, {median:6.1f}x median{verdict}")


if __name__ == "__main__":
    main()
