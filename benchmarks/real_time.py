"""How many times faster than real time a model renders: the measurement the benchmarks share."""

from __future__ import annotations

import time

import numpy as np

from barsynth.models import get_model


def real_time(model_name: str, parameters: dict, *, duration_s: float, sample_rate: float,
              repeat: int) -> tuple[float, float]:
    """Best and median x real time of whole ``render`` calls, after one short render that
    compiles or loads the kernels."""
    model = get_model(model_name)
    model.render(parameters, duration_s=0.05, sample_rate=sample_rate)
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        model.render(parameters, duration_s=duration_s, sample_rate=sample_rate)
        times.append(time.perf_counter() - start)
    return duration_s / min(times), duration_s / float(np.median(times))
