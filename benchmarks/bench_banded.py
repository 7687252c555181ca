"""Benchmark of the banded-waveguide model (run by hand, never as a timed test).

    taskset -c 1 python benchmarks/bench_banded.py [--repeat N]

Prints x real-time of 10 s at 44.1 kHz rendered offline for
  * a struck 4-mode bar (preset uniform-bar),
  * a bowed 4-mode bar (preset uniform-bar, excitation = bow, bowed for all 10 s),
  * a struck 12-mode bowl (preset bowl),
each the whole render() call (voice set-up, loop design, mallet pulse or bow
stroke, kernel, normalisation), best and median of N.

Targets on one core (issue 4): struck 4-mode bar >= 1000x, bowed 4-mode bar
>= 400x, struck 12-mode bowl >= 350x (the C++ peer, STK's BandedWG, manages about
970x, 345x and 330x on this kind of machine).
"""

from __future__ import annotations

import argparse

from real_time import real_time

from barsynth.presets import preset_parameters

SAMPLE_RATE = 44_100
DURATION_S = 10.0
BOWED = {"excitation": "bow", "bow_duration_s": DURATION_S}
CASES = (("struck 4-mode bar", "uniform-bar", {}, 1000.0),
         ("bowed 4-mode bar", "uniform-bar", BOWED, 400.0),
         ("struck 12-mode bowl", "bowl", {}, 350.0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    args = parser.parse_args()
    for label, preset, changes, target in CASES:
        parameters = {**preset_parameters("banded", preset), **changes}
        best, median = real_time("banded", parameters, duration_s=DURATION_S, sample_rate=SAMPLE_RATE,
                                 repeat=args.repeat)
        verdict = "meets" if best >= target else "MISSES"
        print(f"{label:<22} {best:7.0f}x real-time best, {median:7.0f}x median "
              f"(target {target:.0f}x: {verdict})")


if __name__ == "__main__":
    main()
