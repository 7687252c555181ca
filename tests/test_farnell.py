"""Farnell's twang and the anchor (spec 5), measured: glide, band centres, envelopes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import strategies as st

from barsynth import ParameterError
from barsynth.models import get_model
from barsynth.models.farnell import design
from barsynth.models.farnell import FARNELL_TABLE, FarnellVoice

MODEL = get_model("farnell")
RATE = 48000.0


def traced(params, seconds, *, seed=0, rate=RATE):
    voice = FarnellVoice(params, sample_rate=rate, seed=seed)
    voice.trigger()
    return voice.trace(int(seconds * rate))


def test_drive_phasor_glides_18_hz_down_to_f_over_4():
    """Measured from the drive signal itself: the time between its wraps."""
    f, depth = 400.0, 1.0
    _, lanes = traced({"frequency_hz": f, "vibrato_depth_hz": depth}, 1.0)
    p = lanes["drive"]
    assert p.min() >= 0.0 and p.max() < 1.0
    wraps = np.flatnonzero(np.diff(p) > 0.5) + 1  # a falling ramp jumps up at each wrap
    times = wraps / RATE
    measured = 1.0 / np.diff(times)
    mid = 0.5 * (times[1:] + times[:-1])
    # expected: f/4 plus the vibrato's quarter, plus 6 E(t) with E = 3 (1 - t/7)^64
    expected = (f + depth * np.sin(2 * np.pi * 5.0 * mid)) / 4 + 18.0 * (1 - mid / 7.0) ** 64
    assert measured == pytest.approx(expected, rel=0.01)
    first = measured[0]
    assert first == pytest.approx(f / 4 + 18.0, abs=1.5)
    late = measured[mid > 0.6]
    assert np.mean(late) == pytest.approx(f / 4, abs=0.3)
    # the glide term falls to 1/e in about 110 ms (the spec's "fast glide")
    glide = 18.0 * (1 - np.array([0.0, 0.11]) / 7.0) ** 64
    assert glide[1] / glide[0] == pytest.approx(math.exp(-1), rel=0.02)


def test_clamped_envelope_falls_as_c4_and_ends_at_1_5_s():
    _, lanes = traced({"vibrato_depth_hz": 1.0}, 2.0)
    clamped = np.abs(lanes["clamped"])
    window = int(0.05 * RATE)
    assert clamped[int(1.5 * RATE) + 1:].max() == 0.0
    assert clamped[int(1.40 * RATE):int(1.45 * RATE)].max() > 0.0
    full = sum(design.CLAMPED_GAINS)  # the bank's peak, reached each time the drive passes 0
    for t in (0.1, 0.5, 0.9, 1.2):
        start = int(t * RATE)
        peak = clamped[start:start + window].max()
        expected = full * (1 - (t + 0.05) / 1.5) ** 4  # the window's smallest envelope
        upper = full * (1 - t / 1.5) ** 4
        assert expected * 0.97 <= peak <= upper * 1.001


def test_free_bands_sit_at_the_free_bar_ratios_after_the_glide():
    f = 300.0
    spectra = []
    for seed in range(4):
        _, lanes = traced({"frequency_hz": f, "vibrato_depth_hz": 1.0}, 1.5, seed=seed)
        seg = lanes["free"][int(0.9 * RATE):]
        spectra.append(np.abs(np.fft.rfft(seg * np.hanning(seg.size), 1 << 17)) ** 2)
    power = np.mean(spectra, axis=0)
    freqs = np.fft.rfftfreq(1 << 17, 1 / RATE)
    for ratio in design.FREE_RATIOS:
        centre = f * ratio
        band = (freqs > centre * (1 - 1.5 / design.BAND_Q)) & (freqs < centre * (1 + 1.5 / design.BAND_Q))
        found = np.exp(np.sum(power[band] * np.log(freqs[band])) / np.sum(power[band]))
        assert abs(1200 * math.log2(found / centre)) < 5.0, (ratio, found)


def test_free_bands_start_30_percent_sharp():
    f = 300.0
    _, lanes = traced({"frequency_hz": f, "vibrato_depth_hz": 1.0}, 0.03)
    seg = lanes["free"]
    spectrum = np.abs(np.fft.rfft(seg * np.hanning(seg.size), 1 << 16))
    freqs = np.fft.rfftfreq(1 << 16, 1 / RATE)
    top = f * design.FREE_RATIOS[-1]
    window = (freqs > top * 1.1) & (freqs < top * 1.45)
    peak = freqs[window][np.argmax(spectrum[window])]
    assert peak > top * 1.2  # still near 1.3 x within the first 30 ms


def test_anchor_drives_with_a_cosine_no_wraps():
    _, plain = traced({"anchor": False}, 0.5)
    _, anchor = traced({"anchor": True}, 0.5)
    assert np.max(np.abs(np.diff(plain["drive"]))) > 0.9  # the phasor's wraps
    assert np.max(np.abs(np.diff(anchor["drive"]))) < 0.05  # a cosine has none
    assert anchor["drive"].min() < -0.99 and anchor["drive"].max() > 0.99
    a = MODEL.render({"anchor": True}, duration_s=0.5)
    b = MODEL.render({"anchor": False}, duration_s=0.5)
    assert not np.allclose(a, b)


def test_describe_lists_the_patch_modes():
    modes = MODEL.describe({"frequency_hz": 426.0})
    clamped = [m.frequency_hz for m in modes if m.group == "clamped"]
    free = [m.frequency_hz for m in modes if m.group == "free-bar"]
    assert clamped == pytest.approx([106.5 * r for r in design.CLAMPED_RATIOS])
    assert free == pytest.approx([426.0 * r for r in design.FREE_RATIOS])
    low_rate = MODEL.describe({"frequency_hz": 800.0}, sample_rate=22050)
    assert all(m.frequency_hz < 11025 for m in low_rate) and len(low_rate) < len(modes)


def test_a_band_above_nyquist_is_muted_not_folded():
    """f = 700 Hz at 22.05 kHz: band 6 (13 kHz) is above Nyquist; folded, it would land
    at 9.0 kHz, 338 Hz below band 5. Compare the free-bar spectrum there with the point
    mirrored across band 5: a fold would stand far above its mirror."""
    rate, f = 22050.0, 700.0
    top = f * design.FREE_RATIOS[-1]
    assert top > rate / 2
    assert all(m.frequency_hz < rate / 2 for m in MODEL.describe({"frequency_hz": f}, sample_rate=rate))
    spectra = []
    for seed in range(4):
        _, lanes = traced({"frequency_hz": f, "vibrato_depth_hz": 1.0}, 1.5, seed=seed, rate=rate)
        seg = lanes["free"][int(0.9 * rate):]
        spectra.append(np.abs(np.fft.rfft(seg * np.hanning(seg.size), 1 << 16)) ** 2)
    power = np.mean(spectra, axis=0)
    freqs = np.fft.rfftfreq(1 << 16, 1 / rate)
    alias = rate - top
    band5 = f * design.FREE_RATIOS[-2]
    mirror = 2 * band5 - alias

    def near(x):
        return power[(freqs > x - 20) & (freqs < x + 20)].mean()

    assert near(alias) < 3.0 * near(mirror)


def test_frequency_change_while_sounding_glides_without_a_click():
    voice = FarnellVoice({"vibrato_depth_hz": 1.0})
    voice.trigger()
    voice.process(int(0.3 * RATE), dtype=np.float64)
    voice.set_parameters(frequency_hz=600.0)
    after, lanes = voice.trace(int(0.05 * RATE))
    steps = -np.diff(np.concatenate([[0.0], lanes["drive"]]))
    steps = steps[(steps > 0) & (steps < 0.5)] * RATE  # drive frequency per sample
    assert np.all(np.diff(steps) < 1.0)  # it rises over a few ms (0.2 Hz a sample), never jumps 43 Hz
    assert np.all(np.isfinite(after))
    assert steps[-1] == pytest.approx(150.0, abs=2.0)


def _strategy(p):
    if p.kind == "bool":
        return st.booleans()
    return st.floats(min_value=p.minimum, max_value=p.maximum, allow_nan=False)


@pytest.mark.parametrize("p", [p for p in FARNELL_TABLE if p.kind == "float"], ids=lambda p: p.name)
def test_every_parameter_rejected_just_outside_its_range(p):
    span = p.maximum - p.minimum
    for bad in (p.minimum - 1e-6 * span, p.maximum + 1e-6 * span, float("nan")):
        with pytest.raises(ParameterError, match=p.name):
            MODEL.render({p.name: bad}, duration_s=0.01)


def test_trace_gives_the_samples_process_gives():
    a, b = FarnellVoice(seed=3), FarnellVoice(seed=3)
    a.trigger()
    b.trigger()
    samples, lanes = a.trace(1000)
    assert np.array_equal(samples, b.process(1000, dtype=np.float64))
    assert sorted(lanes) == ["clamped", "drive", "free"] and all(v.shape == (1000,) for v in lanes.values())
    more, _ = a.trace(500)
    assert np.array_equal(more, b.process(500, dtype=np.float64))


def test_the_golden_glide_does_not_click():
    """The golden 'glide' (frequency 426 -> 500 Hz and level -6 dB 0.1 s into the note):
    the output's largest sample-to-sample step near the change is no larger than the
    note's own steps just before it."""
    from golden import CHANGE_AT_S, GLIDES, render_case

    rate = 48000
    x = render_case("farnell", {}, rate, GLIDES["farnell"])
    change = int(CHANGE_AT_S * rate)
    ms = rate // 1000
    steps = np.abs(np.diff(x))
    assert steps[change - 2 * ms:change + 10 * ms].max() <= 1.05 * steps[change - 20 * ms:change].max()


def test_a_note_that_has_died_away_leaves_its_filters_at_exactly_zero():
    """Filter states below kernel.TINY (-600 dB) are set to 0, so a silent voice never computes
    with subnormal numbers (about 6 times slower); what was heard is not changed by it (the
    golden sounds)."""
    from barsynth.models.farnell import kernel

    voice = FarnellVoice(sample_rate=48000)
    voice.trigger()
    first = voice.process(48000, dtype=np.float64)
    assert np.abs(first).max() > 0.1
    for _ in range(4):
        voice.process(48000)
    tail = voice.process(48000, dtype=np.float64)
    scalars, bands = voice._patch.scalars, voice._patch.bands
    assert not tail.any()
    assert scalars[kernel.S.lowpass] == 0.0 and scalars[kernel.S.hp_last] == 0.0 and not bands.any()
