"""The banded-waveguide model (spec 3.1): modes where physics puts them, strikes and
plucks whose mode levels follow the mode shapes and the mallet, and superposition."""

from __future__ import annotations

import math

import numpy as np
import pytest

from barsynth.analysis import measure_partial
from barsynth.dsp.mallet import hertz_stiffness, mallet_pulse
from barsynth.errors import ParameterError
from barsynth.models import get_model
from barsynth.exciters.strike import HARDEST_CONTACT_S, SOFTEST_CONTACT_S
from barsynth.physics import bar_frequencies, mode_shape
from barsynth.presets import preset_names, preset_parameters

MODEL = get_model("banded")


def raw(parameters, seconds, rate=48000):
    return MODEL.render(parameters, duration_s=seconds, sample_rate=rate, normalize=False, dtype=np.float64)


def test_physics_tuning_is_the_free_free_bar():
    p = {"youngs_modulus_pa": 200e9, "density_kg_m3": 7850.0, "length_m": 0.4, "thickness_m": 0.008,
         "mode_count": 5, "q": 500.0}
    modes = MODEL.describe(p, sample_rate=96000)
    expected = bar_frequencies(youngs_modulus_pa=200e9, density_kg_m3=7850.0, length_m=0.4, thickness_m=0.008,
                               bc="free-free", count=5)
    assert [m.frequency_hz for m in modes] == pytest.approx(expected, rel=1e-12)
    assert [m.t60_s for m in modes] == pytest.approx(500 * math.log(1000) / (math.pi * expected), rel=1e-12)


@pytest.mark.parametrize("rate", [44100, 48000, 96000])
@pytest.mark.parametrize("preset", preset_names("banded"))
def test_every_preset_rings_in_tune_with_its_t60s(preset, rate):
    parameters = preset_parameters("banded", preset)
    modes = MODEL.describe(parameters, sample_rate=rate)
    longest = max(m.t60_s for m in modes)
    x = raw(parameters, min(2.0, 1.2 * longest), rate)
    skip = int(0.03 * rate)  # past the mallet and the loops' start-up
    for mode in modes:
        if abs(mode.gain) < 0.05:  # a node of the strike or pick-up point: nothing to measure
            continue
        partial = measure_partial(x[skip:], rate, mode.frequency_hz)
        if partial.level_db < -100:
            continue
        assert abs(1200 * math.log2(partial.frequency_hz / mode.frequency_hz)) < 1.0, (mode, partial)
        assert partial.t60_s == pytest.approx(mode.t60_s, rel=0.05), (mode, partial)


def _mode_level(x, rate, frequency, t60, skip):
    """A mode's amplitude at t = 0, from its measured level at ``skip`` and its decay."""
    partial = measure_partial(x[skip:], rate, frequency)
    return 10 ** (partial.level_db / 20) * 10 ** (3 * skip / rate / t60)


def test_a_strike_rings_each_mode_as_the_mallet_pulse_and_the_mode_shapes_say():
    rate = 48000
    p = {"tuning": "ratios", "frequency_hz": 200.0, "mode_ratios": (1.0, 2.756, 5.404, 8.933),
         "mode_t60s_s": (2.0, 1.5, 1.0, 0.8), "mass_kg": 0.2, "strike_position": 0.13, "pickup_position": 0.31,
         "mallet_hardness": 0.6, "mallet_velocity_m_s": 1.5, "mallet_mass_kg": 0.02}
    x = raw(p, 1.5, rate)
    contact = SOFTEST_CONTACT_S * (HARDEST_CONTACT_S / SOFTEST_CONTACT_S) ** 0.6
    pulse = mallet_pulse(mass_kg=0.02, velocity_m_s=1.5, stiffness=hertz_stiffness(contact, 0.02), sample_rate=rate)
    n = np.arange(pulse.size)
    skip = int(0.05 * rate)
    for k, (ratio, t60) in enumerate(zip(p["mode_ratios"], p["mode_t60s_s"]), start=1):
        f = 200.0 * ratio
        spectrum = abs(np.sum(pulse / rate * np.exp(-2j * np.pi * f * n / rate)))  # N s at f
        expected = spectrum * abs(mode_shape("free-free", k, 0.13) * mode_shape("free-free", k, 0.31)) / 0.2
        assert _mode_level(x, rate, f, t60, skip) == pytest.approx(expected, rel=0.06), k


def test_a_node_of_the_strike_point_leaves_its_mode_silent():
    rate = 48000
    p = {"tuning": "ratios", "frequency_hz": 300.0, "mode_ratios": (1.0, 2.756, 5.404), "mode_t60s_s": (1.0,) * 3,
         "strike_position": 0.5, "pickup_position": 0.2}  # the middle: a node of the 2nd (antisymmetric) mode
    x = raw(p, 1.0, rate)
    skip = int(0.05 * rate)
    levels = [measure_partial(x[skip:], rate, 300.0 * r).level_db for r in (1.0, 2.756, 5.404)]
    assert levels[1] < min(levels[0], levels[2]) - 60


def test_a_harder_mallet_brings_out_the_high_modes():
    """Below the softest pulse's first spectral null (about 1.5 / contact time), a
    shorter contact gives the high mode more level against the fundamental."""
    rate = 48000
    base = {"tuning": "ratios", "frequency_hz": 300.0, "mode_ratios": (1.0, 4.0), "mode_t60s_s": (1.0, 1.0)}
    top_over_bottom = []
    for hardness in (0.6, 0.8, 1.0):  # contact 0.96, 0.44, 0.2 ms at 1 m/s
        x = raw({**base, "mallet_hardness": hardness}, 0.8, rate)
        skip = int(0.04 * rate)
        top_over_bottom.append(measure_partial(x[skip:], rate, 1200.0).level_db
                               - measure_partial(x[skip:], rate, 300.0).level_db)
    assert all(b > a + 0.5 for a, b in zip(top_over_bottom, top_over_bottom[1:])), top_over_bottom


def test_a_pluck_rings_each_mode_as_the_released_displacement_says():
    rate = 48000
    p = {"tuning": "ratios", "frequency_hz": 150.0, "mode_ratios": (1.0, 2.756, 5.404), "mode_t60s_s": (1.5,) * 3,
         "mass_kg": 0.5, "excitation": "pluck", "strike_position": 0.2, "pickup_position": 0.05,
         "pluck_displacement_mm": 2.0, "release_time_ms": 0.05}
    x = raw(p, 1.0, rate)
    omega = 2 * math.pi * 150.0 * np.array(p["mode_ratios"])
    shapes_s = np.array([mode_shape("free-free", k, 0.2) for k in (1, 2, 3)])
    shapes_p = np.array([mode_shape("free-free", k, 0.05) for k in (1, 2, 3)])
    force = 2e-3 / np.sum(shapes_s ** 2 / (0.5 * omega ** 2))  # what holds the point 2 mm out
    skip = int(0.05 * rate)
    for k in range(3):
        expected = force * abs(shapes_s[k] * shapes_p[k]) / (0.5 * omega[k])  # velocity amplitude, m/s
        assert _mode_level(x, rate, omega[k] / (2 * math.pi), 1.5, skip) == pytest.approx(expected, rel=0.03)


def test_modes_above_a_quarter_of_the_sample_rate_are_muted_not_folded():
    rate = 22050
    p = {"tuning": "ratios", "frequency_hz": 1000.0, "mode_ratios": (1.0, 4.0, 7.0, 14.0), "mode_t60s_s": (1.0,) * 4}
    assert [round(m.frequency_hz) for m in MODEL.describe(p, sample_rate=rate)] == [1000, 4000]
    x = raw(p, 1.0, rate)
    spectrum = np.abs(np.fft.rfft(x[2000:] * np.hanning(x.size - 2000)))
    freqs = np.fft.rfftfreq(x.size - 2000, 1 / rate)
    alias = rate - 14000.0  # where the 14 kHz mode would fold
    near = lambda f: spectrum[np.abs(freqs - f) < 30].max()  # noqa: E731
    assert 20 * np.log10(near(alias) / near(1000.0)) < -80
    assert 20 * np.log10(near(7000.0) / near(1000.0)) < -80


@pytest.mark.parametrize("change,needle", [
    ({"tuning": "ratios", "mode_ratios": ()}, "mode_ratios is empty"),
    ({"tuning": "ratios", "mode_ratios": (1.0, 2.0), "mode_t60s_s": (1.0, 1.0, 1.0)}, "3 values for 2 modes"),
    ({"tuning": "ratios", "frequency_hz": 1000.0, "mode_ratios": (1.0,), "mode_t60s_s": (0.006,)},
     "too short for a mode at 1000.0 Hz"),
    ({"tuning": "ratios", "frequency_hz": 4000.0, "mode_ratios": (4.0,)}, "no mode of this object"),
    ({"mode_ratios": "1,300"}, "value 2 = '300' is out of range"),
])
def test_objects_that_cannot_ring_are_refused_with_one_line(change, needle):
    with pytest.raises(ParameterError) as info:
        raw(change, 0.1, 22050)
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_a_change_of_the_set_of_modes_keeps_what_rings_ringing():
    """Fewer modes, then more (new loops, no new strike): the modes that stay keep their state,
    so the bar rings on at a similar level instead of falling silent."""
    p = {"tuning": "ratios", "frequency_hz": 300.0, "mode_ratios": (1.0, 2.7, 5.1), "mode_t60s_s": (2.0, 1.0, 0.5)}
    voice = MODEL.voice(p, sample_rate=48000)
    voice.trigger()
    before = voice.process(4800, dtype=np.float64)
    voice.set_parameters(frequency_hz=2400.0)  # the third mode (12.2 kHz) goes above a quarter of the rate
    after = voice.process(4800, dtype=np.float64)
    voice.set_parameters(frequency_hz=300.0)  # and comes back, silent
    again = voice.process(4800, dtype=np.float64)
    assert list(voice._bank.modes) == [0, 1, 2]
    level = np.abs(before[-480:]).max()
    assert 0.3 * level < np.abs(after[:480]).max() < 2 * level
    assert 0.1 * level < np.abs(again[:480]).max() < 2 * level


def test_a_note_that_has_died_away_leaves_its_loops_at_exactly_zero():
    """Loops whose every value is below kernel.TINY (-600 dB) are set to 0 at fixed sample
    indices (every FLUSH_PERIOD from the reset), so a silent voice never computes with
    subnormal numbers; blocks of any size still give the same samples (the contract suite),
    and what was heard is unchanged (the golden sounds)."""
    from barsynth.models.banded import kernel

    voice = MODEL.voice(preset_parameters("banded", "uniform-bar"), sample_rate=8000)
    voice.trigger()
    assert np.abs(voice.process(8000, dtype=np.float64)).max() > 0.01
    for _ in range(119):
        voice.process(8000)
    assert not voice.process(8000, dtype=np.float64).any()
    state = voice._state
    assert not state.buffers.any() and all(not state.filters[name].any() for name in kernel.FILTER.names)
