"""Benchmark of the ruler twang (run by hand, never as a timed test).

    python benchmarks/bench_twang.py [--repeat N]

Prints
  * x real-time of a 2 s twang at 48 kHz rendered offline (default preset),
  * the time per 256-sample streaming block (median, 99th percentile, worst),
  * the CLI's wall time for one render from a cold process start, with the numba
    cache warm (the usual case) and with an empty cache (the very first run).

Targets on one core of the 2-core development machine: >= 1000x real-time offline,
<= 0.2 ms per 256-sample block, <= 1.5 s for the CLI render.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from barsynth.models import get_model

SAMPLE_RATE = 48_000
DURATION_S = 2.0
BLOCK = 256


def offline(repeat: int) -> float:
    model = get_model("twang")
    model.render(duration_s=0.1, sample_rate=SAMPLE_RATE)  # compile / load the kernels
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        model.render(duration_s=DURATION_S, sample_rate=SAMPLE_RATE)
        times.append(time.perf_counter() - start)
    best = min(times)
    print(f"offline: 2 s at 48 kHz in {best * 1e3:.2f} ms (best of {repeat}, "
          f"median {np.median(times) * 1e3:.2f} ms) -> {DURATION_S / best:.0f}x real-time")
    return DURATION_S / best


def streaming(repeat: int) -> float:
    voice = get_model("twang").voice(sample_rate=SAMPLE_RATE)
    voice.trigger()
    voice.process(BLOCK)
    times = []
    blocks = int(DURATION_S * SAMPLE_RATE) // BLOCK
    for _ in range(repeat):
        voice.trigger()
        for _ in range(blocks):
            start = time.perf_counter()
            voice.process(BLOCK)
            times.append(time.perf_counter() - start)
    t = np.array(times) * 1e3
    print(f"streaming: {BLOCK}-sample blocks: median {np.median(t):.4f} ms, "
          f"p99 {np.percentile(t, 99):.4f} ms, worst {t.max():.4f} ms "
          f"(budget at 48 kHz: {BLOCK / SAMPLE_RATE * 1e3:.2f} ms)")
    return float(np.median(t))


def cli(repeat: int) -> float:
    exe = shutil.which("barsynth") or str(Path(sys.executable).with_name("barsynth"))
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "twang.wav")
        cmd = [exe, "render", "twang", "--preset", "plastic-30cm", "--duration", "2", "-o", out]  # as measured
        env = dict(os.environ)
        subprocess.run(cmd, check=True, capture_output=True, env=env)  # warm the numba cache
        times = []
        for _ in range(repeat):
            start = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True, env=env)
            times.append(time.perf_counter() - start)
        env_cold = dict(env, NUMBA_CACHE_DIR=os.path.join(tmp, "empty-numba-cache"))
        start = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, env=env_cold)
        first = time.perf_counter() - start
    print(f"cli: one render from a cold process: best {min(times):.3f} s, "
          f"median {np.median(times):.3f} s (numba cache warm); "
          f"{first:.2f} s with an empty numba cache (first run after install)")
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}, numpy {np.__version__}, cpu count {os.cpu_count()}")
    offline(args.repeat)
    streaming(max(1, args.repeat // 4))
    cli(max(3, args.repeat // 4))


if __name__ == "__main__":
    main()
