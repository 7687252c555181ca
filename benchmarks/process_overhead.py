"""The fixed cost of one ``voice.process(n, out=buf)`` call, per model (run by hand, not a test).

    python benchmarks/process_overhead.py                 # every model
    python benchmarks/process_overhead.py --models twang fd --calls 20000

For each model's default voice at 48 kHz, triggered and warmed up (kernels compiled or loaded
from numba's cache, a few thousand calls made), it times ``process(1, out=buf)`` and
``process(256, out=buf)`` into a caller-owned float64 buffer: the median over ``--repeats``
batches of ``--calls`` calls, per call, in CPU time (``resource.getrusage``: the machine may be
shared) and wall time. ``process(1)`` is nearly all fixed cost (the base class's checks, the
call into the kernel: numba's dispatcher types every argument on each call unless the voice
calls a resolved overload). ``_render(1 sample)`` calls the model's ``_render`` directly: its
part of the fixed cost, without the base class's checks (``process(1) - _render``). The
per-sample cost is ``(t256 - t1) / 255``.

A voice renders only while it sounds; a default note rings for seconds, so the batches
(a few seconds of sound at most) stay inside the note. Models are timed alternately, batch
by batch, so a change of load touches them all alike.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time

import numpy as np

from barsynth.models.base import get_model, model_names


def cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def batch(voice, n: int, buf: np.ndarray, calls: int) -> tuple[float, float]:
    """(CPU s, wall s) per call of ``calls`` calls of ``voice.process(n, out=buf)``; ``n`` = 0:
    ``voice._render(buf)`` (one sample), the model's own part without the base class's checks."""
    c0, w0 = cpu_seconds(), time.perf_counter()
    if n:
        process = voice.process
        for _ in range(calls):
            process(n, out=buf)
    else:
        render = voice._render
        for _ in range(calls):
            render(buf)
    return (cpu_seconds() - c0) / calls, (time.perf_counter() - w0) / calls


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--models", nargs="+", default=list(model_names()), choices=model_names())
    parser.add_argument("--calls", type=int, default=2000, help="calls per batch")
    parser.add_argument("--repeats", type=int, default=15, help="batches per figure (median)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[0, 1, 256],
                        help="block sizes (0: voice._render of one sample, the model's part alone)")
    args = parser.parse_args()

    voices, buffers = {}, {}
    for name in args.models:
        voice = get_model(name).voice(sample_rate=48000.0, seed=0, max_block=max(args.sizes))
        voice.trigger()
        for n in args.sizes:  # compile or load the kernels, warm the caches
            buffers[name, n] = np.zeros(max(n, 1))
            batch(voice, n, buffers[name, n], 2000)
        voices[name] = voice
    results: dict[tuple[str, int], list[tuple[float, float]]] = {key: [] for key in buffers}
    for _ in range(args.repeats):
        for name, voice in voices.items():
            voice.trigger()  # every batch inside a fresh note
            for n in args.sizes:
                results[name, n].append(batch(voice, n, buffers[name, n], args.calls))

    print(f"voice.process(n, out=float64 buffer) at 48 kHz, per call: median of {args.repeats} batches "
          f"of {args.calls} calls (CPU time; wall in brackets)")
    header = "".join(f"{f'n={n}' if n else '_render(1 sample)':>22}" for n in args.sizes)
    print(f"  {'model':<10}{header}")
    for name in voices:
        cells = []
        for n in args.sizes:
            rows = results[name, n]
            cpu = statistics.median(r[0] for r in rows) * 1e6
            wall = statistics.median(r[1] for r in rows) * 1e6
            cells.append(f"{cpu:9.2f} us ({wall:7.2f})")
        print(f"  {name:<10}{''.join(f'{c:>22}' for c in cells)}")


if __name__ == "__main__":
    main()
