"""The measuring layer measures: partials, decays, files and pictures of sounds.

Every signal is built here with NumPy from its true parameters, so each check
compares a measurement with the truth.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from barsynth.analysis import (
    Partial,
    band_decay_t60,
    find_partials,
    load_audio,
    measure_partial,
    partial_ratios,
    plot_sound,
    spectrogram,
)
from barsynth.errors import AudioFileError, BarsynthError, ParameterError

LN1000 = math.log(1000.0)
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def decaying_cosines(modes, sample_rate, duration_s):
    """Sum of A exp(-t ln(1000) / T60) cos(2 pi f t + phase) for (f, A, T60, phase)."""
    t = np.arange(int(round(duration_s * sample_rate))) / sample_rate
    x = np.zeros_like(t)
    for frequency_hz, amplitude, t60_s, phase in modes:
        envelope = np.exp(-t * LN1000 / t60_s) if math.isfinite(t60_s) else 1.0
        x += amplitude * envelope * np.cos(2.0 * math.pi * frequency_hz * t + phase)
    return x


def cents(measured, true):
    return abs(1200.0 * math.log2(measured / true))


def level_db(amplitude):
    return 20.0 * math.log10(amplitude)


def nearest(partials, frequency_hz):
    return min(partials, key=lambda p: abs(math.log(p.frequency_hz / frequency_hz)))


# A bar-like sound: eight modes from 8.9 Hz to 15 kHz, T60 from 25 s down to
# 0.05 s, levels spanning 60 dB, and a pair only 5 % apart (1000 / 1050 Hz).
BAR_MODES = [
    # frequency_hz, amplitude, t60_s, phase
    (8.9, 0.30, 25.0, 0.3),
    (61.7, 0.20, 9.0, 1.1),
    (173.0, 0.25, 4.0, 2.0),
    (1000.0, 0.10, 1.2, 0.7),
    (1050.0, 0.02, 2.0, 2.9),
    (2890.0, 0.003, 0.6, 4.0),
    (7400.0, 0.0003, 0.25, 5.1),
    (15000.0, 0.05, 0.05, 0.2),
]


@pytest.fixture(scope="module", params=[44100, 48000, 96000])
def bar(request):
    sample_rate = request.param
    x = decaying_cosines(BAR_MODES, sample_rate, 2.0)
    return x, sample_rate, find_partials(x, sample_rate)


# ----------------------------------------------------------------------------------
# find_partials
# ----------------------------------------------------------------------------------
def test_find_partials_finds_every_mode_and_nothing_else(bar):
    x, sample_rate, partials = bar
    assert len(partials) == len(BAR_MODES)
    freqs = [p.frequency_hz for p in partials]
    assert freqs == sorted(freqs)
    for frequency_hz, _, _, _ in BAR_MODES:
        assert cents(nearest(partials, frequency_hz).frequency_hz, frequency_hz) < 1.0


def test_find_partials_measures_t60_and_level(bar):
    _, _, partials = bar
    for frequency_hz, amplitude, t60_s, _ in BAR_MODES:
        p = nearest(partials, frequency_hz)
        assert p.t60_s == pytest.approx(t60_s, rel=0.03), frequency_hz
        assert p.level_db == pytest.approx(level_db(amplitude), abs=0.5), frequency_hz


def test_two_partials_five_percent_apart_are_both_found():
    sample_rate = 48000
    modes = [(440.0, 0.4, 1.5, 0.0), (462.0, 0.1, 0.9, 1.0)]
    partials = find_partials(decaying_cosines(modes, sample_rate, 1.5), sample_rate)
    assert len(partials) == 2
    for (frequency_hz, amplitude, t60_s, _), p in zip(modes, partials):
        assert cents(p.frequency_hz, frequency_hz) < 1.0
        assert p.t60_s == pytest.approx(t60_s, rel=0.03)
        assert p.level_db == pytest.approx(level_db(amplitude), abs=0.5)


def test_a_fast_partial_next_to_a_slow_one():
    # 5 % apart, one dying in 50 ms, 30 dB apart in level
    sample_rate = 44100
    modes = [(2000.0, 0.5, 0.05, 0.0), (2100.0, 0.016, 3.0, 2.0)]
    partials = find_partials(decaying_cosines(modes, sample_rate, 1.0), sample_rate)
    assert len(partials) == 2
    for (frequency_hz, amplitude, t60_s, _), p in zip(modes, partials):
        assert cents(p.frequency_hz, frequency_hz) < 1.0
        assert p.t60_s == pytest.approx(t60_s, rel=0.03)
        assert p.level_db == pytest.approx(level_db(amplitude), abs=0.5)


def test_low_partial_decaying_far_slower_than_the_sound_lasts():
    # 8.9 Hz, T60 25 s, in 2 s: the sound decays by less than 5 dB
    sample_rate = 48000
    x = decaying_cosines([(8.9, 0.5, 25.0, 0.4)], sample_rate, 2.0)
    (p,) = find_partials(x, sample_rate)
    assert cents(p.frequency_hz, 8.9) < 1.0
    assert p.t60_s == pytest.approx(25.0, rel=0.05)
    q = measure_partial(x, sample_rate, 8.9)
    assert cents(q.frequency_hz, 8.9) < 0.2
    assert q.t60_s == pytest.approx(25.0, rel=0.05)


def test_a_steady_sine_does_not_decay():
    sample_rate = 48000
    t = np.arange(2 * sample_rate) / sample_rate
    x = 0.5 * np.sin(2.0 * math.pi * 1000.0 * t)
    (p,) = find_partials(x, sample_rate)
    assert cents(p.frequency_hz, 1000.0) < 0.2
    assert p.t60_s == math.inf or p.t60_s > 100.0
    assert p.level_db == pytest.approx(level_db(0.5), abs=0.1)
    decay = band_decay_t60(x, sample_rate, 1000.0, 50.0)
    assert decay == math.inf or decay > 100.0


def test_float32_input_from_a_file_measures_as_well():
    sample_rate = 48000
    modes = [(220.0, 0.5, 2.0, 0.1), (611.0, 0.2, 0.7, 1.3)]
    x = decaying_cosines(modes, sample_rate, 2.0).astype(np.float32)
    partials = find_partials(x, sample_rate)
    assert len(partials) == 2
    for (frequency_hz, amplitude, t60_s, _), p in zip(modes, partials):
        assert cents(p.frequency_hz, frequency_hz) < 0.2
        assert p.t60_s == pytest.approx(t60_s, rel=0.01)
        assert p.level_db == pytest.approx(level_db(amplitude), abs=0.05)


def test_partials_in_background_noise():
    sample_rate = 48000
    modes = [(440.0, 0.5, 1.5, 0.3), (1210.0, 0.2, 0.8, 1.0), (2400.0, 0.05, 0.4, 2.0)]
    rng = np.random.default_rng(7)
    x = decaying_cosines(modes, sample_rate, 2.0) + 1e-4 * rng.standard_normal(2 * sample_rate)
    partials = find_partials(x, sample_rate)
    assert len(partials) == 3
    for (frequency_hz, amplitude, t60_s, _), p in zip(modes, partials):
        assert cents(p.frequency_hz, frequency_hz) < 1.0
        assert p.t60_s == pytest.approx(t60_s, rel=0.05)
        assert p.level_db == pytest.approx(level_db(amplitude), abs=0.5)


def test_a_recording_with_silence_noise_and_dc_before_the_strike():
    sample_rate = 48000
    modes = [(220.0, 0.5, 1.5, 0.3), (611.0, 0.2, 0.4, 1.0), (3000.0, 0.1, 0.08, 2.0)]
    strike = decaying_cosines(modes, sample_rate, 2.0)
    x = np.concatenate([np.zeros(int(0.2 * sample_rate)), strike])
    rng = np.random.default_rng(11)
    x = x + 1e-5 * rng.standard_normal(x.size) + 0.002
    partials = find_partials(x, sample_rate)
    assert len(partials) == 3
    for (frequency_hz, amplitude, t60_s, _), p in zip(modes, partials):
        assert cents(p.frequency_hz, frequency_hz) < 1.0
        assert p.t60_s == pytest.approx(t60_s, rel=0.03)
        assert p.level_db == pytest.approx(level_db(amplitude), abs=0.5)  # at the strike


def test_options_limit_what_is_reported(bar):
    x, sample_rate, _ = bar
    strongest = find_partials(x, sample_rate, max_partials=3)
    # the three loudest, sorted by frequency
    assert [round(p.frequency_hz) for p in strongest] == [9, 62, 173]
    loud = find_partials(x, sample_rate, min_level_db=-30.0)
    assert all(p.level_db >= level_db(0.30) - 30.0 for p in loud)
    assert len(loud) == 6
    high = find_partials(x, sample_rate, min_frequency_hz=100.0)
    assert min(p.frequency_hz for p in high) > 100.0
    merged = find_partials(x, sample_rate, min_separation_cents=100.0)
    assert not any(abs(p.frequency_hz - 1050.0) < 1.0 for p in merged)  # the weaker of the pair


def test_silence_and_tiny_inputs_have_no_partials():
    assert find_partials(np.zeros(48000), 48000) == []
    assert find_partials(np.ones(5), 48000) == []
    p = measure_partial(np.zeros(48000), 48000, 100.0)
    assert math.isnan(p.frequency_hz) and p.level_db == -math.inf


# ----------------------------------------------------------------------------------
# measure_partial
# ----------------------------------------------------------------------------------
@pytest.mark.parametrize("sample_rate", [44100, 48000, 96000])
def test_measure_partial_is_precise(sample_rate):
    x = decaying_cosines(BAR_MODES, sample_rate, 2.0)
    for frequency_hz, amplitude, t60_s, _ in BAR_MODES:
        # asked for 0.1 % off the truth
        p = measure_partial(x, sample_rate, frequency_hz * 1.001)
        assert cents(p.frequency_hz, frequency_hz) < 0.2, frequency_hz
        assert p.t60_s == pytest.approx(t60_s, rel=0.03), frequency_hz
        assert p.level_db == pytest.approx(level_db(amplitude), abs=0.5), frequency_hz


@pytest.mark.parametrize("bandwidth_hz", [5.0, 12.5, 25.0])
def test_measure_partial_with_a_given_bandwidth(bandwidth_hz):
    sample_rate = 48000
    modes = [(1000.0, 0.5, 1.0, 0.3), (1050.0, 0.005, 2.0, 1.1)]
    x = decaying_cosines(modes, sample_rate, 2.0)
    for frequency_hz, amplitude, t60_s, _ in modes:
        p = measure_partial(x, sample_rate, frequency_hz, bandwidth_hz=bandwidth_hz)
        assert cents(p.frequency_hz, frequency_hz) < 0.2
        assert p.t60_s == pytest.approx(t60_s, rel=0.03)
        assert p.level_db == pytest.approx(level_db(amplitude), abs=0.5)


def test_measure_partial_where_there_is_none():
    sample_rate = 48000
    x = decaying_cosines([(440.0, 0.5, 1.5, 0.0)], sample_rate, 1.0)
    p = measure_partial(x, sample_rate, 3000.0)
    assert math.isnan(p.frequency_hz) and math.isnan(p.t60_s) and p.level_db == -math.inf


# ----------------------------------------------------------------------------------
# band_decay_t60
# ----------------------------------------------------------------------------------
def noise_resonance(seed, sample_rate=48000, duration_s=3.0, centre_hz=1000.0, q=20.0, t60_s=0.8):
    """White noise through a two-pole band-pass, faded out exponentially."""
    from scipy import signal

    rng = np.random.default_rng(seed)
    n = int(duration_s * sample_rate)
    b, a = signal.iirpeak(centre_hz, q, sample_rate)
    t = np.arange(n) / sample_rate
    y = signal.lfilter(b, a, rng.standard_normal(n)) * np.exp(-t * LN1000 / t60_s)
    return 0.5 * y / np.max(np.abs(y))


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("bandwidth_hz", [50.0, 200.0])
def test_band_decay_t60_of_a_noise_excited_resonance(seed, bandwidth_hz):
    y = noise_resonance(seed)
    assert band_decay_t60(y, 48000, 1000.0, bandwidth_hz) == pytest.approx(0.8, rel=0.10)


def test_band_decay_t60_above_a_noise_floor():
    rng = np.random.default_rng(3)
    y = noise_resonance(3, t60_s=0.5) + 10 ** (-70 / 20) * rng.standard_normal(3 * 48000)
    assert band_decay_t60(y, 48000, 1000.0, 100.0) == pytest.approx(0.5, rel=0.10)


def test_band_decay_t60_of_a_damped_cosine_is_exact():
    x = decaying_cosines([(440.0, 0.5, 1.5, 0.3), (3000.0, 0.5, 0.2, 0.0)], 48000, 2.0)
    assert band_decay_t60(x, 48000, 440.0, 40.0) == pytest.approx(1.5, rel=0.01)
    assert band_decay_t60(x, 48000, 3000.0, 200.0) == pytest.approx(0.2, rel=0.01)


def test_find_partials_on_a_noise_excited_resonance():
    y = noise_resonance(0)
    partials = find_partials(y, 48000)
    assert 1 <= len(partials) <= 8
    strongest = max(partials, key=lambda p: p.level_db)
    assert abs(strongest.frequency_hz - 1000.0) < 50.0  # within the resonance's bandwidth


# ----------------------------------------------------------------------------------
# results
# ----------------------------------------------------------------------------------
def test_partial_json_uses_null_for_inf_and_nan():
    plain = Partial(440.0, -6.0, 1.5).to_json()
    assert plain == {"frequency_hz": 440.0, "level_db": -6.0, "t60_s": 1.5}
    steady = Partial(440.0, -6.0, math.inf).to_json()
    assert steady["t60_s"] is None
    unknown = Partial(math.nan, -math.inf, math.nan).to_json()
    assert unknown == {"frequency_hz": None, "level_db": None, "t60_s": None}
    json.dumps([steady, unknown], allow_nan=False)  # strict JSON


def test_partial_ratios():
    partials = [Partial(100.0, 0.0, 1.0), Partial(276.0, -3.0, 0.5), Partial(540.4, -9.0, 0.2)]
    assert partial_ratios(partials) == pytest.approx([1.0, 2.76, 5.404])
    assert partial_ratios([300.0, 150.0]) == pytest.approx([2.0, 1.0])
    assert partial_ratios([]).size == 0
    with pytest.raises(ParameterError):
        partial_ratios([0.0, 100.0])


def test_ratios_of_a_free_free_bar():
    # Euler-Bernoulli free-free bar: 1, 2.756, 5.404, 8.933
    ratios = [1.0, 2.756, 5.404, 8.933]
    modes = [(200.0 * r, 0.3 / (i + 1), 2.0 / (i + 1), i) for i, r in enumerate(ratios)]
    partials = find_partials(decaying_cosines(modes, 44100, 1.5), 44100)
    assert partial_ratios(partials) == pytest.approx(ratios, rel=1e-6)


# ----------------------------------------------------------------------------------
# files
# ----------------------------------------------------------------------------------
def test_wav_round_trip(tmp_path):
    import soundfile

    sample_rate = 44100
    x = decaying_cosines([(440.0, 0.5, 1.0, 0.0)], sample_rate, 0.5)
    stereo = np.stack([x, 0.5 * x], axis=1)
    path = tmp_path / "strike.wav"
    soundfile.write(path, stereo, sample_rate, subtype="FLOAT")
    mono, rate = load_audio(path)
    assert rate == sample_rate
    assert mono.ndim == 1 and mono.dtype == np.float64
    np.testing.assert_allclose(mono, 0.75 * x, atol=1e-6)
    (p,) = find_partials(mono, rate)
    assert cents(p.frequency_hz, 440.0) < 0.2


def test_flac_round_trip_in_16_bit(tmp_path):
    import soundfile

    x = decaying_cosines([(1000.0, 0.5, 1.0, 0.0)], 48000, 0.3)
    path = tmp_path / "strike.flac"
    soundfile.write(str(path), x, 48000, subtype="PCM_16")
    mono, rate = load_audio(str(path))
    assert rate == 48000
    np.testing.assert_allclose(mono, x, atol=2.0 / 32768)


def test_missing_file(tmp_path):
    path = tmp_path / "nothing-here.wav"
    with pytest.raises(AudioFileError, match="nothing-here.wav") as info:
        load_audio(path)
    assert "\n" not in str(info.value)


def test_text_file_named_wav(tmp_path):
    path = tmp_path / "not-audio.wav"
    path.write_text("this is not a sound\n")
    with pytest.raises(AudioFileError, match="not-audio.wav") as info:
        load_audio(path)
    assert "\n" not in str(info.value)
    assert isinstance(info.value, BarsynthError)


def test_empty_wav_and_folder(tmp_path):
    import soundfile

    path = tmp_path / "empty.wav"
    soundfile.write(path, np.zeros(0), 44100)
    with pytest.raises(AudioFileError, match="empty.wav"):
        load_audio(path)
    with pytest.raises(AudioFileError, match=str(tmp_path.name)):
        load_audio(tmp_path)


# ----------------------------------------------------------------------------------
# pictures
# ----------------------------------------------------------------------------------
def test_spectrogram_shows_a_tone_where_it_is():
    sample_rate = 48000
    t = np.arange(sample_rate) / sample_rate
    x = np.cos(2.0 * math.pi * 3000.0 * t)
    times, freqs, power_db = spectrogram(x, sample_rate, window_s=0.02, hop_s=0.01)
    assert power_db.shape == (freqs.size, times.size)
    assert times[0] == 0.0 and times[-1] <= 1.0
    assert np.diff(times) == pytest.approx(0.01)
    assert freqs[-1] == pytest.approx(sample_rate / 2)
    middle = power_db[:, times.size // 2]
    assert freqs[np.argmax(middle)] == pytest.approx(3000.0, abs=freqs[1])
    assert middle.max() == pytest.approx(0.0, abs=1.5)  # a unit cosine is 0 dB


def test_plot_sound_writes_a_png(tmp_path):
    sample_rate = 44100
    x = decaying_cosines(BAR_MODES[:5], sample_rate, 1.0)
    partials = find_partials(x, sample_rate)
    path = plot_sound(x, sample_rate, tmp_path / "bar.png", title="a bar", partials=partials)
    data = path.read_bytes()
    assert data.startswith(PNG_SIGNATURE) and len(data) > 10_000
    other = plot_sound(x[:100], sample_rate, str(tmp_path / "tiny.png"), max_frequency_hz=5000.0)
    assert other.read_bytes().startswith(PNG_SIGNATURE)


def test_importing_analysis_loads_neither_matplotlib_nor_scipy():
    code = (
        "import sys, barsynth.analysis; "
        "print(sorted(m for m in ('matplotlib', 'scipy', 'soundfile') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


# ----------------------------------------------------------------------------------
# bad arguments
# ----------------------------------------------------------------------------------
GOOD = np.zeros(4800)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: find_partials(np.zeros((2, 100)), 48000), "samples"),
        (lambda: find_partials(np.zeros(0), 48000), "samples"),
        (lambda: find_partials(np.array([0.0, np.nan, 0.0]), 48000), "samples"),
        (lambda: find_partials(np.zeros(10, dtype=complex), 48000), "samples"),
        (lambda: find_partials("noise", 48000), "samples"),
        (lambda: find_partials(GOOD, 0), "sample_rate"),
        (lambda: find_partials(GOOD, -44100), "sample_rate"),
        (lambda: find_partials(GOOD, float("nan")), "sample_rate"),
        (lambda: find_partials(GOOD, "fast"), "sample_rate"),
        (lambda: find_partials(GOOD, 48000, max_partials=0), "max_partials"),
        (lambda: find_partials(GOOD, 48000, max_partials=2.5), "max_partials"),
        (lambda: find_partials(GOOD, 48000, min_level_db=10.0), "min_level_db"),
        (lambda: find_partials(GOOD, 48000, min_separation_cents=-1.0), "min_separation_cents"),
        (lambda: find_partials(GOOD, 48000, min_frequency_hz=30000.0), "min_frequency_hz"),
        (lambda: measure_partial(GOOD, 48000, 0.0), "frequency_hz"),
        (lambda: measure_partial(GOOD, 48000, 24000.0), "frequency_hz"),
        (lambda: measure_partial(GOOD, 48000, 440.0, bandwidth_hz=-5.0), "bandwidth_hz"),
        (lambda: band_decay_t60(GOOD, 48000, 30000.0, 100.0), "centre_hz"),
        (lambda: band_decay_t60(GOOD, 48000, 1000.0, 0.0), "bandwidth_hz"),
        (lambda: spectrogram(GOOD, 48000, window_s=0.0), "window_s"),
        (lambda: spectrogram(GOOD, 48000, window_s=10.0), "window_s"),
        (lambda: spectrogram(GOOD, 48000, hop_s=-0.01), "hop_s"),
        (lambda: plot_sound(GOOD, 48000, "/no/such/folder/x.png"), "path"),
    ],
)
def test_bad_arguments_raise_parameter_error(call, name):
    with pytest.raises(ParameterError, match=name) as info:
        call()
    assert isinstance(info.value, ValueError)
    assert "\n" not in str(info.value)
