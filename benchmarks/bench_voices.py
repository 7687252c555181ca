"""How many voices of each model one core keeps in real time, in 256-sample blocks, and the
fixed cost of one ``voice.process`` call (run by hand).

    taskset -c 1 python benchmarks/bench_voices.py [--models banded twang] [--seconds 2]
    taskset -c 1 python benchmarks/bench_voices.py --only calls     # the fixed cost alone

Voices per core: for each model (its defaults) an :class:`~barsynth.playing.Instrument` of
``--voices`` voices (default 16) is given that many notes (a chromatic run from C4, each its own
voice) and rendered for ``--seconds`` in 256-sample blocks at 48 kHz, CPU time measured. One
voice's cost per block is that time / (blocks x voices); one core keeps ``5.33 ms / that``
voices in real time (the ceiling: a real player also needs time for its audio callback and
events).

Fixed cost per call: one voice (its defaults, triggered, its kernels compiled and warm) is
called ``process(n, out=buf)`` into a caller-owned buffer (float64, as the Instrument gives it,
and float32) for n in 1, 16, 64, 256, each in batches of about 20 ms (CPU time, the median of
``--repeats`` batches, each inside a fresh note); ``cost(n) = a + b n`` is fitted with relative
weights (a model's per-sample cost would otherwise drown its fixed part). ``a`` is the fixed
cost per call (the base class's checks, the voice's Python, the call into the kernel), ``b``
the cost per sample.

Targets (issue 17): >= 200 banded bars, >= 100 twangs; a fixed cost <= 1 us per call.

Measured on one core (``taskset -c 1``; a 2-core machine shared with other work, so a few
percent either way), main at eb8092c -> branch call-cost (the fast paths: Voice.process's one
cheap test of a plain buffer, banded's one kernel call where only its loops ring, the
Instrument's one-pass mix and peak):

    model     voices in real time   fixed us per call, f64   f32           ns/sample
    twang         558 ->  966           3.28 -> 2.76      4.48 -> 3.40       8
    farnell       113 ->  122           1.57 -> 1.17      2.74 -> 1.75     175
    banded        520 -> 1048           3.35 -> 1.35      4.55 -> 2.00       9
    allpass       104 ->  115           2.96 -> 2.05      4.12 -> 2.94      55
    fd (1 step)    28 ->   29           2.84 -> 2.20      4.06 -> 2.94     700
    ruler           5 ->    5           4.86 -> 4.09      5.83 -> 4.58    3300
    kalimba        10 ->   10           4.80 -> 3.97      5.95 -> 4.51    1900

What is left of the fixed cost is mostly numba unboxing the kernel's arguments (about 45 ns an
array, 15 ns a number: banded 9 arrays, 0.5 us; twang's five records 22 arrays and 22 numbers,
1.9 us), then Voice.process's test of the buffer (0.3 us) and the voice's own Python (0.1-0.3
us). Under 1 us would take a model's state packed in fewer arrays (the kernels' argument types
would change, and with them the compiled code: not done here, the sounds must stay the same).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from barsynth.models import get_model, model_names  # noqa: E402
from barsynth.playing.instrument import Instrument  # noqa: E402

RATE = 48000
BLOCK = 256
FAST = {"fd": {"oversampling": 1}}
SIZES = (1, 16, 64, 256)
BATCH_S = 0.02  # CPU time a batch of calls aims at


def cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def voices_per_core(model: str, voices: int, seconds: float) -> tuple[float, float]:
    """(ms of one core per voice per block, voices one core sustains)."""
    instrument = Instrument(model, voices=voices, parameters=FAST.get(model), sample_rate=RATE, max_block=BLOCK)
    for k in range(voices):
        instrument.note_on(48 + k, 100)
    instrument.process(BLOCK * 4)  # compiled, warmed
    blocks = int(seconds * RATE) // BLOCK
    began = cpu_seconds()
    for _ in range(blocks):
        instrument.process(BLOCK)
    per_voice_block = (cpu_seconds() - began) / (blocks * voices)
    return per_voice_block * 1e3, (BLOCK / RATE) / per_voice_block


def seconds_per_call(voice, n: int, buf: np.ndarray, calls: int) -> float:
    """CPU seconds per call of ``calls`` calls of ``voice.process(n, out=buf)``."""
    process = voice.process
    began = time.process_time()
    for _ in range(calls):
        process(n, out=buf)
    return (time.process_time() - began) / calls


def call_costs(model: str, dtype: type, repeats: int) -> dict[int, float]:
    """Median CPU seconds per ``process(n, out=buf)`` call, for each n of ``SIZES``."""
    voice = get_model(model).voice(FAST.get(model), sample_rate=RATE, max_block=BLOCK)
    voice.trigger()
    costs = {}
    for n in SIZES:
        buf = np.zeros(n, dtype=dtype)
        seconds_per_call(voice, n, buf, 200)  # compiled, warm
        calls = max(20, int(BATCH_S / max(seconds_per_call(voice, n, buf, 50), 1e-8)))
        batches = []
        for _ in range(repeats):
            voice.trigger()  # inside a fresh note (a voice that has died away may run faster)
            batches.append(seconds_per_call(voice, n, buf, calls))
        costs[n] = statistics.median(batches)
    return costs


def fixed_and_per_sample(costs: dict[int, float]) -> tuple[float, float]:
    """``(a, b)`` of ``cost(n) = a + b n`` (s, s per sample), least squares weighted by
    ``1 / cost(n)``: each point's relative error counts alike."""
    n = np.array(list(costs), dtype=float)
    t = np.array(list(costs.values()))
    weights = 1.0 / t
    (a, b), *_ = np.linalg.lstsq(np.column_stack([np.ones_like(n), n]) * weights[:, None], t * weights, rcond=None)
    return float(a), float(b)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="*", default=list(model_names()))
    parser.add_argument("--voices", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--repeats", type=int, default=5, help="batches per call cost (median)")
    parser.add_argument("--only", choices=("voices", "calls"), help="one of the two measurements")
    args = parser.parse_args()
    if args.only != "calls":
        print(f"{args.voices} voices each, {args.seconds:g} s in {BLOCK}-sample blocks at {RATE} Hz, one core")
        print(f"{'model':10s} {'ms/voice/block':>15s} {'voices in real time':>20s}")
        for model in args.models:
            ms, count = voices_per_core(model, args.voices, args.seconds)
            print(f"{model:10s} {ms:15.4f} {count:20.0f}", flush=True)
    if args.only != "voices":
        print(f"voice.process(n, out=buf): cost(n) = a + b n fitted over n = {SIZES}, CPU time, one voice")
        print(f"{'model':10s} {'a f64 (us)':>11s} {'a f32 (us)':>11s} {'b (ns/sample)':>14s} {'n=1 f64 (us)':>13s}")
        for model in args.models:
            f64 = call_costs(model, np.float64, args.repeats)
            f32 = call_costs(model, np.float32, args.repeats)
            a64, b64 = fixed_and_per_sample(f64)
            a32, _ = fixed_and_per_sample(f32)
            print(f"{model:10s} {a64 * 1e6:11.2f} {a32 * 1e6:11.2f} {b64 * 1e9:14.1f} {f64[1] * 1e6:13.2f}",
                  flush=True)


if __name__ == "__main__":
    main()
