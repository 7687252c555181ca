"""The one smoothing primitive: linear and multiplicative ramps, in seconds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from barsynth.dsp.smoothing import SmoothedValue


def test_a_linear_ramp_reaches_its_target_in_the_ramp_and_holds():
    value = SmoothedValue(0.0, ramp_s=0.01, step_rate=48000, kind="linear")
    value.set_target(1.0)
    path = np.array([value.next_value() for _ in range(600)])
    assert value.steps == 480
    assert np.allclose(np.diff(path[:480]), 1 / 480)  # a straight line
    assert path[479] == 1.0 and np.all(path[480:] == 1.0)


def test_a_multiplicative_ramp_is_straight_on_a_log_scale():
    value = SmoothedValue(100.0, ramp_s=0.01, step_rate=1000, kind="multiplicative")
    value.set_target(1600.0)
    path = np.array([value.next_value() for _ in range(12)])
    assert np.allclose(np.diff(np.log2(path[:10])), 0.4)  # four octaves in ten steps
    assert path[9] == 1600.0 and path[-1] == 1600.0


def test_a_new_target_mid_ramp_starts_from_where_the_value_is():
    value = SmoothedValue(0.0, ramp_s=0.001, step_rate=10000, kind="linear")  # 10 steps
    value.set_target(1.0)
    for _ in range(5):
        value.next_value()
    assert value.current == pytest.approx(0.5)
    value.set_target(0.0)
    assert value.next_value() == pytest.approx(0.45)


def test_skip_equals_stepping():
    one, other = (SmoothedValue(2.0, ramp_s=0.05, step_rate=1000, kind=k) for k in ("multiplicative",) * 2)
    for v in (one, other):
        v.set_target(50.0)
    for _ in range(17):
        one.next_value()
    assert other.skip(17) == pytest.approx(one.current, rel=1e-12)
    assert other.skip(1000) == 50.0 and not other.is_smoothing


def test_unknown_kind_is_refused():
    with pytest.raises(ValueError, match="linear"):
        SmoothedValue(1.0, ramp_s=0.01, step_rate=100, kind="cubic")
    assert math.isclose(SmoothedValue(1.0, ramp_s=0.01, step_rate=100).target, 1.0)


def test_the_same_target_again_lets_the_ramp_carry_on():
    value = SmoothedValue(0.0, ramp_s=0.001, step_rate=10000, kind="linear")  # 10 steps
    value.set_target(1.0)
    for _ in range(5):
        value.next_value()
    value.set_target(1.0)
    assert [value.next_value() for _ in range(5)][-1] == 1.0
