"""The instrument's mix: add_and_peak gives exactly NumPy's sum and peak (the Instrument's samples
and its choice of a quiet voice do not depend on it)."""

import math

import numpy as np
import pytest

from barsynth.playing.mixing import add_and_peak


@pytest.mark.parametrize("n", [1, 7, 256])
def test_the_sum_and_the_peak_are_numpys(n):
    rng = np.random.default_rng(n)
    block, out = rng.standard_normal(n) * 1e-3, rng.standard_normal(n)
    expected = out + block
    peak = add_and_peak(out, block)
    assert np.array_equal(out, expected)
    assert peak == float(np.max(np.abs(block)))


def test_a_negative_peak_counts_by_its_size():
    assert add_and_peak(np.zeros(3), np.array([0.5, -2.0, 1.0])) == 2.0


def test_a_nan_gives_a_nan_peak_as_numpy_does():
    block = np.array([1.0, math.nan, 3.0])
    assert math.isnan(add_and_peak(np.zeros(3), block)) and math.isnan(np.max(np.abs(block)))
