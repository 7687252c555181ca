"""The ruler twang, measured: frequencies, decays, gains, Nyquist, noise bands, glides, clicks.

What every model owes the voice contract (blocks, seeds, rates, random settings, clicks on a
change, allocations) is in tests/test_voice_contract.py, with the twang's scenarios."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import stats

from barsynth import ParameterError
from barsynth.analysis import band_decay_t60, measure_partial
from barsynth.models import get_model
from barsynth.models.twang import TWANG_TABLE, TwangVoice
from barsynth.physics import bar_frequencies, lambdas
from barsynth.presets import preset_names, preset_parameters
from clicks import MAX_HIGHPASS_SPIKE, MAX_STEP_RATIO, highpass_spike, step_ratio

MODEL = get_model("twang")
CENTS = 1200.0


def cents(a: float, b: float) -> float:
    return CENTS * math.log2(a / b)


def _strategy(p):
    if p.kind == "choice":
        return st.sampled_from(p.choices)
    if p.kind == "bool":
        return st.booleans()
    return st.floats(min_value=p.minimum, max_value=p.maximum, allow_nan=False)


def deterministic(**overrides):
    """Only the cantilever oscillators (no noise), vibrato and slide off."""
    return {"free_bar_gain": 0.0, **overrides}


# -- the modes -------------------------------------------------------------------------
def test_describe_follows_the_beam_physics():
    p = {"youngs_modulus_pa": 3.2e9, "density_kg_m3": 1180.0, "length_m": 0.3, "thickness_m": 0.003}
    modes = MODEL.describe(p, sample_rate=48000)
    groups = {g: [m for m in modes if m.group == g] for g in ("full-cantilever", "short-cantilever", "free-bar")}
    full = bar_frequencies(bc="clamped-free", count=6, **p)
    free = bar_frequencies(bc="free-free", count=6, **p)
    assert [m.frequency_hz for m in groups["full-cantilever"]] == pytest.approx(full, rel=1e-12)
    assert [m.frequency_hz for m in groups["short-cantilever"]] == pytest.approx(full / 0.49, rel=1e-12)
    assert [m.frequency_hz for m in groups["free-bar"]] == pytest.approx(free, rel=1e-12)
    # the spec's note: a 30 cm plastic ruler's full-length fundamental is about 8 Hz
    assert 8.0 < full[0] < 10.0
    for m in modes:  # T60 = ln(1000) Q / (pi f), Q = 100 by default
        assert m.t60_s == pytest.approx(math.log(1000) * 100 / (math.pi * m.frequency_hz), rel=1e-12)


@pytest.mark.parametrize("mapping", ["linear", "log"])
@pytest.mark.parametrize("shape", [0.5, 1.0, 1.5, 4.0, 10.0])
def test_gains_follow_the_beta_density(shape, mapping):
    rate = 48000.0
    modes = MODEL.describe({"shape": shape, "gain_mapping": mapping}, sample_rate=rate)
    full = [m for m in modes if m.group == "full-cantilever"]
    short = [m for m in modes if m.group == "short-cantilever"]
    free = [m for m in modes if m.group == "free-bar"]
    shaped = full + free
    f = np.array([m.frequency_hz for m in shaped])
    if mapping == "linear":
        x = f / (rate / 2)
    else:
        x = np.log(f) / np.log(rate / 2)
    pdf = stats.beta(shape, 4).pdf(x)
    expected = pdf / pdf.max()
    assert [m.gain for m in shaped] == pytest.approx(expected, rel=1e-9)
    assert max(m.gain for m in shaped) == pytest.approx(1.0)
    assert [m.gain for m in short] == pytest.approx([0.75 * m.gain for m in full], rel=1e-12)


def test_modes_at_or_above_nyquist_are_dropped_and_not_aliased():
    # a thin steel bar at 8 kHz: the upper short-cantilever and free modes pass Nyquist
    p = deterministic(youngs_modulus_pa=200e9, density_kg_m3=7850.0, length_m=0.1,
                      thickness_m=0.002, q=800)
    rate = 8000.0
    all_full = bar_frequencies(youngs_modulus_pa=200e9, density_kg_m3=7850.0, length_m=0.1,
                               thickness_m=0.002, bc="clamped-free", count=6)
    above = [f for f in np.concatenate([all_full, all_full / 0.49]) if f >= rate / 2]
    assert above, "the test needs modes above Nyquist"
    listed = [m.frequency_hz for m in MODEL.describe(p, sample_rate=rate)]
    assert all(f < rate / 2 for f in listed)
    x = MODEL.render(p, duration_s=1.0, sample_rate=rate, normalize=False).astype(np.float64)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    freqs = np.fft.rfftfreq(x.size, 1 / rate)
    peak = spectrum.max()
    for f in above:
        alias = abs((f + rate / 2) % rate - rate / 2)  # where a folded partial would land
        band = (freqs > alias - 20) & (freqs < alias + 20)
        near_real = any(abs(alias - g) < 40 for g in listed)
        if not near_real:
            assert spectrum[band].max() < peak * 1e-5, f"energy at the alias {alias:.0f} Hz of {f:.0f} Hz"


# -- the rendered sound, measured ------------------------------------------------------
@pytest.mark.parametrize("rate", [44100.0, 48000.0, 96000.0])
@pytest.mark.parametrize("preset", ["plastic-30cm", "steel-30cm"])
def test_oscillator_peaks_within_one_cent_and_t60_within_5_percent(preset, rate):
    params = {**preset_parameters("twang", preset), **deterministic()}
    modes = MODEL.describe(params, sample_rate=rate)
    x = MODEL.render(params, duration_s=3.0, sample_rate=rate, normalize=False).astype(np.float64)
    freqs = sorted(m.frequency_hz for m in modes)
    checked = 0
    for m in modes:
        others = [f for f in freqs if f != m.frequency_hz]
        gap = min(abs(f - m.frequency_hz) for f in others)
        if gap < 2.0:  # an exact near-coincidence cannot be split by any measurement
            continue
        if m.gain < 1e-3 or m.t60_s < 0.05:
            continue
        found = measure_partial(x, rate, m.frequency_hz, bandwidth_hz=min(0.4 * gap, 0.4 * m.frequency_hz))
        assert abs(cents(found.frequency_hz, m.frequency_hz)) < 1.0, (m, found)
        assert found.t60_s == pytest.approx(m.t60_s, rel=0.05), (m, found)
        checked += 1
    assert checked >= 8


FREE_BAND_PARAMS = {"full_cantilever_gain": 0.0, "short_cantilever_gain": 0.0, "q": 200.0,
                    "free_band_q": 20.0, "youngs_modulus_pa": 200e9, "density_kg_m3": 7850.0,
                    "thickness_m": 0.001, "length_m": 0.15}


def test_free_bar_bands_centred_as_described():
    """The free-bar bands are noise: their centres are measured over six seeds, as the
    power-weighted mean log-frequency of the averaged spectrum within one bandwidth of
    the centre (a 4th-order band-pass is nearly symmetric in log f)."""
    rate = 48000.0
    modes = [m for m in MODEL.describe(FREE_BAND_PARAMS, sample_rate=rate) if m.group == "free-bar"]
    runs = [MODEL.render(FREE_BAND_PARAMS, duration_s=3.0, sample_rate=rate, seed=s, normalize=False)
            .astype(np.float64) for s in range(6)]
    power = np.mean([np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2 for x in runs], axis=0)
    freqs = np.fft.rfftfreq(runs[0].size, 1 / rate)
    for m in modes[:5]:
        bandwidth = m.frequency_hz / 20.0
        window = (freqs > m.frequency_hz - bandwidth) & (freqs < m.frequency_hz + bandwidth)
        centre = np.exp(np.sum(power[window] * np.log(freqs[window])) / np.sum(power[window]))
        assert abs(cents(centre, m.frequency_hz)) < 5.0, (m.frequency_hz, centre)


@pytest.mark.parametrize("band", range(5))
def test_each_free_bar_band_decays_with_its_t60(band):
    """Each band soloed (mode_mask), its energy envelope averaged over six seeds: in the
    full mix the skirts of slower bands hold up the tail of faster ones."""
    rate = 48000.0
    modes = [m for m in MODEL.describe(FREE_BAND_PARAMS, sample_rate=rate) if m.group == "free-bar"]
    mode = modes[band]
    mask = np.zeros(18, dtype=bool)
    mask[12 + band] = True
    measured = []
    for seed in range(6):
        voice = TwangVoice(FREE_BAND_PARAMS, sample_rate=rate, seed=seed, mode_mask=mask)
        voice.trigger()
        x = voice.process(int(min(3.0, 4 * mode.t60_s) * rate), dtype=np.float64)
        measured.append(band_decay_t60(x, rate, mode.frequency_hz, mode.frequency_hz / 20))
    assert np.mean(measured) == pytest.approx(mode.t60_s, rel=0.05), measured


def test_mode_mask_solos_and_rejects_bad_masks():
    mask = np.zeros(18, dtype=bool)
    mask[3] = True
    voice = TwangVoice(deterministic(), mode_mask=mask)
    voice.trigger()
    x = voice.process(48000, dtype=np.float64)
    mode = [m for m in MODEL.describe(deterministic()) if m.group == "full-cantilever"][3]
    spectrum = np.abs(np.fft.rfft(x))
    peak_hz = np.argmax(spectrum) * 48000 / x.size
    assert abs(peak_hz - mode.frequency_hz) < 1.5
    # the level scale ignores the mask: a soloed mode keeps its place in the mix
    modes = MODEL.describe(deterministic())
    cantilever_sum = sum(m.gain for m in modes if m.group != "free-bar")
    assert x[0] == pytest.approx(10 ** (-3 / 20) * mode.gain / cantilever_sum)
    for bad in ([1, 0], np.full(18, 2)):
        with pytest.raises(ParameterError, match="mode_mask"):
            TwangVoice(mode_mask=bad)


def test_first_sample_is_the_level():
    for level in (-3.0, -20.0):
        x = MODEL.render({"level_db": level}, duration_s=0.01, normalize=False, dtype=np.float64)
        assert x[0] == pytest.approx(10 ** (level / 20), rel=1e-12)


def test_normalised_render_peaks_at_minus_one_dbfs():
    x = MODEL.render(duration_s=0.5)
    assert x.dtype == np.float32
    assert float(np.max(np.abs(x))) == pytest.approx(10 ** (-1 / 20), rel=1e-6)


def test_vibrato_swings_the_loudest_mode_by_the_depth():
    rate = 48000.0
    params = deterministic(vibrato_rate_hz=4.0, vibrato_depth_hz=10.0, q=800.0, level_db=-3.0)
    modes = MODEL.describe(params, sample_rate=rate)
    loudest = max(modes, key=lambda m: m.gain)
    x = MODEL.render(params, duration_s=2.0, sample_rate=rate, normalize=False).astype(np.float64)
    t = np.arange(x.size) / rate
    analytic = x * np.exp(-2j * np.pi * loudest.frequency_hz * t)
    from scipy.signal import butter, sosfiltfilt

    sos = butter(4, 40.0, fs=rate, output="sos")
    baseband = sosfiltfilt(sos, analytic.real) + 1j * sosfiltfilt(sos, analytic.imag)
    inst = loudest.frequency_hz + np.diff(np.unwrap(np.angle(baseband))) * rate / (2 * np.pi)
    middle = inst[int(0.3 * rate):int(1.8 * rate)]
    swing = 0.5 * (np.percentile(middle, 99.5) - np.percentile(middle, 0.5))
    assert swing == pytest.approx(10.0, rel=0.1)
    spectrum = np.abs(np.fft.rfft(middle - middle.mean()))
    rate_found = np.fft.rfftfreq(middle.size, 1 / rate)[np.argmax(spectrum)]
    assert rate_found == pytest.approx(4.0, abs=0.7)


def test_slide_raises_the_short_cantilever_by_35_percent():
    rate = 48000.0
    params = {"full_cantilever_gain": 0.0, "free_bar_gain": 0.0, "slide": True, "slide_time_s": 0.5,
              "q": 800.0, "shape": 1.0}
    modes = [m for m in MODEL.describe(params, sample_rate=rate) if m.group == "short-cantilever"]
    target = modes[2]  # a well separated mid mode
    x = MODEL.render(params, duration_s=1.5, sample_rate=rate, normalize=False).astype(np.float64)
    late = x[int(0.7 * rate):]
    found = measure_partial(late, rate, target.frequency_hz * 1.35, bandwidth_hz=0.1 * target.frequency_hz)
    assert abs(cents(found.frequency_hz, target.frequency_hz * 1.35)) < 1.0
    # before the slide gets going the mode is at its resting pitch
    spectrum = np.abs(np.fft.rfft(x[:int(0.05 * rate)] * np.hanning(int(0.05 * rate)), 1 << 16))
    fgrid = np.fft.rfftfreq(1 << 16, 1 / rate)
    win = (fgrid > target.frequency_hz * 0.9) & (fgrid < target.frequency_hz * 1.1)
    assert fgrid[win][np.argmax(spectrum[win])] == pytest.approx(target.frequency_hz, rel=0.03)


def _click_measures(x: np.ndarray, change: int, rate: int) -> tuple[float, float]:
    """(step ratio from 5 ms before to 25 ms after the change, high-pass spike): tests/clicks.py."""
    return step_ratio(x, change, rate, around_ms=(5, 25)), highpass_spike(x, change, rate)


def _measure_change(params, name, value, *, seed=0, rate=48000) -> tuple[float, float]:
    """Trigger, play 0.3 s, change one parameter, play 0.1 s: the click measures."""
    voice = TwangVoice(params, sample_rate=rate, seed=seed)
    voice.trigger()
    before = voice.process(int(0.3 * rate), dtype=np.float64)
    voice.set_parameters(**{name: value})
    x = np.concatenate([before, voice.process(int(0.1 * rate), dtype=np.float64)])
    assert np.all(np.isfinite(x))
    return _click_measures(x, before.size, rate)


NOISY_CHANGES = [("noise_cutoff_hz", 500.0), ("free_band_q", 60.0), ("free_band_q", 2.0),
                 ("free_bar_gain", 4.0), ("length_m", 0.2), ("q", 50.0), ("level_db", -30.0)]


@pytest.mark.parametrize("name,value", NOISY_CHANGES)
def test_change_with_the_noise_bands_sounding_does_not_click(name, value):
    """With the free bar on, steps are noise; only the 12 kHz high-pass spike is a fair
    measure (every band of this ruler lies below 3 kHz)."""
    _, spike = _measure_change({"q": 400.0}, name, value, seed=5)
    assert spike <= MAX_HIGHPASS_SPIKE, (name, spike)


def test_raising_the_mix_from_almost_nothing_stays_at_the_level():
    rate = 48000
    voice = TwangVoice({"full_cantilever_gain": 0.001, "short_cantilever_gain": 0.0, "free_bar_gain": 0.0},
                       sample_rate=rate)
    voice.trigger()
    quiet = voice.process(int(0.1 * rate), dtype=np.float64)
    voice.set_parameters(full_cantilever_gain=1.0, short_cantilever_gain=0.75, free_bar_gain=1.0)
    loud = voice.process(int(0.3 * rate), dtype=np.float64)
    level = 10 ** (-3 / 20)
    assert np.max(np.abs(quiet)) < 0.01 * level
    assert 0.1 * level < np.max(np.abs(loud)) < level


def test_vibrato_turned_off_mid_note_returns_to_pitch():
    rate = 48000.0
    params = deterministic(vibrato_rate_hz=5.0, q=800.0)
    loudest = max(MODEL.describe(params, sample_rate=rate), key=lambda m: m.gain)
    voice = TwangVoice(params, sample_rate=rate)
    voice.trigger()
    voice.process(int(0.37 * rate))
    voice.set_parameters(vibrato_rate_hz=0.0)
    voice.process(int(0.2 * rate))
    x = voice.process(int(1.0 * rate), dtype=np.float64)
    found = measure_partial(x, rate, loudest.frequency_hz, bandwidth_hz=20.0)
    assert abs(cents(found.frequency_hz, loudest.frequency_hz)) < 0.5


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.fixed_dictionaries({p.name: _strategy(p) for p in TWANG_TABLE if p.sets is None}),
       st.fixed_dictionaries({p.name: _strategy(p) for p in TWANG_TABLE if p.sets is None}),
       st.sampled_from([8000.0, 48000.0, 192000.0]))
def test_random_changes_mid_note_stay_finite_and_bounded(first, second, rate):
    """Any jump across the ranges while sounding: finite, and within the level times the
    largest mix (1.14 cantilever, 4 free bar) with room for noise crests."""
    second["level_db"] = first["level_db"]
    voice = TwangVoice(first, sample_rate=rate, seed=1)
    voice.trigger()
    x = np.concatenate([voice.process(int(0.05 * rate), dtype=np.float64),
                        (voice.set_parameters(**second), voice.process(int(0.25 * rate), dtype=np.float64))[1]])
    assert np.all(np.isfinite(x))
    assert np.max(np.abs(x)) < 8.0 * 10 ** (first["level_db"] / 20)


def test_change_is_heard_within_50_ms():
    rate = 48000
    voice = TwangVoice(deterministic(q=800.0), sample_rate=rate)
    voice.trigger()
    voice.process(int(0.1 * rate))
    voice.set_parameters(level_db=-40.0)
    voice.process(int(0.05 * rate))
    x = voice.process(int(0.02 * rate), dtype=np.float64)
    assert np.max(np.abs(x)) < 10 ** (-36 / 20)


# -- robustness --------------------------------------------------------------------------
@pytest.mark.parametrize("p", [p for p in TWANG_TABLE if p.kind in ("float", "int")], ids=lambda p: p.name)
def test_every_parameter_rejected_just_outside_its_range(p):
    span = p.maximum - p.minimum
    for bad in (p.minimum - 1e-6 * span, p.maximum + 1e-6 * span, float("nan"), float("inf"), "x"):
        with pytest.raises(ParameterError) as info:
            MODEL.render({p.name: bad}, duration_s=0.01)
        message = str(info.value)
        assert p.name in message and "allowed" in message
        assert p.unit_label in message
    MODEL.render({p.name: p.minimum}, duration_s=0.01)
    MODEL.render({p.name: p.maximum}, duration_s=0.01)


def test_choice_bool_and_unknown_parameters_rejected():
    for values in ({"gain_mapping": "cubic"}, {"slide": "maybe"}, {"no_such_thing": 1.0}):
        with pytest.raises(ParameterError):
            MODEL.render(values, duration_s=0.01)
    voice = TwangVoice()
    with pytest.raises(ParameterError):
        voice.set_parameters(q=10.0)
    assert voice.parameters.q == 100.0  # a refused change leaves the voice as it was
    for bad in (-1, 1.5, True):
        with pytest.raises(ParameterError):
            voice.process(bad)
    for bad_dtype in ("foo", np.int16):
        with pytest.raises(ParameterError, match="dtype"):
            voice.process(4, dtype=bad_dtype)
        with pytest.raises(ParameterError, match="dtype"):
            MODEL.render(duration_s=0.1, dtype=bad_dtype)
    with pytest.raises(ParameterError, match="parameters"):
        MODEL.render([1, 2], duration_s=0.1)


@pytest.mark.parametrize("duration", [0.0, -1.0, 601.0, float("inf"), 1e-6])
def test_bad_durations_rejected(duration):
    with pytest.raises(ParameterError, match="duration_s"):
        MODEL.render(duration_s=duration)


def test_presets_exist_resolve_and_sound():
    names = preset_names("twang")
    for needed in ("plastic-30cm", "wooden-30cm", "steel-30cm"):
        assert needed in names
    for name in names:
        params = TWANG_TABLE.resolve(preset_parameters("twang", name))
        x = MODEL.render(params, duration_s=0.5, normalize=False, dtype=np.float64)
        assert np.all(np.isfinite(x))
        # every preset is cantilever-dominated, so its first sample is exactly the level
        assert x[0] == pytest.approx(10 ** (params.level_db / 20), rel=1e-12)
        assert len(MODEL.describe(params)) == 18


def test_lambdas_used_are_the_physics_layer_ones():
    from barsynth.models.twang.design import mode_lambdas

    assert np.array_equal(mode_lambdas()[:6], lambdas("clamped-free", 6))
    assert np.array_equal(mode_lambdas()[6:], lambdas("free-free", 6))


def test_retrigger_after_a_change_sounds_like_a_fresh_note():
    """The old note's filter state must not ring out through the new note's bands."""
    rate = 48000.0
    old = {"q": 400.0}
    new = {"youngs_modulus_pa": 1e8, "density_kg_m3": 900.0, "length_m": 0.5, "thickness_m": 0.003,
           "free_band_q": 100.0, "level_db": 0.0}
    fresh = MODEL.render(new, duration_s=0.5, sample_rate=rate, normalize=False, dtype=np.float64)
    voice = TwangVoice(old, sample_rate=rate)
    voice.trigger()
    voice.process(int(0.2 * rate))
    voice.set_parameters(**new)
    voice.trigger()
    again = voice.process(int(0.5 * rate), dtype=np.float64)
    assert np.max(np.abs(again)) < 1.5 * np.max(np.abs(fresh))


def test_renders_without_an_audible_mode_are_refused():
    sub_audio = {"youngs_modulus_pa": 1e8, "density_kg_m3": 22000.0, "length_m": 1.0, "thickness_m": 0.0003}
    assert all(m.frequency_hz < 20 for m in MODEL.describe(sub_audio))
    with pytest.raises(ParameterError, match="20 Hz"):
        MODEL.render(sub_audio, duration_s=0.2)


def test_extreme_values_of_the_wrong_size_are_parameter_errors():
    voice = TwangVoice()
    with pytest.raises(ParameterError, match="q"):
        voice.set_parameters(q=10**400)
    with pytest.raises(ParameterError, match="num_samples"):
        voice.process(2**62)
    with pytest.raises(ParameterError, match="dtype"):
        voice.process(4, dtype=None)


def test_the_control_vector_has_every_table_row_by_name():
    from barsynth.models.twang.table import ROWS, control_vector

    assert ROWS._fields == TWANG_TABLE.names
    assert tuple(ROWS) == tuple(range(len(TWANG_TABLE)))
    p = TWANG_TABLE.resolve({"gain_mapping": "log", "slide": True, "length_m": 0.2, "material": "steel"})
    values = control_vector(p)
    assert values[ROWS.gain_mapping] == 1.0 and values[ROWS.slide] == 1.0 and values[ROWS.length_m] == 0.2
    assert values[ROWS.youngs_modulus_pa] == p.youngs_modulus_pa


def test_ramps_are_multiplicative_for_log_scaled_rows():
    from barsynth.dsp.smoothing import LINEAR, MULTIPLICATIVE
    from barsynth.models.twang.voice import RAMP_KINDS

    for p, kind in zip(TWANG_TABLE, RAMP_KINDS):
        assert kind == (MULTIPLICATIVE if p.scale == "log" else LINEAR), p.name


def test_a_change_reaches_its_target_within_the_smoothing_time():
    """q from 100 to 400 (multiplicative) and length from 0.3 to 0.2 m (linear): the modes
    described for the new values sound exactly once the ramp of SMOOTHING_TIME_S has ended."""
    from barsynth.models.twang import SMOOTHING_TIME_S

    rate = 48000
    new = {"q": 400.0, "length_m": 0.2}
    voice = TwangVoice(deterministic(), sample_rate=rate)
    voice.trigger()
    voice.process(int(0.1 * rate))
    voice.set_parameters(**new)
    voice.process(int(SMOOTHING_TIME_S * rate) + 2 * 96)
    x = voice.process(rate, dtype=np.float64)
    loudest = max(MODEL.describe(deterministic(**new), sample_rate=rate), key=lambda m: m.gain)
    found = measure_partial(x, rate, loudest.frequency_hz, bandwidth_hz=0.2 * loudest.frequency_hz)
    assert abs(cents(found.frequency_hz, loudest.frequency_hz)) < 1.0
    assert found.t60_s == pytest.approx(loudest.t60_s, rel=0.05)


def test_the_golden_glide_does_not_click():
    """The golden 'glide' sound (length, q and level changed together 0.1 s into the note):
    no high-pass spike; and with the cantilever modes only (no noise, whose steps would
    hide a click's), no step beyond the click threshold either."""
    from golden import CHANGE_AT_S, GLIDES, render_case

    rate = 48000
    change = int(CHANGE_AT_S * rate)
    _, spike = _click_measures(render_case("twang", {}, rate, GLIDES["twang"]), change, rate)
    assert spike <= MAX_HIGHPASS_SPIKE, spike
    ratio, spike = _click_measures(render_case("twang", deterministic(), rate, GLIDES["twang"]), change, rate)
    assert ratio <= MAX_STEP_RATIO and spike <= MAX_HIGHPASS_SPIKE, (ratio, spike)


def test_mode_mask_set_on_a_voice_from_the_model():
    mask = np.zeros(18, dtype=bool)
    mask[3] = True
    soloed = TwangVoice(deterministic(), mode_mask=mask)
    voice = MODEL.voice(deterministic())
    voice.mode_mask = mask
    assert np.array_equal(voice.mode_mask, mask.astype(float))
    for v in (soloed, voice):
        v.trigger()
    assert np.array_equal(voice.process(4800), soloed.process(4800))
    with pytest.raises(ParameterError, match="mode_mask"):
        voice.mode_mask = [1, 0]


# -- the two kernels ---------------------------------------------------------------------
# A note that holds still runs the static kernel, designed once in Python (kernel.design_note);
# warm_up() puts a voice on the dynamic kernel, which designs in compiled code. Both must give
# the very same samples, and a static voice must be able to switch at any frame.
STILL_CASES = [
    {},
    {"length_m": 0.12, "thickness_m": 0.006, "q": 733.0, "shape": 4.7, "free_band_q": 57.0, "level_db": -17.3},
    {"gain_mapping": "log", "shape": 0.6, "free_bar_gain": 3.3, "noise_cutoff_hz": 17000.0, "material": "steel"},
    {"short_length_ratio": 0.31, "full_cantilever_gain": 0.2, "vibrato_rate_hz": 3.0, "vibrato_depth_hz": 0.0},
    {"length_m": 0.05, "thickness_m": 0.02, "youngs_modulus_pa": 4e11, "q": 50.0},  # modes above Nyquist
]


def _still_and_warm(params, rate, mode_mask=None):
    still = TwangVoice(params, sample_rate=rate, seed=3, mode_mask=mode_mask)
    warm = TwangVoice(params, sample_rate=rate, seed=3, mode_mask=mode_mask)
    warm.warm_up()
    return still, warm


@pytest.mark.parametrize("rate", [22050, 44100, 96000])
@pytest.mark.parametrize("params", STILL_CASES)
def test_a_still_note_designed_in_python_is_the_compiled_design(params, rate):
    """design() and _control() as plain Python give the compiled doubles: every record after
    the first frame, and every sample."""
    mask = np.ones(18)
    mask[[1, 8, 15]] = 0.0
    still, warm = _still_and_warm(params, rate, mask)
    for voice in (still, warm):
        voice.trigger()
    frame = still._setup.frame_len
    assert np.array_equal(still.process(frame, dtype=np.float64), warm.process(frame, dtype=np.float64))
    assert still._static and not warm._static  # (the cases hold still: otherwise this compares nothing)
    for ours, theirs in zip((still._osc, still._bands, still._modes), (warm._osc, warm._bands, warm._modes)):
        for name, a, b in zip(ours._fields, ours, theirs):
            assert np.array_equal(a, b), name
    from barsynth.models.twang.kernel import S

    keep = [i for i in range(len(S)) if i != S.dynamic]  # (see kernel.design_note)
    assert np.array_equal(still._note.scalars[keep], warm._note.scalars[keep])
    n = int(0.3 * rate)
    assert np.array_equal(still.process(n, dtype=np.float64), warm.process(n, dtype=np.float64))


@pytest.mark.parametrize("at", [0, 1, 95, 96, 97, 192, 4000])
@pytest.mark.parametrize("change", ["set", "same", "mask", "warm_up"])
def test_a_still_note_can_switch_to_the_dynamic_kernel_at_any_frame(at, change):
    """A change at any point of a still note (a new value, the same value again, a new mode
    mask, warm_up() itself) gives the samples of a voice that ran the dynamic kernel all along."""
    rate = 48000  # frames of 96 samples
    still, warm = _still_and_warm(STILL_CASES[1], rate)
    heads = []
    for voice in (still, warm):
        voice.trigger()
        heads.append(voice.process(at, dtype=np.float64) if at else np.zeros(0))
        if change == "set":
            voice.set_parameters(q=200.0, level_db=-6.0)
        elif change == "same":
            voice.set_parameters(q=voice.parameters.q)
        elif change == "mask":
            voice.mode_mask = [i % 4 != 1 for i in range(18)]
        else:
            voice.warm_up()
    assert np.array_equal(heads[0], heads[1])
    assert not still._static
    assert np.array_equal(still.process(8000, dtype=np.float64), warm.process(8000, dtype=np.float64))


def test_a_plain_note_runs_the_static_kernel_and_a_moving_one_the_dynamic():
    """What a first render compiles: a note that holds still needs only the static kernel (half
    the compile time); vibrato, slide and changes need the dynamic one."""
    plain = TwangVoice(sample_rate=48000)
    plain.trigger()
    plain.process(1000)
    assert plain._run_static is not None and plain._run_dynamic is None
    for params in ({"vibrato_rate_hz": 5.0}, {"slide": True}):
        moving = TwangVoice(params, sample_rate=48000)
        moving.trigger()
        moving.process(1000)
        assert moving._run_dynamic is not None and moving._run_static is None, params
    plain.set_parameters(q=150.0)
    plain.process(1000)
    assert plain._run_dynamic is not None
    plain.trigger()  # once it has the dynamic kernel, a voice keeps it
    plain.process(1000)
    assert not plain._static


def test_a_warmed_voice_keeps_the_dynamic_kernel_at_a_new_rate():
    voice = TwangVoice(sample_rate=48000)
    voice.warm_up()
    voice.prepare(44100)
    voice.trigger()
    assert not voice._static
    fresh = TwangVoice(sample_rate=44100)
    fresh.trigger()
    assert fresh._static
    assert np.array_equal(voice.process(5000, dtype=np.float64), fresh.process(5000, dtype=np.float64))
