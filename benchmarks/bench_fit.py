"""Benchmark of ``fit_recording`` (run by hand, never as a timed test): issue 14's target is a
2 s recording fitted in at most 2 s on one core.

    taskset -c 0 python benchmarks/bench_fit.py [--repeat N]

Prints, for each case, the warm wall-clock time (best and median of N runs) and CPU time of
:func:`barsynth.fitting.fit_recording` (analysis, fit, render of the fit, comparison and
spectral distance: everything ``barsynth fit`` does but reading and writing files). The cases,
all 2 s at 44.1 kHz: barsynth's marimba preset rendered with noise at -40 dB and a short room
(scripts/fit_quality.py's synthetic recording) fitted with the banded model; MuseScore's
marimba samples at root keys 48 (2.16 s, cut to 2 s) and 60 (1.72 s), when the soundfont is
installed, fitted with
the banded, twang and fd models; the synthetic note with the twang and fd models.

OpenBLAS is held to one thread before NumPy loads, as the ``barsynth`` program does.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from barsynth.fitting import fit_recording  # noqa: E402

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "fit_quality.py"
SECONDS = 2.0
TARGET_S = 2.0


def quality_script():
    spec = importlib.util.spec_from_file_location("fit_quality", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["fit_quality"] = module
    spec.loader.exec_module(module)
    return module


def cases() -> list[tuple[str, str, np.ndarray, float, float | None]]:
    """(name, model, samples, sample rate, nominal Hz)."""
    fq = quality_script()
    synthetic, _ = fq.synthetic("marimba", None)
    out = [("synthetic marimba preset (noise, room)", model, synthetic[: int(SECONDS * fq.SYNTH_RATE)],
            float(fq.SYNTH_RATE), None) for model in ("banded", "twang", "fd")]
    from barsynth.models import get_model

    # the recordings each model is for: a ruler for the twang, a bar for fd (-40 dB noise, seeded)
    for model, settings in (("twang", {}), ("fd", {"material": "aluminium"})):
        x = get_model(model).render(settings, duration_s=SECONDS, sample_rate=fq.SYNTH_RATE, seed=1,
                                    dtype=np.float64)
        x = x + 0.01 * np.max(np.abs(x)) * np.random.default_rng(2).standard_normal(x.size)
        out.append((f"barsynth's {model} default (noise -40 dB)", model, x, float(fq.SYNTH_RATE), None))
    path = fq.FONTS["MuseScore"]
    if path.exists():
        for note in fq.notes({"MuseScore": path}, fq.KEYS, ("marimba",)):
            if note.key in (48, 60):
                x = note.samples[: int(SECONDS * note.sample_rate)]
                out += [(f"MuseScore marimba, key {note.key}", model, x, note.sample_rate, note.nominal_hz)
                        for model in ("banded", "twang", "fd")]
    return out


def measure(model: str, x: np.ndarray, rate: float, nominal_hz: float | None, repeat: int) -> tuple[float, float, float]:
    """(best, median wall s, median CPU s) of ``repeat`` warm runs (one run first, not counted)."""
    fit_recording(x, rate, model=model, nominal_hz=nominal_hz)
    walls, cpus = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        fit_recording(x, rate, model=model, nominal_hz=nominal_hz)
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return min(walls), statistics.median(walls), statistics.median(cpus)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"fit_recording, warm, {args.repeat} runs, {cores} core(s) allowed; target <= {TARGET_S:g} s")
    print("| recording | length (s) | model | best (s) | median (s) | CPU (s) | within target |")
    print("|---|---|---|---|---|---|---|")
    for name, model, x, rate, nominal in cases():
        best, median, cpu = measure(model, x, rate, nominal, args.repeat)
        print(f"| {name} | {x.size / rate:.2f} | {model} | {best:.3f} | {median:.3f} | {cpu:.3f} | {'yes' if median <= TARGET_S else 'no'} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
