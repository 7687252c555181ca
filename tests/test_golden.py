"""Golden sounds: every preset of every model (and a few non-default settings) must keep
the samples recorded in golden_sounds.json (see tests/golden.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from golden import (GOLDEN_FILE, cpu_features, digest, duration_of, fingerprint, float64_family, render_case,
                    signed_fingerprint, sound_cases)

GOLDEN = json.loads(GOLDEN_FILE.read_text())
SAME_CPU = float64_family(GOLDEN["cpu_features"]) == float64_family(cpu_features())
CASES = sound_cases()


def test_every_case_has_a_golden_sound():
    assert sorted(name for name, *_ in CASES) == sorted(GOLDEN["sounds"])


@pytest.mark.parametrize("name, model, params, rate, change", CASES, ids=[c[0] for c in CASES])
def test_golden_sound(name, model, params, rate, change):
    samples = render_case(model, params, rate, change, duration_of(name))
    golden = GOLDEN["sounds"][name]
    assert np.isfinite(samples).all() and np.abs(samples).max() > 0
    if SAME_CPU:
        assert digest(samples) == golden["sha256"], f"{name}: the samples changed"
    else:  # another CPU family: NumPy's vector maths may differ in the last bit
        np.testing.assert_allclose(fingerprint(samples, rate), golden["rms"], rtol=1e-9, atol=1e-300)
        np.testing.assert_allclose(signed_fingerprint(samples, rate), golden["ramp"], rtol=1e-9,
                                   atol=1e-9 * np.abs(golden["ramp"]).max())


def test_a_newer_cpu_of_the_same_family_compares_exactly():
    """Features that touch no float64 arithmetic (a Sapphire Rapids' AVX512FP16) do not turn the
    exact comparison into the fingerprint's."""
    skx = "AVX,AVX2,AVX512F,AVX512_SKX,FMA3,SSE42"
    assert float64_family(skx + ",AVX512FP16,AVX512_SPR") == float64_family(skx)
    assert float64_family(skx) != float64_family("AVX,AVX2,FMA3,SSE42")


def test_the_signed_fingerprint_sees_a_flipped_sign():
    name, model, params, rate, change = CASES[0]
    samples = render_case(model, params, rate, change)
    assert fingerprint(-samples, rate) == fingerprint(samples, rate)
    assert not np.allclose(signed_fingerprint(-samples, rate), GOLDEN["sounds"][name]["ramp"], rtol=1e-9)


def test_a_changed_sample_changes_the_hash():
    name, model, params, rate, change = CASES[0]
    samples = render_case(model, params, rate, change)
    samples[samples.size // 2] = np.nextafter(samples[samples.size // 2], np.inf)
    assert digest(samples) != GOLDEN["sounds"][name]["sha256"]
