"""Benchmark of the physical ruler twang (run by hand, never as a timed test).

    taskset -c 1 python benchmarks/bench_ruler.py [--repeat N] [--preset P] [--set NAME=VALUE ...]

Prints x real-time of a 2 s twang at 48 kHz rendered offline by the ``ruler`` model (the
finite-difference ruler, finger clamp and one-sided desk contact of spec 9; its defaults, a
30 cm ruler, unless --preset / --set say otherwise), each the whole render() call (static
release shape, grid, contact solves, desk modes, normalisation), best and median of N after one
short render that compiles or loads the kernels.

One core: ``taskset -c 1`` pins the process, and the script sets NUMBA_NUM_THREADS=1 before
numba loads, so no kernel may spread over the other core.

Target on one core (issue 16, deliverable 6): >= 5x real-time.
"""

from __future__ import annotations

import argparse
import os
import sys

os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # before barsynth imports numba

from real_time import real_time

from barsynth.errors import BarsynthError

MODEL = "ruler"
SAMPLE_RATE = 48_000
DURATION_S = 2.0
TARGET = 5.0


def _parameters(preset: str | None, assignments: list[str]) -> dict:
    """The model's parameters: its defaults, a preset, then the --set values, checked."""
    from barsynth.models import get_model
    from barsynth.parameters import parse_assignments
    from barsynth.presets import preset_parameters

    table = get_model(MODEL).table
    layers = [preset_parameters(MODEL, preset)] if preset else []
    return table.resolve(*layers, parse_assignments(assignments))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    parser.add_argument("--preset", help=f"a preset of the {MODEL} model (barsynth presets {MODEL})")
    parser.add_argument("--set", dest="assignments", action="append", default=[], metavar="NAME=VALUE",
                        help=f"set a parameter (repeatable; barsynth params {MODEL})")
    args = parser.parse_args()
    try:
        parameters = _parameters(args.preset, args.assignments)
    except BarsynthError as exc:
        print(f"bench_ruler: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    setting = " ".join([f"preset {args.preset}" if args.preset else "defaults", *args.assignments])
    best, median = real_time(MODEL, parameters, duration_s=DURATION_S, sample_rate=SAMPLE_RATE,
                             repeat=args.repeat)
    verdict = "meets" if best >= TARGET else "MISSES"
    print(f"{MODEL} ({setting}), {DURATION_S:g} s at {SAMPLE_RATE / 1000:g} kHz, "
          f"NUMBA_NUM_THREADS={os.environ['NUMBA_NUM_THREADS']}, cpu affinity "
          f"{sorted(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else '?'}")
    print(f"{'offline render':<36} {best:6.1f}x real-time best, {median:6.1f}x median "
          f"(target {TARGET:g}x: {verdict})")


if __name__ == "__main__":
    main()
