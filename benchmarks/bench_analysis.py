"""Benchmark of the note analysis (run by hand, never as a timed test).

    python benchmarks/bench_analysis.py [--repeat N] [WAV ...]

Prints, for each sound, the time :func:`barsynth.analysis.analyze_note` takes (warm: the
best and the median of N runs, wall clock and CPU), and the CLI's wall time for
``barsynth analyze FILE --json`` from a cold process start. The sounds: a 2 s, 44.1 kHz
synthetic marimba-like note (1:4:10, a 60 Hz hum, a noise burst, white noise at -40 dB
re peak), a 2 s render of barsynth's twang, the same note at 96 kHz, and any WAV files
given. For comparison, the old :func:`~barsynth.analysis.find_partials` on the first.

OpenBLAS is held to one thread before NumPy loads, as the ``barsynth`` program does
(``barsynth.entry``): the fits do small linear algebra, for which more threads only spin.
Target on one core of the 2-core development machine: <= 0.5 s for a 2 s, 44.1 kHz note.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from barsynth.analysis import analyze_note, find_partials  # noqa: E402
from barsynth.audio_io import load_audio, write_audio  # noqa: E402

LN1000 = math.log(1000.0)


def marimba(sample_rate: float, duration_s: float = 2.0, seed: int = 1) -> np.ndarray:
    """A marimba-like note (262 Hz, 1:4:10), a 60 Hz hum, a 5 ms noise burst, noise at -40 dB."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration_s * sample_rate))) / sample_rate
    x = np.zeros_like(t)
    for f, a, t60 in [(262.0, 0.5, 1.5), (1048.0, 0.25, 0.4), (2620.0, 0.1, 0.15)]:
        x += a * np.exp(-t * LN1000 / t60) * np.cos(2 * np.pi * f * t + 1.0)
    x += 0.05 * np.cos(2 * np.pi * 60.0 * t)
    x += 0.3 * np.exp(-t / 0.0017) * rng.standard_normal(t.size)
    return x + 0.01 * np.max(np.abs(x)) * rng.standard_normal(t.size)


def twang(sample_rate: float, duration_s: float = 2.0) -> np.ndarray:
    from barsynth.models import get_model

    return np.asarray(get_model("twang").render(duration_s=duration_s, sample_rate=sample_rate), dtype=np.float64)


def timed(samples: np.ndarray, sample_rate: float, repeat: int, function=analyze_note) -> tuple[float, float, float]:
    """(best wall, median wall, best CPU) seconds of ``function(samples, sample_rate)``, warm."""
    function(samples, sample_rate)
    walls, cpus = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        function(samples, sample_rate)
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return min(walls), float(np.median(walls)), min(cpus)


def cli_wall(path: Path) -> float:
    """Wall time of ``barsynth analyze PATH --json`` in a new process, s (best of 3)."""
    command = [sys.executable, "-m", "barsynth", "analyze", str(path), "--json"]
    best = math.inf
    for _ in range(3):
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True)
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("wavs", nargs="*", type=Path)
    args = parser.parse_args()
    sounds = [
        ("marimba-like 2 s, 44.1 kHz", marimba(44100.0), 44100.0),
        ("twang 2 s, 44.1 kHz", twang(44100.0), 44100.0),
        ("marimba-like 2 s, 96 kHz", marimba(96000.0), 96000.0),
    ]
    for path in args.wavs:
        samples, rate = load_audio(path)
        sounds.append((f"{path.name} ({samples.size / rate:.2f} s, {rate / 1000:g} kHz)", samples, rate))
    print(f"analyze_note, warm, best of {args.repeat} (median), CPU:")
    with tempfile.TemporaryDirectory() as folder:
        for i, (name, samples, rate) in enumerate(sounds):
            best, median, cpu = timed(samples, rate, args.repeat)
            note = analyze_note(samples, rate)
            f0 = f"{note.f0_hz:.2f} Hz" if note.f0_hz else "none"
            path = Path(folder) / f"sound{i}.wav"
            write_audio(path, samples / max(1.0, float(np.max(np.abs(samples)))), rate, fmt="WAV", subtype="FLOAT")
            print(f"  {name:<40} {best * 1e3:7.1f} ms ({median * 1e3:7.1f} ms), CPU {cpu * 1e3:7.1f} ms; "
                  f"CLI {cli_wall(path):.2f} s; f0 {f0}, {len(note.partials)} partials")
    best, median, _ = timed(sounds[0][1], sounds[0][2], 1, find_partials)
    print(f"find_partials on the first, for comparison: {best * 1e3:.0f} ms")


if __name__ == "__main__":
    main()
