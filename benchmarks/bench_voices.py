"""How many voices of each model one core keeps in real time, in 256-sample blocks (run by hand).

    taskset -c 1 python benchmarks/bench_voices.py [--models banded twang] [--seconds 2]

For each model (its defaults) an :class:`~barsynth.playing.Instrument` of ``--voices`` voices
(default 16) is given that many notes (a chromatic run from C4, each its own voice) and rendered
for ``--seconds`` in 256-sample blocks at 48 kHz, CPU time measured. One voice's cost per block
is that time / (blocks x voices); one core keeps ``5.33 ms / that`` voices in real time (the
ceiling: a real player also needs time for its audio callback and events).

Targets (issue 17): >= 200 banded bars, >= 100 twangs.
"""

from __future__ import annotations

import argparse
import os
import resource

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from barsynth.models import model_names  # noqa: E402
from barsynth.playing.instrument import Instrument  # noqa: E402

RATE = 48000
BLOCK = 256
FAST = {"fd": {"oversampling": 1}}


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="*", default=list(model_names()))
    parser.add_argument("--voices", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    print(f"{args.voices} voices each, {args.seconds:g} s in {BLOCK}-sample blocks at {RATE} Hz, one core")
    print(f"{'model':10s} {'ms/voice/block':>15s} {'voices in real time':>20s}")
    for model in args.models:
        ms, count = voices_per_core(model, args.voices, args.seconds)
        print(f"{model:10s} {ms:15.4f} {count:20.0f}")


if __name__ == "__main__":
    main()
