"""Measure the three bar models on the same bar: partial errors and cost (spec 3.2, 3.3).

    python scripts/compare_bar_models.py [--write docs/comparison.md] [--repeat N]

The bar: aluminium, 30 x 4 x 1 cm, free-free, struck near one end, heard at the other,
44.1 kHz. Each model renders 2 s; every partial of the first six modes of spec 1.2
is measured in the sound (`barsynth.analysis.measure_partial`) and compared with the
closed form, in cents (each partial measured where the model's own ``describe``
says its mode n rings; "missing" if the model has no mode n); the cost is x real time of the whole `render` call (best of
N, one process). With --write the table replaces the one between the markers
``<!-- comparison:begin -->`` and ``<!-- comparison:end -->`` in the file.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from barsynth.analysis import measure_partial
from barsynth.models import get_model, model_names
from barsynth.physics import bar_frequencies

SAMPLE_RATE = 44_100
DURATION_S = 2.0
MODES = 6
BAR = {"youngs_modulus_pa": 69e9, "density_kg_m3": 2700.0, "length_m": 0.30, "thickness_m": 0.01, "width_m": 0.04}
HIT = {"strike_position": 0.1, "pickup_position": 0.97, "mallet_hardness": 0.9}
CASES = [
    ("banded", "banded waveguide, 6 modes", {"tuning": "physics", "mode_count": MODES, "q": 300.0}),
    ("allpass", "all-pass waveguide, order 8", {"bc": "free-free", "allpass_order": 8, "q": 300.0}),
    ("allpass", "all-pass waveguide, order 24", {"bc": "free-free", "allpass_order": 24, "q": 300.0}),
    ("fd", "finite differences, 50 points, 1 step a sample", {"points": 50, "oversampling": 1}),
    ("fd", "finite differences, 100 points, 1 step a sample", {"points": 100, "oversampling": 1}),
    ("fd", "finite differences, 100 points, 4 steps a sample", {"points": 100, "oversampling": 4}),
    ("fd", "finite differences, 200 points, 8 steps a sample", {"points": 200, "oversampling": 8}),
]


def measure(model_name: str, parameters: dict, repeat: int) -> tuple[list[float], float]:
    model = get_model(model_name)
    p = {**BAR, **HIT, **parameters}
    model.render(p, duration_s=0.05, sample_rate=SAMPLE_RATE)  # compile / load the kernels
    times, x = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        x = model.render(p, duration_s=DURATION_S, sample_rate=SAMPLE_RATE, normalize=False, dtype=np.float64)
        times.append(time.perf_counter() - start)
    exact = bar_frequencies(bc="free-free", count=MODES, **{k: v for k, v in BAR.items() if k != "width_m"})
    skip = int(0.02 * SAMPLE_RATE)
    predicted = [m.frequency_hz for m in model.describe(p, sample_rate=SAMPLE_RATE)]
    errors = []
    for n, f in enumerate(exact):  # measured in the sound where the model says its mode n rings
        if n >= len(predicted):
            errors.append(math.nan)
            continue
        found = measure_partial(x[skip:], SAMPLE_RATE, predicted[n]).frequency_hz
        errors.append(1200.0 * math.log2(found / f))
    return errors, DURATION_S / min(times)


def table(rows: list[tuple[str, list[float], float]]) -> str:
    exact = bar_frequencies(bc="free-free", count=MODES, **{k: v for k, v in BAR.items() if k != "width_m"})
    head = " | ".join(f"mode {n} ({f:.0f} Hz)" for n, f in enumerate(exact, start=1))
    lines = [f"| model | {head} | x real time |", "|---" * (MODES + 2) + "|"]
    for label, errors, speed in rows:
        cells = " | ".join("missing" if math.isnan(e) else f"{e:+.1f}" for e in errors)
        lines.append(f"| {label} | {cells} | {speed:.0f}x |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--write", type=Path, help="Markdown file whose comparison table to replace.")
    args = parser.parse_args()
    rows = []
    for model_name, label, parameters in CASES:
        if model_name not in model_names():
            continue
        errors, speed = measure(model_name, parameters, args.repeat)
        rows.append((label, errors, speed))
        print(f"{label:<50} " + " ".join(f"{e:+7.1f}" for e in errors) + f"  {speed:7.1f}x", flush=True)
    text = table(rows)
    print(text)
    if args.write:
        doc = args.write.read_text(encoding="utf-8")
        begin, end = "<!-- comparison:begin -->\n", "<!-- comparison:end -->"
        a, b = doc.index(begin) + len(begin), doc.index(end)
        args.write.write_text(doc[:a] + text + doc[b:], encoding="utf-8")
        print(f"wrote the table into {args.write}")


if __name__ == "__main__":
    main()
