"""Click measures shared by the tests (the voice contract, the cross-fades, the twang's own).

A click is a step or a burst of high frequencies that the sound itself does not have:

- :func:`step_ratio`: the largest sample-to-sample step from ``around_ms[0]`` before to
  ``around_ms[1]`` after the change, over the larger of the largest steps in the 20 ms before
  it and in the 20 ms after that window (a change without a click stays near 1; a cut or a
  jump of level gives several);
- :func:`highpass_spike`: the largest output of an 8th-order high-pass (12 kHz: above every
  mode of a test sound, so only a click reaches it) from 5 ms before to 30 ms after the change,
  relative to the signal's peak within 50 ms of it.

``tests/test_voice_contract.py::test_the_click_measures_catch_an_unsmoothed_change`` and
``tests/test_crossfade.py::test_a_bare_restart_clicks_and_the_cross_faded_one_does_not`` show
that both can fail.
"""

from __future__ import annotations

import numpy as np

MAX_STEP_RATIO = 1.5
MAX_HIGHPASS_SPIKE = 5e-3  # -46 dB re the signal's peak
CLICK_HIGHPASS_HZ = 12000.0


def largest_step(x: np.ndarray) -> float:
    return float(np.max(np.abs(np.diff(x)))) if x.size > 1 else 0.0


def step_ratio(x: np.ndarray, change: int, rate: int, *, around_ms: tuple[int, int] = (2, 15)) -> float:
    """The step ratio around a change at sample ``change`` (see the module's docstring)."""
    ms = rate // 1000
    lead, lag = around_ms
    before = largest_step(x[change - 20 * ms:change])
    across = largest_step(x[change - lead * ms:change + lag * ms])
    after = largest_step(x[change + lag * ms:change + (lag + 20) * ms])
    return across / max(before, after, 1e-300)


def highpass_spike(x: np.ndarray, change: int, rate: int) -> float:
    """The high-pass spike around a change at sample ``change`` (see the module's docstring)."""
    from scipy.signal import butter, sosfilt

    ms = rate // 1000
    high = sosfilt(butter(8, CLICK_HIGHPASS_HZ, "highpass", fs=rate, output="sos"), x)
    peak = np.max(np.abs(x[change - 50 * ms:change + 50 * ms]))
    return float(np.max(np.abs(high[change - 5 * ms:change + 30 * ms])) / peak)
