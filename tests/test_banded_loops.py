"""Banded-waveguide loops (spec 3.1): each rings where and as long as it was asked to.

Measured with barsynth's own partial analysis on the loop's impulse response, after
its first three periods (the loop's one-period latency and the start-up transient of
its other, fast-decaying poles).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from barsynth.analysis import measure_partial
from barsynth.dsp.smoothing import SmoothedValue
from barsynth.models.banded import kernel as K
from barsynth.models.banded.design import design_loop, loop_records


def bank(designs, input_weights=None, output_weights=None):
    """The kernel's loops for ``designs``, with per-loop input and output weights (1 by default)."""
    loops = loop_records(designs)
    if input_weights is not None:
        loops["force_in"] *= np.array(input_weights)
    if output_weights is not None:
        loops["out"] = output_weights
    return loops


UNIT_LEVEL = SmoothedValue(1.0, ramp_s=1.0, step_rate=1.0, kind="multiplicative").state
"""The output gain held at 1 (a dsp.smoothing state: the kernel leaves the loops' sum as it is)."""


def run(out, force, loops, state):
    K.process(out, np.zeros(0), force, 0.0, loops, state, UNIT_LEVEL, 0)


def impulse_response(design, seconds):
    loops = bank([design])
    out = np.empty(int(seconds * design.sample_rate))
    run(out, np.array([1.0]), loops, K.empty_state(1, design.delay))
    return out


CASES = [(rate, f, t60) for rate in (44100, 48000, 96000)
         for f in np.geomspace(30.0, rate / 4, 7) for t60 in (0.3, 1.0, 4.0)]


@pytest.mark.parametrize("rate,frequency,t60", CASES, ids=[f"{r}-{f:.0f}Hz-{t}s" for r, f, t in CASES])
def test_every_loop_rings_at_its_frequency_and_decays_in_its_t60(rate, frequency, t60):
    design = design_loop(frequency, t60, rate)
    x = impulse_response(design, min(1.5 * t60, 3.0))
    skip = 3 * math.ceil(rate / frequency)
    partial = measure_partial(x[skip:], rate, frequency)
    assert abs(1200 * math.log2(partial.frequency_hz / frequency)) < 1.0  # cents
    assert partial.t60_s == pytest.approx(t60, rel=0.05)
    # A unit impulse rings the mode with unit amplitude, whatever the pitch and rate.
    expected_db = 20 * math.log10(design.pole_radius ** skip)
    assert partial.level_db == pytest.approx(expected_db, abs=0.1)


def test_the_loops_are_tighter_than_the_promise():
    """The pole is placed exactly: 0.01 cent and 0.1 % where 1 cent and 5 % are promised."""
    worst_cents = worst_t60 = 0.0
    for rate, frequency, t60 in CASES[::4]:
        design = design_loop(frequency, t60, rate)
        x = impulse_response(design, min(1.5 * t60, 3.0))
        partial = measure_partial(x[3 * math.ceil(rate / frequency):], rate, frequency)
        worst_cents = max(worst_cents, abs(1200 * math.log2(partial.frequency_hz / frequency)))
        worst_t60 = max(worst_t60, abs(partial.t60_s / t60 - 1))
    assert worst_cents < 0.02 and worst_t60 < 0.001


def test_a_decay_from_q_down_to_three_is_still_exact():
    rate = 48000
    for frequency in (30.0, 1000.0):
        t60 = 3 * math.log(1000) / (math.pi * frequency)  # Q = 3
        design = design_loop(frequency, t60, rate)
        x = impulse_response(design, 0.5)
        partial = measure_partial(x[3 * math.ceil(rate / frequency):4000 + rate // 10], rate, frequency)
        assert abs(1200 * math.log2(partial.frequency_hz / frequency)) < 0.1
        assert partial.t60_s == pytest.approx(t60, rel=0.01)


@pytest.mark.parametrize("frequency,t60,rate", [(12001.0, 1.0, 48000), (0.0, 1.0, 48000), (440.0, 0.0, 48000),
                                                (440.0, -1.0, 48000)])
def test_loops_that_cannot_be_designed_are_refused(frequency, t60, rate):
    with pytest.raises(ValueError):
        design_loop(frequency, t60, rate)


def test_blocks_of_any_size_give_the_same_samples():
    rate = 44100
    designs = [design_loop(f, t, rate) for f, t in ((110.0, 2.0), (303.2, 1.0), (2000.0, 0.4), (9000.0, 0.2))]
    loops = bank(designs, input_weights=[1.0, -0.5, 0.8, 0.3], output_weights=[1.0, 0.7, -0.4, 0.2])
    rng = np.random.default_rng(3)
    force = np.zeros(20000)
    force[[0, 5000, 5001, 12000]] = 1.0, 0.5, -0.25, 2.0
    whole = np.empty(force.size)
    longest = int(loops["delay"].max())
    run(whole, force, loops, K.empty_state(4, longest))
    state = K.empty_state(4, longest)
    pieces, start = [], 0
    while start < force.size:
        n = int(rng.integers(1, 700))
        out = np.empty(min(n, force.size - start))
        run(out, force[start:start + out.size], loops, state)
        pieces.append(out)
        start += out.size
    assert np.array_equal(np.concatenate(pieces), whole)


@pytest.mark.parametrize("rate", [8000, 22050, 44100, 96000])
def test_the_broadest_and_highest_loops_are_stable(rate):
    """Q = 3 at a quarter of the sample rate: the band-pass widens to the mode."""
    for frequency in (rate / 4, 0.9 * rate / 4, 0.7 * rate / 4):
        t60 = 3 * math.log(1000) / (math.pi * frequency)
        design = design_loop(frequency, t60, rate)
        assert 0.0 < design.gain < 1.0
        x = impulse_response(design, 0.05)
        skip = 3 * math.ceil(rate / frequency)
        partial = measure_partial(x[skip:skip + max(int(1.5 * t60 * rate), 64)], rate, frequency)
        assert abs(1200 * math.log2(partial.frequency_hz / frequency)) < 1.0
        assert partial.t60_s == pytest.approx(t60, rel=0.05)


@settings(max_examples=40, deadline=None)
@given(st.floats(20.0, 11025.0), st.floats(0.05, 30.0), st.sampled_from([22050, 44100, 48000, 96000]))
def test_any_loop_in_range_is_stable_and_dies_away(frequency, t60, rate):
    frequency = min(frequency, rate / 4)
    t60 = max(t60, 3 * math.log(1000) / (math.pi * frequency))
    design = design_loop(frequency, t60, rate)
    assert 0.0 < design.gain < 1.0
    x = impulse_response(design, 0.3)
    assert np.all(np.isfinite(x))
    period = math.ceil(rate / frequency)
    late = np.max(np.abs(x[-4 * period:]))
    early = np.max(np.abs(x[3 * period:7 * period]))
    assert late <= early * design.pole_radius ** (x.size - 7 * period) * 1.5 + 1e-12
