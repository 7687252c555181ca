"""Benchmark of the finite-difference bar (run by hand, never as a timed test).

    taskset -c 1 python benchmarks/bench_fd.py [--repeat N]

Prints x real-time of 2 s at 44.1 kHz rendered offline by a 100-point grid (the
default aluminium bar, free-free), one scheme step per output sample, when
  * struck (the Hertzian mallet coupled to the bar),
  * bowed (Newton's method on the friction every step, bowed for the whole 2 s),
  * bowed with the explicit (forced-oscillation) friction,
and struck at the model's default of 4 steps per sample (the accurate setting),
and a thick rosewood bar (0.40 x 0.05 x 0.02 m, E/G = 14) in Timoshenko form
(theory = timoshenko: the two-field grid, 199 unknowns for 100 points) struck at 1, 2
and 4 steps per sample, each the whole render() call (grid, stability check,
factorisation, kernel, normalisation), best and median of N. The Timoshenko cases
also print describe's error of modes 1-5 against the converged thick bar (cents).

Targets on one core: struck >= 20x real-time (one step per sample, issue 5);
Timoshenko, 100 points, >= 10x real-time (issue 15).
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
THICK = {"theory": "timoshenko", "youngs_modulus_pa": 20e9, "density_kg_m3": 1000.0, "shear_modulus_pa": 1.4e9,
         "shear_coefficient": 5 / 6, "length_m": 0.40, "width_m": 0.05, "thickness_m": 0.02}
TIMOSHENKO_CASES = tuple((f"Timoshenko, 100 points, {n} step{'s' if n > 1 else ''}", {**THICK, "oversampling": n},
                          10.0) for n in (1, 2, 4))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args()
    from barsynth.models.fd import mode_errors_cents

    for label, changes, target in CASES + TIMOSHENKO_CASES:
        best, median = real_time("fd", {"points": 100, **changes}, duration_s=DURATION_S,
                                 sample_rate=SAMPLE_RATE, repeat=args.repeat)
        verdict = "" if target is None else f" (target {target:.0f}x: {'meets' if best >= target else 'MISSES'})"
        print(f"{label:<36} {best:6.1f}x real-time best, {median:6.1f}x median{verdict}")
        if changes.get("theory") == "timoshenko":
            errors = mode_errors_cents({"points": 100, **changes}, sample_rate=SAMPLE_RATE, count=5)
            print(f"{'':<36} describe's modes 1-5 against the converged bar: "
                  + " ".join(f"{e:+.2f}" for e in errors) + " cents")


if __name__ == "__main__":
    main()
