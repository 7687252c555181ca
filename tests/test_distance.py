"""barsynth's spectral distance (spec 7.3) between a recording and a resynthesis."""

from __future__ import annotations

import numpy as np
import pytest

from barsynth.analysis.distance import onset_at, sine_baseline, spectral_distance
from barsynth.errors import ParameterError

RATE = 44100


def note(freqs, levels_db, t60s, rate=RATE, seconds=1.5, delay_s=0.0):
    t = np.arange(int(seconds * rate)) / rate
    x = sum(10 ** (l / 20) * np.cos(2 * np.pi * f * t) * np.exp(-t * np.log(1000) / t60)
            for f, l, t60 in zip(freqs, levels_db, t60s))
    return np.concatenate([np.zeros(int(delay_s * rate)), x])


def test_a_sound_against_itself_is_zero_and_the_distance_is_symmetric_in_level():
    x = note([440, 1760, 4400], [0, -10, -20], [2, 1, 0.5])
    assert spectral_distance(x, x, RATE) == 0.0
    assert spectral_distance(x, 0.01 * x, RATE) == pytest.approx(0.0, abs=1e-9)  # scaled to the same power


def test_onsets_are_cut_so_a_delay_changes_nothing():
    x = note([440, 1760], [0, -10], [2, 1])
    late = note([440, 1760], [0, -10], [2, 1], delay_s=0.25)
    assert onset_at(late, RATE) == int(0.25 * RATE) - int(round(0.003 * RATE))
    assert spectral_distance(x, late, RATE) < 0.5


def test_the_distance_grows_with_what_is_wrong():
    x = note([440, 1760, 4400], [0, -10, -20], [2, 1, 0.5])
    near = note([440, 1760, 4400], [0, -11, -21], [2, 1.1, 0.5])
    missing = note([440, 1760], [0, -10], [2, 1])
    detuned = note([466, 1865, 4662], [0, -10, -20], [2, 1, 0.5])
    d_near, d_missing, d_detuned = (spectral_distance(x, y, RATE) for y in (near, missing, detuned))
    assert d_near < d_missing < d_detuned


def test_the_sine_baseline_is_one_decaying_sine():
    y = sine_baseline(440.0, 1.0, RATE, RATE)
    assert y.size == RATE and abs(y).max() <= 1.0
    late = np.abs(y[-200:]).max()
    assert 20 * np.log10(late) == pytest.approx(-60.0, abs=0.5)
    x = note([440, 1760, 4400], [0, -6, -12], [1, 1, 1])
    assert spectral_distance(x, y, RATE) > spectral_distance(x, x[:RATE] + 1e-3 * y, RATE)


@pytest.mark.parametrize("rate", [8000, 22050, 48000, 96000, 192000])
def test_every_rate_scales_the_window(rate):
    x = note([300, 1200], [0, -10], [1, 0.5], rate=rate)
    y = note([300, 1250], [0, -10], [1, 0.5], rate=rate)
    d = spectral_distance(x, y, rate)
    assert 0.0 < d < 20.0


def test_silence_is_refused_in_one_line():
    with pytest.raises(ParameterError, match="silent") as info:
        spectral_distance(np.zeros(RATE), note([440], [0], [1]), RATE)
    assert "\n" not in str(info.value)
